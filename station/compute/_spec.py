"""Which backend measures: ``local`` (a process pool on this machine, the default), ``local:N`` (a
``distributed.LocalCluster`` of N worker processes) or a Dask scheduler's address.

One parser for the command line's ``--cluster``, the configuration's ``[compute] cluster`` and the
service, so that every door accepts and refuses the same values with the same words.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from urllib.parse import urlsplit

from station.batch import max_jobs

#: Dask's default scheduler port, taken when an address names none.
DEFAULT_SCHEDULER_PORT = 8786
SCHEMES = ("tcp", "tls")
CLUSTER_HELP = (
    "local (a process pool here), local:N (a Dask LocalCluster of N worker processes) or a Dask "
    "scheduler's address, e.g. tcp://10.0.0.5:8786"
)


def parse_cluster(text: str) -> str:
    """The normalised backend name: ``local``, ``local:N`` or ``SCHEME://HOST:PORT``.

    Raises
    ------
    ValueError
        Naming the value and what is allowed (e.g. ``local:0``, ``http://x``, a port out of range).
    """
    value = text.strip()
    if value.lower() == "local":
        return "local"
    if value.lower().startswith("local:"):
        n = value.split(":", 1)[1].strip()
        if not re.fullmatch(r"[0-9]+", n) or not 1 <= int(n) <= max_jobs():
            raise ValueError(f"cluster {text!r}: local:N needs N from 1 to {max_jobs()} worker processes")
        return f"local:{int(n)}"
    address = value if "://" in value else f"tcp://{value}"
    try:
        parts = urlsplit(address)
        port = parts.port
    except ValueError as exc:
        raise ValueError(f"cluster {text!r}: not an address ({exc}); expected {CLUSTER_HELP}") from None
    if parts.scheme not in SCHEMES:
        raise ValueError(
            f"cluster {text!r}: scheme {parts.scheme!r} is not one of {', '.join(SCHEMES)}; "
            f"expected {CLUSTER_HELP}"
        )
    if not parts.hostname or parts.path not in ("", "/") or parts.query or parts.username:
        raise ValueError(f"cluster {text!r}: expected {CLUSTER_HELP}")
    host = f"[{parts.hostname}]" if ":" in parts.hostname else parts.hostname
    return f"{parts.scheme}://{host}:{port or DEFAULT_SCHEDULER_PORT}"


@dataclass(frozen=True)
class ComputeSpec:
    """The backend chosen by the command line or the configuration.

    ``cluster``: as :func:`parse_cluster` gives it. ``jobs``: the local pool's processes (``local``
    only). ``ship_images``: the client reads every frame and sends its bytes with the task, for
    workers that do not share the data directory (a cluster only).
    """

    cluster: str = "local"
    jobs: int = 1
    ship_images: bool = False

    def __post_init__(self) -> None:
        if parse_cluster(self.cluster) != self.cluster:
            raise ValueError(f"cluster {self.cluster!r} is not normalised: use parse_cluster()")
        if not 1 <= self.jobs <= max_jobs():
            raise ValueError(f"jobs must be from 1 to {max_jobs()}, got {self.jobs}")
        if self.ship_images and self.cluster == "local":
            raise ValueError(
                "ship_images (--ship-images) sends the frames to a cluster's workers: name a cluster too "
                "(--cluster ADDRESS or local:N, or [compute] cluster); the local pool reads the files itself"
            )

    @classmethod
    def of(cls, cluster: str | None = None, *, jobs: int = 1, ship_images: bool = False) -> ComputeSpec:
        """A spec from unchecked text (ValueError naming what is wrong)."""
        return cls(parse_cluster(cluster or "local"), jobs, ship_images)

    @property
    def local_workers(self) -> int | None:
        """N of ``local:N``, else None."""
        return int(self.cluster.split(":", 1)[1]) if self.cluster.startswith("local:") else None

    @property
    def is_pool(self) -> bool:
        """The local process pool (no Dask)."""
        return self.cluster == "local"
