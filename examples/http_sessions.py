"""The station's two sessions through its web API, with plain HTTP (the standard library only).

Start the service first (``station serve --sim``, or ``make run``), then::

    STATION_API_TOKEN=... python examples/http_sessions.py [--url http://127.0.0.1:8465]

The token is the one ``station serve`` printed (``...?token=TOKEN``) or the one it was given through
``STATION_API_TOKEN`` or the configuration. The script runs the seed's validation (answering each
micrometer prompt itself when nobody else does: what a person at the table would confirm) and a
six-joint repeatability test, following each session's progress through the API, and prints the results.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import urllib.error
import urllib.request
from typing import Any

FINAL = {"stopped", "aborted", "failed", "succeeded", "interrupted"}


class Station:
    """A tiny client of ``/api/v1``: JSON in, JSON out, errors as the problem's ``detail``."""

    def __init__(self, url: str, token: str) -> None:
        self.url = url.rstrip("/") + "/api/v1"
        self.token = token

    def call(self, method: str, path: str, body: dict[str, Any] | None = None) -> Any:
        data = json.dumps(body).encode() if body is not None else None
        request = urllib.request.Request(self.url + path, data=data, method=method)
        request.add_header("Authorization", f"Bearer {self.token}")
        if data is not None:
            request.add_header("Content-Type", "application/json")
        try:
            with urllib.request.urlopen(request, timeout=60) as response:
                text = response.read()
                return json.loads(text) if text else None
        except urllib.error.HTTPError as exc:
            problem = json.loads(exc.read() or b"{}")
            raise SystemExit(f"{method} {path}: {exc.code} {problem.get('detail', exc.reason)}") from None

    def run(self, kind: str, params: dict[str, Any], *, answer_prompts: bool) -> dict[str, Any]:
        """Start a session, follow it to its end (answering prompts if asked to), return its results."""
        session = self.call("POST", "/sessions", {"kind": kind, "params": params})
        sid = session["id"]
        print(f"{kind} session {sid} started", file=sys.stderr)
        last = None
        while session["state"] not in FINAL:
            p = session["progress"]
            line = f"  {session['state']}: {p['done']}/{p['total']} steps"
            if line != last:
                print(line, file=sys.stderr)
                last = line
            if answer_prompts and session["state"] == "awaiting_operator":
                prompt = self.call("GET", "/prompt")
                if prompt is not None:
                    readings = {f["name"]: f["requested"] for f in prompt["fields"]}
                    print(f"  operator: {prompt['message']}", file=sys.stderr)
                    self.call("POST", f"/prompt/{prompt['id']}/confirm", {"readings": readings})
            time.sleep(0.2)
            session = self.call("GET", f"/sessions/{sid}")
        print(f"{kind} session {sid}: {session['state']}", file=sys.stderr)
        results: dict[str, Any] = self.call("GET", f"/sessions/{sid}/results")
        return results


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--url", default="http://127.0.0.1:8465", help="the service's address")
    parser.add_argument(
        "--token", default=os.environ.get("STATION_API_TOKEN"), help="default $STATION_API_TOKEN"
    )
    parser.add_argument("--validation", default="{}", help="validation parameters (JSON)")
    parser.add_argument("--repeatability", default='{"cycles": 10}', help="repeatability parameters (JSON)")
    parser.add_argument("--answer-prompts", action="store_true", help="confirm each table prompt as asked")
    args = parser.parse_args(argv)
    if not args.token:
        parser.error("give --token or set STATION_API_TOKEN (station serve printed it in the page's URL)")
    station = Station(args.url, args.token)
    print(f"station: {station.call('GET', '/station')['name']}", file=sys.stderr)
    validation = station.run("validation", json.loads(args.validation), answer_prompts=args.answer_prompts)
    v = validation["results"]
    nan = float("nan")
    print(
        f"validation {validation['id']}: {validation['state']}; "
        f"mean {v.get('mean_um', nan):.3f} um, max {v.get('max_um', nan):.3f} um (rigid fit); "
        f"parallelogram mean {v.get('parallelogram_mean_um', nan):.3f} um"
    )
    repeatability = station.run(
        "repeatability", json.loads(args.repeatability), answer_prompts=args.answer_prompts
    )
    rp = repeatability["results"].get("rp_mm", {})
    print(
        f"repeatability {repeatability['id']}: {repeatability['state']}; RP (mm): "
        + ", ".join(f"{test} {value:.4f}" for test, value in rp.items())
    )
    for done in (validation, repeatability):
        print(f"report: {station.url}/sessions/{done['id']}/report.html")
    return 0 if validation["state"] == repeatability["state"] == "succeeded" else 1


if __name__ == "__main__":
    sys.exit(main())
