"""The Dask backend: frames measured by the workers of a ``distributed`` scheduler (a lab's machines),
or of a ``LocalCluster`` started here (``local:N``).

* **Tasks are batches of frames**, a few per worker and at most ``MAX_BATCH`` frames each; the
  measurement parameters are one task of their own that every batch depends on: each worker fetches
  them once, not with each batch (and, unlike scattered data, they survive the loss of every worker).
* **Frames travel as paths** when the workers share the data directory at the same path (checked on
  every worker before the work starts, and again by each task where it runs: a worker that cannot
  read it is refused by name), or **as bytes** read here (``ship_images``).
* **Only the client writes**: results come back as ``station measure``'s results, in input order;
  the caller records them.
* **Faults**: a worker that dies has its tasks run again elsewhere by the scheduler (same frames, same
  software: the same numbers). A batch that kills workers repeatedly (the scheduler's
  ``allowed-failures``) ends in ``KilledWorker``: each of its frames is then measured alone, and a
  frame that kills workers alone, with no other suspect in flight, gets a ``worker_died`` error. A
  scheduler that goes away fails the run with ClusterUnavailableError; cancelling (Ctrl-C, an abort)
  cancels the tasks on the cluster.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import socket
import threading
from collections import deque
from collections.abc import Iterator
from typing import Any
from urllib.parse import urlsplit

from station.batch import AnyParams, FileResult, display_name, measure_file
from station.compute._backend import Cancelled, Frames, OnResult, as_items, batch_ranges, never
from station.compute._checks import Samples
from station.compute._errors import (
    ClusterUnavailableError,
    ComputeCancelledError,
    ComputeError,
    WorkerRefusedError,
)
from station.compute._tasks import ImageBytes, Item, MeasureOne, item_name, worker_died
from station.compute._workers import admit, run_batch, same_params, samples_of, worker_names
from station.imageio import DEFAULT_MAX_BYTES, ImageFileError, ImageLimits, read_file_bytes

log = logging.getLogger(__name__)

MAX_BATCH = 64
POLL_S = 0.1
#: How long to wait for the scheduler to answer, and for a first worker to join it (s).
CONNECT_TIMEOUT_S = 10.0
#: ``local:N``'s Dask configuration (README, "Sizing": what a lab's workers should run with too):
#: a frame's batch may kill one worker and be tried again, a second death ends it; no statistical
#: profiler sampling every worker's stack 100 times a second, and the event loops' health check every
#: second instead of every 20 ms (together, 60 % of an idle LocalCluster's CPU, and threads that take the
#: GIL from the measurement).
LOCAL_CONFIG = {
    "distributed.scheduler.allowed-failures": 1,
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
}


def _unreachable(address: str, why: str) -> ClusterUnavailableError:
    return ClusterUnavailableError(
        f"the Dask scheduler at {address} {why}: start it (`dask scheduler`) and its workers (`dask worker "
        f"{address}`), check the address and the firewall, or measure here with --cluster local"
    )


@contextlib.contextmanager
def _quiet(name: str = "distributed") -> Iterator[None]:
    """Silence a logger's tracebacks while a client whose scheduler is gone is closed."""
    logger = logging.getLogger(name)
    level = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        logger.setLevel(level)


class DaskBackend:
    """Measures on a Dask cluster: ``cluster`` is a scheduler's address or ``local:N``.

    The scheduler is reached (or the LocalCluster started) on the first ``measure``, and again after
    it was lost; ``close()`` disconnects (and stops a LocalCluster).
    """

    def __init__(
        self,
        cluster: str,
        *,
        ship_images: bool = False,
        measure_one: MeasureOne = measure_file,
        connect_timeout_s: float = CONNECT_TIMEOUT_S,
    ) -> None:
        self.cluster = cluster
        self.ship_images = ship_images
        self._measure_one = measure_one
        self._timeout = connect_timeout_s
        self._client: Any = None
        self._local: Any = None
        self._checked: dict[str, set[str]] = {}  # worker address -> directories it was found to read

    @property
    def name(self) -> str:
        n = self._local_workers()
        if n is None:
            return f"the Dask cluster at {self.cluster}"
        return f"a Dask LocalCluster of {n} worker{'s' if n > 1 else ''}"

    def _local_workers(self) -> int | None:
        return int(self.cluster.split(":", 1)[1]) if self.cluster.startswith("local:") else None

    # ------------------------------------------------------------------ connection

    def client(self) -> Any:
        """The connected ``distributed.Client`` (connecting, or starting the LocalCluster, first)."""
        if self._client is not None and self._client.status == "running":
            return self._client
        self._drop_client()
        n = self._local_workers()
        if n is None:
            self._reachable()
        import dask
        from distributed import Client, LocalCluster

        if n is not None:
            if self._local is None:
                with dask.config.set(LOCAL_CONFIG):
                    self._local = LocalCluster(
                        n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0"
                    )
            self._client = Client(self._local, set_as_default=False)
        else:
            try:
                self._client = Client(self.cluster, timeout=self._timeout, set_as_default=False)
            except (OSError, TimeoutError) as exc:
                raise _unreachable(self.cluster, f"cannot be reached ({exc})") from None
            try:
                self._client.wait_for_workers(1, timeout=self._timeout)
            except TimeoutError:
                self._drop_client()
                raise ClusterUnavailableError(
                    f"no worker has joined the Dask scheduler at {self.cluster} within {self._timeout:g} s: "
                    f"start workers with `dask worker {self.cluster}` in the station's environment"
                ) from None
        log.info("measuring on %s", self.name)
        self._checked.clear()
        return self._client

    def _reachable(self) -> None:
        """Fail at once on a refused or unresolvable address (Dask's own connect retries it until its
        timeout)."""
        parts = urlsplit(self.cluster)
        try:
            with socket.create_connection((parts.hostname or "", parts.port or 0), timeout=self._timeout):
                pass
        except OSError as exc:
            raise _unreachable(self.cluster, f"cannot be reached ({exc.strerror or exc})") from None

    def _drop_client(self) -> None:
        client, self._client = self._client, None
        if client is None:
            return
        quiet = _quiet() if client.status != "running" else contextlib.nullcontext()
        with quiet, contextlib.suppress(Exception):  # a lost client's close only logs its loss again
            client.close(timeout=2)

    def close(self) -> None:
        self._drop_client()
        local, self._local = self._local, None
        if local is not None:
            local.close()

    def _alive(self, client: Any) -> None:
        if client.status != "running":
            raise _unreachable(self.cluster, "went away during the run; its tasks are lost")

    # ------------------------------------------------------------------ measuring

    def measure(
        self,
        items: Frames,
        params: AnyParams,
        *,
        limits: ImageLimits | None = None,
        on_result: OnResult | None = None,
        cancelled: Cancelled | None = None,
    ) -> Iterator[FileResult]:
        """See :class:`~station.compute.MeasureBackend`."""
        given = as_items(items)
        names = [item_name(item) for item in given]
        work: list[Item] = [item if isinstance(item, ImageBytes) else os.path.abspath(item) for item in given]
        check = cancelled or never
        for index, result in self._results(work, params, limits, check):
            if check():  # also between results a batch already brought: a cancel never waits for a batch
                raise ComputeCancelledError("cancelled: the cluster's tasks for this run were cancelled")
            name, raw = display_name(names[index])
            if result.file != name or result.file_bytes_b64 != raw:  # the name as the caller gave it
                result = FileResult(name, result.measurement, result.error, result.code, raw)
            if on_result is not None:
                on_result(result)
            yield result

    def _results(
        self, work: list[Item], params: AnyParams, limits: ImageLimits | None, check: Cancelled
    ) -> Iterator[tuple[int, FileResult]]:
        client = self.client()
        samples = {} if self.ship_images else samples_of(work)
        admit(client, samples, self._checked)
        threads = max(1, sum(client.nthreads().values()))
        todo = deque(batch_ranges(len(work), threads, MAX_BATCH))
        window: deque[tuple[range, dict[int, FileResult], Any]] = deque()
        params_future = client.submit(same_params, params, pure=False, key=_key("params"))
        try:
            while todo or window:
                while todo and len(window) < 2 * threads:
                    batch = todo.popleft()
                    ready, future = self._submit(client, work, batch, params_future, limits, samples)
                    window.append((batch, ready, future))
                batch, ready, future = window[0]
                results = self._batch_results(
                    client, work, batch, ready, future, params_future, limits, check
                )
                window.popleft()
                yield from zip(batch, results, strict=True)
                if todo and set(worker_names(client)) - set(self._checked):
                    admit(client, samples, self._checked)  # a worker joined: check it before it gets work
        finally:
            self._cancel(client, [*(f for _, _, f in window if f is not None), params_future])

    def _submit(
        self,
        client: Any,
        work: list[Item],
        batch: range,
        params_future: Any,
        limits: ImageLimits | None,
        samples: Samples,
    ) -> tuple[dict[int, FileResult], Any]:
        """Send one batch; with ``ship_images`` its files are read here first, and a file that cannot
        be read is that frame's error without a task."""
        ready: dict[int, FileResult] = {}
        items: list[Item] = []
        for index in batch:
            item = work[index]
            if self.ship_images and isinstance(item, str):
                path = item
                try:
                    max_bytes = limits.max_bytes if limits is not None else DEFAULT_MAX_BYTES
                    item = ImageBytes(path, read_file_bytes(path, max_bytes=max_bytes, what="image file"))
                except ImageFileError as exc:
                    ready[index] = FileResult.for_path(path, error=exc.reason, code=exc.code)
                    continue
            items.append(item)
        if not items:
            return ready, None
        future = client.submit(
            run_batch, items, params_future, limits, self._measure_one, samples, pure=False, key=_key("batch")
        )
        return ready, future

    def _batch_results(
        self,
        client: Any,
        work: list[Item],
        batch: range,
        ready: dict[int, FileResult],
        future: Any,
        params_future: Any,
        limits: ImageLimits | None,
        check: Cancelled,
    ) -> list[FileResult]:
        if future is None:
            return [ready[i] for i in batch]
        from distributed import KilledWorker

        sent = [i for i in batch if i not in ready]
        try:
            measured = self._gather(client, future, check)
        except KilledWorker as exc:
            log.warning("a batch of %d frames killed its workers (%s): measuring each alone", len(sent), exc)
            measured = self._alone(client, [work[i] for i in sent], params_future, limits, check)
        ready.update(zip(sent, measured, strict=True))
        return [ready[i] for i in batch]

    def _alone(
        self, client: Any, items: list[Item], params_future: Any, limits: ImageLimits | None, check: Cancelled
    ) -> list[FileResult]:
        """Each frame of a killing batch as a task of its own; a frame whose task is killed again is
        tried once more with nothing else of this run's suspects in flight, and one that kills workers
        then too is ``worker_died``.

        The scheduler counts a death against every task *assigned* to the dead worker, queued ones too
        (``WorkerState.processing``): an innocent frame queued behind the killer on the same worker
        reaches ``allowed-failures`` with it. Tried by itself, it is measured.
        """
        from distributed import KilledWorker

        out: list[FileResult | None] = []
        suspects: list[int] = []
        futures = [self._submit_one(client, item, params_future, limits) for item in items]
        try:
            for item, future in zip(items, futures, strict=True):
                try:
                    out.extend(self._gather(client, future, check))
                except KilledWorker:
                    log.warning("%s was on a worker that died again: trying it by itself", item_name(item))
                    suspects.append(len(out))
                    out.append(None)
        finally:
            self._cancel(client, futures)
        for index in suspects:
            item = items[index]
            future = self._submit_one(client, item, params_future, limits)
            try:
                (out[index],) = self._gather(client, future, check)
            except KilledWorker as exc:
                log.warning("%s killed its workers by itself: it is that frame's error", item_name(item))
                out[index] = worker_died(item_name(item), type(exc).__name__)
            finally:
                self._cancel(client, [future])
        return [r for r in out if r is not None]

    def _submit_one(self, client: Any, item: Item, params_future: Any, limits: ImageLimits | None) -> Any:
        samples = {} if self.ship_images else samples_of([item])
        return client.submit(
            run_batch, [item], params_future, limits, self._measure_one, samples, pure=False, key=_key("one")
        )

    @staticmethod
    def _cancel(client: Any, futures: list[Any]) -> None:
        if client.status == "running":
            with contextlib.suppress(Exception):
                client.cancel(futures, force=True)

    def _gather(self, client: Any, future: Any, check: Cancelled) -> list[FileResult]:
        """The batch's results, polling ``check`` before and while waiting, and the scheduler's connection
        while waiting (a cancel asked for while results come faster than the poll still stops the run)."""
        from distributed import KilledWorker

        if check():
            raise ComputeCancelledError("cancelled: the cluster's tasks for this run were cancelled")
        done = threading.Event()
        future.add_done_callback(lambda _: done.set())
        while not done.wait(POLL_S):
            if check():
                raise ComputeCancelledError("cancelled: the cluster's tasks for this run were cancelled")
            self._alive(client)
        self._alive(client)
        try:
            results: list[FileResult] = future.result()
        except (KilledWorker, WorkerRefusedError):
            raise
        except asyncio.CancelledError:
            self._alive(client)
            raise _unreachable(self.cluster, "cancelled the run's tasks (it restarted?)") from None
        except Exception as exc:
            raise ComputeError(
                f"a task failed on {self.name} ({type(exc).__name__}: {exc}); see the worker's log"
            ) from exc
        return results


def _key(kind: str) -> str:
    import uuid

    return f"station-measure-{kind}-{uuid.uuid4().hex}"
