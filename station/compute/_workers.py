"""Admitting a cluster's workers: what the client checks on every worker before it gets work, and the
task every worker runs (which checks again where it runs, for a worker that joined later)."""

from __future__ import annotations

import contextlib
import logging
import os
from collections.abc import Sequence
from typing import Any

from station.batch import AnyParams, FileResult
from station.compute import _checks
from station.compute._errors import WorkerRefusedError
from station.compute._tasks import Item, MeasureOne, measure_batch
from station.imageio import ImageLimits
from station.runtime import tune_allocator

log = logging.getLogger(__name__)


def _this_worker() -> str:
    from distributed import get_worker

    worker = get_worker()
    return f"worker {worker.name!r} at {worker.address}"


def run_batch(
    items: Sequence[Item],
    params: AnyParams,
    limits: ImageLimits | None,
    measure_one: MeasureOne,
    samples: _checks.Samples,
) -> list[FileResult]:
    """The task, on a worker: refuse if this worker cannot read the batch's directories as the client
    does, else measure the batch (in a process whose allocator keeps image buffers, as the station's
    own processes do: ``station.runtime``)."""
    tune_allocator()
    dirs = {os.path.dirname(item) for item in items if isinstance(item, str)}
    problems = _checks.unreadable({d: s for d, s in samples.items() if d in dirs})
    if problems:
        raise WorkerRefusedError(f"{_this_worker()} {'; '.join(problems)}{SHARE_HINT}")
    return measure_batch(items, params, limits, measure_one)


SHARE_HINT = (
    ": mount the data directory at the same path on every worker (the lab's network share), or send "
    "the frames with --ship-images"
)


def samples_of(work: Sequence[Item]) -> dict[str, tuple[str, int]]:
    """For each directory of the frames, its first frame that exists here and its size."""
    samples: dict[str, tuple[str, int]] = {}
    for item in work:
        if isinstance(item, str):
            directory = os.path.dirname(item)
            if directory not in samples:
                with contextlib.suppress(OSError):
                    samples[directory] = (item, os.stat(item).st_size)
    return samples


def same_params(params: AnyParams) -> AnyParams:
    """The parameters' task: each worker fetches its result once and keeps it for every batch; unlike
    scattered data, the scheduler can compute it again when every worker holding it has died."""
    return params


def worker_names(client: Any) -> dict[str, str]:
    """address -> how errors name the worker."""
    info = client.scheduler_info(n_workers=-1)["workers"]
    return {addr: f"worker {w.get('name', addr)!r} at {addr}" for addr, w in info.items()}


def admit(client: Any, samples: _checks.Samples, checked: dict[str, set[str]]) -> None:
    """Check every worker not yet ``checked`` for these directories: it reads them as the client does
    and runs the same software; WorkerRefusedError naming each one that does not. ``checked`` (worker
    address -> directories it reads) is updated with the workers admitted."""
    workers = worker_names(client)
    todo = [a for a in workers if a not in checked or not set(samples) <= checked[a]]
    if not todo:
        return
    reports = client.run(_checks.probe, samples, workers=todo, on_error="return")
    mine = _checks.fingerprint()
    problems = []
    for addr, report in sorted(reports.items()):
        who = workers.get(addr, f"worker at {addr}")
        if isinstance(report, OSError | TimeoutError):  # it left (or died) since it was listed
            log.info("%s did not answer the check (%s): it is asked again after the next batch", who, report)
            continue
        if isinstance(report, BaseException):
            problems.append(
                f"{who} cannot run the station's measurement ({type(report).__name__}: {report}): "
                "start `dask worker` in the station's environment (the project installed with "
                "constraints.txt)"
            )
            continue
        found = []
        differs = _checks.software_differences(mine, report["software"])
        if differs:
            found.append(
                f"{who} has {', '.join(differs)}: its numbers would not be the station's; install the "
                "project with constraints.txt there"
            )
        if report["unreadable"]:
            found.append(f"{who} {'; '.join(report['unreadable'])}{SHARE_HINT}")
        if found:
            problems.extend(found)
        else:
            checked.setdefault(addr, set()).update(samples)
    if problems:
        raise WorkerRefusedError("; ".join(problems))
