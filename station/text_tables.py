"""Plain-text tables for the command line (measurements, validation, sweeps), and the seed's Table 1 layout
shared with session reports."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from station.batch import FileResult
from station.displacements import ValidationResult
from station.parameter_study import SEED_TABLE_1, seed_trials


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


@dataclass(frozen=True)
class SweepRow:
    """One trial of a parameter study as Table 1 shows it: MaxE / MeanE in mm, None when it failed."""

    number: int
    overrides: Mapping[str, Any]
    max_e_mm: float | None
    mean_e_mm: float | None
    error: str | None = None


#: Table 1's overrides in the seed's column order (Filter, SK, TW, TH); TW = TESTWIDTH (station/sweep.py).
SEED_COLUMNS: tuple[tuple[str, str], ...] = (
    ("Filter", "filter"),
    ("SK", "skip"),
    ("TW", "testwidth"),
    ("TH", "testheight"),
)


def sweep_table(
    rows: Sequence[SweepRow], best: int | None, *, seed_layout: bool
) -> tuple[list[str], list[list[str]]]:
    """Table 1's headers and cells, one row per trial, the best trial marked ``*``.

    ``seed_layout``: the seed's columns Filter, SK, TW, TH (override names matched case-insensitively);
    otherwise one column per override of the first trial. A failed trial shows "failed" and its error.
    """
    names = list(rows[0].overrides) if rows else []
    cells_out = []
    for t in rows:
        mark = "*" if best is not None and t.number == best else ""
        if t.max_e_mm is not None and t.mean_e_mm is not None:
            maxe, meane = f"{t.max_e_mm:.5f}", f"{t.mean_e_mm:.5f}"
        else:
            maxe, meane = "failed", t.error or ""
        if seed_layout:
            o = {str(k).lower(): v for k, v in t.overrides.items()}
            cells = [str(t.number), str(o.get("filter", "")).capitalize()]
            cells += [str(o.get(key, "")) for _, key in SEED_COLUMNS[1:]]
        else:
            cells = [str(t.number), *(str(t.overrides.get(n, "")) for n in names)]
        cells_out.append([*cells, maxe, meane, mark])
    headers = ["Trial", *(h for h, _ in SEED_COLUMNS)] if seed_layout else ["Trial", *names]
    return [*headers, "MaxE", "MeanE", "best"], cells_out


def seed_table_1() -> tuple[list[str], list[list[str]]]:
    """The seed's own Table 1 (MaxE / MeanE in mm), for comparison beside a sweep."""
    return (
        ["Trial", *(h for h, _ in SEED_COLUMNS), "MaxE", "MeanE"],
        [
            [str(n), f.capitalize(), str(sk), str(tw), str(th), f"{mx:.4f}", f"{mn:.4f}"]
            for n, f, sk, tw, th, mx, mn in SEED_TABLE_1
        ],
    )


def is_seed_table_1(overrides: Sequence[Mapping[str, Any]]) -> bool:
    """Whether a sweep's trials are exactly the seed's nine (so Table 1's layout applies)."""
    return [{str(k).lower(): v for k, v in o.items()} for o in overrides] == seed_trials()


def sweep_note(mode: str | None, *, seed_layout: bool, fit: str = "parallelogram") -> str:
    """What Table 1's columns mean; ``fit``: the errors' fit, the seed's ``parallelogram`` or ``rigid``."""
    if fit == "parallelogram":
        after = "after the well-fit parallelogram"
    else:
        after = f"after the {fit} fit (the seed's Table 1 is after the parallelogram fit)"
    note = f"MaxE / MeanE in mm {after}; * = lowest MeanE, then MaxE"
    if mode:
        note = f"{mode} mode; {note}"
    if seed_layout:
        note += "\nTW = TESTWIDTH, TH = TESTHEIGHT (the column headers' reading)"
    return note


def sweep_report(rows: Sequence[SweepRow], best: int | None, mode: str | None, *, seed_layout: bool) -> str:
    """Table 1 as text, with the seed's own table beside it in the seed's layout."""
    text = table(*sweep_table(rows, best, seed_layout=seed_layout))
    out = f"{text}\n\n{sweep_note(mode, seed_layout=seed_layout)}"
    if seed_layout:
        out += "\n\nthe seed's Table 1:\n" + table(*seed_table_1())
    return out
