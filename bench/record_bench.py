"""Record benchmark: capture write rate, bytes per capture, resident memory over a long session.

A session like the runner's: per capture one 640x480 8-bit frame rendered by the sim (noise differs
frame to frame, as a camera's does), stored as PNG through ``Record.save_capture`` (temp file, fsync,
rename, directory fsync), then its ``station measure --json`` object through ``add_measurement`` and
an ``image_captured`` event: three committed transactions per capture, SQLite in WAL mode with
``synchronous=NORMAL``. Resident memory is read at capture 1,000 and 10,000; the issue's budget is a
growth under 50 MB between the two.

``python -m bench.record_bench [--captures N] [--data DIR]`` prints the numbers as JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from sim.artifact import Pose, render
from station.record import Record
from station.vision import MeasureParams, measure

FRAMES = 16  # distinct rendered frames, cycled (rendering is not what is measured)
CHECKPOINTS = (1_000, 10_000)


def rss_mb() -> float:
    """Resident set size of this process, MB (from /proc/self/status)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise RuntimeError("no VmRSS in /proc/self/status")


def _frames() -> list[np.ndarray]:
    rng = np.random.default_rng(0)
    return [render(Pose(x_mm=0.01 * i, y_mm=-0.005 * i, rotation_deg=1.0), rng=rng)[0] for i in range(FRAMES)]


def _disk_bytes(directory: Path) -> int:
    return sum(p.stat().st_size for p in directory.rglob("*") if p.is_file())


def run(captures: int = CHECKPOINTS[-1], data_dir: Path | None = None) -> dict[str, Any]:
    """Write ``captures`` captures with measurements and events; return rates, sizes and RSS."""
    frames = _frames()
    result = {"file": "", "ok": True, **measure(frames[0], MeasureParams()).to_json()}
    params = MeasureParams().model_dump(mode="json")
    with tempfile.TemporaryDirectory(prefix="record-bench-", dir=data_dir) as tmp:
        data = Path(tmp)
        rss: dict[str, float] = {"start": round(rss_mb(), 1)}
        with Record(data) as rec:
            session = rec.create_session(
                "bench", params={}, config={}, identities={}, software={"station": "bench"}
            )
            rec.begin_step(session.id, 0, "captures")
            png_bytes = 0
            start = time.perf_counter()
            for i in range(captures):
                frame = frames[i % FRAMES]
                cap = rec.save_capture(
                    session.id, 0, i, frame, timestamp_s=i / 30, meta={"pose": [0.0] * 6, "exposure_us": 2000}
                )
                png_bytes += (data / cap.path).stat().st_size
                rec.add_measurement(
                    session.id, cap.id, {**result, "file": cap.path}, params=params, software="bench"
                )
                rec.add_event(session.id, "image_captured", {"capture_id": cap.id, "step": 0, "frame": i})
                if i + 1 in CHECKPOINTS:
                    rss[str(i + 1)] = round(rss_mb(), 1)
            elapsed = time.perf_counter() - start
            rec.finish_step(session.id, 0)
            images_bytes = _disk_bytes(data / "images")
            db_bytes = _disk_bytes(data) - images_bytes
        out: dict[str, Any] = {
            "captures": captures,
            "image": "640x480 uint8 (sim, nominal preset)",
            "captures_per_s": round(captures / elapsed, 1),
            "ms_per_capture": round(1000 * elapsed / captures, 2),
            "png_bytes_per_capture": round(png_bytes / captures),
            "db_bytes_per_capture": round(db_bytes / captures),
            "rss_mb": rss,
        }
        if all(str(n) in rss for n in CHECKPOINTS):
            out["rss_growth_1k_to_10k_mb"] = round(rss["10000"] - rss["1000"], 1)
        return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--captures", type=int, default=CHECKPOINTS[-1])
    parser.add_argument("--data", type=Path, default=None, help="parent of the temporary data directory")
    args = parser.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    print(json.dumps(run(args.captures, args.data), indent=2))


if __name__ == "__main__":
    main()
