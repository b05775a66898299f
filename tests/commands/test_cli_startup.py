"""``station measure`` starts without loading what it does not use: the record, the reports, the service,
the plug-ins' sub-commands or Dask (about 2 s of CPU per run before, against ~4 ms per frame measured)."""

from __future__ import annotations

import json
import subprocess
import sys

HEAVY = ("sqlalchemy", "matplotlib", "fastapi", "distributed", "station.record", "station.reporting", "sim")

PROBE = f"""
import contextlib, io, json, sys
from station.cli import main
with contextlib.suppress(SystemExit), contextlib.redirect_stdout(io.StringIO()):
    main([*sys.argv[1:], "--help"])
print(json.dumps(sorted({{m.split(".")[0] if not m.startswith("station.") else ".".join(m.split(".")[:2])
                          for m in sys.modules}} & set({HEAVY!r}))))
"""


def loaded(*argv: str) -> list[str]:
    done = subprocess.run([sys.executable, "-c", PROBE, *argv], capture_output=True, text=True, check=True)
    result: list[str] = json.loads(done.stdout)
    return result


def test_station_measure_loads_only_the_measurement() -> None:
    assert loaded("measure", "--json", "--cluster", "tcp://sched.lab:8786", "x.png") == []


def test_other_commands_still_load_what_they_need() -> None:
    assert "station.record" in loaded("sessions")
