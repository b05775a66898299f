"""Plain-text tables for the command line."""

from __future__ import annotations

from collections.abc import Sequence

from station.batch import FileResult
from station.validation import ValidationResult


def table(headers: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A left-aligned text table."""
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h) for i, h in enumerate(headers)]
    lines = ["  ".join(h.ljust(w) for h, w in zip(headers, widths, strict=True)).rstrip()]
    lines.append("  ".join("-" * w for w in widths))
    lines += ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows]
    return "\n".join(lines)


def measurement_rows(results: Sequence[FileResult]) -> str:
    rows = []
    for r in results:
        m = r.measurement
        if m is None:
            rows.append([r.file, "FAILED", "", "", r.error or ""])
        else:
            rows.append(
                [
                    r.file,
                    f"{m.center_px[0]:9.3f} {m.center_px[1]:9.3f}",
                    f"{m.center_mm[0]:8.4f} {m.center_mm[1]:8.4f}",
                    f"{m.rotation_deg:+6.2f}",
                    "",
                ]
            )
    return table(["file", "center_px (x y)", "center_mm (x y)", "rot_deg", "error"], rows)


def validation_report(v: ValidationResult) -> str:
    """The seed's validation summary (Figures 14-15): displacement errors after each fit, in um."""
    c = v.comparison
    n_ok = int(v.used.sum())
    mode = v.results[0].measurement.params.mode if v.results[0].measurement else "?"
    out = [
        f"validation of {v.image_set.root} ({mode} mode, {v.calibration} calibration): "
        f"{n_ok} of {len(v.results)} images measured",
        "",
        table(
            ["fit", "mean_um", "max_um", "rms_um", "scale", "rotation_deg"],
            [
                [
                    f.kind + label,
                    f"{f.mean:.4f}",
                    f"{f.max:.4f}",
                    f"{f.rms:.4f}",
                    f"{f.scale:.6f}",
                    f"{f.rotation_deg:+.4f}",
                ]
                for f, label in (
                    (c.rigid, " (raw)"),
                    (c.similarity, " (scale fitted)"),
                    (c.affine, " (parallelogram)"),
                )
            ],
        ),
    ]
    if v.center_error_px is not None and len(v.center_error_px):
        e = v.center_error_px
        out += ["", f"centre error vs simulator truth: mean {e.mean():.4f} px, max {e.max():.4f} px"]
    if v.failures:
        out += ["", "not measured:"] + [f"  {r.file}: {r.error}" for r in v.failures]
    return "\n".join(out)
