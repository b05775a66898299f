"""grab_many written once (station.devices.grab_frames / average_frames), shared by every camera."""

from __future__ import annotations

import numpy as np
import pytest

from station.devices import Frame, average_frames, grab_frames


def _frame(
    values: list[list[int]], frame_id: int, *, dtype: type[np.generic] = np.uint8, t: float = 0.0
) -> Frame:
    return Frame(
        image=np.array(values, dtype=dtype), timestamp_s=t, frame_id=frame_id, device_frame_id=frame_id + 100
    )


def test_average_is_the_rounded_mean_in_the_frames_dtype() -> None:
    frames = [_frame([[0, 10], [255, 1]], 1, t=1.0), _frame([[1, 11], [255, 2]], 2, t=3.0)]
    avg = average_frames(frames)
    np.testing.assert_array_equal(avg.image, [[0, 10], [255, 2]])  # 0.5 and 1.5 round to even
    assert avg.image.dtype == np.uint8
    assert (avg.frame_id, avg.device_frame_id, avg.averaged, avg.timestamp_s) == (2, 102, 2, 2.0)


def test_average_keeps_16_bits() -> None:
    frames = [_frame([[65535, 1000]], 1, dtype=np.uint16), _frame([[65533, 3000]], 2, dtype=np.uint16)]
    avg = average_frames(frames)
    assert avg.image.dtype == np.uint16
    np.testing.assert_array_equal(avg.image, [[65534, 2000]])


def test_averaging_averaged_frames_counts_all_of_them() -> None:
    once = average_frames([_frame([[2]], 1), _frame([[4]], 2)])
    assert average_frames([once, _frame([[6]], 3)]).averaged == 3


@pytest.mark.parametrize(
    ("frames", "match"),
    [
        ([], "no frames"),
        ([_frame([[1, 2]], 1), _frame([[1], [2]], 2)], "average frames of one size only"),
        ([_frame([[1]], 1), _frame([[1]], 2, dtype=np.uint16)], "average frames of one size only"),
    ],
)
def test_average_refuses_mixed_or_missing_frames(frames: list[Frame], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        average_frames(frames)


def test_grab_frames_passes_the_timeout_to_every_grab() -> None:
    seen: list[float] = []

    def grab(timeout_s: float) -> Frame:
        seen.append(timeout_s)
        return _frame([[len(seen)]], len(seen))

    frames = grab_frames(grab, 3, timeout_s=0.7)
    assert [f.frame_id for f in frames] == [1, 2, 3]
    assert seen == [0.7, 0.7, 0.7]
    (avg,) = grab_frames(grab, 2, average=True)
    assert avg.averaged == 2
