"""``GET /sessions/{id}/latest.png``: the newest capture the session stored, with that capture's own
measurement. It read every capture and every measurement of the session on each request (the live view
asks with every measurement) and took the last by step order, so after a resumed validation it showed the
resume's check of the last confirmed position (numbered after every step of the plan) for the rest of
the session, whatever was captured since."""

from __future__ import annotations

import json
import time

import cv2
import numpy as np

from station.runner import PRELUDE_BASE
from tests.api.conftest import Served, wait_final, wait_state

PATTERN = [[0.0, 0.0], [254.0, 0.0], [254.0, 254.0], [0.0, 254.0], [127.0, 127.0], [63.5, 190.5]]


def test_latest_is_the_newest_capture_with_its_own_measurement_also_after_a_resume(served: Served) -> None:
    record = served.service.record
    with served.client() as c:
        assert c.post(
            "/api/v1/sessions", json={"kind": "validation", "params": {"pattern_um": PATTERN}}
        ).status_code
        sid = record.list_sessions()[0].id
        # paused after its first positions, aborted, resumed: the resume first captures the last confirmed
        # position again (a prelude step), then goes on with the positions left
        while not any(s.name == "position 1" for s in record.steps(sid)):
            time.sleep(0.02)
        assert c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "pause"}).status_code == 201
        wait_state(c, sid, {"paused"})
        assert c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "abort"}).status_code == 201
        assert wait_final(c, sid)["state"] == "aborted"
        assert c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "resume"}).status_code == 201
        final = wait_final(c, sid)
        assert final["state"] == "succeeded", final["error"]
        latest = c.get(f"/api/v1/sessions/{sid}/latest.png")
    assert latest.status_code == 200
    captures = record.captures(sid)
    assert any(cap.step_index >= PRELUDE_BASE for cap in captures)  # the resume's check was captured
    newest = max(captures, key=lambda cap: cap.id)
    assert newest.step_index == len(PATTERN) - 1  # the last position, stored after the check
    (measured,) = [m for m in record.measurements(sid) if m.capture_id == newest.id]
    numbers = json.loads(latest.headers["x-measurement"])
    assert numbers["ok"] is True
    assert numbers["center_px"] == measured.result["center_px"]
    # the picture is that capture's frame (the overlay drawn on it)
    shown = cv2.imdecode(np.frombuffer(latest.content, np.uint8), cv2.IMREAD_GRAYSCALE)
    frame = record.load_image(newest)
    assert shown is not None
    assert shown.shape == frame.shape[:2]
    assert np.median(np.abs(shown.astype(int) - frame.astype(int))) <= 1
