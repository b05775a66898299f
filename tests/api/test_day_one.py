"""Day one on the simulated station (issue 23's first target), through the API only, nothing taken from
the sim's truth: the service starts from the lab's ``station.toml`` whose taught values are what its
drawings give (the reference pose a fraction of a degree off, every artifact 1-2 mm off, normals and
turns a degree or a few off, the sensor mount's z a placeholder). The test then does what the lab
engineer would do, with the page's routes:

1. teach the sensor mount (the arm as installed: the camera square to the table and sharp), then the
   reference pose;
2. teach the table's artifact, and for each of the four bench artifacts jog there (joint jogs through
   the lift pose, the target from the drawing's position through the station's nominal model), jog the
   camera until the measured crossing is in view and centred, and teach it;
3. back to the reference pose; calibrate the camera (the session asks for the calibration target on the
   X-Y table and the simulated operator puts it there; the world's lens is seeded, ``true_intrinsics_seed``,
   and the lab starts from the datasheet's pinhole as its camera model), then self-test the controller
   (:func:`self_test`; it asks for the artifact's cross on the table again);
4. validate, then calibrate the arm with the small fast configuration.

The sim's truth enters the assertions only: the reference pose within 0.1 deg and the sensor mount within
0.1 mm, every artifact's crossing within 0.1 mm of what ``sim.station`` computes from its true arm, its
normal and turn within 0.2 deg (read through the nominal model, whose orientation error enters them: see
:func:`check_taught`), the calibrated camera's focal lengths within 0.05 % and principal point within 1 px
of the sim's true intrinsics, its model written and used by every later session (their scale checks read
it), and the arm calibration's targets met as with the sim-taught cell
(``tests/sessions/test_calibration_sim.py``). About 5 minutes on this shared machine: marked slow.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import httpx
import numpy as np
import pytest

from sim.calibration_truth import truth_report
from sim.model_frame import artifacts_in_model_frame
from sim.station import SIM_SENSOR_MOUNT, taught_artifacts_mm, taught_normals, taught_turns_deg
from sim.world import WorldSpec
from station.arm_route import lift_pose, split_move
from station.camera_model import CameraIntrinsics, read_camera_model, write_camera_model
from station.config import load_config
from station.kinds.calibration.params import calibration_cell_from_config
from station.kinematics import Kinematics
from station.runner import stored_captures
from station.teach import pose_to_see
from station.vision import MeasureParams
from station.worker import SessionHost
from tests.api.conftest import AUTH, Served, wait_final
from tests.api.teach_station import lab_config, served_with_config

pytestmark = [pytest.mark.slow, pytest.mark.timeout(1500)]

NAMES = ["table", "A", "B", "C", "D"]
DRAWING: dict[str, Any] = {
    # what the lab's drawings and datasheets give: a fraction of a degree, 1-2 mm, a degree or a few off
    "reference": [0.3, 29.7, 60.4, 0.0, 89.6, 0.0],
    "artifacts": [
        [481.0, 1.0, 331.0],
        [351.5, 249.0, 382.5],
        [419.0, -198.5, 341.5],
        [1.5, -399.5, 402.0],
        [-99.0, 378.5, 422.0],
    ],
    "normals": [
        [0.0, 0.0, 1.0],
        [0.16, -0.31, 0.937],
        [0.13, 0.31, 0.94],
        [-0.355, 0.22, 0.91],
        [-0.25, -0.23, 0.94],
    ],
    "turns": [0.0, 148.0, -158.0, 122.0, -133.0],
    "sensor_z": 2.0,
}
VALIDATION = {
    "kind": "validation",
    "params": {"pattern_um": [[0.0, 0.0], [254.0, 0.0], [254.0, 254.0], [0.0, 254.0], [127.0, 127.0]]},
}
CALIBRATION = {"kind": "calibration", "params": {"turns_deg": [-20.0, 70.0, 160.0], "settle_s": 0.05}}
CAMERA_CALIBRATION = {"kind": "camera-calibration", "params": {}}
"""The camera's calibration with its default views and bounds (focal lengths 0.05 %, principal point 1 px)."""
LENS_SEED = 3
"""The sim camera's true intrinsics (``WorldSpec.true_intrinsics_seed``): focal 1.3 % above the datasheet's,
principal point 3 and 7 px off the centre, radial distortion."""
MODEL = "camera-model.json"
"""The station's camera model (``[camera] camera_model``, beside ``station.toml``): the datasheet's pinhole
until the camera's calibration replaces it."""
UP_DOWN_STEP_DEG = 5.0
"""Joint jogs on the way up to and down from the lift pose: the shoulder and elbow alternate in steps
this small, so the one-joint-at-a-time path stays near the straight one."""
ACROSS_STEP_DEG = 10.0
"""Joint jogs at the lift pose (the camera high above every fixture): the largest jog."""


# ------------------------------------------------------------------ the station's side (no truth)


def commanded(c: httpx.Client) -> list[float]:
    r = c.get("/api/v1/station/robot")
    assert r.status_code == 200, r.text
    joints: list[float] = r.json()["position"]["commanded_joints_deg"]
    return joints


def jog_joint(c: httpx.Client, joint: int, delta: float) -> None:
    r = c.post(
        "/api/v1/station/robot/jog", json={"mode": "joint", "joint": joint, "delta_deg": round(delta, 3)}
    )
    assert r.status_code == 200, r.text


def jog_camera(c: httpx.Client, axis: str, delta: float) -> None:
    r = c.post("/api/v1/station/robot/jog", json={"mode": "camera", "axis": axis, "delta": round(delta, 3)})
    assert r.status_code == 200, r.text


def jog_to(c: httpx.Client, target: Sequence[float]) -> int:
    """Jog, one joint at a time, from where the arm is to ``target``: up to the lift pose, across, down
    (``station.arm_route``'s legs); the number of jogs."""
    start = commanded(c)
    legs = (
        split_move(start, lift_pose(start), UP_DOWN_STEP_DEG),
        split_move(lift_pose(start), lift_pose(target), ACROSS_STEP_DEG),
        split_move(lift_pose(target), target, UP_DOWN_STEP_DEG),
    )
    here = list(start)
    jogs = 0
    for leg in legs:
        for waypoint in leg:
            for j in range(6):
                delta = float(waypoint[j]) - here[j]
                if abs(delta) >= 0.0005:
                    jog_joint(c, j + 1, delta)
                    here[j] = float(waypoint[j])
                    jogs += 1
    np.testing.assert_allclose(commanded(c), target, atol=2e-3)
    return jogs


def approach(
    reference: Sequence[float], nominal: Kinematics, wd: float, k: int, drawing: dict[str, Any] = DRAWING
) -> list[float]:
    """The joints that show artifact ``k`` where ``drawing`` places it, square to its drawn normal at the
    working distance and turned as drawn (the cross square in the image), in the arm's configuration
    nearest the reference pose (the one a person teaches in: its wrist not flipped): that configuration
    squared with no turn, then the wrist's last joint turned (the camera sits on its axis)."""
    position, normal, turn = drawing["artifacts"][k], drawing["normals"][k], drawing["turns"][k]
    square = pose_to_see(reference, nominal, position, wd, normal=normal, turn_deg=0.0)
    seed = [*square[:5], float(square[5]) + turn]
    q = pose_to_see(seed, nominal, position, wd, normal=normal, turn_deg=turn)
    return [round(float(v), 3) for v in q]


def crossing_px(c: httpx.Client) -> tuple[tuple[float, float] | None, tuple[int, int]]:
    """The measured crossing in the live frame (px; None when none is in view) and the frame's size."""
    r = c.get("/api/v1/camera/snapshot.png", params={"overlay": "true"})
    assert r.status_code == 200, r.text
    image = cv2.imdecode(np.frombuffer(r.content, np.uint8), cv2.IMREAD_UNCHANGED)
    assert image is not None
    size = (int(image.shape[1]), int(image.shape[0]))
    doc = json.loads(r.headers.get("x-measurement", "{}"))
    if not doc.get("ok"):
        return None, size
    return (float(doc["center_px"][0]), float(doc["center_px"][1])), size


SEARCH_MM = [
    (0.0, 0.0),
    (3.0, 0.0),
    (0.0, 3.0),
    (-3.0, 0.0),
    (-3.0, 0.0),
    (0.0, -3.0),
    (0.0, -3.0),
    (3.0, 0.0),
    (3.0, 0.0),
]
"""Camera jogs (x, y mm, each from the last) of a search around where the crossing should be: the field
is about 6.4 x 4.8 mm."""


def centre_crossing(c: httpx.Client, pixel_mm: float) -> None:
    """Jog the camera until the measured crossing is in view (a small search) and centred (twice)."""
    for dx, dy in SEARCH_MM:
        if dx or dy:
            jog_camera(c, "x", dx) if dx else jog_camera(c, "y", dy)
        seen, size = crossing_px(c)
        if seen is not None:
            break
    else:
        raise AssertionError("the crossing is not in view anywhere near where the drawing places it")
    for _ in range(2):
        off = (seen[0] - (size[0] - 1) / 2.0, seen[1] - (size[1] - 1) / 2.0)
        if math.hypot(*off) * pixel_mm < 0.05:
            break
        for axis, v in zip(("x", "y"), off, strict=True):
            if abs(v) * pixel_mm >= 0.01:
                jog_camera(c, axis, v * pixel_mm)
        again, size = crossing_px(c)
        assert again is not None, "the crossing left the view while centring it"
        seen = again


def teach(c: httpx.Client, path: str, body: dict[str, Any] | None = None) -> dict[str, Any]:
    r = c.post(f"/api/v1/station/teach/{path}", json=body)
    assert r.status_code == 200, r.text
    doc: dict[str, Any] = r.json()
    return doc


SELFTEST_CHECKS = ["directions", "world", "ready"]
SELFTEST = {"kind": "selftest", "params": {"checks": SELFTEST_CHECKS}}
"""The halt check is left out: the twin's clock runs 100 times real time here, so the slow joint move it
halts has ended before the halt key reaches the controller (``tests/sessions/test_selftest_kind.py`` times
the halt at the real clock)."""


def self_test(c: httpx.Client) -> str:
    """The controller self-test as a session: every check it ran passed; returns its session id."""
    out = run(c, SELFTEST)
    results = out["results"]
    states = {ch["name"]: ch["state"] for ch in results["controller_checks"]}
    assert set(states) == set(SELFTEST_CHECKS), states
    assert set(states.values()) == {"passed"}, results["controller_checks"]
    assert results["passed"] is True
    assert results["identity"], "the self-test holds for the controller it ran on"
    sid: str = out["id"]
    return sid


def run(c: httpx.Client, body: dict[str, Any]) -> dict[str, Any]:
    r = c.post("/api/v1/sessions", json=body)
    assert r.status_code == 201, r.text
    doc = wait_final(c, r.json()["id"])
    assert doc["state"] == "succeeded", doc
    outcome = c.get(f"/api/v1/sessions/{doc['id']}/results")
    assert outcome.status_code == 200, outcome.text
    out: dict[str, Any] = outcome.json()
    return out


# ------------------------------------------------------------------ the truth (assertions only)


def truth(host: SessionHost) -> dict[str, Any]:
    world = host.devices.truth.world
    return {
        "reference": list(world.spec.reference_joints_deg),
        "artifacts": taught_artifacts_mm(world, digits=None),
        "normals": taught_normals(world, digits=None),
        "turns": taught_turns_deg(world, digits=None),
    }


def angle_deg(a: Sequence[float], b: Sequence[float]) -> float:
    u, v = np.asarray(a, float), np.asarray(b, float)
    cos = float(u @ v / (np.linalg.norm(u) * np.linalg.norm(v)))
    return math.degrees(math.acos(max(-1.0, min(1.0, cos))))


def turn_error_deg(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


# ------------------------------------------------------------------ the day


def test_day_one_from_the_drawings_to_a_calibrated_arm(tmp_path: Path) -> None:
    began = time.monotonic()
    path = tmp_path / "station.toml"
    text = lab_config(
        reference=DRAWING["reference"],
        artifacts=DRAWING["artifacts"],
        normals=DRAWING["normals"],
        turns=DRAWING["turns"],
        names=NAMES,
        sensor_z=DRAWING["sensor_z"],
    )
    path.write_text(text.replace("[camera]\n", f'[camera]\ncamera_model = "{MODEL}"\n', 1), encoding="utf-8")
    config = load_config(path)
    assert config.calibration is not None
    pixel_mm, wd = config.calibration.pixel_mm, config.calibration.working_distance_mm
    datasheet_model(tmp_path / MODEL, wd / pixel_mm)
    nominal = Kinematics(tool=config.camera_mount().matrix())
    lens = WorldSpec(true_intrinsics_seed=LENS_SEED)
    with (
        served_with_config(path, tmp_path / "data", seed=3, time_scale=1000.0, spec=lens) as served,
        httpx.Client(base_url=served.base, headers=AUTH, timeout=900.0) as c,
    ):
        # 1. the arm as installed, the camera square to the table and sharp: the sensor mount, the reference
        mount = teach(c, "sensor-mount")["taught"]
        reference = teach(c, "reference")["taught"]
        # 2. the table's artifact (in view at the reference pose), then the bench's
        taught = {"table": teach(c, "artifact/table")["taught"]}
        jogs = 0
        for k in range(1, 5):
            target = approach(reference["reference_joints_deg"], nominal, wd, k)
            jogs += jog_to(c, target)
            centre_crossing(c, pixel_mm)
            taught[NAMES[k]] = teach(c, f"artifact/{NAMES[k]}")["taught"]
        taught_s = time.monotonic() - began
        # the truth now: the validation moves the table (and its artifact) later
        check_taught(served.service.in_worker(truth), path, mount, reference, taught)
        # 3. home, then the camera (the calibration target put on the table through its prompt) and the
        # controller (the cross put back through its own)
        r = c.post("/api/v1/station/robot/to-reference")
        assert r.status_code == 200, r.text
        camera = run(c, CAMERA_CALIBRATION)
        assert table_asked(served, camera["id"]) == "target"
        check_camera(served, camera, tmp_path / MODEL)
        r = c.post("/api/v1/station/robot/to-reference")  # the calibration ends at its last view, tilted
        assert r.status_code == 200, r.text
        tested = self_test(c)
        assert table_asked(served, tested) == "cross"
        # 4. validate and calibrate the arm: each carries the self-test it ran under
        validation = run(c, VALIDATION)
        assert validation["results"]["selftest"]["session_id"] == tested
        assert validation["results"]["selftest"]["passed"] is True
        cal = run(c, CALIBRATION)
        assert cal["results"]["selftest"]["session_id"] == tested
        check_calibration(served, cal)
        # the calibrated model is the one every later session's scale check read, and it agreed
        for sid in (tested, validation["id"], cal["id"]):
            check_model_used(served, sid, tmp_path / MODEL)
        # 5. after the arm's calibration, each artifact taught again through it
        again = reteach(c, cal["id"], reference["reference_joints_deg"], nominal, wd, pixel_mm, taught)
        check_retaught(served.service.in_worker(frame_truth), again, cal["id"])
    print(f"day one: {jogs} jogs, taught in {taught_s:.0f} s, all in {time.monotonic() - began:.0f} s")


def check_taught(
    true: dict[str, Any],
    path: Path,
    mount: dict[str, Any],
    reference: dict[str, Any],
    taught: dict[str, dict[str, Any]],
) -> None:
    """Every taught value within 0.1 mm / 0.1 deg of what the sim computes from its true arm."""
    assert mount["translation_z_mm"] == pytest.approx(SIM_SENSOR_MOUNT.translation_mm[2], abs=0.1)
    np.testing.assert_allclose(reference["reference_joints_deg"], true["reference"], atol=0.1)
    errors = {
        name: (
            float(np.max(np.abs(np.subtract(taught[name]["position_mm"], true["artifacts"][k])))),
            angle_deg(taught[name]["normal"], true["normals"][k]),
            turn_error_deg(taught[name]["turn_deg"], true["turns"][k]),
        )
        for k, name in enumerate(NAMES)
    }
    print(
        "taught - truth (position mm, normal deg, turn deg):",
        {n: [round(v, 3) for v in e] for n, e in errors.items()},
    )
    for name, (position, normal, turn) in errors.items():
        assert position < 0.1, (name, errors)
        # The normal and the turn are read through the nominal model: the arm's orientation error there
        # (its joint-zero errors, about 0.1 deg on this arm) enters them whole. Seen with seed 3: normals
        # 0.01-0.12 deg, turns 0.09-0.15 deg off; held to 0.2 deg (the 0.1 is held once taught
        # again through the calibrated arm: check_retaught). Positions: 0.03-0.05 mm.
        assert normal < 0.2, (name, errors)
        assert turn < 0.2, (name, errors)
    # the file holds them (rounded as written), its comments kept
    config = load_config(path)
    assert config.calibration is not None
    assert config.calibration.names() == NAMES
    for k in range(5):
        np.testing.assert_allclose(config.calibration.artifacts_mm[k], true["artifacts"][k], atol=0.1)
    assert "# the artifacts as the drawing places them" in path.read_text(encoding="utf-8")


def datasheet_model(path: Path, focal_px: float) -> None:
    """The lab's first camera model: the datasheet's pinhole (focal length ``working_distance_mm /
    pixel_mm``, principal point at the centre of the camera's 640 x 480 frames, no distortion)."""
    K = np.array([[focal_px, 0.0, 319.5], [0.0, focal_px, 239.5], [0.0, 0.0, 1.0]])
    write_camera_model(CameraIntrinsics(K, np.zeros(5), (640, 480)), path)


def table_asked(served: Served, sid: str) -> str | None:
    """What the session asked the operator to put on the X-Y table (None: it asked nothing)."""
    events = served.service.record.events(sid, limit=10_000)
    asked = [e.data["content"] for e in events if e.type == "table_content" and e.data["asked"]]
    return asked[0] if asked else None


def true_lens(host: SessionHost) -> list[list[float]]:
    """The sim camera's true camera matrix (truth, for the assertions)."""
    return [[float(v) for v in row] for row in host.devices.truth.world.true_intrinsics.camera_matrix]


def check_camera(served: Served, camera: dict[str, Any], model: Path) -> None:
    """The calibrated camera against the sim's true intrinsics, and its model written where configured."""
    results = camera["results"]
    K = np.array(served.service.in_worker(true_lens))
    found = {name: float(results[name]["value"]) for name in ("fx", "fy", "cx", "cy")}
    true = dict(zip(("fx", "fy", "cx", "cy"), K[[0, 1, 0, 1], [0, 1, 2, 2]], strict=True))
    print("camera - truth (px):", {n: round(found[n] - float(t), 4) for n, t in true.items()})
    assert found["fx"] == pytest.approx(K[0, 0], rel=0.0005)
    assert found["fy"] == pytest.approx(K[1, 1], rel=0.0005)
    assert found["cx"] == pytest.approx(K[0, 2], abs=1.0)
    assert found["cy"] == pytest.approx(K[1, 2], abs=1.0)
    assert Path(results["camera_model_file"]).resolve() == model.resolve()
    written = read_camera_model(model)
    np.testing.assert_allclose(
        written.camera_matrix[[0, 1, 0, 1], [0, 1, 2, 2]], [found[n] for n in ("fx", "fy", "cx", "cy")]
    )
    assert written.image_size == (640, 480)


def check_model_used(served: Served, sid: str, model: Path) -> None:
    """The session's pre-flight scale check read the calibrated model and agreed with the grooves."""
    events = served.service.record.events(sid, limit=10_000)
    checks = [e.data for e in events if e.type == "scale_check"]
    assert checks, f"session {sid} made no scale check"
    assert checks[0]["model_from"] == f"camera model {model}", checks[0]
    assert checks[0]["passed"] is True, checks[0]


def check_calibration(served: Served, calibration: dict[str, Any]) -> None:
    """The arm calibration's targets, as with the sim-taught cell."""
    results = calibration["results"]
    record = served.service.record
    row = record.get_session(calibration["id"])
    cell = calibration_cell_from_config(row.config, MeasureParams())
    assert cell is not None
    report = truth_report(results, stored_captures(record, calibration["id"]), cell)
    before, after, floor = report["before_um"], report["after_um"], report["floor_um"]
    assert results["configurations"] >= 45
    assert after * 10 <= before
    assert after <= 2 * floor, f"after {after:.1f} um, true floor {floor:.1f} um"
    assert report["max_abs_z"] <= 4.0
    checks = {ch["name"]: ch for ch in results["checks"]}
    assert all(ch["passed"] for ch in checks.values() if ch["severity"] == "fail"), checks


def reteach(
    c: httpx.Client,
    calibration_id: str,
    reference: Sequence[float],
    nominal: Kinematics,
    wd: float,
    pixel_mm: float,
    taught: dict[str, dict[str, Any]],
) -> dict[str, dict[str, Any]]:
    """Back to each artifact (the table's at the reference pose, the others where the first teach placed
    them, jogged there as before) and taught again through the calibration session."""
    body = {"calibration_session": calibration_id}
    assert c.post("/api/v1/station/robot/to-reference").status_code == 200
    centre_crossing(c, pixel_mm)
    again = {"table": teach(c, "artifact/table", body)["taught"]}
    first = {
        "artifacts": [taught[n]["position_mm"] for n in NAMES],
        "normals": [taught[n]["normal"] for n in NAMES],
        "turns": [taught[n]["turn_deg"] for n in NAMES],
    }
    for k in range(1, 5):
        jog_to(c, approach(reference, nominal, wd, k, first))
        centre_crossing(c, pixel_mm)
        again[NAMES[k]] = teach(c, f"artifact/{NAMES[k]}", body)["taught"]
    return again


def frame_truth(host: SessionHost) -> list[Any]:
    """The artifacts in the calibrated model's base frame (``sim.model_frame``): the normals' and turns'
    truth, with the crossings' positions in the world's frame (read through the nominal model either way)."""
    world = host.devices.truth.world
    positions = taught_artifacts_mm(world, digits=None)
    return [
        (positions[k], normal, turn) for k, (_, normal, turn) in enumerate(artifacts_in_model_frame(world))
    ]


def check_retaught(true: list[Any], again: dict[str, dict[str, Any]], calibration_id: str) -> None:
    """Taught through the calibrated arm, every normal and turn within 0.1 deg of the truth in its frame
    (the one its nominal base row defines), and every crossing (read through the nominal model: a
    calibration from crossings alone leaves the calibrated one's position loose, ``station.teach``'s
    notes) within 0.1 mm of the truth. Seen here: normals 0.007-0.024 deg (read by turning the wrist;
    the camera shifted gave 0.012-0.116), turns 0.022-0.027 deg, positions 0.041-0.093 mm."""
    errors = {
        name: (
            float(np.max(np.abs(np.subtract(again[name]["position_mm"], true[k][0])))),
            angle_deg(again[name]["normal"], true[k][1]),
            turn_error_deg(again[name]["turn_deg"], true[k][2]),
        )
        for k, name in enumerate(NAMES)
    }
    print(
        "re-taught - truth (position mm, normal deg, turn deg):",
        {n: [round(v, 3) for v in e] for n, e in errors.items()},
    )
    for name, (position, normal, turn) in errors.items():
        assert again[name]["model"]["calibration_session"] == calibration_id
        assert position < 0.1, (name, errors)
        assert normal < 0.1, (name, errors)
        assert turn < 0.1, (name, errors)
