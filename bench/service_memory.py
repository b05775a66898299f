"""The HTTP side's memory under the largest uploads ``POST /api/v1/measure`` accepts (issue 18, row 7).

``station serve`` runs as a process of its own (no station: ``/measure`` needs none); four clients
then upload at once, four times over, each time the largest image of one kind that passes every cap
(64 MiB file, 50 Mpx, 256 MiB decoded): 16-bit colour at 6688 x 6688 px (256 MiB decoded), 8-bit colour,
16-bit and 8-bit grey at 7071 x 7071 (50 Mpx), each a crossing the station measures (bands of grey,
like the artifact's grooves) compressed as PNG; and colour noise at 4400 x 4400, whose PNG (55 MiB)
is near the body cap. Before each round the process's high-water
mark is reset (``/proc/PID/clear_refs``); after it, its peak resident memory (``VmHWM``) is read.

Issue 18's target: under 1.5 GB with four maximum-size uploads at once. Before the decoded-size cap
and ``/measure``'s slots, one 7000 x 7000 16-bit colour upload took 1.66 GB, four 5.48 GB.
``python -m bench.service_memory [--rounds ...]``; ``bench/results/service_memory.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

import cv2
import httpx
import numpy as np

RESULTS = Path(__file__).parent / "results" / "service_memory.json"
TOKEN = "memory-bench-token-0123456789"
TARGET_MB = 1500
KINDS: dict[str, tuple[int, int, type[np.generic]]] = {  # name: (side px, channels, dtype)
    "rgb16": (6688, 3, np.uint16),
    "rgb8": (7071, 3, np.uint8),
    "grey16": (7071, 1, np.uint16),
    "grey8": (7071, 1, np.uint8),
    "noise-rgb8": (4400, 3, np.uint8),  # incompressible: a 55 MiB file, near the 64 MiB body cap
}


@dataclass
class Round:
    kind: str
    side_px: int
    decoded_mib: float
    file_mib: float
    statuses: list[int]
    measured: int
    peak_rss_mb: float
    seconds: float


def crossing_png(side: int, channels: int, dtype: type[np.generic], *, noise: bool = False) -> bytes:
    """A dark cross on a light field (the grooves' look), ``side`` px square, as PNG; or, with ``noise``,
    random values (nothing to measure, nothing to compress: the largest file for its pixels)."""
    if noise:
        values = np.random.default_rng(0).integers(0, 256, (side, side, channels), np.uint8)
        ok, buf = cv2.imencode(".png", values, [cv2.IMWRITE_PNG_COMPRESSION, 1])
        assert ok
        return bytes(buf.tobytes())
    light, dark = (200, 30) if dtype == np.uint8 else (50000, 8000)
    image = np.full((side, side), light, dtype)
    half = side // 2
    image[half - side // 40 : half + side // 40, :] = dark
    image[:, half - side // 40 : half + side // 40] = dark
    if channels == 3:
        image = np.dstack([image] * 3)
    ok, buf = cv2.imencode(".png", image)
    assert ok
    return bytes(buf.tobytes())


def _status(pid: int, key: str) -> float:
    text = Path(f"/proc/{pid}/status").read_text()
    match = re.search(rf"^{key}:\s+(\d+) kB", text, re.MULTILINE)
    assert match, key
    return int(match.group(1)) / 1024


class Server:
    """``station serve`` (no station) on a free port, its stdout watched for the URL."""

    def __init__(self, data: Path) -> None:
        env = {**os.environ, "STATION_API_TOKEN": TOKEN}
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "station.cli", "serve", "--port", "0", "--data", str(data)],
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
            env=env,
        )
        assert self.proc.stdout is not None
        self.base = ""
        for line in self.proc.stdout:
            if "open http" in line:
                self.base = line.split("open ", 1)[1].split()[0].rstrip("/")
                break
        if not self.base:
            raise RuntimeError(f"station serve did not start (exit {self.proc.wait()})")
        threading.Thread(target=self.proc.stdout.read, daemon=True).start()

    def stop(self) -> None:
        self.proc.terminate()
        self.proc.wait(60)


def one_round(server: Server, kind: str, clients: int) -> Round:
    side, channels, dtype = KINDS[kind]
    png = crossing_png(side, channels, dtype, noise=kind.startswith("noise"))
    pid = server.proc.pid
    Path(f"/proc/{pid}/clear_refs").write_text("5")  # the high-water mark from now on
    started = time.monotonic()

    def upload(_: int) -> tuple[int, bool]:
        with httpx.Client(base_url=server.base, headers={"Authorization": f"Bearer {TOKEN}"}) as c:
            r = c.post("/api/v1/measure", content=png, headers={"content-type": "image/png"}, timeout=600)
        return r.status_code, r.status_code == 200 and bool(r.json().get("ok"))

    with ThreadPoolExecutor(clients) as pool:
        answers = list(pool.map(upload, range(clients)))
    return Round(
        kind=kind,
        side_px=side,
        decoded_mib=round(side * side * channels * np.dtype(dtype).itemsize / 2**20, 1),
        file_mib=round(len(png) / 2**20, 2),
        statuses=[s for s, _ in answers],
        measured=sum(ok for _, ok in answers),
        peak_rss_mb=round(_status(pid, "VmHWM"), 1),
        seconds=round(time.monotonic() - started, 1),
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--kinds", nargs="+", default=list(KINDS), choices=list(KINDS))
    parser.add_argument("--clients", type=int, default=4)
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        server = Server(Path(tmp) / "data")
        try:
            idle = _status(server.proc.pid, "VmRSS")
            rounds = [one_round(server, kind, args.clients) for kind in args.kinds]
        finally:
            server.stop()
    print(f"station serve (no station), idle: {idle:.0f} MB resident; {args.clients} concurrent uploads:")
    print("| image | px | decoded | file | answers | measured | peak RSS | s |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rounds:
        print(
            f"| {r.kind} | {r.side_px}x{r.side_px} | {r.decoded_mib} MiB | {r.file_mib} MiB | "
            f"{', '.join(map(str, r.statuses))} | {r.measured}/{len(r.statuses)} | {r.peak_rss_mb:.0f} MB | "
            f"{r.seconds} |"
        )
    worst = max(r.peak_rss_mb for r in rounds)
    print(f"worst peak {worst:.0f} MB (target < {TARGET_MB} MB): {'met' if worst < TARGET_MB else 'MISSED'}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    doc = {"clients": args.clients, "idle_rss_mb": round(idle, 1), "target_mb": TARGET_MB}
    args.out.write_text(json.dumps({**doc, "rounds": [asdict(r) for r in rounds]}, indent=1))


if __name__ == "__main__":
    main()
