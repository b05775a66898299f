"""Sessions measuring through a backend: the same numbers as the stored session, and a backend that
fails leaves the session resumable."""

from __future__ import annotations

import pytest

from station.cli import main
from station.compute import ComputeSpec
from station.session import run_session
from tests.compute.cluster import free_port
from tests.compute.conftest import StoredSession, measured, same_results


def test_a_reanalysis_in_the_local_pool_reproduces_the_stored_session(stored: StoredSession) -> None:
    again = run_session(
        "reanalyse", params={"session": stored.id}, data=stored.data, compute=ComputeSpec(jobs=2)
    )
    assert again.state == "succeeded", again.error
    assert same_results(again.results["validation"], stored.results)
    assert measured(stored.data, again.id) == measured(stored.data, stored.id)


@pytest.mark.timeout(180)
def test_a_scheduler_that_cannot_be_reached_fails_the_session_which_then_resumes(
    stored: StoredSession,
) -> None:
    gone = f"tcp://127.0.0.1:{free_port()}"
    failed = run_session(
        "reanalyse", params={"session": stored.id}, data=stored.data, compute=ComputeSpec(gone)
    )
    assert failed.state == "failed"
    assert failed.error is not None
    assert f"the Dask scheduler at {gone} cannot be reached" in failed.error
    assert "dask scheduler" in failed.error
    assert measured(stored.data, failed.id) == []  # nothing half-recorded
    resumed = run_session(resume=failed.id, data=stored.data, compute=ComputeSpec())
    assert (resumed.id, resumed.state) == (failed.id, "succeeded")
    assert same_results(resumed.results["validation"], stored.results)
    assert measured(stored.data, resumed.id) == measured(stored.data, stored.id)


def test_station_run_says_why_the_cluster_failed_and_how_to_continue(
    stored: StoredSession, capsys: pytest.CaptureFixture[str]
) -> None:
    gone = f"tcp://127.0.0.1:{free_port()}"
    argv = [
        "run",
        "reanalyse",
        "--param",
        f"session={stored.id}",
        "--data",
        str(stored.data),
        "--cluster",
        gone,
    ]
    assert main(argv) == 1
    out = capsys.readouterr().out
    assert f"the Dask scheduler at {gone} cannot be reached" in out
    assert "station run --resume " in out
