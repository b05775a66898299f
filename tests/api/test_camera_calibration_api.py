"""``POST /api/v1/sessions`` with kind ``camera-calibration`` on the simulated station: the typed results,
and a bad parameter refused before anything moves.

The session asks the operator to put the calibration target on the X-Y table before its pre-flight; the
served station's simulated operator does (after a cross and a ruler validation on one served station:
``tests/api/test_table_content_api.py``)."""

from __future__ import annotations

import pytest

from tests.api.conftest import Served, ServeFactory, wait_final
from tests.sessions.test_camera_calibration_sim import SMALL as SESSION_SMALL

#: the sessions' small set of views (10) with bounds it meets (the defaults' 308 views: tests/sessions)
SMALL = {**SESSION_SMALL, "focal_bound_pct": 1.0, "principal_bound_px": 5.0}


@pytest.mark.timeout(180)
def test_a_camera_calibration_runs_through_the_api(make_served: ServeFactory) -> None:
    served = make_served(time_scale=1000.0)  # the cross on its table
    with served.client() as c:
        r = c.post("/api/v1/sessions", json={"kind": "camera-calibration", "params": SMALL})
        assert r.status_code == 201, r.text
        final = wait_final(c, r.json()["id"])
        assert final["state"] == "succeeded", final.get("error")
        asked = [e.data for e in served.service.record.events(final["id"]) if e.type == "table_content"]
        assert asked[0]["content"] == "target"
        assert asked[0]["asked"] is True
        results = final["results"]
        for name in ("fx", "fy", "cx", "cy"):
            assert results[name]["sigma"] > 0
        assert results["distortion"]["k1"]["sigma"] > 0
        assert results["views"] == results["views_taken"] == 10
        assert results["image_size"] == [640, 480]
        assert results["camera_model_file"].endswith("camera-model.json")
        table = c.get(f"/api/v1/sessions/{final['id']}/results", params={"format": "csv"})
        assert table.status_code == 200
        assert table.text.splitlines()[0] == "name,value,sigma"


def test_a_bad_view_plan_is_refused_with_what_to_do(served: Served) -> None:
    with served.client() as c:
        r = c.post("/api/v1/sessions", json={"kind": "camera-calibration", "params": {"heights_mm": [0.0]}})
        assert r.status_code == 422
        assert "at least two different heights" in r.json()["detail"]
        r = c.post("/api/v1/sessions", json={"kind": "camera-calibration", "params": {"tilts_deg": [40]}})
        assert r.status_code == 422
        assert "tilts_deg" in r.json()["detail"]
        assert c.get("/api/v1/sessions").json()["total"] == 0  # nothing started
