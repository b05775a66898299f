"""Issue 23 in the page: the jog panel moves the simulated arm (a joint, and the camera in its own frame,
checked against the sim's true camera), its buttons go off with the reason while a stop is latched, the
"Safety in force" panel lists the rules, and one artifact is taught from the page (the configuration file
rewritten with its comments kept, the taught crossing within 0.1 mm of the truth)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from sim.station import sim_fixtures, taught_artifacts_mm
from station.config import load_config
from station.worker import SessionHost
from tests.api.conftest import ServeFactory, acknowledge_stop
from tests.api.page.conftest import api, open_page
from tests.api.teach_station import lab_config, served_with_config

ALLOWED = "document.querySelector('#jog-section').dataset.allowed === 'true'"


def camera_pose(host: SessionHost) -> list[list[float]]:
    pose: list[list[float]] = host.devices.truth.world.camera_pose().tolist()
    return pose


def fixtures(host: SessionHost) -> int:
    return len(sim_fixtures(host.devices.truth.world))


def table_crossing(host: SessionHost) -> list[float]:
    """The table artifact's crossing as the sim's true arm places it (assertions only)."""
    return list(taught_artifacts_mm(host.devices.truth.world, digits=None)[0])


def latch(host: SessionHost) -> None:
    robot = host.devices.robot
    robot.connect()
    try:
        robot.stop()
    finally:
        robot.close()


def click_jog(page: Any, button: str) -> str:
    """Press a jog button once it is on; the result line once the jog has answered."""
    page.wait_for_function(ALLOWED)
    page.click(button)
    page.wait_for_function(
        "['done', 'refused'].includes(document.querySelector('#jog-result').dataset.state)"
    )
    return str(page.text_content("#jog-result"))


@pytest.mark.slow
@pytest.mark.timeout(240)
def test_the_jog_panel_moves_the_simulated_arm_and_says_why_it_is_off(
    make_served: ServeFactory, browser: Any
) -> None:
    served = make_served()
    visit = open_page(browser, served.base)
    page = visit.page
    with api(served.base) as c:
        start = c.get("/api/v1/station/robot").json()["position"]["commanded_joints_deg"]
        page.select_option("#jog-step", "1")
        text = click_jog(page, "#jog-j1-plus")
        assert page.get_attribute("#jog-result", "data-state") == "done", text
        assert text.startswith("J1 +1 deg"), text
        now = c.get("/api/v1/station/robot").json()["position"]["commanded_joints_deg"]
        np.testing.assert_allclose(now, [start[0] + 1.0, *start[1:]], atol=1e-3)

        # the camera 1 mm along the image's right: the true camera moves so (the twin's repeatability)
        before = np.array(served.service.in_worker(camera_pose))
        text = click_jog(page, "#jog-x-plus")
        assert text.startswith("camera x +1 mm"), text
        after = np.array(served.service.in_worker(camera_pose))
        moved = before[:3, :3].T @ (after[:3, 3] - before[:3, 3])
        np.testing.assert_allclose(moved, [1.0, 0.0, 0.0], atol=0.08)

        # the safety in force
        page.wait_for_function("document.querySelector('#safety-keep-out') !== null")
        n = served.service.in_worker(fixtures)
        assert page.text_content("#safety-keep-out").startswith(f"{n} configured volumes")
        assert page.text_content("#safety-speed-cap").startswith("80 %")
        assert page.text_content("#safety-remote").startswith("refused")
        assert page.text_content("#safety-local-ack").startswith("required")
        assert page.text_content("#safety-latch").startswith("not latched")

        # a latched stop: every jog button off, the reason beside them, the latch in the safety panel
        served.service.in_worker(latch)
        page.wait_for_function("document.querySelector('#jog-section').dataset.allowed === 'false'")
        assert "latched" in (page.text_content("#jog-reason") or "")
        assert page.is_disabled("#jog-j1-plus")
        assert page.is_disabled("#teach-reference")
        page.wait_for_function("document.querySelector('#safety-latch').textContent.startsWith('latched')")
        assert "acknowledge" in (page.text_content("#safety-latch") or "")
        acknowledge_stop(c)
        page.wait_for_function(ALLOWED)
        assert page.is_enabled("#jog-j1-plus")
    assert visit.console_errors == []
    assert visit.failed == []


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_teaching_an_artifact_from_the_page_rewrites_the_configuration(tmp_path: Path, browser: Any) -> None:
    path = tmp_path / "station.toml"
    text = lab_config(
        reference=[0.0, 30.0, 60.0, 0.0, 90.0, 0.0],
        artifacts=[[480.0, 2.0, 331.0]],  # the drawing's: a few millimetres off
        normals=[[0.0, 0.0, 1.0]],
        turns=[0.0],
        names=["table"],
        sensor_z=0.0,
    )
    path.write_text(text, encoding="utf-8")
    with served_with_config(path, tmp_path / "data", seed=3) as served:
        visit = open_page(browser, served.base)
        page = visit.page
        page.wait_for_function(ALLOWED)
        assert page.is_disabled("#teach-artifact")  # no name yet
        page.fill("#teach-artifact-name", "table")
        page.wait_for_function("!document.querySelector('#teach-artifact').disabled")
        page.click("#teach-artifact")
        page.wait_for_function(
            "['done', 'refused'].includes(document.querySelector('#teach-result').dataset.state)",
            timeout=240_000,
        )
        shown = page.text_content("#teach-result") or ""
        assert page.get_attribute("#teach-result", "data-state") == "done", shown
        assert "artifact table written into station.toml" in shown
        assert "[calibration] artifact 'table': crossing" in (page.text_content("#teach-changes") or "")
        backups = list(tmp_path.glob("station.toml.*.bak"))
        assert len(backups) == 1
        assert backups[0].name in shown
        assert backups[0].read_text(encoding="utf-8") == text
        written = path.read_text(encoding="utf-8")
        assert "# the artifacts as the drawing places them" in written
        cal = load_config(path).calibration
        assert cal is not None
        np.testing.assert_allclose(cal.artifacts_mm[0], served.service.in_worker(table_crossing), atol=0.1)
        assert visit.console_errors == []
        assert visit.failed == []
