"""The service's OpenAPI document fuzzed with schemathesis: every operation, with and without the token,
with data that fits the schema and data that does not, then a stateful run that follows the document's
links (a created or imported session's id into its own routes).

Every answer is checked against the document: not a server error, a documented status, the documented
media type, the documented headers, a body that fits the documented schema (``status_code_conformance``,
``content_type_conformance``, ``response_headers_conformance``, ``response_schema_conformance`` and
``not_a_server_error``). The event streams are left out (the station's never ends).

``make test`` runs a bounded version (``tests/api/test_fuzz.py``); ``python -m bench.api_fuzz`` (a ``make
bench`` step) runs 100 examples per operation and mode, on the simulated station, and writes
``bench/results/api_fuzz.json``.
"""

from __future__ import annotations

import argparse
import collections
import json
import logging
import tempfile
import threading
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import schemathesis
from hypothesis import HealthCheck, given, settings
from hypothesis.errors import FlakyStrategyDefinition, Unsatisfiable
from schemathesis.checks import not_a_server_error
from schemathesis.core.result import Ok
from schemathesis.generation import GenerationMode
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    response_headers_conformance,
    response_schema_conformance,
    status_code_conformance,
)
from schemathesis.transport.serialization import serialize_binary


@schemathesis.serializer("application/zip")
def _zip(ctx: Any, value: Any) -> bytes:
    """The import's body: bytes as generated (schemathesis has no serializer for zip)."""
    return serialize_binary(value)


CHECKS = [
    not_a_server_error,
    status_code_conformance,
    content_type_conformance,
    response_headers_conformance,
    response_schema_conformance,
]
SKIP = r"/events$"
"""The event streams: the station's never ends, a session's only with the session."""
RESULTS = Path(__file__).parent / "results" / "api_fuzz.json"


@dataclass
class FuzzReport:
    """What the run sent and what it found."""

    operations: int = 0
    requests: int = 0
    stateful_requests: int = 0
    scenarios: int = 0
    stateful_restarts: int = 0
    """Stateful runs that Hypothesis stopped as flaky (the service's state is not replayed)."""
    server_errors: list[str] = field(default_factory=list)
    violations: list[str] = field(default_factory=list)
    statuses: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0
    seconds_by_operation: dict[str, float] = field(default_factory=dict)

    def summary(self) -> str:
        return (
            f"schemathesis: {self.requests} requests over {self.operations} operations "
            f"({self.stateful_requests} in {self.scenarios} stateful scenarios), "
            f"{len(self.server_errors)} server errors, "
            f"{len(self.violations)} schema violations; statuses {dict(sorted(self.statuses.items()))}"
        )


def _failures(exc: BaseException) -> Iterator[BaseException]:
    inner = getattr(exc, "exceptions", None)
    if inner:
        for e in inner:
            yield from _failures(e)
    else:
        yield exc


class _Run:
    def __init__(self, base: str, token: str, report: FuzzReport) -> None:
        self.base = base
        self.auth = {"Authorization": f"Bearer {token}"}
        self.report = report
        self.statuses: collections.Counter[str] = collections.Counter()

    def check(self, case: Any, response: Any, headers: dict[str, str]) -> None:
        self.statuses[str(response.status_code)] += 1
        where = f"{case.method} {case.formatted_path} -> {response.status_code}"
        if response.status_code >= 500:
            self.report.server_errors.append(f"{where}: {response.text[:300]}")
        try:
            case.validate_response(response, checks=CHECKS, headers=headers)
        except Exception as exc:  # noqa: BLE001 - every failure is counted, not raised
            for failure in _failures(exc):
                title = getattr(failure, "title", type(failure).__name__)
                self.report.violations.append(f"{where}: {title}: {str(failure)[:300]}")


def fuzz(base: str, token: str, *, examples: int, stateful_examples: int, steps: int = 10) -> FuzzReport:
    """Fuzz the service at ``base`` (``examples`` per operation and generation mode, each sent with and
    without the token; ``stateful_examples`` scenarios of up to ``steps`` calls)."""
    started = time.monotonic()
    report = FuzzReport()
    run = _Run(base, token, report)
    schema = schemathesis.openapi.from_url(f"{base}/api/v1/openapi.json").exclude(path_regex=SKIP)
    operations = [r.ok() for r in schema.get_all_operations() if isinstance(r, Ok)]
    report.operations = len(operations)
    fast = settings(
        max_examples=examples,
        deadline=None,
        database=None,
        derandomize=True,
        suppress_health_check=list(HealthCheck),
    )
    for op in operations:
        began = time.monotonic()
        for mode in (GenerationMode.POSITIVE, GenerationMode.NEGATIVE):

            @fast
            @given(case=op.as_strategy(generation_mode=mode))
            def one(case: Any) -> None:
                for headers in (run.auth, {}):
                    response = case.call(base_url=base, headers=headers, timeout=60)
                    report.requests += 1
                    run.check(case, response, headers)

            try:
                one()
            except Unsatisfiable:  # nothing of this operation can be negated (no parameter, no body)
                assert mode is GenerationMode.NEGATIVE, op.label
        report.seconds_by_operation[op.label] = round(time.monotonic() - began, 2)
    if stateful_examples:
        began = time.monotonic()
        machine = schema.as_state_machine()

        class Scenario(machine):  # type: ignore[misc, valid-type]
            def setup(self) -> None:
                report.scenarios += 1

            def get_call_kwargs(self, case: Any) -> dict[str, Any]:
                return {"base_url": base, "headers": run.auth, "timeout": 60}

            def validate_response(self, response: Any, case: Any, **kwargs: Any) -> None:
                report.stateful_requests += 1
                report.requests += 1
                run.check(case, response, run.auth)

        # The service keeps its state from one scenario to the next (sessions, prompts), so a scenario that
        # Hypothesis replays may take another turn (a link with no session behind it yet): it calls that a
        # flaky strategy and stops. The run then goes on with a fresh seed until the scenarios are done.
        first = True
        while report.scenarios < stateful_examples and report.stateful_restarts <= stateful_examples:
            try:
                Scenario.run(
                    settings=settings(
                        max_examples=stateful_examples - report.scenarios,
                        stateful_step_count=steps,
                        deadline=None,
                        database=None,
                        derandomize=first,
                        suppress_health_check=list(HealthCheck),
                    )
                )
            except FlakyStrategyDefinition:
                report.stateful_restarts += 1
            first = False
        report.seconds_by_operation["stateful"] = round(time.monotonic() - began, 2)
    report.statuses = dict(run.statuses)
    report.seconds = round(time.monotonic() - started, 1)
    return report


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--examples", type=int, default=100, help="examples per operation and mode (100)")
    parser.add_argument("--stateful", type=int, default=100, help="stateful scenarios (100)")
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")

    import uvicorn

    from api import Access, ServeLimits, ServiceSettings, StationService, create_app, server_config

    token = "fuzz-token-0123456789abcdef"
    with tempfile.TemporaryDirectory() as tmp:
        service = StationService(ServiceSettings(sim=True, data=Path(tmp) / "data"))
        limits = ServeLimits()
        server = uvicorn.Server(
            server_config(create_app(service, Access(token)), limits, host="127.0.0.1", port=0)
        )
        thread = threading.Thread(target=server.run, daemon=True)
        thread.start()
        while not server.started:
            time.sleep(0.05)
        base = f"http://127.0.0.1:{server.servers[0].sockets[0].getsockname()[1]}"
        try:
            report = fuzz(base, token, examples=args.examples, stateful_examples=args.stateful)
        finally:
            server.should_exit = True
            thread.join(60)
    print(report.summary())
    for line in (report.server_errors + report.violations)[:20]:
        print("  ", line)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(
        json.dumps({"examples_per_operation_and_mode": args.examples, **asdict(report)}, indent=1)
    )
    raise SystemExit(1 if report.server_errors or report.violations else 0)


if __name__ == "__main__":
    main()
