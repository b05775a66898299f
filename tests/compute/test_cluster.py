"""The Dask backend against a real cluster: a ``dask scheduler`` and two ``dask worker`` processes on
localhost, started here. Marked ``cluster``: ``make test`` runs these apart from the rest (a loaded
machine slows the workers' start-up, not the verdicts).

Every verdict is bit-identity with the frames measured one at a time in this process (or with the
stored session), whatever the cluster went through.
"""

from __future__ import annotations

import json
import logging
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from station.batch import FileResult
from station.compute import (
    ClusterUnavailableError,
    ComputeCancelledError,
    ComputeSpec,
    DaskBackend,
)
from station.session import run_session
from tests.compute.cluster import ROOT, Cluster, running_cluster, unshare_available, without_directory
from tests.compute.conftest import PARAMS, StoredSession, measured, same_results
from tests.conftest import needs_system
from tests.poison import dies_on_poison

pytestmark = [pytest.mark.cluster, pytest.mark.timeout(300)]

WORKERS = ("alpha", "beta")


@pytest.fixture(scope="module")
def cluster() -> Iterator[Cluster]:
    with running_cluster(WORKERS) as c:
        yield c


@pytest.fixture
def two(cluster: Cluster) -> Cluster:
    """The cluster with exactly its two workers connected (a test before may have killed one)."""
    cluster.ready(WORKERS)
    return cluster


def lines(results: list[FileResult]) -> list[str]:
    return [json.dumps(r.to_json()) for r in results]


def station(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "station.cli", *args], cwd=cwd, capture_output=True, text=True, timeout=240
    )


def test_station_measure_on_the_cluster_prints_the_lines_measured_here(
    two: Cluster, frames: list[Path], reference: list[str]
) -> None:
    # relative names, as a user types them: the workers get the absolute path, the lines the name as given
    names = [f.name for f in frames]
    done = station("measure", "--json", "--cluster", two.address, *names, cwd=frames[0].parent)
    assert done.returncode == 0, done.stderr
    docs = [json.loads(line) for line in done.stdout.splitlines()]
    assert [d.pop("file") for d in docs] == names
    expected = [json.loads(line) for line in reference]
    for doc in expected:
        del doc["file"]
    assert docs == expected


def test_shipped_images_measure_as_the_files(two: Cluster, frames: list[Path], reference: list[str]) -> None:
    backend = DaskBackend(two.address, ship_images=True)
    try:
        assert lines(list(backend.measure(frames, PARAMS))) == reference
    finally:
        backend.close()


def test_a_session_reanalysed_on_the_cluster_is_the_local_run_and_the_stored_session(
    two: Cluster, stored: StoredSession
) -> None:
    on_cluster = run_session(
        "reanalyse", params={"session": stored.id}, data=stored.data, compute=ComputeSpec(two.address)
    )
    here = run_session("reanalyse", params={"session": stored.id}, data=stored.data, compute=ComputeSpec())
    assert (on_cluster.state, here.state) == ("succeeded", "succeeded"), (on_cluster.error, here.error)
    assert on_cluster.results == here.results
    assert same_results(on_cluster.results["validation"], stored.results)
    original = measured(stored.data, stored.id)
    assert measured(stored.data, on_cluster.id) == measured(stored.data, here.id) == original


def _processing(cluster: Cluster) -> dict[str, tuple[int, int]]:
    """name -> (pid, tasks processing) of each worker, from the scheduler."""

    def state(dask_scheduler: Any) -> dict[str, tuple[int, int]]:
        return {str(w.name): (w.pid, len(w.processing)) for w in dask_scheduler.workers.values()}

    result: dict[str, tuple[int, int]] = cluster.client().run_on_scheduler(state)
    return result


def test_a_worker_killed_mid_run_leaves_the_results_unchanged(
    two: Cluster, frames: list[Path], reference: list[str]
) -> None:
    killed: list[tuple[int, int]] = []  # (pid, results received when it was killed)
    got: list[FileResult] = []

    def kill_a_busy_worker(result: FileResult) -> None:
        got.append(result)
        if killed:
            return
        pid, busy = max(_processing(two).values(), key=lambda w: w[1])
        if busy:  # it holds a task: SIGKILL, as the OOM killer does (no goodbye to the scheduler)
            os.kill(pid, signal.SIGKILL)
            killed.append((pid, len(got)))

    backend = DaskBackend(two.address)
    try:
        results = list(backend.measure(frames * 4, PARAMS, on_result=kill_a_busy_worker))
    finally:
        backend.close()
    ((pid, at),) = killed
    assert at < len(frames) * 4  # mid-run
    assert lines(results) == reference * 4
    after = two.ready(WORKERS)  # its nanny started it again
    assert pid not in {w["pid"] for w in after.values()}


def test_a_frame_that_kills_its_workers_is_its_worker_died_error(
    two: Cluster, frames: list[Path], reference: list[str], tmp_path: Path
) -> None:
    poison = tmp_path / "poison.png"
    poison.write_bytes(frames[0].read_bytes())
    items = [*frames[:10], poison, *frames[10:16]]
    backend = DaskBackend(two.address, measure_one=dies_on_poison)
    try:
        results = list(backend.measure(items, PARAMS))
    finally:
        backend.close()
    assert results[10].code == "worker_died"
    assert results[10].file == str(poison)
    assert "tried alone and failed again" in str(results[10].error)
    assert lines(results[:10] + results[11:]) == reference[:16]


def test_frames_queued_behind_a_killer_on_its_only_worker_are_measured(
    two: Cluster, frames: list[Path], reference: list[str], tmp_path: Path
) -> None:
    # one worker: the scheduler queues the next frame on it behind the killer, and counts each death
    # against both; only the killer may be blamed
    poison = tmp_path / "poison.png"
    poison.write_bytes(frames[0].read_bytes())
    items = [frames[0], poison, *frames[1:4]]
    two.stop_worker("beta")
    backend = DaskBackend(two.address, measure_one=dies_on_poison)
    try:
        results = list(backend.measure(items, PARAMS))
    finally:
        backend.close()
        two.start_worker("beta")
    assert [r.code for r in results].count("worker_died") == 1
    assert results[1].code == "worker_died"
    assert lines(results[:1] + results[2:]) == reference[:4]


def test_cancelling_cancels_the_clusters_tasks(
    two: Cluster, frames: list[Path], reference: list[str]
) -> None:
    got: list[FileResult] = []
    backend = DaskBackend(two.address)
    try:
        run = backend.measure(frames * 4, PARAMS, on_result=got.append, cancelled=lambda: len(got) >= 2)
        with pytest.raises(ComputeCancelledError, match="cancelled"):
            list(run)
        assert backend.client().status == "running"  # still connected: the cancel, not a hang-up, did it
        two.wait_for(lambda _: two.tasks() == 0, "the run's tasks to be cancelled", timeout_s=30)
    finally:
        backend.close()
    assert 2 <= len(got) < len(frames) * 4
    assert lines(got) == (reference * 4)[: len(got)]


def test_a_worker_without_the_data_directory_is_refused_by_name(
    two: Cluster, frames: list[Path], reference: list[str]
) -> None:
    needs_system("unshare (a mount namespace: root and util-linux)", unshare_available())
    share = frames[0].parent
    two.start_worker("no-share", prefix=without_directory(share))
    try:
        two.ready([*WORKERS, "no-share"])
        done = station("measure", "--json", "--cluster", two.address, *map(str, frames), cwd=ROOT)
        assert done.returncode == 1
        assert done.stdout == ""  # refused before anything was measured
        assert "worker 'no-share' at tcp://" in done.stderr
        assert f"cannot read {frames[0]}" in done.stderr
        assert "mount the data directory at the same path on every worker" in done.stderr
        assert "--ship-images" in done.stderr
        assert "alpha" not in done.stderr
        assert "beta" not in done.stderr
        # the bytes travel instead: every worker, the one without the share included, can measure
        backend = DaskBackend(two.address, ship_images=True)
        try:
            assert lines(list(backend.measure(frames, PARAMS))) == reference
        finally:
            backend.close()
    finally:
        two.stop_worker("no-share")


def test_a_local_cluster_measures_as_the_pool(frames: list[Path], reference: list[str]) -> None:
    backend = DaskBackend("local:2")
    try:
        assert lines(list(backend.measure(frames, PARAMS))) == reference
    finally:
        backend.close()


def test_a_scheduler_that_goes_away_mid_run_is_a_clear_error(frames: list[Path]) -> None:
    with running_cluster(["solo"]) as solo:
        got: list[FileResult] = []

        def kill_the_scheduler(result: FileResult) -> None:
            got.append(result)
            if len(got) == 1:
                solo.scheduler.kill()

        backend = DaskBackend(solo.address)
        try:
            with pytest.raises(ClusterUnavailableError) as exc:
                list(backend.measure(frames, PARAMS, on_result=kill_the_scheduler))
        finally:
            backend.close()
    assert f"the Dask scheduler at {solo.address}" in str(exc.value)
    assert "--cluster local" in str(exc.value)
    assert 1 <= len(got) < len(frames)


def test_the_service_reanalyses_on_the_configured_cluster(
    stored: StoredSession, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    from station.worker import SessionHost, WorkerSpec

    caplog.set_level(logging.INFO, logger="station.compute")
    config = tmp_path / "station.toml"
    config.write_text(
        'name = "a465-lab-1"\n[camera]\ndriver = "v4l2"\noptions = { device = "/dev/video9" }\n'
        '[compute]\ncluster = "local:1"\n',
        encoding="utf-8",
    )
    host = SessionHost(WorkerSpec(config=config, data=stored.data), send=lambda message: None)
    try:
        assert isinstance(host.compute, DaskBackend)
        assert host.compute.name == "a Dask LocalCluster of 1 worker"
        sid = host.rpc_create("reanalyse", {"session": stored.id}, {})  # as POST /sessions does
        assert host.rpc_wait(240)
    finally:
        host.shutdown()
    assert measured(stored.data, sid) == measured(stored.data, stored.id)
    assert "measuring on a Dask LocalCluster of 1 worker" in caplog.messages  # where it measured


def test_an_archive_selection_on_the_cluster_is_the_local_run(two: Cluster, tmp_path: Path) -> None:
    """Issue 24, item 3 on a cluster: a sweep and a re-analysis of a selection measure each group of
    sessions in one call on the workers, with the numbers of the local pool."""
    data = tmp_path / "data"
    ids = []
    for n in (2, 1):
        out = run_session("validation", sim=True, params={"steps_per_side": n}, data=data)
        assert out.state == "succeeded", out.error
        ids.append(out.id)
    for kind, params in (
        ("sweep", {"sessions": ids, "grid": {"skip": [1, 2]}}),
        ("reanalyse", {"sessions": ids}),
    ):
        on_cluster = run_session(kind, params=params, data=data, compute=ComputeSpec(two.address))
        here = run_session(kind, params=params, data=data, compute=ComputeSpec())
        assert (on_cluster.state, here.state) == ("succeeded", "succeeded"), (on_cluster.error, here.error)
        assert on_cluster.results == here.results
    assert len(measured(data, on_cluster.id)) == 8 + 4  # the re-analysis recorded every capture
    assert measured(data, on_cluster.id) == measured(data, here.id)
