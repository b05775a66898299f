"""The layering checker passes on the project and catches a forbidden import."""

from __future__ import annotations

from pathlib import Path

from tools.check_layers import check, main

ROOT = Path(__file__).resolve().parent.parent


def test_project_respects_its_layers() -> None:
    assert check(ROOT) == []


def test_checker_catches_forbidden_imports(tmp_path: Path) -> None:
    for pkg in ("station/vision", "drivers", "sim", "api"):
        (tmp_path / pkg).mkdir(parents=True)
        (tmp_path / pkg / "__init__.py").write_text("")
    (tmp_path / "station" / "__init__.py").write_text("")
    (tmp_path / "station" / "vision" / "core.py").write_text("from station import config\n")
    (tmp_path / "station" / "runner.py").write_text("import sim.world\n")
    (tmp_path / "drivers" / "x.py").write_text("from sim import twin\n")
    (tmp_path / "sim" / "y.py").write_text("from . import world\nfrom drivers.camera import v4l2\n")
    found = {(str(v.path), v.imported) for v in check(tmp_path)}
    assert ("station/vision/core.py", "station") in found
    assert ("station/runner.py", "sim.world") in found
    assert ("drivers/x.py", "sim") in found
    assert ("sim/y.py", "drivers.camera") in found
    assert not any(imported == "sim.world" and path == "sim/y.py" for path, imported in found)
    assert main([str(tmp_path)]) == 1
