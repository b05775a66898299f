"""``station scale-calibration show|history|revert``: the station's scale calibration and its history."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from station import scale_calibration as scal
from station.config import ConfigurationError, load_config
from station.record import lock_holder
from station.session import data_dir_for


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "scale-calibration",
        help="show, list or revert the station's scale calibration (the groove width it measures with)",
        description="The station's scale calibration (DATA/scale-calibration.json), written only by a "
        "validation that passed its checks, and its history (DATA/scale-calibration-history/).",
    )
    p.add_argument("action", choices=("show", "history", "revert"))
    p.add_argument(
        "--data",
        metavar="DIR",
        help="data directory (default: the configuration's, $STATION_DATA, ./station-data)",
    )
    p.add_argument("--config", metavar="FILE", help="station configuration (for its data directory)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=lambda args: run(p, args))


def run(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    try:
        config = load_config(args.config) if args.config else None
    except ConfigurationError as exc:
        parser.error(str(exc))
    data = data_dir_for(args.data, config)
    if not data.is_dir():
        print(f"station scale-calibration: no data directory {data}; give --data DIR", file=sys.stderr)
        return 2
    try:
        if args.action == "show":
            return _show(data, args.json, configured=config.scale_calibration if config else None)
        if args.action == "history":
            return _history(data, args.json)
        return _revert(data, args.json)
    except scal.ScaleCalibrationError as exc:
        print(f"station scale-calibration: {exc}", file=sys.stderr)
        return 1


def _show(data: Path, as_json: bool, configured: Path | None) -> int:
    doc = scal.status(data)
    if as_json:
        print(json.dumps(doc))
    elif doc["calibration"] is None:
        print(
            f"no scale calibration in {data}: sessions measure with the nominal groove width; a validation "
            "that passes its checks writes one (station run validation ...)"
        )
    else:
        print(_line(doc["calibration"], doc["entry"]))
        for c in doc["calibration"].get("checks") or []:
            print(f"  {c['name']}: {'passed' if c['passed'] else 'not passed'} ({c['message']})")
    if configured is not None:
        print(f"note: this configuration's sessions measure with {configured} instead", file=sys.stderr)
    return 0 if doc["calibration"] is not None else 1


def _line(cal: dict[str, Any], entry: dict[str, Any] | None) -> str:
    how = ""
    if entry is not None:
        restores = f" of version {entry['restores']}" if entry.get("restores") else ""
        how = f" ({entry['action']}{restores}, written {entry['written_at']})"
    return (
        f"version {cal.get('version') or '-'}: groove width {cal['groove_width_mm']:.6f} mm, "
        f"u {cal['u_mm']:.6f} mm, from validation session {cal.get('session_id') or '-'}{how}"
    )


def _history(data: Path, as_json: bool) -> int:
    items = scal.history_json(data)
    if as_json:
        print(json.dumps(items))
        return 0
    if not items:
        print(f"no scale calibration history in {data}")
    for e in items:
        cal = e["calibration"]
        what = "none (nominal groove width)" if cal is None else _line(cal, None)
        print(f"{e['version']:>4}  {e['written_at']}  {e['action']:<10}  {what}")
    return 0


def _revert(data: Path, as_json: bool) -> int:
    holder = lock_holder(data)
    if holder is not None:
        print(
            f"station scale-calibration: session {holder.get('session_id')} is running "
            f"(pid {holder.get('pid')}); revert once it has ended",
            file=sys.stderr,
        )
        return 1
    entry = scal.revert(data)
    if as_json:
        print(json.dumps(entry.model_dump(mode="json")))
    elif entry.calibration is None:
        print(f"reverted: no scale calibration now (version {entry.version}); sessions use the nominal width")
    else:
        print("reverted: " + _line(entry.calibration.model_dump(mode="json"), entry.model_dump(mode="json")))
    return 0
