"""Noise presets of the simulated artifact camera: every rendering parameter, named and versioned.

A preset fixes *all* the values that shape a rendered image besides the pose and the artifact:
optical blur, grey levels, noise, glints, scratches, texture and vignetting. Benchmarks quote a preset
by name and version, so any change of a value must bump ``version``.

``nominal`` is the seed's camera (Pulnix TM-200, SNR >= 50 dB) on a clean artifact; ``hard`` is a
worn artifact under poor optics and light. ``PRESETS`` holds both; ``get_preset`` looks one up.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from typing import Any

__all__ = ["MAX_GLINTS_PER_MM", "MAX_SCRATCHES_PER_MM2", "PRESETS", "NoisePreset", "get_preset"]

FULL_SCALE_DN = 255.0
"""Largest 8-bit grey level, the signal of the SNR figure (video peak, as camera data sheets quote it)."""

MAX_GLINTS_PER_MM = 10.0
"""Largest glint density a preset may ask for (the artifact's glint catalogue is drawn at this density)."""

MAX_SCRATCHES_PER_MM2 = 1.0
"""Largest scratch density a preset may ask for (the artifact's scratch catalogue is drawn at this)."""


@dataclass(frozen=True)
class NoisePreset:
    """Every parameter of the simulated camera and artifact surface, except geometry.

    Grey levels are in DN (8-bit digital numbers, 0-255); lengths on the artifact in mm (artifact
    frame); lengths in the image in px.

    Attributes
    ----------
    name : str
        Preset name, as passed to ``get_preset``.
    version : int
        Bumped whenever any value changes (benchmarks quote name and version).
    blur_sigma_px : float
        Standard deviation of the Gaussian optical point-spread function, px.
    land_level_dn, paint_level_dn : float
        Grey level of the bare aluminium lands and of the black paint in the grooves, DN, before
        vignetting and noise.
    read_noise_dn : float
        Standard deviation of the signal-independent (read) noise, DN.
    shot_noise_gain_dn_per_e : float
        Conversion gain, DN per photo-electron: the shot-noise variance is ``gain * signal`` (DN^2).
    salt_pepper_fraction : float
        Fraction of pixels replaced by 0 or 255 (with equal probability) after quantisation.
    glints_per_mm : float
        Specular glints in the paint per mm of groove length (each groove), at most
        ``MAX_GLINTS_PER_MM``.
    glint_sigma_min_mm, glint_sigma_max_mm : float
        Range of the Gaussian radius (standard deviation) of a glint on the artifact, mm.
    glint_peak_min_dn, glint_peak_max_dn : float
        Range of a glint's peak brightness above the paint before blur, DN (may saturate).
    glint_wall_margin_mm : float
        Glint centres keep at least this distance from the groove walls, mm.
    scratches_per_mm2 : float
        Scratches on the lands per mm^2 of artifact surface, at most ``MAX_SCRATCHES_PER_MM2``.
    scratch_depth_dn : float
        Largest darkening of a scratch (its core, before blur), DN.
    scratch_width_max_mm, scratch_length_max_mm : float
        Largest width and length of a scratch, mm.
    texture_rms_dn : float
        RMS of the machining streaks on the lands before optical blur and pixel integration, DN.
    vignetting : float
        Fractional fall-off of brightness at the image corners (radial, quadratic, fixed to the camera).
    """

    name: str
    version: int
    blur_sigma_px: float
    land_level_dn: float
    paint_level_dn: float
    read_noise_dn: float
    shot_noise_gain_dn_per_e: float
    salt_pepper_fraction: float
    glints_per_mm: float
    glint_sigma_min_mm: float
    glint_sigma_max_mm: float
    glint_peak_min_dn: float
    glint_peak_max_dn: float
    glint_wall_margin_mm: float
    scratches_per_mm2: float
    scratch_depth_dn: float
    scratch_width_max_mm: float
    scratch_length_max_mm: float
    texture_rms_dn: float
    vignetting: float

    def __post_init__(self) -> None:
        def need(ok: bool, what: str) -> None:
            if not ok:
                raise ValueError(f"noise preset {self.name!r}: {what}")

        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, float | int) and not isinstance(value, bool):
                need(math.isfinite(value), f"{f.name} must be finite, got {value!r}")
                need(value >= 0, f"{f.name} must be >= 0, got {value!r}")
        need(self.paint_level_dn < self.land_level_dn <= FULL_SCALE_DN, "need paint < land <= 255 DN")
        need(self.salt_pepper_fraction < 1.0, "salt_pepper_fraction must be below 1")
        need(self.glints_per_mm <= MAX_GLINTS_PER_MM, f"glints_per_mm must be <= {MAX_GLINTS_PER_MM}")
        need(
            self.scratches_per_mm2 <= MAX_SCRATCHES_PER_MM2,
            f"scratches_per_mm2 must be <= {MAX_SCRATCHES_PER_MM2}",
        )
        need(self.glint_sigma_min_mm <= self.glint_sigma_max_mm, "glint sigma range is reversed")
        need(self.glint_peak_min_dn <= self.glint_peak_max_dn, "glint peak range is reversed")
        need(self.vignetting < 1.0, "vignetting must be below 1 (fraction of brightness lost at corners)")

    @property
    def contrast_dn(self) -> float:
        """Land minus paint grey level, DN."""
        return self.land_level_dn - self.paint_level_dn

    def noise_dn(self, signal_dn: float) -> float:
        """Standard deviation of read and shot noise together at grey level ``signal_dn``, DN."""
        return math.sqrt(self.read_noise_dn**2 + self.shot_noise_gain_dn_per_e * max(signal_dn, 0.0))

    def snr_db(self) -> float:
        """Peak signal-to-noise ratio, dB: ``20 log10(255 / noise at the land level)``."""
        return 20.0 * math.log10(FULL_SCALE_DN / self.noise_dn(self.land_level_dn))

    def to_dict(self) -> dict[str, Any]:
        """All values as a JSON-ready dict."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> NoisePreset:
        """Inverse of ``to_dict``; raises ValueError naming missing or unknown keys."""
        names = {f.name for f in fields(cls)}
        missing, unknown = names - set(data), set(data) - names
        if missing or unknown:
            raise ValueError(f"noise preset: missing keys {sorted(missing)}, unknown keys {sorted(unknown)}")
        return cls(**dict(data))


NOMINAL = NoisePreset(
    name="nominal",
    version=1,
    blur_sigma_px=1.0,
    land_level_dn=205.0,
    paint_level_dn=40.0,
    read_noise_dn=0.8,
    shot_noise_gain_dn_per_e=0.0005,  # 0.32 DN of shot noise on the lands: 49.4 dB with the read noise
    salt_pepper_fraction=0.0,
    glints_per_mm=0.3,
    glint_sigma_min_mm=0.008,
    glint_sigma_max_mm=0.02,
    glint_peak_min_dn=40.0,
    glint_peak_max_dn=120.0,
    glint_wall_margin_mm=0.1,
    scratches_per_mm2=0.02,
    scratch_depth_dn=12.0,
    scratch_width_max_mm=0.008,
    scratch_length_max_mm=1.5,
    texture_rms_dn=2.0,
    vignetting=0.08,
)

HARD = NoisePreset(
    name="hard",
    version=2,  # v2: scratches 40 -> 80 DN deep (v1's were lost in the blur)
    blur_sigma_px=1.8,
    land_level_dn=195.0,
    paint_level_dn=50.0,
    read_noise_dn=3.0,
    shot_noise_gain_dn_per_e=0.01,
    salt_pepper_fraction=0.004,
    glints_per_mm=3.0,
    glint_sigma_min_mm=0.01,
    glint_sigma_max_mm=0.04,
    glint_peak_min_dn=60.0,
    glint_peak_max_dn=220.0,
    glint_wall_margin_mm=0.0,
    scratches_per_mm2=0.3,
    scratch_depth_dn=80.0,
    scratch_width_max_mm=0.015,
    scratch_length_max_mm=3.0,
    texture_rms_dn=6.0,
    vignetting=0.3,
)

PRESETS: dict[str, NoisePreset] = {p.name: p for p in (NOMINAL, HARD)}
"""The named presets, by name."""


def get_preset(name: str) -> NoisePreset:
    """The preset called ``name``; ValueError naming the choices when there is none."""
    try:
        return PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown noise preset {name!r}; choose one of: {', '.join(PRESETS)}") from None
