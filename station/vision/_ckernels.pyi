"""Type stub of the compiled kernels (``_ckernels.c``); ``_kernels`` chooses between them and numpy."""

import numpy as np
import numpy.typing as npt

def profiles(
    img: npt.NDArray[np.uint8] | npt.NDArray[np.float32],
    along: npt.NDArray[np.int64],
    owner: npt.NDArray[np.int64],
    mu: npt.NDArray[np.float64],
    half: int,
    impulse_dn: float,
    colcoef: npt.NDArray[np.float64] | None,
    yn: npt.NDArray[np.float64] | None,
    with_spread: bool,
    out_index: npt.NDArray[np.int64],
    out_across: npt.NDArray[np.float64],
    out_strength: npt.NDArray[np.float64],
    out_spread: npt.NDArray[np.float64],
    /,
) -> int: ...
def fine(
    img: npt.NDArray[np.uint8] | npt.NDArray[np.float32],
    slope: npt.NDArray[np.float64],
    intercept: npt.NDArray[np.float64],
    colcoef: npt.NDArray[np.float64] | None,
    yn: npt.NDArray[np.float64] | None,
    passes: int,
    window_px: int,
    window_sigmas: float,
    profile_step: int,
    corner_margin_px: float,
    impulse_dn: float,
    min_edge_points: int,
    min_contrast_dn: float,
    min_contrast_fraction: float,
    outlier_sigma: float,
    residual_limit_px: float,
    out_stats: npt.NDArray[np.float64],
    out_points: npt.NDArray[np.float64],
    /,
) -> tuple[tuple[int, int, int, int], bool, int]: ...
def project(
    small: npt.NDArray[np.float32],
    h: int,
    w: int,
    scale: int,
    theta: float,
    out_u: npt.NDArray[np.float64],
    out_v: npt.NDArray[np.float64],
    out_counts: npt.NDArray[np.float64],
    out_sums: npt.NDArray[np.float64],
    /,
) -> tuple[float, int, float, int]: ...
def illumination(
    small: npt.NDArray[np.float32],
    land: npt.NDArray[np.bool_],
    basis: npt.NDArray[np.float64],
    out_coef: npt.NDArray[np.float64],
    /,
) -> int: ...
def testbox(
    response: npt.NDArray[np.float32],
    sign: float,
    axis: int,
    reverse: bool,
    level: float,
    candidates: npt.NDArray[np.int64],
    testheight: int,
    testwidth: int,
    skip: int,
    backoff: int,
    out_points: npt.NDArray[np.int64],
    /,
) -> int: ...
def edge_fit(
    gray: npt.NDArray[np.uint8],
    pixels: npt.NDArray[np.int64],
    vertical: bool,
    corr_tol: float,
    change_tol: float,
    max_removals: int,
    min_points: int,
    out_points: npt.NDArray[np.float64],
    out_kept: npt.NDArray[np.bool_],
    /,
) -> tuple[int, int, float, float, float, float]: ...
def edge_contrast(values: npt.NDArray[np.float32], out: npt.NDArray[np.float64], /) -> None: ...
def second_band(
    turned: npt.NDArray[np.float32], row: float, width: float, depth_fraction: float, /
) -> float | None: ...
def arms(
    edges_h: npt.NDArray[np.float64],
    distance_h: npt.NDArray[np.float64],
    edges_v: npt.NDArray[np.float64],
    distance_v: npt.NDArray[np.float64],
    width_h: float,
    width_v: float,
    present_fraction: float,
    tolerance: float,
    out_farthest: npt.NDArray[np.float64],
    /,
) -> int: ...
def band_edges(
    profile: npt.NDArray[np.float64], counts: npt.NDArray[np.float64], /
) -> tuple[int, int, int]: ...
def lands(
    u: npt.NDArray[np.float64],
    v: npt.NDArray[np.float64],
    v_mid: float,
    v_half: float,
    u_mid: float,
    u_half: float,
    out: npt.NDArray[np.bool_],
    /,
) -> None: ...
def quality(gray: npt.NDArray[np.uint8], /) -> tuple[int, int, float]: ...
def prewitt(
    gray: npt.NDArray[np.uint8], out_gy: npt.NDArray[np.float32], out_gx: npt.NDArray[np.float32], /
) -> tuple[float, float, float, float]: ...
def above(response: npt.NDArray[np.float32], level: float, /) -> bytes: ...
def groove_maps(
    c0: float,
    c1: float,
    u0: float,
    u1: float,
    n0: float,
    n1: float,
    t_from: float,
    w: float,
    gap: float,
    out_mapx: npt.NDArray[np.float32],
    out_mapy: npt.NDArray[np.float32],
    /,
) -> None: ...
