"""A real Dask cluster on localhost for the tests: ``dask scheduler`` and ``dask worker`` processes, as a
lab runs them (README, "A lab's archive on a Dask cluster"), on free ports, short-lived.

Workers run under a nanny (``dask worker``'s default), which starts a worker process again when it
dies, as on a lab's machines. Every process is told to end by itself if the test run dies: workers
when the scheduler has gone (``--death-timeout``), the scheduler when idle (``--idle-timeout``).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
DASK = str(Path(sys.executable).parent / "dask")
START_TIMEOUT_S = 90.0
SCHEDULER_OPTIONS = ("--no-dashboard", "--idle-timeout", "600")
WORKER_OPTIONS = ("--nthreads", "1", "--no-dashboard", "--death-timeout", "20", "--memory-limit", "0")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


#: What README's "A lab's archive on a Dask cluster" tells a lab to run its scheduler and workers with.
LAB_ENV = {
    "DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED": "False",
    "DASK_DISTRIBUTED__ADMIN__TICK__INTERVAL": "1s",
}


def _env(**extra: str) -> dict[str, str]:
    # the tests' own modules (tests.poison) importable on the workers, as the project is
    env = {**os.environ, **LAB_ENV, "PYTHONPATH": str(ROOT), **extra}
    env.pop("PYTEST_CURRENT_TEST", None)
    return env


class Cluster:
    """One scheduler and its workers; ``client()`` connects a ``distributed.Client`` to it."""

    def __init__(self, *, allowed_failures: int = 1) -> None:
        self.port = free_port()
        self.address = f"tcp://127.0.0.1:{self.port}"
        self.workers: dict[str, subprocess.Popen[bytes]] = {}
        self.scheduler = subprocess.Popen(
            [DASK, "scheduler", "--host", "127.0.0.1", "--port", str(self.port), *SCHEDULER_OPTIONS],
            cwd=ROOT,
            env=_env(DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES=str(allowed_failures)),
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        self._client: Any = None

    def start_worker(self, name: str, *, prefix: Sequence[str] = ()) -> None:
        """``dask worker ADDRESS --name NAME`` (one process, one thread), run through ``prefix``."""
        self.workers[name] = subprocess.Popen(
            [*prefix, DASK, "worker", self.address, "--name", name, *WORKER_OPTIONS],
            cwd=ROOT,
            env=_env(),
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )

    def stop_worker(self, name: str) -> None:
        proc = self.workers.pop(name)
        proc.terminate()
        try:
            proc.wait(20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)
        self.wait_for(lambda info: name not in {w["name"] for w in info.values()}, f"{name} to leave")

    def client(self) -> Any:
        from distributed import Client

        if self._client is None:
            self._client = Client(self.address, timeout=START_TIMEOUT_S, set_as_default=False)
        return self._client

    def workers_info(self) -> dict[str, Any]:
        """address -> the scheduler's record of the worker (asked now, not cached)."""

        def info(dask_scheduler: Any) -> dict[str, Any]:
            return {a: {"name": str(w.name), "pid": w.pid} for a, w in dask_scheduler.workers.items()}

        result: dict[str, Any] = self.client().run_on_scheduler(info)
        return result

    def wait_for(self, ready: Any, what: str, timeout_s: float = START_TIMEOUT_S) -> dict[str, Any]:
        """Poll the scheduler until ``ready(workers_info)``; fail naming ``what`` after the timeout."""
        deadline = time.monotonic() + timeout_s
        while True:
            info = self.workers_info()
            if ready(info):
                return info
            if time.monotonic() > deadline:
                raise TimeoutError(f"the test cluster: waited {timeout_s:.0f} s for {what}; workers: {info}")
            time.sleep(0.2)

    def ready(self, names: Sequence[str]) -> dict[str, Any]:
        """Wait until exactly the workers ``names`` are connected; address -> info."""
        wanted = set(names)
        return self.wait_for(lambda info: {w["name"] for w in info.values()} == wanted, f"workers {names}")

    def tasks(self) -> int:
        """How many tasks the scheduler holds."""

        def count(dask_scheduler: Any) -> int:
            return len(dask_scheduler.tasks)

        return int(self.client().run_on_scheduler(count))

    def close(self) -> None:
        if self._client is not None:
            with contextlib.suppress(Exception):
                self._client.close(timeout=5)
        for proc in [*self.workers.values(), self.scheduler]:
            proc.terminate()
        for proc in [*self.workers.values(), self.scheduler]:
            try:
                proc.wait(20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5)


@contextlib.contextmanager
def running_cluster(workers: Sequence[str], *, allowed_failures: int = 1) -> Iterator[Cluster]:
    cluster = Cluster(allowed_failures=allowed_failures)
    try:
        for name in workers:
            cluster.start_worker(name)
        cluster.ready(workers)
        yield cluster
    finally:
        cluster.close()


def unshare_available() -> bool:
    """Whether this machine lets a process have a mount namespace of its own (root, util-linux)."""
    if shutil.which("unshare") is None:
        return False
    done = subprocess.run(["unshare", "--mount", "true"], capture_output=True, check=False)
    return done.returncode == 0


def without_directory(directory: Path) -> list[str]:
    """A command prefix that runs a program in a mount namespace where ``directory`` is an empty
    mount point: a machine that has not mounted the lab's share."""
    script = f'mount -t tmpfs none "{directory}" && exec "$@"'
    return ["unshare", "--mount", "--propagation", "private", "sh", "-c", script, "sh"]
