"""The calibration target's description and the view geometry a calibration takes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from station.camcal import STANDARD_TARGET, CharucoTarget, ViewSpec, plan_views


def test_standard_target_fills_the_field_with_corners() -> None:
    t = STANDARD_TARGET
    assert t.size_mm == (12.0, 9.0)
    assert t.corner_count == 23 * 17
    assert t.marker_count == 216
    assert t.cell_mm == pytest.approx(0.05)  # a marker bit: 5 px at 10 um/px
    field_w, field_h = 6.4, 4.8
    assert (field_w // t.square_mm) * (field_h // t.square_mm) >= 80  # corners in one view, about


def test_corner_ids_are_opencvs() -> None:
    t = STANDARD_TARGET
    np.testing.assert_allclose(
        t.corners_mm(), np.asarray(t.board().getChessboardCorners(), dtype=float), atol=1e-6
    )
    assert t.board().getLegacyPattern() is False


def test_pattern_is_exact_at_whole_marker_bits() -> None:
    t = STANDARD_TARGET
    n = t.cells_per_square()
    assert n == 10
    fine = t.pattern(4 * n).reshape(t.squares_y * n, 4, t.squares_x * n, 4)
    assert np.all(fine.min(axis=(1, 3)) == fine.max(axis=(1, 3)))  # every bit wholly black or white
    assert fine[0, 0, 0, 0] == 0  # top-left square black
    assert CharucoTarget(square_mm=0.5, marker_mm=0.333).cells_per_square() is None


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"marker_mm": 0.5}, "must be smaller than square_mm"),
        ({"squares_x": 30, "squares_y": 20}, "needs 300 markers but DICT_4X4_250 has 250"),
        ({"square_mm": -1}, "greater than 0"),
        ({"dictionary": "DICT_7X7_50"}, "DICT_4X4_50"),
    ],
)
def test_bad_target_descriptions_say_what_to_change(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(ValidationError, match=message):
        CharucoTarget.model_validate(kwargs)


def test_target_description_round_trips_through_json() -> None:
    t = CharucoTarget(certificate={"certificate_id": "PTB-123", "pitch_u_rel": 2e-6})
    assert CharucoTarget.model_validate_json(t.model_dump_json()) == t


def test_a_tilt_keeps_the_in_focus_point_on_the_axis_at_the_working_distance() -> None:
    wd = 68.0
    T = ViewSpec(tilt_deg=12.0, azimuth_deg=30.0, turn_deg=40.0).camera_motion(wd)
    focus = np.array([0.0, 0.0, wd, 1.0])  # in the square pose's frame
    seen = np.linalg.solve(T, focus)  # the same point in the moved camera's frame
    np.testing.assert_allclose(seen[:3], [0.0, 0.0, wd], atol=1e-12)
    axis = T[:3, 2]
    assert math.degrees(math.acos(axis @ [0.0, 0.0, 1.0])) == pytest.approx(12.0)
    tilt_axis = np.cross([0.0, 0.0, 1.0], axis)
    assert math.degrees(math.atan2(tilt_axis[1], tilt_axis[0])) == pytest.approx(
        30.0
    )  # right-handed about the azimuth


def test_height_moves_along_the_tilted_axis_away_from_the_target() -> None:
    base = ViewSpec(tilt_deg=8.0, azimuth_deg=90.0)
    up = ViewSpec(tilt_deg=8.0, azimuth_deg=90.0, height_mm=0.3)
    T0, T1 = base.camera_motion(68.0), up.camera_motion(68.0)
    np.testing.assert_allclose(T1[:3, :3], T0[:3, :3])
    np.testing.assert_allclose(T1[:3, 3] - T0[:3, 3], -0.3 * T0[:3, 2], atol=1e-12)


def test_plan_takes_square_views_at_heights_and_tilted_views_around() -> None:
    views = plan_views(
        square_turns_deg=(0.0, 90.0),
        heights_mm=(-0.3, 0.0, 0.3),
        square_passes=1,
        tilts_deg=(10.0,),
        azimuths=4,
        tilted_turns_deg=(0.0, 90.0),
    )
    assert len(views) == 2 * 3 + 4 * 2
    groups: dict[int, list[ViewSpec]] = {}
    for v in views:
        groups.setdefault(v.group, []).append(v)
    assert len(groups) == 2 + 8
    for members in groups.values():  # one orientation per group; only the square ones at several heights
        assert len({(v.tilt_deg, v.azimuth_deg, v.turn_deg) for v in members}) == 1
        assert len(members) == (3 if members[0].tilt_deg == 0.0 else 1)
    assert sorted({v.azimuth_deg for v in views if v.tilt_deg}) == [0.0, 90.0, 180.0, 270.0]
    with pytest.raises(ValueError, match="tilt_deg must be in"):
        ViewSpec(tilt_deg=70.0)
    with pytest.raises(ValueError, match="azimuths must be >= 1"):
        plan_views(azimuths=0)
    with pytest.raises(ValueError, match="square_passes must be >= 1"):
        plan_views(square_passes=0)


def test_square_views_repeat_the_heights_away_from_focus() -> None:
    views = plan_views(square_turns_deg=(0.0,), heights_mm=(0.0, -1.5, 1.5), square_passes=3, azimuths=1)
    square = [v.height_mm for v in views if v.tilt_deg == 0.0]
    # in focus once (the others are followed from it), low and high three times over
    assert square == [0.0, -1.5, 1.5, -1.5, 1.5, -1.5, 1.5]
    assert len(plan_views()) == 4 * (1 + 2 * 26) + 96  # the defaults: TARGET.md
