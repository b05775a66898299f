"""Reading the ruler's absolute code: which graduation is which, from the cells in one view.

Once the graduations' phase is known, the code cells sit at known places: cell ``c`` of the view at
``s = c / cells_per_pitch`` (periods, the frame's own count). Each cell's grey level is the mean
over its central half (along the ruler) in each of a few sub-strips across the track, the median of
those taken (a speck spoils one sub-strip, not the cell), and set against the graduations' own dark
and bright levels at the same place (``WindowPhases``): ``q = 1`` reads as a mark (bit 1), ``0`` as
bare ground (bit 0), in between as unreadable. The bits read are then slid along the ruler's code:
the place where they agree, with at most one disagreement per 8 cells read beyond the register
length and every other place disagreeing in at least 2 more cells, names the graduation at
``s = 0``; beyond the ruler's ends the code reads 0 (no marks). Accepting a wrong place then takes
at least ``(d + 2) / 2`` misread cells, ``d`` the code's distance between two places over the
cells read (3 or more over 28 cells, the shortest stretch the envelope allows: RULER.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from station.vision._ruler_errors import CodeInconsistentError, CodeUnreadableError
from station.vision._ruler_spec import RulerSpec

FloatArray = npt.NDArray[np.float64]

#: A cell is a mark above this normalised darkness, bare ground below 1 - it.
MARK_LEVEL = 0.65
#: Every other place of the code must disagree with the cells read in at least this many more cells.
MIN_MARGIN = 2
#: Disagreements accepted at the place found: one per this many cells read beyond the register length.
CELLS_PER_DISAGREEMENT = 8


@dataclass(frozen=True)
class CodeReading:
    """What the code said: the graduation at the frame's ``s = 0`` and the evidence.

    ``graduation``: absolute index of the graduation at ``s = 0``; ``first_cell``: absolute index of
    the first cell in view; ``bits``: one character per cell in view (``0``, ``1``, ``?`` unreadable);
    ``darkness``: each cell's normalised darkness; ``disagreements``: cells read that contradict the
    code at the accepted place; ``margin``: how many more the next-best place contradicts.
    """

    graduation: int
    first_cell: int
    bits: str
    darkness: FloatArray
    disagreements: int
    margin: int

    @property
    def read(self) -> int:
        """Number of cells read (not ``?``)."""
        return sum(1 for b in self.bits if b != "?")


def cell_darkness(
    bins: FloatArray,
    bin_s: FloatArray,
    substrip: npt.NDArray[np.int64],
    cells_per_pitch: int,
    dark: FloatArray,
    bright: FloatArray,
) -> tuple[npt.NDArray[np.int64], FloatArray]:
    """Each whole cell's normalised darkness (0 ground, 1 mark) from the code track's bins.

    Parameters
    ----------
    bins : (n, 6) ndarray
        The code strips' bins (``_ruler_bins.BIN_FIELDS``).
    bin_s : (n,) ndarray
        Each bin's mean ``s`` in the final frame (periods; NaN for an empty bin).
    substrip : (n,) ndarray
        The sub-strip of each bin.
    cells_per_pitch : int
        Cells per period.
    dark, bright : callables' values
        The graduations' dark and bright grey levels at each bin's ``s`` ((n,) arrays).

    Returns
    -------
    cells : ndarray of int
        The frame's cell numbers ``c`` (cell ``c`` centred at ``s = c / cells_per_pitch``).
    darkness : ndarray
        Median over sub-strips of each cell's normalised darkness (NaN where no sub-strip saw it).
    """
    n = bins[:, 0]
    valid = (n > 0) & np.isfinite(bin_s)
    pos = np.where(valid, bin_s, 0.0) * cells_per_pitch
    cell = np.rint(pos).astype(np.int64)
    central = valid & (np.abs(pos - cell) <= 0.25)
    if not central.any():
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    lo = int(cell[central].min())
    count = int(cell[central].max()) - lo + 1
    subs = int(substrip.max()) + 1
    key = (cell[central] - lo) * subs + substrip[central]
    size = count * subs
    total_n = np.bincount(key, n[central], minlength=size)
    total_i = np.bincount(key, bins[central, 1], minlength=size)
    total_dark = np.bincount(key, n[central] * dark[central], minlength=size)
    total_bright = np.bincount(key, n[central] * bright[central], minlength=size)
    seen = total_n > 0
    safe = np.maximum(total_n, 1.0)
    level, d, b = total_i / safe, total_dark / safe, total_bright / safe
    q = np.where(
        seen & (np.abs(d - b) > 1e-9), (level - b) / np.where(np.abs(d - b) > 1e-9, d - b, 1.0), np.nan
    )
    q = q.reshape(count, subs)
    return np.arange(lo, lo + count), _row_nanmedian(q)


def _row_nanmedian(q: FloatArray) -> FloatArray:
    """``np.nanmedian(q, axis=1)`` of a few columns, NaN (without a warning) for a row of NaN only:
    each row sorted (NaN last), the middle of its finite values, or the mean of the two middle ones."""
    ordered = np.sort(q, axis=1)
    k = np.count_nonzero(np.isfinite(q), axis=1)
    upper = np.take_along_axis(ordered, np.maximum(k // 2, 0)[:, None], axis=1)[:, 0]
    lower = np.take_along_axis(ordered, np.maximum((k - 1) // 2, 0)[:, None], axis=1)[:, 0]
    middle = np.where(k % 2 == 1, upper, (lower + upper) / 2.0)
    return np.asarray(np.where(k > 0, middle, np.nan))


def read_code(cells: npt.NDArray[np.int64], darkness: FloatArray, spec: RulerSpec) -> CodeReading:
    """Find the graduation at ``s = 0`` from the cells' darkness (module docstring).

    Raises
    ------
    CodeUnreadableError
        Fewer cells read than the code's register length.
    CodeInconsistentError
        No place of the code agrees with the cells read well enough, or two places agree alike.
    """
    per = spec.code.cells_per_pitch
    order = spec.code.order
    bits = np.full(len(cells), -1, dtype=np.int64)
    finite = np.isfinite(darkness)
    bits[finite & (darkness >= MARK_LEVEL)] = 1
    bits[finite & (darkness <= 1.0 - MARK_LEVEL)] = 0
    text = "".join("?" if b < 0 else str(int(b)) for b in bits)
    known = bits >= 0
    read = int(known.sum())
    if read < order:
        raise CodeUnreadableError(
            f"only {read} of the {len(cells)} code cells in view could be read ({text}); at least {order} "
            "are needed: clean the ruler's code track, check focus and lighting, or centre the ruler in the "
            "frame"
        )
    code = spec.code_bits().astype(np.int64)
    total = len(code)
    # graduation g at s = 0 puts view cell c at absolute cell j = c + per * g
    g_lo = -int(cells.max()) // per - 1
    g_hi = (total - 1 - int(cells.min())) // per + 1
    g = np.arange(g_lo, g_hi + 1)
    j = cells[known][None, :] + per * g[:, None]
    expected = np.where((j >= 0) & (j < total), code[np.clip(j, 0, total - 1)], 0)
    disagree = np.count_nonzero(expected != bits[known][None, :], axis=1)
    # a place must show at least `order` of the ruler's own cells
    on_ruler = np.count_nonzero((j >= 0) & (j < total), axis=1) >= order
    disagree = np.where(on_ruler, disagree, read + MIN_MARGIN + 1)
    order_idx = np.argsort(disagree, kind="stable")
    best, second = int(disagree[order_idx[0]]), int(disagree[order_idx[1]]) if len(g) > 1 else read
    allowed = (read - order) // CELLS_PER_DISAGREEMENT
    graduation = int(g[order_idx[0]])
    if best > allowed or second - best < MIN_MARGIN:
        where = graduation * spec.pitch_mm
        raise CodeInconsistentError(
            f"the {read} code cells read ({text}) match no place of ruler {spec.name!r}'s code: the closest, "
            f"near {where:.1f} mm, disagrees in {best} cells (at most {allowed} allowed) and the next in "
            f"{second}; is this the ruler described (its code), is the image mirrored, or is the code track "
            "damaged there?"
        )
    return CodeReading(
        graduation=graduation,
        first_cell=int(cells[0]) + per * graduation,
        bits=text,
        darkness=darkness,
        disagreements=best,
        margin=second - best,
    )
