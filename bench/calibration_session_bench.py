"""The kinematic calibration on the simulated station, full configuration, judged against the truth.

``python -m bench.calibration_session_bench [--param NAME=VALUE ...]``: one ``calibration`` session with
the default parameters (the sim cell's five artifacts, four camera turns, every joint solution: 68
configurations) on the simulated station, timed from start to results; then, from the world's truth:
the relative error before / after / floor (the floor with the true model, beside the session's own
estimate), the identified parameters within their 95 % intervals and the largest error in sigmas; and
compensated moves: the arm sent to look square at each bench artifact from a turn the session did not
use, with the calibrated model to the estimated artifact and with the nominal model to the taught one,
where the crossing lands (um from the optical axis; "not in view" when it is not measured). Written to
``bench/results/calibration_session.json`` too.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

from sim.calibration_truth import pointing_errors_um, truth_report
from sim.station import build_sim_station
from station.calibration import CalibrationResult
from station.kinds.calibration.params import calibration_cell_from_config
from station.runner import stored_captures
from station.session import open_record, run_session
from station.vision import MeasureParams


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE")
    args = parser.parse_args()
    params: dict[str, Any] = {}
    for item in args.param:
        name, _, text = item.partition("=")
        params[name] = json.loads(text)
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        outcome = run_session("calibration", sim=True, params=params, data=tmp)
        seconds = time.perf_counter() - start
        if outcome.state != "succeeded":
            raise SystemExit(f"the session ended {outcome.state}: {outcome.error}")
        with open_record(tmp) as record:
            row = record.get_session(outcome.id)
            cell = calibration_cell_from_config(row.config, MeasureParams())
            assert cell is not None
            truth = truth_report(outcome.results, stored_captures(record, outcome.id), cell)
    result = CalibrationResult.model_validate(outcome.results["calibration"])
    devices = build_sim_station()
    assert devices.robot is not None
    devices.robot.connect()
    devices.camera.connect()
    try:
        bench = list(range(1, len(cell.artifacts_mm)))
        calibrated = pointing_errors_um(devices, cell, result, placements=bench)
        nominal = pointing_errors_um(devices, cell, result, placements=bench, calibrated=False)
    finally:
        devices.robot.close()
        devices.camera.close()
        devices.close_owned()
    r = outcome.results

    def fmt(values: list[float | None]) -> str:
        return ", ".join("not in view" if v is None else f"{v:.0f}" for v in values)

    print(
        f"session: {seconds:.0f} s wall,"
        f" {r['configurations']} of {r['planned_configurations']} configurations"
    )
    print(f"  {r['observations']} captures used, {len(r['held_out_configurations'])} configurations held out")
    print(
        f"relative error (um): before {truth['before_um']:.1f}, after {truth['after_um']:.1f},"
        f" floor {truth['floor_um']:.1f} (true model;"
        f" the session's estimate {truth['floor_estimate_um']:.1f})"
    )
    print(
        f"  after/floor {truth['after_um'] / truth['floor_um']:.2f} (target <= 2),"
        f" before/after {truth['before_um'] / truth['after_um']:.0f} (target >= 10)"
    )
    print(
        f"parameters: {truth['identified']} identified, {100 * truth['inside_95']:.0f} % inside their 95 %"
        f" intervals (target >= 90 %), largest error {truth['max_abs_z']:.2f} sigma (target <= 4);"
        f" condition number {r['condition_number']:.3g}"
    )
    print(f"compensated moves, crossing from the optical axis (um): calibrated {fmt(calibrated)}")
    print(f"                                                nominal {fmt(nominal)}")
    out = Path(__file__).parent / "results" / "calibration_session.json"
    out.parent.mkdir(exist_ok=True)
    summary = {
        "session_s": seconds,
        "configurations": r["configurations"],
        "planned_configurations": r["planned_configurations"],
        "observations": r["observations"],
        "condition_number": r["condition_number"],
        "pointing_calibrated_um": calibrated,
        "pointing_nominal_um": nominal,
        **{k: v for k, v in truth.items() if k != "parameters"},
    }
    out.write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
