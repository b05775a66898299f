"""The one place that opens the backend a :class:`~station.compute.ComputeSpec` names."""

from __future__ import annotations

from station.batch import measure_file
from station.compute._backend import MeasureBackend
from station.compute._dask import DaskBackend
from station.compute._local import LocalBackend
from station.compute._spec import ComputeSpec
from station.compute._tasks import MeasureOne


def open_backend(spec: ComputeSpec, *, measure_one: MeasureOne = measure_file) -> MeasureBackend:
    """The backend ``spec`` names, not yet connected (a cluster is reached on the first ``measure``).

    ``local``: :class:`~station.compute.LocalBackend` (nothing to start or install); ``local:N`` and
    an address: :class:`~station.compute.DaskBackend` (Dask is imported only when it connects).
    """
    if spec.is_pool:
        return LocalBackend(spec.jobs, measure_one=measure_one)
    return DaskBackend(spec.cluster, ship_images=spec.ship_images, measure_one=measure_one)
