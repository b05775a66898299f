"""``/measure``'s gate (``api/_gate.py``): places, slots by weight, first come first served."""

from __future__ import annotations

import asyncio

import pytest

from api._errors import ApiError
from api._gate import DecodeGate

MIB = 2**20


def test_an_image_weighs_its_share_of_the_decoded_size_cap() -> None:
    gate = DecodeGate(2, 2)
    cap = 256 * MIB
    assert gate.weight(None, cap) == 1
    assert gate.weight(50 * MIB, cap) == 1  # 8-bit grey at 50 Mpx
    assert gate.weight(128 * MIB, cap) == 1
    assert gate.weight(128 * MIB + 1, cap) == 2
    assert gate.weight(cap, cap) == 2  # 16-bit colour at the cap: both cores' turns
    assert DecodeGate(4, 0).weight(cap, cap) == 4
    assert DecodeGate(1, 0).weight(cap, cap) == 1


def test_places_beyond_slots_and_queue_are_refused() -> None:
    async def run() -> None:
        gate = DecodeGate(1, 1)
        async with gate.place(), gate.place():
            with pytest.raises(ApiError) as refused:
                async with gate.place():
                    pass
            assert refused.value.status == 503
            assert refused.value.headers == {"Retry-After": "1"}
        assert gate.admitted == 0

    asyncio.run(run())


def test_a_heavy_image_waits_for_every_slot_and_the_order_is_kept() -> None:
    async def run() -> None:
        gate = DecodeGate(2, 4)
        order: list[str] = []
        light_in = asyncio.Event()
        release_light = asyncio.Event()

        async def light(name: str, hold: asyncio.Event | None = None) -> None:
            async with gate.slots_for(1):
                order.append(name)
                light_in.set()
                if hold is not None:
                    await hold.wait()

        async def heavy() -> None:
            async with gate.slots_for(2):
                order.append("heavy")
                assert gate.busy == 2

        first = asyncio.create_task(light("light-1", release_light))
        await light_in.wait()
        waiting_heavy = asyncio.create_task(heavy())
        await asyncio.sleep(0)
        later = asyncio.create_task(light("light-2"))  # a free slot, but the heavy one came first
        await asyncio.sleep(0)
        assert order == ["light-1"]
        release_light.set()
        await asyncio.gather(first, waiting_heavy, later)
        assert order == ["light-1", "heavy", "light-2"]
        assert gate.busy == 0

    asyncio.run(run())


def test_a_cancelled_wait_gives_its_turn_on() -> None:
    async def run() -> None:
        gate = DecodeGate(1, 2)
        hold = asyncio.Event()
        got: list[str] = []

        async def holder() -> None:
            async with gate.slots_for(1):
                await hold.wait()

        async def waiter(name: str) -> None:
            async with gate.slots_for(1):
                got.append(name)

        first = asyncio.create_task(holder())
        await asyncio.sleep(0)
        cancelled = asyncio.create_task(waiter("cancelled"))
        behind = asyncio.create_task(waiter("behind"))
        await asyncio.sleep(0)
        cancelled.cancel()
        hold.set()
        await asyncio.gather(first, behind)
        assert got == ["behind"]
        assert gate.busy == 0

    asyncio.run(run())
