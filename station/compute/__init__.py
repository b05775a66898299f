"""Compute backends: where many frames are measured.

One small, typed door for every caller that measures many captures or files (``station measure``,
``station validate`` and ``sweep``, the ``reanalyse`` and ``sweep`` sessions, and the archive-wide plans
to come): *measure these frames (paths or bytes) with these parameters, report progress, give back
``station measure``'s results in order*::

    from station.compute import ComputeSpec, open_backend

    with contextlib.closing(open_backend(ComputeSpec.of("tcp://10.0.0.5:8786"))) as backend:
        for result in backend.measure(paths, params, on_result=progress, cancelled=stop.is_set):
            record(result.to_json())

* ``local`` (the default): :class:`LocalBackend`, this machine's process pool; nothing to start.
* ``local:N``: a ``distributed.LocalCluster`` of N worker processes started here.
* ``tcp://HOST:PORT``: the workers of a running Dask scheduler (:class:`DaskBackend`), which read the
  frames from the data directory at the same path, or get their bytes (``ship_images``).

Results are the same numbers on every backend (same frames, same parameters, same software: the
software is checked on every worker). Dask is imported only when a cluster is used.
"""

from station.compute._backend import Cancelled, Frames, MeasureBackend, OnResult, batch_ranges
from station.compute._dask import DaskBackend
from station.compute._errors import (
    ClusterUnavailableError,
    ComputeCancelledError,
    ComputeError,
    WorkerRefusedError,
)
from station.compute._local import LocalBackend
from station.compute._open import open_backend
from station.compute._spec import CLUSTER_HELP, ComputeSpec, parse_cluster
from station.compute._tasks import ImageBytes, Item, MeasureOne, measure_batch, measure_item

__all__ = [
    "CLUSTER_HELP",
    "Cancelled",
    "ClusterUnavailableError",
    "ComputeCancelledError",
    "ComputeError",
    "ComputeSpec",
    "DaskBackend",
    "Frames",
    "ImageBytes",
    "Item",
    "LocalBackend",
    "MeasureBackend",
    "MeasureOne",
    "OnResult",
    "WorkerRefusedError",
    "batch_ranges",
    "measure_batch",
    "measure_item",
    "open_backend",
    "parse_cluster",
]
