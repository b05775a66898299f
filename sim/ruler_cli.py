"""``station sim render-set --artifact ruler``: a ruler image set on disk (``sim.ruler_imageset``)."""

from __future__ import annotations

import argparse
import sys
import time

from sim.imageset import ImageSetError, TableSpec
from sim.ruler_imageset import (
    RulerEnvelope,
    load_ruler_truth,
    render_ruler_random_set,
    render_ruler_validation_set,
)

__all__ = ["render_ruler_set"]

DEFAULT_RANDOM_COUNT = 48


def _fail(message: str) -> int:
    sys.stderr.write(f"station sim: {message}\n")
    return 1


def render_ruler_set(args: argparse.Namespace) -> int:
    """Render the ruler set ``args`` ask for (``render-set``'s options); 0 done, 1 refused."""
    start = time.perf_counter()
    if args.true_width_mm is not None:
        return _fail("--true-width-mm applies to the cross's groove only")
    try:
        if args.pattern == "validation":
            if args.count is not None or args.max_rotation is not None:
                return _fail("--count and --max-rotation apply to --pattern random only")
            table = TableSpec(rotation_deg=args.table_rotation_deg, skew_deg=args.table_skew_deg)
            out = render_ruler_validation_set(
                args.out_dir, preset=args.preset, seed=args.seed, table=table, force=args.force
            )
        else:
            if args.table_rotation_deg or args.table_skew_deg:
                return _fail("--table-rotation-deg and --table-skew-deg apply to --pattern validation only")
            envelope = RulerEnvelope(
                max_rotation_deg=180.0 if args.max_rotation is None else args.max_rotation
            )
            out = render_ruler_random_set(
                args.out_dir,
                preset=args.preset,
                count=DEFAULT_RANDOM_COUNT if args.count is None else args.count,
                seed=args.seed,
                envelope=envelope,
                force=args.force,
            )
        header, images = load_ruler_truth(out)
    except (ImageSetError, ValueError, OSError) as exc:
        return _fail(str(exc))
    preset = header["preset"]
    sys.stderr.write(
        f"station sim: {len(images)} {header['kind']} ruler images, preset {preset['name']} "
        f"v{preset['version']}, seed {header['seed']}, {time.perf_counter() - start:.1f} s -> {out}\n"
    )
    sys.stdout.write(f"{out}\n")
    return 0
