"""What can go wrong with a compute backend itself (not with a frame: a frame's failure is its result)."""

from __future__ import annotations


class ComputeError(Exception):
    """The backend cannot measure: the message says what happened and what to do."""


class ClusterUnavailableError(ComputeError):
    """The Dask scheduler cannot be reached, or went away during the run (its tasks are lost)."""


class WorkerRefusedError(ComputeError):
    """A worker cannot do this work as the station would (it cannot read the data directory, or runs
    other measuring software): nothing is measured until every worker can, or it leaves the cluster."""


class ComputeCancelledError(ComputeError):
    """The run was cancelled (Ctrl-C, abort): the tasks still queued or running were cancelled."""
