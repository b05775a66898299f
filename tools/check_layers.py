"""Check the direction of dependencies between the project's packages (README, "Layout").

Rules, each ``(importer prefix, forbidden prefixes, allowed exceptions)``:

* ``station.vision`` is a pure measurement core: it imports nothing of the project but itself;
* nothing in ``station`` imports ``api``, ``drivers`` or ``sim`` (devices are built by name through
  entry points, see ``station/config.py``);
* drivers and twins never import each other, nor the API.

Run as ``python tools/check_layers.py [ROOT]``; exits 1 and lists every offending import.
"""

from __future__ import annotations

import ast
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

PROJECT_PACKAGES = ("station", "drivers", "sim", "api")


@dataclass(frozen=True)
class Rule:
    importer: str
    forbidden: tuple[str, ...]
    allowed: tuple[str, ...] = ()
    why: str = ""


RULES: tuple[Rule, ...] = (
    Rule("station.vision", PROJECT_PACKAGES, ("station.vision",), "the measurement core imports nothing"),
    Rule("station", ("api", "drivers", "sim"), (), "the core never imports the API, drivers or twins"),
    Rule("drivers", ("sim", "api"), (), "drivers never import twins or the API"),
    Rule("sim", ("drivers", "api"), (), "twins never import drivers or the API"),
    Rule("api", ("drivers", "sim"), (), "the API builds devices through station.config"),
)


@dataclass(frozen=True)
class Violation:
    path: Path
    line: int
    module: str
    imported: str
    rule: Rule

    def __str__(self) -> str:
        return f"{self.path}:{self.line}: {self.module} imports {self.imported} ({self.rule.why})"


def _matches(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imports_of(tree: ast.AST, module: str, is_package: bool) -> Iterator[tuple[int, str]]:
    """Yield (line, absolute module name) for every import in ``tree``."""
    package = module if is_package else module.rpartition(".")[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)] if node.level > 1 else base
                target = ".".join([*base, *([node.module] if node.module else [])])
            else:
                target = node.module or ""
            yield node.lineno, target
            for alias in node.names:  # `from station import vision` imports station.vision
                yield node.lineno, f"{target}.{alias.name}"


def check(root: Path) -> list[Violation]:
    violations: list[Violation] = []
    for top in PROJECT_PACKAGES:
        for path in sorted((root / top).rglob("*.py")):
            module = module_name(path, root)
            tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
            for line, imported in imports_of(tree, module, path.name == "__init__.py"):
                for rule in RULES:
                    if not _matches(module, rule.importer):
                        continue
                    if any(_matches(imported, a) for a in rule.allowed):
                        continue
                    if any(_matches(imported, f) for f in rule.forbidden):
                        violations.append(Violation(path.relative_to(root), line, module, imported, rule))
                        break
    return violations


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    root = Path(args[0]) if args else Path(__file__).resolve().parent.parent
    found = check(root)
    for v in found:
        print(v, file=sys.stderr)
    if found:
        print(f"layering: {len(found)} forbidden import(s)", file=sys.stderr)
        return 1
    print("layering: ok")
    return 0


if __name__ == "__main__":
    sys.exit(main())
