"""A validation with the ruler through the API (issue 22, item 4): the parameter is taken as the others
are; the session asks the operator to put the ruler on the X-Y table, and the service's simulated operator
does (after a cross validation on one served station: ``tests/api/test_table_content_api.py``)."""

from __future__ import annotations

import pytest

from station.worker import SessionHost
from tests.api.conftest import ServeFactory, wait_final

RULER = {
    "kind": "validation",
    "params": {"artifact": "ruler", "pattern_um": [[0, 0], [254, 0], [0, 254], [254, 254]]},
}


@pytest.mark.timeout(240)
def test_a_ruler_validation_runs_once_the_ruler_is_on_the_table(make_served: ServeFactory) -> None:
    served = make_served()  # the cross on its table
    with served.client() as c:
        r = c.post("/api/v1/sessions", json=RULER)
        assert r.status_code == 201, r.text
        final = wait_final(c, r.json()["id"])
        assert final["state"] == "succeeded", final["error"]
        asked = [e.data for e in served.service.record.events(final["id"]) if e.type == "table_content"]
        assert asked[0]["content"] == "ruler"
        assert asked[0]["asked"] is True
        assert final["results"]["artifact"] == "ruler"
        assert final["results"]["groove_width_mm"] is None
        assert final["results"]["mean_um"] < 0.5


def decline_next(host: SessionHost) -> None:
    """The served station's simulated operator declines its next prompt (in the worker process)."""
    host.devices.truth.operator.cancel_next()


def ruler_on_table(host: SessionHost) -> bool:
    return bool(host.devices.truth.world.table_content == "ruler")


@pytest.mark.timeout(240)
def test_an_operator_without_a_ruler_ends_the_session_saying_what_to_do(make_served: ServeFactory) -> None:
    served = make_served()  # the cross on its table
    served.service.in_worker(decline_next)
    with served.client() as c:
        r = c.post("/api/v1/sessions", json=RULER)
        assert r.status_code == 201, r.text
        final = wait_final(c, r.json()["id"])
        assert final["state"] == "failed"
        assert "the operator declined to put the ruler on the X-Y table" in final["error"]
        assert "put the ruler on the X-Y table, then start the session again" in final["error"]
        assert not served.service.in_worker(ruler_on_table)
        assert served.service.record.captures(final["id"]) == []  # ended before pre-flight: nothing moved


def test_an_unknown_artifact_is_refused_with_nothing_started(make_served: ServeFactory) -> None:
    with make_served().client() as c:
        r = c.post("/api/v1/sessions", json={"kind": "validation", "params": {"artifact": "rule"}})
        assert r.status_code == 422, r.text
        assert "artifact" in r.text
        assert c.get("/api/v1/sessions").json()["total"] == 0
