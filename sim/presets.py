"""Noise presets of the simulated artifact camera: every rendering parameter, named and versioned.

A preset fixes *all* the values that shape a rendered image besides the pose and the artifact:
optical blur, grey levels, noise, glints, scratches, texture and vignetting. Benchmarks quote a preset
by name and version, so any change of a value must bump ``version``.

``nominal`` is the seed's camera (Pulnix TM-200, SNR >= 50 dB) on a clean artifact; ``hard`` is a
worn artifact under poor optics and light; ``hard-specks`` is ``hard`` with chips in the grooves' paint
(bare metal, each with a glint) and bright dust specks all over the artifact, the frames on which a
cross check that reads a groove's end from a local dip in its contrast refuses whole crosses. The
benchmarks use ``nominal`` and ``hard``, whose frames the flecks and specks leave unchanged (their
densities are 0 there). ``PRESETS`` holds them; ``get_preset`` looks one up.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import MISSING, asdict, dataclass, fields, replace
from typing import Any

__all__ = [
    "MAX_FLECKS_PER_MM",
    "MAX_GLINTS_PER_MM",
    "MAX_SCRATCHES_PER_MM2",
    "MAX_SPECKS_PER_MM2",
    "PRESETS",
    "NoisePreset",
    "get_preset",
]

FULL_SCALE_DN = 255.0
"""Largest 8-bit grey level, the signal of the SNR figure (video peak, as camera data sheets quote it)."""

MAX_GLINTS_PER_MM = 10.0
"""Largest glint density a preset may ask for (the artifact's glint catalogue is drawn at this density)."""

MAX_SCRATCHES_PER_MM2 = 1.0
"""Largest scratch density a preset may ask for (the artifact's scratch catalogue is drawn at this)."""

MAX_FLECKS_PER_MM = 10.0
"""Largest density of chips in the paint a preset may ask for (the catalogue is drawn at this)."""

MAX_SPECKS_PER_MM2 = 10.0
"""Largest density of dust specks a preset may ask for (the catalogue is drawn at this)."""


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
    flecks_per_mm : float
        Chips in the grooves' paint (flecks of bare metal showing through) per mm of groove length
        (each groove), at most ``MAX_FLECKS_PER_MM``; anywhere across the groove, walls included.
        Default 0: a preset written before flecks existed has none.
    fleck_cluster_mm : float
        Chips come in clusters of six (a damaged spot of the paint) spread over this length along the
        groove, mm.
    fleck_sigma_min_mm, fleck_sigma_max_mm : float
        Range of the Gaussian radius of a chip on the artifact, mm.
    fleck_peak_min_dn, fleck_peak_max_dn : float
        Range of a chip's peak brightness above the paint before blur, DN.
    fleck_glint_peak_dn : float
        Largest peak of the specular glint on each chip (radius a third of the chip's), DN above the
        paint before blur; each chip's is drawn between half of it and all of it.
    specks_per_mm2 : float
        Bright dust specks lying on the artifact (lands and grooves alike) per mm^2, at most
        ``MAX_SPECKS_PER_MM2``. Default 0.
    speck_sigma_min_mm, speck_sigma_max_mm : float
        Range of the Gaussian radius of a speck, mm.
    speck_peak_min_dn, speck_peak_max_dn : float
        Range of a speck's peak brightness before blur, DN added to whatever lies under it (specular:
        may be well above full scale, the pixel saturates).
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
    flecks_per_mm: float = 0.0
    fleck_cluster_mm: float = 0.0
    fleck_sigma_min_mm: float = 0.0
    fleck_sigma_max_mm: float = 0.0
    fleck_peak_min_dn: float = 0.0
    fleck_peak_max_dn: float = 0.0
    fleck_glint_peak_dn: float = 0.0
    specks_per_mm2: float = 0.0
    speck_sigma_min_mm: float = 0.0
    speck_sigma_max_mm: float = 0.0
    speck_peak_min_dn: float = 0.0
    speck_peak_max_dn: float = 0.0

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
        need(self.flecks_per_mm <= MAX_FLECKS_PER_MM, f"flecks_per_mm must be <= {MAX_FLECKS_PER_MM}")
        need(self.specks_per_mm2 <= MAX_SPECKS_PER_MM2, f"specks_per_mm2 must be <= {MAX_SPECKS_PER_MM2}")
        need(self.fleck_sigma_min_mm <= self.fleck_sigma_max_mm, "fleck sigma range is reversed")
        need(self.fleck_peak_min_dn <= self.fleck_peak_max_dn, "fleck peak range is reversed")
        need(self.speck_sigma_min_mm <= self.speck_sigma_max_mm, "speck sigma range is reversed")
        need(self.speck_peak_min_dn <= self.speck_peak_max_dn, "speck peak range is reversed")

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
        """Inverse of ``to_dict``; raises ValueError naming missing or unknown keys. A key with a
        default (a feature added later, such as the flecks) may be missing: a set written before it
        existed had none of it."""
        names = {f.name for f in fields(cls)}
        required = {f.name for f in fields(cls) if f.default is MISSING}
        missing, unknown = required - set(data), set(data) - names
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

HARD_SPECKS = replace(
    HARD,
    name="hard-specks",
    version=1,
    flecks_per_mm=6.0,  # a damaged spot per mm of groove: most frames' borders cut an arm near one
    fleck_cluster_mm=0.3,
    fleck_sigma_min_mm=0.01,
    fleck_sigma_max_mm=0.03,
    fleck_peak_min_dn=80.0,  # bare metal under paint residue: a chip is nearly as bright as a land
    fleck_peak_max_dn=160.0,
    fleck_glint_peak_dn=600.0,  # a chip's broken edge catches the light: its glint saturates
    specks_per_mm2=1.5,
    speck_sigma_min_mm=0.005,
    speck_sigma_max_mm=0.015,
    speck_peak_min_dn=300.0,  # specular: the larger ones saturate
    speck_peak_max_dn=1200.0,
)

PRESETS: dict[str, NoisePreset] = {p.name: p for p in (NOMINAL, HARD, HARD_SPECKS)}
"""The named presets, by name."""


def get_preset(name: str) -> NoisePreset:
    """The preset called ``name``; ValueError naming the choices when there is none."""
    try:
        return PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown noise preset {name!r}; choose one of: {', '.join(PRESETS)}") from None
