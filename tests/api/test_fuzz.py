"""The OpenAPI document lists every answer each route gives (issue 18, row 17), and schemathesis finds
none that it does not, within a bounded budget (``python -m bench.api_fuzz`` runs 100 examples per
operation): no server error, and every answer's status, media type, headers and body as documented."""

from __future__ import annotations

from typing import Any

import httpx
import pytest

from tests.api.conftest import TOKEN, Served

pytest.importorskip("schemathesis")
from bench.api_fuzz import fuzz

EXAMPLES_PER_OPERATION = 6
STATEFUL_SCENARIOS = 5


@pytest.fixture
def document(served: Served) -> dict[str, Any]:
    with httpx.Client(base_url=served.base, timeout=30) as c:
        doc: dict[str, Any] = c.get("/api/v1/openapi.json").json()
    return doc


def test_the_document_lists_the_answers(served: Served, document: dict[str, Any]) -> None:
    """export.zip was documented as JSON, no refusal was documented, Last-Event-ID had no schema."""
    paths = document["paths"]
    export = paths["/api/v1/sessions/{session_id}/export.zip"]["get"]["responses"]
    assert set(export["200"]["content"]) == {"application/zip"}
    assert "Content-Disposition" in export["200"]["headers"]
    report = paths["/api/v1/sessions/{session_id}/report.html"]["get"]["responses"]
    assert set(report["200"]["content"]) == {"text/html"}
    for path, item in paths.items():
        for method, operation in item.items():
            answers = operation["responses"]
            for status in ("400", "405", "408", "503"):  # the edge's, before any route
                assert status in answers, (method, path, status)
            if path not in ("/api/v1/health", "/api/v1/access"):  # the two routes open to anyone
                assert {"401", "403"} <= set(answers), (method, path)
            if "{session_id}" in path:
                assert "404" in answers, (method, path)
            for status, answer in answers.items():
                if status[0] in "45":
                    assert set(answer["content"]) == {"application/problem+json"}, (method, path, status)
            assert answers["405"]["headers"]["Allow"]["required"] is True
    last = [p for p in paths["/api/v1/events"]["get"]["parameters"] if p["name"] == "Last-Event-ID"]
    assert last[0]["in"] == "header"
    assert last[0]["schema"]["type"] == "integer"
    with served.client() as c:
        wrong = c.delete("/api/v1/sessions")
        assert wrong.status_code == 405
        assert wrong.headers["allow"] == "GET, POST"  # both routes of the path, not the first one's
        assert wrong.headers["content-type"] == "application/problem+json"
        stream = "/api/v1/sessions/abcdef123456/events"
        assert c.get(stream, headers={"Last-Event-ID": "12"}).status_code == 404  # valid: no such session
        assert c.get(stream, headers={"Last-Event-ID": "twelve"}).status_code == 422


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_no_request_from_the_schema_gets_an_undocumented_answer(served: Served) -> None:
    report = fuzz(
        served.base, TOKEN, examples=EXAMPLES_PER_OPERATION, stateful_examples=STATEFUL_SCENARIOS, steps=8
    )
    print(report.summary(), report.seconds_by_operation)
    assert report.operations >= 18
    assert report.stateful_requests > 0
    assert report.server_errors == []
    assert report.violations == []
    with served.client() as c:
        assert c.get("/api/v1/health").status_code == 200
