"""The camera-calibration target: a ChArUco board for a 6.4 x 4.8 mm field at about 10 um/px.

Why ChArUco and these sizes: ``TARGET.md`` in this package. The description is a pydantic model (it is
what a station's configuration and a calibration's record hold); the OpenCV board it stands for is built
by :meth:`CharucoTarget.board`.

Frame of the target (mm): origin at the board's top-left outer corner, x along the first row of
squares, y down the columns, z = x cross y into the board (away from a camera looking at its face). The
top-left square is black (OpenCV 4.6+ layout, not the legacy one). Chessboard corner ``i`` (OpenCV's
ChArUco corner id) is at ``((i % (squares_x - 1) + 1) * square_mm, (i // (squares_x - 1) + 1) *
square_mm, 0)``.
"""

from __future__ import annotations

import functools
import math
from typing import Literal

import cv2
import numpy as np
import numpy.typing as npt
from pydantic import BaseModel, ConfigDict, Field, model_validator

__all__ = ["DICTIONARIES", "STANDARD_TARGET", "CharucoTarget", "TargetCertificate"]

FloatArray = npt.NDArray[np.float64]

DictionaryName = Literal[
    "DICT_4X4_50",
    "DICT_4X4_100",
    "DICT_4X4_250",
    "DICT_4X4_1000",
    "DICT_5X5_50",
    "DICT_5X5_100",
    "DICT_5X5_250",
    "DICT_5X5_1000",
]

#: Dictionary name -> (OpenCV id, bits per side, markers in it).
DICTIONARIES: dict[str, tuple[int, int, int]] = {
    "DICT_4X4_50": (cv2.aruco.DICT_4X4_50, 4, 50),
    "DICT_4X4_100": (cv2.aruco.DICT_4X4_100, 4, 100),
    "DICT_4X4_250": (cv2.aruco.DICT_4X4_250, 4, 250),
    "DICT_4X4_1000": (cv2.aruco.DICT_4X4_1000, 4, 1000),
    "DICT_5X5_50": (cv2.aruco.DICT_5X5_50, 5, 50),
    "DICT_5X5_100": (cv2.aruco.DICT_5X5_100, 5, 100),
    "DICT_5X5_250": (cv2.aruco.DICT_5X5_250, 5, 250),
    "DICT_5X5_1000": (cv2.aruco.DICT_5X5_1000, 5, 1000),
}


class TargetCertificate(BaseModel):
    """What the target's calibration certificate states (standard uncertainties, k = 1).

    ``corner_u_mm``: each corner's position about the ideal grid (the pattern's local placement error);
    ``pitch_u_rel``: the pattern's scale (a pitch error scales every length the target gives, e.g. the
    focal length found from known heights); ``flatness_mm``: the face's departure from a plane.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    certificate_id: str | None = Field(None, max_length=200, description="the certificate's number")
    corner_u_mm: float = Field(0.0005, ge=0.0, le=0.05, description="corner placement, mm (k=1)")
    pitch_u_rel: float = Field(1e-5, ge=0.0, le=0.01, description="relative pitch (scale), k=1")
    flatness_mm: float = Field(0.001, ge=0.0, le=0.1, description="flatness of the face, mm")


class CharucoTarget(BaseModel):
    """A ChArUco board: a chessboard whose white squares hold ArUco markers that name its corners.

    Defaults: the station's standard target (``TARGET.md``): 24 x 18 squares of 0.5 mm (12 x 9 mm),
    markers of 0.3 mm from ``DICT_4X4_250`` (216 markers), so that a 6.4 x 4.8 mm field holds about 80
    of its 391 corners wherever the camera looks, and each marker bit is 5 px at 10 um/px.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    kind: Literal["charuco"] = "charuco"
    dictionary: DictionaryName = "DICT_4X4_250"
    squares_x: int = Field(24, ge=3, le=200, description="squares along the board's x")
    squares_y: int = Field(18, ge=3, le=200, description="squares along the board's y")
    square_mm: float = Field(0.5, gt=0.0, le=100.0, description="side of a chessboard square, mm")
    marker_mm: float = Field(0.3, gt=0.0, le=100.0, description="side of a marker (its black border in), mm")
    certificate: TargetCertificate = Field(default_factory=TargetCertificate)

    @model_validator(mode="after")
    def _consistent(self) -> CharucoTarget:
        if not self.marker_mm < self.square_mm:
            raise ValueError(
                f"marker_mm ({self.marker_mm}) must be smaller than square_mm ({self.square_mm}): the "
                "marker sits inside a white square"
            )
        markers = self.marker_count
        available = DICTIONARIES[self.dictionary][2]
        if markers > available:
            raise ValueError(
                f"a {self.squares_x} x {self.squares_y} board needs {markers} markers but {self.dictionary} "
                f"has {available}: choose a larger dictionary or fewer squares"
            )
        return self

    @property
    def marker_count(self) -> int:
        """Markers on the board (one per white square)."""
        return (self.squares_x * self.squares_y) // 2

    @property
    def corner_count(self) -> int:
        """Inner chessboard corners (the calibration's points)."""
        return (self.squares_x - 1) * (self.squares_y - 1)

    @property
    def size_mm(self) -> tuple[float, float]:
        """Width and height of the pattern, mm."""
        return self.squares_x * self.square_mm, self.squares_y * self.square_mm

    @property
    def bits(self) -> int:
        """Marker bits per side (without the black border)."""
        return DICTIONARIES[self.dictionary][1]

    @property
    def cell_mm(self) -> float:
        """Side of one marker bit, mm."""
        return self.marker_mm / (self.bits + 2)

    def corners_mm(self) -> FloatArray:
        """Every inner corner's position in the target frame, (N, 3) mm, row ``i`` = corner id ``i``."""
        n = self.squares_x - 1
        ids = np.arange(self.corner_count)
        out = np.zeros((self.corner_count, 3))
        out[:, 0] = (ids % n + 1) * self.square_mm
        out[:, 1] = (ids // n + 1) * self.square_mm
        return out

    def board(self) -> cv2.aruco.CharucoBoard:
        """The OpenCV board this target stands for (built once per description)."""
        return _board(
            self.dictionary, self.squares_x, self.squares_y, float(self.square_mm), float(self.marker_mm)
        )

    def pattern(self, px_per_square: int) -> npt.NDArray[np.uint8]:
        """The board's face as an image, 255 white, 0 black, ``px_per_square`` px per square side.

        Row ``r``, column ``c`` covers ``[c, c + 1] x [r, r + 1] * square_mm / px_per_square`` of the
        target frame. Exact (every pixel wholly black or white) when the markers and their margins are
        whole numbers of pixels, which :meth:`cells_per_square` finds.
        """
        if px_per_square < 2:
            raise ValueError(f"px_per_square must be >= 2, got {px_per_square}")
        size = (self.squares_x * px_per_square, self.squares_y * px_per_square)
        return np.asarray(self.board().generateImage(size, marginSize=0, borderBits=1), dtype=np.uint8)

    def cells_per_square(self, *, limit: int = 400) -> int | None:
        """The fewest pixels per square at which :meth:`pattern` is exact, or None below ``limit``."""
        cells = self.square_mm / self.cell_mm
        margin = (self.square_mm - self.marker_mm) / 2.0 / self.cell_mm
        for n in range(1, limit + 1):
            per_cell = n / cells
            if (
                _whole(per_cell)
                and _whole(margin * per_cell)
                and _whole((self.bits + 2) * per_cell)
                and round(per_cell) >= 1
            ):
                return n
        return None


def _whole(x: float) -> bool:
    return math.isclose(x, round(x), abs_tol=1e-9)


@functools.lru_cache(maxsize=16)
def _board(
    dictionary: str, squares_x: int, squares_y: int, square: float, marker: float
) -> cv2.aruco.CharucoBoard:
    aruco = cv2.aruco.getPredefinedDictionary(DICTIONARIES[dictionary][0])
    board = cv2.aruco.CharucoBoard((squares_x, squares_y), square, marker, aruco)
    board.setLegacyPattern(False)
    return board


STANDARD_TARGET = CharucoTarget()
"""The station's standard target (``TARGET.md``)."""
