"""Check the direction of dependencies between the project's packages and floors (README, "Layout").

Two checks, both over every import of the project's modules, imports inside functions and
``TYPE_CHECKING`` blocks included, and through ``importlib.import_module`` called with a literal name (or
an f-string whose literal head names a package: every module under it counts as imported):

1. **Rules**, each ``(importer prefix, forbidden prefixes, allowed exceptions)``:

   * ``station.vision`` is a pure measurement core: it imports nothing of the project but itself;
   * nothing in ``station`` imports ``api``, ``drivers`` or ``sim`` (devices are built by name through
     entry points, see ``station/config.py``);
   * drivers and twins never import each other, nor the API;
   * ``station``'s own floors: the pure science (vision, kinematics, metrology, calibration, camcal)
     imports no session, record or device code; the record imports no session code (plans, kinds, the
     runner, the worker); drivers import ``station``'s interfaces and the pure science, never session code.

2. **No import cycle** between project modules. The only tolerated ones are listed in ``KNOWN_CYCLES``,
   each with the issue that removes it; they are printed as warnings (and an entry that no longer matches a
   cycle is reported as stale, to be deleted).

Run as ``python tools/check_layers.py [ROOT]``; exits 1 and lists every offending import and cycle.
"""

from __future__ import annotations

import ast
import sys
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

PROJECT_PACKAGES = ("station", "drivers", "sim", "api")

#: The pure science: image -> measurement, kinematics, metrology, identification, camera calibration.
PURE_SCIENCE = (
    "station.vision",
    "station.kinematics",
    "station.metrology",
    "station.calibration",
    "station.camcal",
)
#: Session code: what runs, hosts, stores or shows a session (the record is listed apart).
SESSION_CODE = (
    "station.session",
    "station.runner",
    "station.worker",
    "station.plans",
    "station.kinds",
    "station.batch",
    "station.resources",
    "station.reporting",
    "station.text_tables",
    "station.displacements",
    "station.parameter_study",
    "station.commands",
    "station.cli",
)
RECORD = ("station.record",)
#: Device code: the interfaces and the registry that builds concrete devices.
DEVICE_CODE = ("station.devices", "station.config")


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
    *(
        Rule(
            pure,
            SESSION_CODE + RECORD + DEVICE_CODE,
            (),
            "the pure science imports no session, record or device code",
        )
        for pure in PURE_SCIENCE
    ),
    Rule(
        "station.record", SESSION_CODE, (), "the record imports no plan, kind, runner or other session code"
    ),
    Rule(
        "drivers",
        SESSION_CODE + RECORD,
        (),
        "drivers import station's interfaces and pure science, never session code",
    ),
)


@dataclass(frozen=True)
class KnownCycle:
    """A cycle tolerated until the named issue removes it: every module of the cycle is in ``modules``."""

    modules: frozenset[str]
    issue: str


#: Cycles tolerated until the named issue removes them (none now: issue 21 removed the last, the session
#: code's plans <-> calibration_session circle). A new entry needs an issue that removes it.
KNOWN_CYCLES: tuple[KnownCycle, ...] = ()


@dataclass(frozen=True)
class Violation:
    path: Path
    line: int
    module: str
    imported: str
    rule: Rule

    def __str__(self) -> str:
        return f"{self.path}:{self.line}: {self.module} imports {self.imported} ({self.rule.why})"


@dataclass(frozen=True)
class Cycle:
    """A strongly connected group of modules and the imports that tie it (path, line, importer, imported)."""

    modules: tuple[str, ...]
    ties: tuple[tuple[Path, int, str, str], ...] = field(default=())

    def __str__(self) -> str:
        lines = [f"import cycle of {len(self.modules)} modules: {', '.join(self.modules)}"]
        lines += [f"  {path}:{line}: {a} imports {b}" for path, line, a, b in self.ties]
        return "\n".join(lines)


def _matches(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _import_module_target(node: ast.Call) -> tuple[str, bool] | None:
    """``(name, is_prefix)`` of an ``importlib.import_module(...)`` call, if its argument is legible."""
    func = node.func
    name = func.attr if isinstance(func, ast.Attribute) else func.id if isinstance(func, ast.Name) else ""
    if name != "import_module" or not node.args:
        return None
    arg = node.args[0]
    if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
        return arg.value, False
    if isinstance(arg, ast.JoinedStr) and arg.values:
        head = arg.values[0]
        if isinstance(head, ast.Constant) and isinstance(head.value, str) and "." in head.value:
            return head.value.rpartition(".")[0], True
    return None


def imports_of(tree: ast.AST, module: str, is_package: bool) -> Iterator[tuple[int, str]]:
    """Yield (line, absolute module name) for every import in ``tree``.

    ``importlib.import_module(f"pkg.{x}")`` yields ``pkg.*``: any module under ``pkg``.
    """
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
        elif isinstance(node, ast.Call) and (found := _import_module_target(node)):
            name, is_prefix = found
            yield node.lineno, f"{name}.*" if is_prefix else name


def links_of(tree: ast.AST, module: str, is_package: bool) -> Iterator[tuple[int, str, str | None]]:
    """Yield ``(line, module, name)`` per imported thing: ``name`` is what ``from module import name``
    imports (``None`` for ``import module`` and ``import_module``; ``*`` for any module under ``module``)."""
    package = module if is_package else module.rpartition(".")[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name, None
        elif isinstance(node, ast.ImportFrom):
            target = node.module or ""
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)] if node.level > 1 else base
                target = ".".join([*base, *([node.module] if node.module else [])])
            for alias in node.names:
                yield node.lineno, target, alias.name
        elif isinstance(node, ast.Call) and (found := _import_module_target(node)):
            name, is_prefix = found
            yield node.lineno, name, "*" if is_prefix else None


@dataclass
class Project:
    """The project's modules (name -> path relative to the root) and what each imports."""

    root: Path
    files: dict[str, Path]
    imports: dict[str, list[tuple[int, str]]]
    links: dict[str, list[tuple[int, str, str | None]]]

    @classmethod
    def read(cls, root: Path) -> Project:
        files: dict[str, Path] = {}
        imports: dict[str, list[tuple[int, str]]] = {}
        links: dict[str, list[tuple[int, str, str | None]]] = {}
        for top in PROJECT_PACKAGES:
            for path in sorted((root / top).rglob("*.py")):
                if "migrations" in path.relative_to(root).parts:
                    continue
                module = module_name(path, root)
                tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
                is_package = path.name == "__init__.py"
                files[module] = path.relative_to(root)
                imports[module] = list(imports_of(tree, module, is_package))
                links[module] = list(links_of(tree, module, is_package))
        return cls(root, files, imports, links)

    def _nearest(self, name: str) -> str:
        while name and name not in self.files:
            name = name.rpartition(".")[0]
        return name

    def _is_extension(self, base: str, name: str) -> bool:
        folder = self.root.joinpath(*base.split("."))
        return any(folder.glob(f"{name}.*.so")) or (folder / f"{name}.pyi").exists()

    def edges(self) -> dict[str, dict[str, int]]:
        """Importer -> {imported project module: first line}, drawn as ``import_cycles.py`` draws them:
        ``from pkg import name`` goes to ``pkg.name`` when that is a module, else to ``pkg`` (its face)."""
        graph: dict[str, dict[str, int]] = {m: {} for m in self.files}
        for module, found in self.links.items():
            for line, base, name in found:
                if name == "*":
                    targets = [m for m in self.files if m.startswith(base + ".")]
                elif name is not None and f"{base}.{name}" in self.files:
                    targets = [f"{base}.{name}"]
                elif name is not None and self._is_extension(base, name):
                    targets = []  # a compiled module (``_ckernels``): not the package's face
                else:
                    targets = [self._nearest(base)]
                for target in targets:
                    if target and target != module:
                        graph[module].setdefault(target, line)
        return graph


def check(root: Path) -> list[Violation]:
    """Every import that breaks a rule of ``RULES``."""
    project = Project.read(root)
    violations: list[Violation] = []
    for module, found in project.imports.items():
        for line, imported in found:
            for rule in RULES:
                if not _matches(module, rule.importer):
                    continue
                if any(_matches(imported, a) for a in rule.allowed):
                    continue
                if any(_matches(imported, f) for f in rule.forbidden):
                    violations.append(Violation(project.files[module], line, module, imported, rule))
                    break
    return violations


def _strongly_connected(graph: dict[str, dict[str, int]]) -> list[list[str]]:
    """Tarjan's strongly connected components of more than one module, iteratively."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    groups: list[list[str]] = []
    for start in sorted(graph):
        if start in index:
            continue
        work: list[tuple[str, Iterator[str]]] = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, successors = work[-1]
            for succ in successors:
                if succ not in index:
                    index[succ] = low[succ] = len(index)
                    stack.append(succ)
                    on_stack.add(succ)
                    work.append((succ, iter(sorted(graph[succ]))))
                    break
                if succ in on_stack:
                    low[node] = min(low[node], index[succ])
            else:
                work.pop()
                if work:
                    parent = work[-1][0]
                    low[parent] = min(low[parent], low[node])
                if low[node] == index[node]:
                    group: list[str] = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        group.append(member)
                        if member == node:
                            break
                    if len(group) > 1:
                        groups.append(sorted(group))
    return groups


def cycles(root: Path) -> list[Cycle]:
    """Every import cycle between the project's modules, with the imports that tie each."""
    project = Project.read(root)
    graph = project.edges()
    found: list[Cycle] = []
    for group in _strongly_connected(graph):
        members = set(group)
        ties = tuple(
            (project.files[a], line, a, b)
            for a in group
            for b, line in sorted(graph[a].items())
            if b in members
        )
        found.append(Cycle(tuple(group), ties))
    return found


def known(cycle: Cycle) -> KnownCycle | None:
    """The allow-list entry that tolerates ``cycle``, if any."""
    return next((k for k in KNOWN_CYCLES if set(cycle.modules) <= k.modules), None)


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    root = Path(args[0]) if args else Path(__file__).resolve().parent.parent
    found = check(root)
    for v in found:
        print(v, file=sys.stderr)
    circles = cycles(root)
    bad = [c for c in circles if known(c) is None]
    for c in circles:
        entry = known(c)
        if entry is not None:
            print(f"warning: known cycle, tolerated until {entry.issue} lands:\n{c}", file=sys.stderr)
    for entry in KNOWN_CYCLES:
        if not any(known(c) is entry for c in circles):
            print(
                f"warning: stale KNOWN_CYCLES entry ({entry.issue}): no such cycle now; delete it",
                file=sys.stderr,
            )
    for c in bad:
        print(c, file=sys.stderr)
    if found or bad:
        print(f"layering: {len(found)} forbidden import(s), {len(bad)} import cycle(s)", file=sys.stderr)
        return 1
    print("layering: ok")
    return 0


if __name__ == "__main__":
    sys.exit(main())
