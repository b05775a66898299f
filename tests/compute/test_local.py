"""The local backend: the one implementation of "measure many files" on this machine."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import psutil
import pytest

from station.batch import FileResult
from station.compute import ComputeCancelledError, ImageBytes, LocalBackend
from tests.compute.conftest import PARAMS
from tests.poison import dies_on_poison


def lines(results: list[FileResult]) -> list[str]:
    return [json.dumps(r.to_json()) for r in results]


@pytest.mark.parametrize("jobs", [1, 2])
def test_the_pool_gives_what_one_frame_at_a_time_gives_in_input_order(
    frames: list[Path], reference: list[str], jobs: int
) -> None:
    seen: list[str] = []
    results = list(LocalBackend(jobs).measure(frames, PARAMS, on_result=lambda r: seen.append(r.file)))
    assert lines(results) == reference
    assert seen == [str(f) for f in frames]


def test_frames_given_as_bytes_measure_as_their_files(frames: list[Path], reference: list[str]) -> None:
    items = [ImageBytes(str(f), f.read_bytes()) for f in frames]
    assert lines(list(LocalBackend(2).measure(items, PARAMS))) == reference


def test_a_frame_that_kills_its_worker_twice_is_its_worker_died_error_and_the_rest_is_measured(
    tmp_path: Path, frames: list[Path], reference: list[str]
) -> None:
    poison = tmp_path / "poison.png"
    poison.write_bytes(frames[0].read_bytes())
    items = [*frames[:20], poison, *frames[20:40], poison, *frames[40:]]
    results = list(LocalBackend(2, measure_one=dies_on_poison).measure(items, PARAMS))
    died = [i for i, r in enumerate(results) if r.code == "worker_died"]
    assert died == [20, 41]
    assert "died" in str(results[20].error)
    kept = [r for i, r in enumerate(results) if i not in died]
    assert lines(kept) == reference


@pytest.mark.parametrize("jobs", [1, 2])
def test_cancelling_stops_the_run_and_says_so(frames: list[Path], reference: list[str], jobs: int) -> None:
    got: list[FileResult] = []
    run = LocalBackend(jobs).measure(frames, PARAMS, on_result=got.append, cancelled=lambda: len(got) >= 3)
    with pytest.raises(ComputeCancelledError, match="cancelled"):
        list(run)
    assert 3 <= len(got) < len(frames)
    assert lines(got) == reference[: len(got)]


def test_a_script_without_a_main_guard_gets_one_clear_error_not_a_worker_died_per_frame(
    tmp_path: Path, frames: list[Path]
) -> None:
    script = tmp_path / "unguarded.py"
    script.write_text(
        "from station.compute import LocalBackend\n"
        "from station.vision import MeasureParams\n"
        f"files = {[str(f) for f in frames[:8]]!r}\n"
        "print([r.code for r in LocalBackend(2).measure(files, MeasureParams())])\n",
        encoding="utf-8",
    )
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=120, check=False
    )
    assert done.returncode == 1
    assert "worker_died" not in done.stdout
    assert "ComputeError: the local pool's processes die before measuring anything" in done.stderr
    assert 'guard its top level with `if __name__ == "__main__":`' in done.stderr


def test_a_frame_whose_fresh_worker_died_before_starting_on_it_is_measured_again_not_blamed(
    tmp_path: Path, frames: list[Path], reference: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The flaky failure of the test above, made deterministic: after a worker's death, the first fresh
    process for the suspects dies (killed from outside) before it takes a frame. That frame never ran:
    it is measured again in another process, and only the frame that kills its worker is blamed."""
    real = LocalBackend._check_starts
    killed: list[int] = []

    def started_then_lost(pool: ProcessPoolExecutor) -> None:
        real(pool)
        if not killed:
            pid = pool.submit(os.getpid).result()
            os.kill(pid, signal.SIGKILL)
            with contextlib.suppress(psutil.NoSuchProcess):
                psutil.Process(pid).wait(timeout=30)  # dead before any frame is sent
            killed.append(pid)

    monkeypatch.setattr(LocalBackend, "_check_starts", staticmethod(started_then_lost))
    poison = tmp_path / "poison.png"
    poison.write_bytes(frames[0].read_bytes())
    # 12 frames in batches of 2: the poison shares its batch with frames[10], the first suspect
    items = [*frames[:11], poison]
    results = list(LocalBackend(2, measure_one=dies_on_poison).measure(items, PARAMS))
    assert killed, "no fresh process was started for the suspects"
    assert [i for i, r in enumerate(results) if r.code == "worker_died"] == [11]
    assert lines(results[:11]) == reference[:11]
