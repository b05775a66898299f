"""A validation with the ruler through the API (issue 22, item 4): the parameter is taken as the others
are; the service's simulated station holds what its operator put on the table (``table_artifact``)."""

from __future__ import annotations

import pytest

from tests.api.conftest import ServeFactory, wait_final

RULER = {
    "kind": "validation",
    "params": {"artifact": "ruler", "pattern_um": [[0, 0], [254, 0], [0, 254], [254, 254]]},
}


@pytest.mark.timeout(240)
def test_a_ruler_validation_runs_on_a_station_with_a_ruler_on_its_table(make_served: ServeFactory) -> None:
    with make_served(table_artifact="ruler").client() as c:
        r = c.post("/api/v1/sessions", json=RULER)
        assert r.status_code == 201, r.text
        final = wait_final(c, r.json()["id"])
        assert final["state"] == "succeeded", final["error"]
        assert final["results"]["artifact"] == "ruler"
        assert final["results"]["groove_width_mm"] is None
        assert final["results"]["mean_um"] < 0.5


@pytest.mark.timeout(240)
def test_without_a_ruler_on_the_table_the_session_fails_saying_what_to_do(make_served: ServeFactory) -> None:
    with make_served().client() as c:  # the cross on the table
        r = c.post("/api/v1/sessions", json=RULER)
        assert r.status_code == 201, r.text
        final = wait_final(c, r.json()["id"])
        assert final["state"] == "failed"
        # stopped after the first frames, each refused with what the ruler's measurement saw
        assert "no ruler graduations in view" in final["error"]
        assert "bring the ruler's graduated band into the frame" in final["error"]


def test_an_unknown_artifact_is_refused_with_nothing_started(make_served: ServeFactory) -> None:
    with make_served().client() as c:
        r = c.post("/api/v1/sessions", json={"kind": "validation", "params": {"artifact": "rule"}})
        assert r.status_code == 422, r.text
        assert "artifact" in r.text
        assert c.get("/api/v1/sessions").json()["total"] == 0
