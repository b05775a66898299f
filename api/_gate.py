"""Admission to ``/measure``: a few places, at most one image decoded and measured per core, and 503
for the rest.

An upload's cost is in memory more than in time: a 45 Mpx 16-bit colour frame is 256 MiB decoded and
its measurement needs about as much again. So the gate works in two steps:

* :meth:`DecodeGate.place`: ``slots + queue`` requests at most are let in (the rest get 503 with
  ``Retry-After`` before their body is read); a request reads its body (64 MiB at most) in its place;
* :meth:`DecodeGate.slots_for`: it then waits, first come first served, for as many of the ``slots``
  (one per core) as its image weighs: one, or every slot for an image whose header declares more than
  its share of the decoded-size cap (:meth:`DecodeGate.weight`). Two of the largest images are never
  decoded at once; two ordinary ones are.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections import deque
from collections.abc import AsyncIterator

from api._errors import RETRY_AFTER_S, ApiError


class DecodeGate:
    """``slots`` slots (one per core), ``slots + queue`` places; beyond, :class:`ApiError` 503."""

    def __init__(self, slots: int, queue: int) -> None:
        if slots < 1 or queue < 0:
            raise ValueError(f"a gate needs at least one slot and a queue of 0 or more, got {slots}, {queue}")
        self.slots = slots
        self.queue = queue
        self.admitted = 0
        self._free = slots
        self._waiters: deque[tuple[int, asyncio.Future[None]]] = deque()

    @property
    def busy(self) -> int:
        """Slots held now."""
        return self.slots - self._free

    def weight(self, decoded_bytes: int | None, max_decoded_bytes: int) -> int:
        """The slots an image takes: 1, or more as its decoded size passes multiples of the cap's share
        per slot (an image at the cap takes them all)."""
        if decoded_bytes is None:
            return 1
        share = max(1, max_decoded_bytes // self.slots)
        return max(1, min(self.slots, -(-decoded_bytes // share)))

    @contextlib.asynccontextmanager
    async def place(self) -> AsyncIterator[None]:
        """A place in the gate for the block; 503 (busy) when every place is taken."""
        if self.admitted >= self.slots + self.queue:
            raise ApiError(
                503,
                f"the station is measuring or reading {self.admitted} image(s), its limit: send this one "
                "again in a moment",
                "busy",
                headers={"Retry-After": str(RETRY_AFTER_S["busy"])},
            )
        self.admitted += 1
        try:
            yield
        finally:
            self.admitted -= 1

    @contextlib.asynccontextmanager
    async def slots_for(self, weight: int) -> AsyncIterator[None]:
        """Hold ``weight`` slots for the block, waiting for them behind earlier requests."""
        weight = max(1, min(self.slots, weight))
        if self._free >= weight and not self._waiters:
            self._free -= weight
        else:
            waiter: asyncio.Future[None] = asyncio.get_running_loop().create_future()
            self._waiters.append((weight, waiter))
            try:
                await waiter  # the slots are handed over by the requests that release them
            except asyncio.CancelledError:
                if waiter.done() and not waiter.cancelled():
                    self._release(weight)  # handed the slots just as the wait was cancelled
                else:
                    self._waiters.remove((weight, waiter))
                    self._release(0)  # a smaller request behind it may fit now
                raise
        try:
            yield
        finally:
            self._release(weight)

    def _release(self, weight: int) -> None:
        self._free += weight
        while self._waiters and self._waiters[0][0] <= self._free:
            wanted, waiter = self._waiters.popleft()
            if not waiter.done():
                self._free -= wanted
                waiter.set_result(None)
