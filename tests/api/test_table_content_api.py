"""What lies on the X-Y table, through the API, on one served simulated station (issue 23): each session
asks the operator for what its plan needs (the cross, a ruler, the camera-calibration target) before its
pre-flight, the simulated operator puts it on the world's table and confirms, and a later session needing
the same thing is not asked again; a restarted service knows nothing and asks again."""

from __future__ import annotations

from typing import Any

import httpx
import pytest

from station.worker import SessionHost
from tests.api.conftest import Served, ServeFactory, wait_final
from tests.api.test_camera_calibration_api import SMALL

PATTERN = [[0, 0], [254, 0], [0, 254], [254, 254]]
CROSS = {"kind": "validation", "params": {"pattern_um": PATTERN}}
RULER = {"kind": "validation", "params": {"artifact": "ruler", "pattern_um": PATTERN}}
CAMCAL = {"kind": "camera-calibration", "params": SMALL}  # its API test's views and bounds


def table_content(host: SessionHost) -> str:
    """What lies on the simulated world's X-Y table (in the station's worker process): truth."""
    return str(host.devices.truth.world.table_content)


def run(served: Served, c: httpx.Client, body: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Run a session to its end: its final document and what it recorded about the table (the prompt it
    raised, if any, and its ``table_content`` event)."""
    r = c.post("/api/v1/sessions", json=body)
    assert r.status_code == 201, r.text
    final = wait_final(c, r.json()["id"])
    events = served.service.record.events(final["id"], limit=10_000)
    raised = [e.data for e in events if e.type == "prompt_raised" and e.data["kind"] == "table_content"]
    answered = [e.data for e in events if e.type == "prompt_answered"]
    placed = [e.data for e in events if e.type == "table_content"]
    assert len(placed) == 1, placed
    said = {**placed[0], "message": raised[0]["message"] if raised else None}
    if raised:
        first = next(a for a in answered if a["id"] == raised[0]["id"])
        said["answered"] = (first["outcome"], first["by"])
    return final, said


@pytest.mark.timeout(420)
def test_each_session_asks_for_what_it_needs_and_the_sim_operator_puts_it_there(
    make_served: ServeFactory,
) -> None:
    served = make_served(time_scale=1000.0)
    with served.client() as c:
        final, said = run(served, c, CROSS)  # the station knows nothing yet: it asks, even for the cross
        assert final["state"] == "succeeded", final["error"]
        assert said["asked"] is True
        assert said["content"] == "cross"
        assert said["message"].startswith("Put the artifact's cross on the X-Y table")
        assert said["answered"] == ("confirmed", "sim-operator")

        again, said = run(served, c, CROSS)  # the same thing: not asked again
        assert again["state"] == "succeeded", again["error"]
        assert said["asked"] is False
        assert said["confirmed_in"] == final["id"]
        assert said["message"] is None

        ruler, said = run(served, c, RULER)
        assert ruler["state"] == "succeeded", ruler["error"]
        assert said["asked"] is True
        assert said["message"].startswith("Put the ruler on the X-Y table")
        assert said["answered"] == ("confirmed", "sim-operator")
        assert served.service.in_worker(table_content) == "ruler"
        assert ruler["results"]["artifact"] == "ruler"
        assert ruler["results"]["groove_width_mm"] is None
        assert ruler["results"]["mean_um"] < 0.5

        camcal, said = run(served, c, CAMCAL)
        assert camcal["state"] == "succeeded", camcal.get("error")
        assert said["asked"] is True
        assert said["message"].startswith("Put the ChArUco calibration target on the X-Y table")
        assert served.service.in_worker(table_content) == "target"
        results = camcal["results"]
        for name in ("fx", "fy", "cx", "cy"):
            assert results[name]["sigma"] > 0
        assert results["distortion"]["k1"]["sigma"] > 0
        assert results["views"] == results["views_taken"] == 10  # SMALL's
        assert results["image_size"] == [640, 480]
        assert results["camera_model_file"].endswith("camera-model.json")
        table = c.get(f"/api/v1/sessions/{camcal['id']}/results", params={"format": "csv"})
        assert table.status_code == 200
        assert table.text.splitlines()[0] == "name,value,sigma"
    served.stop()

    restarted = make_served(time_scale=1000.0)  # the same data directory, its record: a new opening
    with restarted.client() as c:
        final, said = run(restarted, c, CAMCAL)  # the target was confirmed before the restart: asked again
        assert said["asked"] is True
        assert said["answered"] == ("confirmed", "sim-operator")
        assert final["state"] == "succeeded", final.get("error")
