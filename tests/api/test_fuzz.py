"""The OpenAPI schema fuzzed with schemathesis within a bounded budget: no request, with or without the
token, makes the server fail (no 5xx), and refusals are problem details. Event streams are left out
(they run until the client leaves)."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings

from tests.api.conftest import AUTH, Served

schemathesis = pytest.importorskip("schemathesis")
from schemathesis.checks import not_a_server_error  # noqa: E402

EXAMPLES_PER_OPERATION = 25
SKIP = ("/events",)


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_no_request_from_the_schema_makes_a_server_error(served: Served) -> None:
    schema = schemathesis.openapi.from_url(f"{served.base}/api/v1/openapi.json")
    operations = [r.ok() for r in schema.get_all_operations()]
    operations = [op for op in operations if not op.path.endswith(SKIP)]
    assert len(operations) >= 15
    cases = 0
    failures: list[str] = []

    for op in operations:

        @settings(
            max_examples=EXAMPLES_PER_OPERATION,
            deadline=None,
            database=None,
            derandomize=True,
            suppress_health_check=list(HealthCheck),
        )
        @given(case=op.as_strategy())
        def run(case: Any) -> None:
            nonlocal cases
            for headers in (AUTH, {}):
                response = case.call(base_url=served.base, headers=headers, timeout=30)
                cases += 1
                if response.status_code >= 500:
                    failures.append(
                        f"{case.method} {case.formatted_path}: {response.status_code} {response.text[:300]}"
                    )
                    case.validate_response(response, checks=[not_a_server_error])
                if response.status_code >= 400:
                    ctype = response.headers.get("content-type", [""])[0]  # lowercase keys, list values
                    assert ctype == "application/problem+json", (
                        case.method,
                        case.formatted_path,
                        response.status_code,
                    )

        run()
    print(f"schemathesis: {cases} requests over {len(operations)} operations, {len(failures)} server errors")
    assert failures == []
    with served.client() as c:
        assert c.get("/api/v1/health").status_code == 200
