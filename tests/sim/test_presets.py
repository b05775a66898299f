"""Noise presets are fixed: benchmarks quote them by name and version."""

from __future__ import annotations

from dataclasses import replace

import pytest

from sim.presets import PRESETS, NoisePreset, get_preset


def test_presets_are_nominal_v1_hard_v2_and_hard_specks_v1() -> None:
    assert sorted(PRESETS) == ["hard", "hard-specks", "nominal"]
    assert {p.name: p.version for p in PRESETS.values()} == {"nominal": 1, "hard": 2, "hard-specks": 1}


def test_hard_specks_is_hard_with_flecks_and_specks() -> None:
    hard, specks = PRESETS["hard"].to_dict(), PRESETS["hard-specks"].to_dict()
    changed = {k for k in hard if hard[k] != specks[k]}
    assert changed == {k for k in hard if k.startswith(("fleck", "speck"))} | {"name", "version"}
    assert specks["flecks_per_mm"] > 0
    assert specks["specks_per_mm2"] > 0


def test_a_preset_written_before_flecks_and_specks_reads_as_having_none() -> None:
    old = {k: v for k, v in PRESETS["hard"].to_dict().items() if not k.startswith(("fleck", "speck"))}
    assert NoisePreset.from_dict(old) == PRESETS["hard"]
    with pytest.raises(ValueError, match=r"missing keys \['blur_sigma_px'\]"):
        NoisePreset.from_dict({k: v for k, v in old.items() if k != "blur_sigma_px"})


@pytest.mark.parametrize(
    ("name", "blur", "read", "salt_pepper", "land", "paint"),
    [("nominal", 1.0, 0.8, 0.0, 205.0, 40.0), ("hard", 1.8, 3.0, 0.004, 195.0, 50.0)],
)
def test_key_values_are_pinned(
    name: str, blur: float, read: float, salt_pepper: float, land: float, paint: float
) -> None:
    # Changing any of these changes every benchmark: bump the preset's version and update this test.
    p = get_preset(name)
    assert (p.blur_sigma_px, p.read_noise_dn, p.salt_pepper_fraction) == (blur, read, salt_pepper)
    assert (p.land_level_dn, p.paint_level_dn) == (land, paint)


def test_nominal_has_the_seed_snr_and_hard_is_harder() -> None:
    nominal, hard = PRESETS["nominal"], PRESETS["hard"]
    assert 49.0 < nominal.snr_db() < 50.5  # the Pulnix TM-200's 50 dB, peak signal to rms noise
    assert hard.snr_db() < nominal.snr_db() - 10
    assert nominal.glints_per_mm < hard.glints_per_mm
    assert nominal.vignetting < hard.vignetting
    assert hard.scratches_per_mm2 > 0
    assert hard.texture_rms_dn > nominal.texture_rms_dn
    assert nominal.contrast_dn == 165.0


def test_unknown_preset_names_the_choices() -> None:
    with pytest.raises(ValueError, match=r"'foggy'.*nominal, hard, hard-specks"):
        get_preset("foggy")


def test_round_trip_and_validation() -> None:
    p = PRESETS["hard"]
    assert NoisePreset.from_dict(p.to_dict()) == p
    with pytest.raises(ValueError, match="unknown keys"):
        NoisePreset.from_dict({**p.to_dict(), "gamma": 1.0})
    with pytest.raises(ValueError, match="read_noise_dn"):
        replace(p, read_noise_dn=-1.0)
    with pytest.raises(ValueError, match="paint < land"):
        replace(p, paint_level_dn=250.0)
