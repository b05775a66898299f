"""The ruler artifact's description: graduations, calibrated pitch, certificate, absolute code.

The design and its reasons are in ``station/vision/RULER.md``. In the ruler's own frame (mm): ``s``
along the ruler (graduation ``k`` centred at ``s = k * pitch``, ``k = 0 .. length / pitch``), ``t``
across it, turned +90 deg from ``s`` (same handedness as the image: with ``s`` along image +x, ``t``
points along image +y); the axis ``t = 0`` is midway between the line tips. The graduation lines
are dark bars ``line_width_mm`` wide across ``|t| <= line_length_mm / 2``, interrupted by the code
track: a band ``code_width_mm`` wide centred at ``t = code_offset_mm`` (off the axis, so that the
two parts of the lines differ in length and the pattern shows which way it runs), holding one
binary cell per ``pitch / cells_per_pitch`` along ``s`` (cell ``j`` centred at ``s = j * cell_mm``,
dark for a 1): the bits of a maximal-length sequence, so that any ``order`` consecutive cells name
their place.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Literal

import numpy as np
import numpy.typing as npt
from pydantic import BaseModel, ConfigDict, Field, model_validator

#: The default ruler's primitive feedback polynomial: x^11 + x^9 + 1 (a maximal-length LFSR).
DEFAULT_TAPS = (11, 9)


class RulerCode(BaseModel):
    """The absolute code: a maximal-length (m-) sequence from a Fibonacci LFSR.

    Bit ``j`` of the track is the register's output at step ``j`` from ``seed``; with a primitive
    polynomial every window of ``order`` consecutive bits occurs once in ``2**order - 1`` bits.
    """

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    order: int = Field(
        11, ge=4, le=20, description="register length: any `order` consecutive cells name their place"
    )
    taps: tuple[int, ...] = Field(
        DEFAULT_TAPS,
        min_length=2,
        description="exponents of the feedback polynomial (x^11 + x^9 + 1: (11, 9))",
    )
    seed: int = Field(
        1, ge=1, description="initial register state (non-zero): where along the sequence cell 0 starts"
    )
    cells_per_pitch: int = Field(4, ge=1, le=8, description="code cells per graduation pitch")

    @model_validator(mode="after")
    def _check(self) -> RulerCode:
        if max(self.taps) != self.order or any(not 1 <= t <= self.order for t in self.taps):
            raise ValueError(
                f"code taps {self.taps} must lie in 1..order with the largest = order ({self.order})"
            )
        if self.seed >= 1 << self.order:
            raise ValueError(f"code seed {self.seed} must be below 2**order ({1 << self.order})")
        period = _period(self.order, self.taps, self.seed)
        if period != (1 << self.order) - 1:
            raise ValueError(
                f"code taps {self.taps} are not a primitive polynomial of degree {self.order}: the sequence "
                f"repeats after {period} bits instead of {(1 << self.order) - 1}; use e.g. (11, 9)"
            )
        return self

    @property
    def period(self) -> int:
        """Length of the sequence before it repeats: ``2**order - 1``."""
        return (1 << self.order) - 1


def _lfsr(order: int, taps: tuple[int, ...], seed: int, count: int) -> npt.NDArray[np.uint8]:
    """``count`` output bits of a Fibonacci LFSR (output: the register's lowest bit)."""
    state = seed
    out = np.empty(count, dtype=np.uint8)
    for i in range(count):
        out[i] = state & 1
        feedback = 0
        for tap in taps:
            feedback ^= (state >> (order - tap)) & 1
        state = (state >> 1) | (feedback << (order - 1))
    return out


@lru_cache(maxsize=16)
def _period(order: int, taps: tuple[int, ...], seed: int) -> int:
    bits = _lfsr(order, taps, seed, 2 * (1 << order))
    first = bits[:order]
    for p in range(1, 1 << order):
        if np.array_equal(bits[p : p + order], first) and np.array_equal(bits[p : 2 * p], bits[:p]):
            return p
    return 1 << order


class RulerSpec(BaseModel):
    """One ruler: its graduations, the calibrated pitch with the certificate's uncertainties, its code.

    Units in each field's description. The defaults describe the station's design (RULER.md): 250 mm,
    0.5 mm pitch, 3.2 mm lines split by an 11-bit code at 0.125 mm cells.
    """

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    name: str = Field(
        "ruler-250", min_length=1, max_length=100, description="identity (e.g. the serial number)"
    )
    length_mm: float = Field(
        250.0, gt=0, le=2000, description="graduated length: graduations 0 .. length/pitch"
    )
    pitch_mm: float = Field(
        0.5, gt=0.05, le=5, description="calibrated mean pitch of the graduations (the certificate's value)"
    )
    pitch_u_ppm: float = Field(
        0.1,
        ge=0,
        le=1000,
        description="standard uncertainty (k=1) of the calibrated pitch, parts per million",
    )
    graduation_u_nm: float = Field(
        15.0, ge=0, le=100_000, description="standard uncertainty (k=1) of one graduation about k * pitch, nm"
    )
    certificate: str = Field("", max_length=200, description="calibration certificate (issuer, number, date)")
    line_width_mm: float = Field(0.25, gt=0, description="width of a graduation line along the ruler")
    line_length_mm: float = Field(
        3.2, gt=0.5, le=20, description="length of the graduation lines across the ruler, tip to tip"
    )
    code_width_mm: float = Field(0.6, gt=0.05, le=10, description="width of the code track across the ruler")
    code_offset_mm: float = Field(
        0.2, ge=-10, le=10, description="centre of the code track from the ruler's axis, toward +t"
    )
    code_gap_mm: float = Field(
        0.2, ge=0.05, le=5, description="clear gap between the code track and the graduation lines each side"
    )
    marks: Literal["dark", "bright"] = Field(
        "dark", description="the lines and code cells against the ground: dark (the design) or bright"
    )
    code: RulerCode = Field(default_factory=RulerCode, description="the absolute code")

    @model_validator(mode="after")
    def _check(self) -> RulerSpec:
        if not 0.2 * self.pitch_mm <= self.line_width_mm <= 0.8 * self.pitch_mm:
            raise ValueError(
                f"line_width_mm {self.line_width_mm} must be 20-80 % of the pitch ({self.pitch_mm} mm); "
                "the design uses half the pitch"
            )
        graduations = self.length_mm / self.pitch_mm
        if abs(graduations - round(graduations)) > 1e-6 * graduations:
            raise ValueError(
                f"length_mm {self.length_mm} must be a whole number of pitches ({self.pitch_mm} mm): "
                f"{graduations:.4f} pitches"
            )
        lower, upper = self.line_segments_mm
        if min(lower[1] - lower[0], upper[1] - upper[0]) < 0.3 or lower[1] - lower[0] == upper[1] - upper[0]:
            raise ValueError(
                "the code track must split the graduation lines into two unequal parts at least 0.3 mm long: "
                f"line_length_mm {self.line_length_mm}, code_width_mm {self.code_width_mm}, code_offset_mm "
                f"{self.code_offset_mm}, code_gap_mm {self.code_gap_mm} give {lower} and {upper}"
            )
        windows = self.cell_count - self.code.order + 1
        if windows > self.code.period - self.code.order + 1:
            raise ValueError(
                f"the code's {self.code.period}-bit sequence is too short for {self.cell_count} cells: "
                f"raise code.order (each +1 doubles it) or shorten the ruler"
            )
        return self

    @property
    def graduation_count(self) -> int:
        """Number of graduation lines: ``length / pitch + 1`` (both ends graduated)."""
        return round(self.length_mm / self.pitch_mm) + 1

    @property
    def cell_mm(self) -> float:
        """Code cell pitch along the ruler, mm."""
        return self.pitch_mm / self.code.cells_per_pitch

    @property
    def cell_count(self) -> int:
        """Number of code cells: one per ``cell_mm`` from ``s = 0`` to ``s = length``."""
        return round(self.length_mm / self.cell_mm) + 1

    @property
    def line_segments_mm(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """The graduation lines' two parts across the ruler, ``((t_from, t_to), (t_from, t_to))``, mm:
        from the line tips at ``-line_length / 2`` to the code gap, and from it to ``+line_length / 2``."""
        half = self.line_length_mm / 2
        code_lo, code_hi = self.code_track_mm
        return ((-half, code_lo - self.code_gap_mm), (code_hi + self.code_gap_mm, half))

    @property
    def code_track_mm(self) -> tuple[float, float]:
        """The code track's extent across the ruler, ``(t_from, t_to)``, mm."""
        return (self.code_offset_mm - self.code_width_mm / 2, self.code_offset_mm + self.code_width_mm / 2)

    @property
    def band_mm(self) -> tuple[float, float]:
        """The whole pattern's extent across the ruler (tip to tip), ``(t_from, t_to)``, mm."""
        return (-self.line_length_mm / 2, self.line_length_mm / 2)

    def position_u_nm(self, position_mm: float) -> float:
        """Standard uncertainty (k=1) the certificate gives a position ``position_mm`` along the ruler, nm."""
        scale_nm = abs(position_mm) * 1e6 * self.pitch_u_ppm * 1e-6
        return math.hypot(self.graduation_u_nm, scale_nm)

    def code_bits(self) -> npt.NDArray[np.uint8]:
        """The code track's bits, one per cell, cell 0 at ``s = 0`` (a read-only array)."""
        return _bits(self.code, self.cell_count)

    def code_index(self) -> dict[int, int]:
        """Where each ``order``-bit window starts: window value (first cell most significant) -> cell."""
        return _index(self.code, self.cell_count)


@lru_cache(maxsize=16)
def _bits(code: RulerCode, count: int) -> npt.NDArray[np.uint8]:
    bits = _lfsr(code.order, code.taps, code.seed, count)
    bits.setflags(write=False)
    return bits


@lru_cache(maxsize=16)
def _index(code: RulerCode, count: int) -> dict[int, int]:
    bits = _bits(code, count)
    weights = 1 << np.arange(code.order - 1, -1, -1)
    windows = np.lib.stride_tricks.sliding_window_view(bits.astype(np.int64), code.order) @ weights
    return {int(v): j for j, v in enumerate(windows)}
