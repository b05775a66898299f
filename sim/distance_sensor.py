"""A simulated Keyence IL laser displacement sensor behind a DL-RS1A, on a real pseudo-terminal.

The twin owns the master side of a pty; the driver (``drivers.keyence_il``) opens the slave path
(``port``) with pyserial as it would open ``/dev/ttyUSB0``. It answers ``M0`` in the DL-RS1A's dialect
(drivers/keyence_il/DIALECT.md) with the TRUE distance from the head's reference point along its beam to
the artifact's top plane in the simulated world, with the head's repeatability (noise), its display
resolution, its measuring range and the readout the unit gives when there is no valid measurement:
beyond the range, a beam that misses the artifact, or incidence steeper than the head can see.

Faults for tests: :meth:`DistanceSensorTwin.inject` (a garbled, lost, cut or refused reply),
:meth:`set_alarm` (the amplifier's error readout), :meth:`unplug` (the port vanishes).

Geometry (mm, the world's base frame): the head's frame is ``camera_pose @ mount``; its origin is the
reference point the distance is measured from and its +z axis the beam. The artifact frame's origin is
on its top plane and its z axis the plane's normal pointing down into the table.
"""

from __future__ import annotations

import logging
import math
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from pydantic import BaseModel, ConfigDict, Field

from sim._pty import PtyPort
from sim.world import World

log = logging.getLogger(__name__)

FloatArray = npt.NDArray[np.float64]

PoseSource = Callable[[], tuple[FloatArray, FloatArray]]
"""Returns (head pose, artifact pose), 4x4 in one frame."""


class HeadModel(BaseModel):
    """The simulated head. Defaults: IL-065 [M catalogue: reference distance 65 mm, range 55-105 mm,
    repeatability 2 µm]; the rest [A]: see drivers/keyence_il/DIALECT.md."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    reference_distance_mm: float = Field(65.0, gt=0)
    measuring_range_mm: tuple[float, float] = (55.0, 105.0)
    repeatability_mm: float = Field(0.002, ge=0, description="1 sigma of the reading's noise [A: the spec]")
    resolution_mm: float = Field(0.001, gt=0, description="display resolution of ±**.***")
    max_incidence_deg: float = Field(
        30.0, gt=0, lt=90, description="steeper than this from the normal: too little light [A]"
    )
    plane_half_size_mm: float = Field(
        50.0, gt=0, description="the artifact's top is a square this far either side of the crossing [A]"
    )


@dataclass(frozen=True)
class BeamHit:
    """Where the beam meets the artifact's top plane: distance (mm) along the beam, incidence (deg from
    the normal), the point in the artifact frame; ``None`` distance when it does not meet it."""

    distance_mm: float | None
    incidence_deg: float | None = None
    point_mm: tuple[float, float] | None = None


def beam_hit(head_pose: FloatArray, artifact_pose: FloatArray) -> BeamHit:
    """The beam (head origin, +z) against the artifact's top plane (origin, normal +z into the table)."""
    o, d = head_pose[:3, 3], head_pose[:3, 2]
    p0, n = artifact_pose[:3, 3], artifact_pose[:3, 2]
    cos_i = float(n @ d)  # the normal points down, away from a head looking at the top
    if cos_i <= 1e-9:
        return BeamHit(None)
    t = float(n @ (p0 - o)) / cos_i
    if t <= 0:
        return BeamHit(None)
    q = artifact_pose[:3, :3].T @ (o + t * d - p0)
    return BeamHit(t, math.degrees(math.acos(min(1.0, cos_i))), (float(q[0]), float(q[1])))


def world_source(world: World, mount: FloatArray) -> PoseSource:
    """Head and surface poses from the world's public truth: ``camera_pose() @ mount``, and what its beam
    meets (``World.surface_pose``: a ruler's glass, else the artifact the camera sees)."""
    m = np.asarray(mount, dtype=np.float64)

    def poses() -> tuple[FloatArray, FloatArray]:
        head = world.camera_pose() @ m
        return head, world.surface_pose(head)

    return poses


FAULT_KINDS = ("garble", "silent", "cut", "error")

# The unit's side of the dialect, written from the manual independently of the driver (sim never imports
# drivers): drivers/keyence_il/DIALECT.md.
MEASURE = "M0"
SPECIAL_READOUTS = {"error": "+EE.EEE", "invalid": "-FF.FFF"}


@dataclass(frozen=True)
class Readout:
    """What the amplifier shows: ``kind`` "value" (a displacement from the reference distance, mm),
    "invalid" (no valid measurement: the display's "-----") or "error" (the amplifier's error state)."""

    kind: str
    value_mm: float | None = None

    def text(self) -> str:
        """As the DL-RS1A prints it in an ``M0`` reply: ``±**.***`` (±99.999: beyond the display)."""
        if self.kind != "value":
            return SPECIAL_READOUTS[self.kind]
        assert self.value_mm is not None
        if abs(self.value_mm) >= 99.999:
            return "+99.999" if self.value_mm > 0 else "-99.999"
        return f"{self.value_mm:+07.3f}"


class DistanceSensorTwin:
    """The simulated DL-RS1A + IL amplifier + head on a pty; ``start()`` it, ``close()`` it."""

    def __init__(
        self,
        source: PoseSource,
        head: HeadModel | None = None,
        *,
        seed: int | None = 0,
    ) -> None:
        self.head = head or HeadModel()
        self._source = source
        self._rng = np.random.default_rng(seed)
        self._lock = threading.Lock()
        self._faults: deque[tuple[str, str]] = deque()
        self._alarm = False
        self._pty = PtyPort()
        self._thread: threading.Thread | None = None
        self._closing = threading.Event()
        self._unplug_requested = threading.Event()
        self._unplugged = threading.Event()
        self._buffer = bytearray()
        self.received: deque[str] = deque(maxlen=1000)

    # ---------------------------------------------------------------- lifecycle

    def start(self) -> DistanceSensorTwin:
        if self._thread is not None:
            return self
        self._pty.open()
        self._thread = threading.Thread(target=self._serve, name=f"il-twin {self._pty.path}", daemon=True)
        self._thread.start()
        log.info("distance sensor twin on %s", self._pty.path)
        return self

    def close(self) -> None:
        """Stop serving and close the pty; safe to call twice."""
        if self._closing.is_set():
            return
        self._closing.set()
        self._pty.wake()
        if self._thread is not None:
            self._thread.join(timeout=5)
        self._pty.dispose()

    def __enter__(self) -> DistanceSensorTwin:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def port(self) -> str:
        if self._pty.path is None:
            raise RuntimeError("the distance sensor twin is not started (or was unplugged)")
        return self._pty.path

    # ---------------------------------------------------------------- control from outside

    def inject(self, kind: str, *, code: str = "29") -> None:
        """The next reply goes wrong: ``garble`` (noise on the line), ``silent`` (lost), ``cut`` (no
        CR LF), ``error`` (``ER,<command>,<code>``)."""
        if kind not in FAULT_KINDS:
            raise ValueError(f"fault kind must be one of {FAULT_KINDS}, got {kind!r}")
        with self._lock:
            self._faults.append((kind, code))

    def set_alarm(self, on: bool) -> None:
        """The amplifier in an error state (it reads ``+EE.EEE``) until cleared."""
        with self._lock:
            self._alarm = on

    def unplug(self, timeout_s: float = 5.0) -> None:
        """Pull the cable: the pty goes away (closed by the serving thread, which alone uses its fds)."""
        if self._thread is None or not self._thread.is_alive():
            self._pty.close()
            return
        self._unplugged.clear()
        self._unplug_requested.set()
        self._pty.wake()
        if not self._unplugged.wait(timeout_s):
            raise RuntimeError("the distance sensor twin did not unplug")

    # ---------------------------------------------------------------- the head

    def truth(self) -> BeamHit:
        """Where the beam meets the artifact now (no noise): truth for tests."""
        head_pose, artifact_pose = self._source()
        return beam_hit(head_pose, artifact_pose)

    def readout(self) -> Readout:
        """What the amplifier shows now."""
        with self._lock:
            alarm = self._alarm
        if alarm:
            return Readout("error")
        h = self.head
        hit = self.truth()
        near, far = h.measuring_range_mm
        if (
            hit.distance_mm is None
            or hit.point_mm is None
            or hit.incidence_deg is None
            or max(abs(hit.point_mm[0]), abs(hit.point_mm[1])) > h.plane_half_size_mm
            or hit.incidence_deg > h.max_incidence_deg
            or not near <= hit.distance_mm <= far
        ):
            return Readout("invalid")
        noisy = hit.distance_mm + float(self._rng.normal(0.0, h.repeatability_mm))
        shown = round((noisy - h.reference_distance_mm) / h.resolution_mm) * h.resolution_mm
        return Readout("value", shown)

    # ---------------------------------------------------------------- serving

    def _serve(self) -> None:
        while not self._closing.is_set():
            if self._unplug_requested.is_set():
                self._unplug_requested.clear()
                self._pty.close()
                self._buffer.clear()
                self._unplugged.set()
            chunk = self._pty.read(0.2)
            if not chunk:
                continue
            self._buffer += chunk
            while True:
                ends = [i for i in (self._buffer.find(b"\r"), self._buffer.find(b"\n")) if i >= 0]
                if not ends:
                    break
                i = min(ends)
                line = bytes(self._buffer[:i]).decode("ascii", errors="replace")
                del self._buffer[: i + 1]
                if line:
                    self._answer(line)

    def _answer(self, line: str) -> None:
        self.received.append(line)
        with self._lock:
            fault = self._faults.popleft() if self._faults else None
        command = line.split(",")[0][:2]
        if fault is not None and fault[0] == "error":
            reply = f"ER,{command},{fault[1]}"
        elif line == MEASURE:
            reply = f"M0,{self.readout().text()}"
        else:
            reply = f"ER,{command},00"  # [M] an invalid command
        if fault is None or fault[0] == "error":
            self._pty.write(reply.encode("ascii") + b"\r\n", self._closing)
        elif fault[0] == "garble":
            self._pty.write(bytes((b ^ 0x5A) | 0x80 for b in reply.encode("ascii")) + b"\r\n", self._closing)
        elif fault[0] == "cut":
            self._pty.write(reply.encode("ascii")[: len(reply) // 2], self._closing)
        # "silent": the reply is lost


#: The default mount (camera frame): 30 mm beside the optical axis, beam parallel to it.
DEFAULT_MOUNT: FloatArray = np.array(
    [[1.0, 0.0, 0.0, 30.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
)


def start_distance_sensor_twin(
    world: World | None = None,
    mount: npt.ArrayLike | None = None,
    *,
    seed: int | None = 0,
    **head: float | tuple[float, float],
) -> DistanceSensorTwin:
    """Device factory (``distance_sensor_twin.sim``): a started twin reading ``world`` (default: a
    default world, the arm still at its reference pose, in focus) through a head at ``camera_pose() @
    mount`` (default :data:`DEFAULT_MOUNT`)."""
    model = HeadModel.model_validate(head)
    m = DEFAULT_MOUNT if mount is None else np.asarray(mount, dtype=np.float64)
    return DistanceSensorTwin(world_source(world or World(), m), model, seed=seed).start()


__all__ = [
    "DEFAULT_MOUNT",
    "FAULT_KINDS",
    "BeamHit",
    "DistanceSensorTwin",
    "HeadModel",
    "PoseSource",
    "Readout",
    "beam_hit",
    "start_distance_sensor_twin",
    "world_source",
]
