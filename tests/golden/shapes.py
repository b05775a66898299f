"""What a golden test compares: a JSON document's shape (keys and JSON types, all the way down) and its
values where they are deterministic for the seeded simulated station.

``shape(doc)`` maps a document to the same tree with each leaf replaced by its JSON type name (``"int"``,
``"float"``, ``"str"``, ``"bool"``, ``"null"``); lists of scalars become ``["list", {types}]``, lists of
objects keep the first element's shape and the union of the others' keys (so a population's length and
order stay in the values, not the shape). ``values(doc, volatile)`` is the document with the leaves at the
``volatile`` paths (ids, times, anything not fixed by the seed) replaced by their type name.

The golden files under ``tests/golden/data/`` were written from main before issue 21's restructuring
(``STATION_GOLDEN_WRITE=1`` rewrites them: only on purpose, with the change explained in the commit).
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Iterable
from pathlib import Path
from typing import Any

DATA = Path(__file__).parent / "data"


def type_name(v: Any) -> str:
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "bool"
    if isinstance(v, int):
        return "int"
    if isinstance(v, float):
        return "float"
    if isinstance(v, str):
        return "str"
    raise TypeError(f"not a JSON scalar: {v!r}")


def shape(doc: Any) -> Any:
    """The document's keys and JSON types (see the module's docstring)."""
    if isinstance(doc, dict):
        return {k: shape(v) for k, v in sorted(doc.items())}
    if isinstance(doc, list):
        if any(isinstance(x, dict) for x in doc):
            merged: dict[str, Any] = {}
            for x in doc:
                for k, v in shape(x).items():
                    merged.setdefault(k, v)
            return [merged]
        if any(isinstance(x, list) for x in doc):
            return [shape(doc[0])] if doc else []
        return ["list", sorted({type_name(x) for x in doc})]
    return type_name(doc)


def values(doc: Any, volatile: Iterable[str], path: str = "") -> Any:
    """``doc`` with the leaves at ``volatile`` paths (``a.b.*.c``: ``*`` any key or index) replaced by
    their type name; NaN written as the string ``"NaN"`` (the golden file is strict JSON)."""
    patterns = list(volatile)

    def walk(v: Any, parts: list[str]) -> Any:
        if parts and _at(parts, patterns):
            return f"<{type_name(v) if not isinstance(v, dict | list) else type(v).__name__}>"
        if isinstance(v, dict):
            return {k: walk(x, [*parts, k]) for k, x in sorted(v.items())}
        if isinstance(v, list):
            return [walk(x, [*parts, str(i)]) for i, x in enumerate(v)]
        if isinstance(v, float) and math.isnan(v):
            return "NaN"
        return v

    return walk(doc, [])


def close(
    got: Any,
    want: Any,
    path: str = "$",
    rel: float = 1e-6,
    abs_: float = 1e-9,
    loose: Iterable[str] = (),
    loose_rel: float = 1e-4,
) -> list[str]:
    """Where ``got`` differs from ``want`` (floats within ``rel`` / ``abs_``, or ``loose_rel`` at the
    ``loose`` paths, written as ``values``' volatile ones; the rest exactly)."""
    if loose and _at(re.sub(r"\[(\d+)\]", r".\1", path).split(".")[1:], loose, under=True):
        rel, loose = loose_rel, ()
    if isinstance(want, dict):
        if not isinstance(got, dict):
            return [f"{path}: {got!r} is not an object"]
        out = [f"{path}: keys {sorted(set(got) ^ set(want))} differ"] if set(got) != set(want) else []
        for k in sorted(set(got) & set(want)):
            out += close(got[k], want[k], f"{path}.{k}", rel, abs_, loose, loose_rel)
        return out
    if isinstance(want, list):
        if not isinstance(got, list) or len(got) != len(want):
            return [f"{path}: {got!r} is not a list of {len(want)}"]
        out = []
        for i, (g, w) in enumerate(zip(got, want, strict=True)):
            out += close(g, w, f"{path}[{i}]", rel, abs_, loose, loose_rel)
        return out
    if isinstance(want, float) and not isinstance(got, bool) and isinstance(got, int | float):
        if type(got) is not float or not math.isclose(got, want, rel_tol=rel, abs_tol=abs_):
            return [f"{path}: {got!r} != {want!r}"]
        return []
    if type(got) is not type(want) or got != want:
        return [f"{path}: {got!r} != {want!r}"]
    return []


def _at(parts: list[str], patterns: Iterable[str], *, under: bool = False) -> bool:
    """Whether the path ``parts`` (keys and indices) is one of ``patterns`` (``a.b.*.c``: ``*`` any key
    or index), or with ``under`` lies at or under one."""
    for p in patterns:
        want = p.split(".")
        if (len(parts) >= len(want) if under else len(parts) == len(want)) and all(
            a in ("*", b) for a, b in zip(want, parts, strict=False)
        ):
            return True
    return False


def golden(name: str, doc: Any) -> Any:
    """The golden document ``name`` (``doc`` written there first under ``STATION_GOLDEN_WRITE=1``)."""
    path = DATA / f"{name}.json"
    if os.environ.get("STATION_GOLDEN_WRITE") == "1":
        DATA.mkdir(exist_ok=True)
        path.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
    return json.loads(path.read_text())
