"""The export format (``session.json``, format ``station-session`` version 1) as a pydantic model.

An import reads a document that anyone may have written, so every key, type and unit is checked here
before anything is written: unknown keys are refused, numbers are finite, times are ISO 8601 with a
time zone, ids match the station's own (12 lowercase hex digits), and each capture's ``path`` is
exactly the one the export writes for it (``images/<session id>/<step:05d>-<frame:02d>.png``). What
the model cannot say alone (unique steps, events and frames; measurements of the session's own
captures) is checked after it by :func:`parse_document`.

Units: ``timestamp_s`` seconds (the capture's clock), ``z_mm`` millimetres, ``width``/``height``
pixels, times UTC. Every refusal is an :class:`ImportRefusedError` naming the field.
"""

from __future__ import annotations

import json
import math
import re
from collections import Counter
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import (
    AwareDatetime,
    BaseModel,
    ConfigDict,
    Field,
    StrictBool,
    StrictFloat,
    StrictInt,
    StrictStr,
    ValidationError,
    model_validator,
)

from station.record._errors import ImportRefusedError, RecordError
from station.record._rows import SessionState, StepState

FORMAT = "station-session"
FORMAT_VERSION = 1
DOCUMENT = "session.json"
MAX_DOCUMENT_BYTES = 64 * 1024 * 1024
"""session.json's cap: about 4 kB per capture (a 10,000-capture session's is about 40 MB); the worst
64 MiB (one list of floats) parses into about 1.2 GB of Python objects before it is checked."""
SESSION_ID = re.compile(r"[0-9a-f]{12}")
MAX_IMAGE_SIDE_PX = 100_000

SessionId = Annotated[StrictStr, Field(pattern=r"^[0-9a-f]{12}$")]
Sha256 = Annotated[StrictStr, Field(pattern=r"^[0-9a-f]{64}$")]
Index = Annotated[StrictInt, Field(ge=0, le=2**31 - 1)]
Id = Annotated[StrictInt, Field(ge=0, le=2**63 - 1)]
JsonObject = dict[str, Any]
"""A JSON object as ``json.loads`` gives it (its values can only be JSON's types); its numbers are
checked finite after the model (:func:`_check_finite`), much faster than pydantic's ``JsonValue``."""
Finite = Annotated[StrictFloat | StrictInt, Field(allow_inf_nan=False)]
Name64 = Annotated[StrictStr, Field(min_length=1, max_length=64)]
Name128 = Annotated[StrictStr, Field(min_length=1, max_length=128)]


def capture_path(session_id: str, step_index: int, frame_index: int) -> str:
    """A capture's image path relative to the data directory (and to an export folder)."""
    return f"images/{session_id}/{step_index:05d}-{frame_index:02d}.png"


def capture_file(data_dir: Path, session_id: str, step_index: int, frame_index: int, path: str) -> Path:
    """A capture's file in the data directory, after checking that its recorded ``path`` is the
    station's own for it (a record altered by hand, or filled by an import before these checks, may
    name any file)."""
    want = capture_path(session_id, step_index, frame_index)
    if path != want or not SESSION_ID.fullmatch(session_id):
        raise RecordError(
            f"capture step {step_index} frame {frame_index} of session {session_id[:40]!r} names the file "
            f"{path[:80]!r}, not the station's {want[:80]!r}: the record was altered; restore it from a "
            "backup or import the session again"
        )
    return data_dir / want


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class SessionDoc(_Strict):
    """The session row."""

    id: SessionId
    kind: Annotated[StrictStr, Field(pattern=r"^[a-z][a-z0-9_]{0,63}$")]
    state: SessionState
    created_at: AwareDatetime
    updated_at: AwareDatetime
    params: JsonObject
    config: JsonObject
    identities: JsonObject
    software: JsonObject
    results: JsonObject | None
    error: StrictStr | None
    parent_id: SessionId | None
    station: Name128


class StepDoc(_Strict):
    index: Index
    name: Name128
    state: StepState
    data: JsonObject
    started_at: AwareDatetime
    finished_at: AwareDatetime | None


class EventDoc(_Strict):
    id: Id = Field(description="the exporting record's id (the importing record gives its own)")
    seq: Annotated[StrictInt, Field(ge=1, le=2**31 - 1)]
    time: AwareDatetime
    type: Name64
    data: JsonObject


class CaptureDoc(_Strict):
    id: Id = Field(description="the exporting record's id (the importing record gives its own)")
    step_index: Index
    frame_index: Index
    path: Annotated[StrictStr, Field(max_length=512)]
    width: Annotated[StrictInt, Field(ge=1, le=MAX_IMAGE_SIDE_PX, description="px")]
    height: Annotated[StrictInt, Field(ge=1, le=MAX_IMAGE_SIDE_PX, description="px")]
    dtype: Literal["uint8", "uint16"]
    sha256: Sha256
    timestamp_s: Finite = Field(description="s, the capture's clock")
    meta: JsonObject
    z_mm: Finite | None = Field(None, description="mm, the distance sensor's reading")


class CaptureRef(_Strict):
    session_id: SessionId
    step_index: Index
    frame_index: Index


class MeasurementDoc(_Strict):
    id: Id = Field(description="the exporting record's id (the importing record gives its own)")
    capture_id: Id = Field(description="the exporting record's capture id (``capture`` says which)")
    capture: CaptureRef
    params_hash: Sha256
    software: Name128
    ok: StrictBool
    result: JsonObject


class ExportDocument(_Strict):
    """``session.json``: a header, the session row and its rows, in the export's order."""

    format: Literal["station-session"]
    format_version: Literal[1]
    schema_revision: Annotated[StrictStr, Field(max_length=64)]
    session: SessionDoc
    steps: list[StepDoc]
    events: list[EventDoc]
    captures: list[CaptureDoc]
    measurements: list[MeasurementDoc]

    @model_validator(mode="after")
    def _consistent(self) -> ExportDocument:
        sid = self.session.id
        for i, c in enumerate(self.captures):
            want = capture_path(sid, c.step_index, c.frame_index)
            if c.path != want:
                raise _RefusalError(
                    f"captures[{i}].path",
                    f"{c.path[:80]!r} is not this capture's path in an export: it must be {want!r}",
                )
        _unique("steps", "index", [s.index for s in self.steps])
        _unique("events", "seq", [e.seq for e in self.events])
        _unique(
            "captures", "(step_index, frame_index)", [(c.step_index, c.frame_index) for c in self.captures]
        )
        own = {(c.step_index, c.frame_index) for c in self.captures}
        for i, m in enumerate(self.measurements):
            ref = m.capture
            if ref.session_id == sid and (ref.step_index, ref.frame_index) not in own:
                raise _RefusalError(
                    f"measurements[{i}].capture",
                    f"step {ref.step_index} frame {ref.frame_index} of this session is not among its "
                    "captures",
                )
        if self.session.parent_id == sid:
            raise _RefusalError("session.parent_id", "a session cannot be its own parent")
        return self


class _RefusalError(ValueError):
    """A consistency problem found by the model's validator (becomes an ImportRefusedError)."""

    def __init__(self, field: str, reason: str) -> None:
        super().__init__(reason)
        self.field = field
        self.reason = reason


def _unique(array: str, key: str, values: list[Any]) -> None:
    repeated = [v for v, n in Counter(values).items() if n > 1]
    if repeated:
        first = values.index(repeated[0])
        raise _RefusalError(
            f"{array}[{values.index(repeated[0], first + 1)}].{key}", f"{repeated[0]} is repeated"
        )


_PATTERNS = {
    "^[0-9a-f]{12}$": "a station session id (12 lowercase hex digits)",
    "^[0-9a-f]{64}$": "a sha256 (64 lowercase hex digits)",
    "^[a-z][a-z0-9_]{0,63}$": "a session kind (lowercase letters, digits and _)",
}
_TAGS = frozenset({"list", "dict", "str", "int", "float", "bool", "none", "function-after"})
_NUL_ESCAPE = re.compile(r"(?<!\\)(?:\\\\)*\\u0000")


def _where(loc: tuple[int | str, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif part not in _TAGS and not part.startswith(("function-", "constrained-")):
            out += f".{part}" if out else part
    return out or "(the document)"


def _refused(exc: ValidationError) -> ImportRefusedError:
    errors = exc.errors(include_url=False)
    first = errors[0]
    cause = first.get("ctx", {}).get("error")
    if isinstance(cause, _RefusalError):
        return ImportRefusedError(f"{DOCUMENT}: {cause.field}", cause.reason)
    reason = str(first["msg"])
    if first["type"] == "missing":
        reason = "is missing"
    elif first["type"] == "extra_forbidden":
        reason = "is not a key of the export format"
    elif first["type"] == "string_pattern_mismatch":
        pattern = str(first.get("ctx", {}).get("pattern", ""))
        reason = f"{str(first['input'])[:60]!r} is not {_PATTERNS.get(pattern, 'of the form ' + pattern)}"
    more = len(errors) - 1
    if more:
        reason += f" (and {more} more problem{'s' if more > 1 else ''})"
    return ImportRefusedError(f"{DOCUMENT}: {_where(tuple(first['loc']))}", reason)


def parse_document(data: bytes) -> ExportDocument:
    """Parse and check ``session.json``'s bytes; ImportRefusedError naming the field otherwise."""
    if len(data) > MAX_DOCUMENT_BYTES:
        raise ImportRefusedError(DOCUMENT, f"is over the {MAX_DOCUMENT_BYTES // 2**20} MiB limit")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ImportRefusedError(DOCUMENT, f"is not UTF-8 text (byte {exc.start})") from None
    if _NUL_ESCAPE.search(text):
        raise ImportRefusedError(DOCUMENT, "holds a NUL character (\\u0000), which the record cannot store")
    try:
        raw = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ImportRefusedError(
            DOCUMENT, f"is not valid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}"
        ) from None
    except RecursionError:
        raise ImportRefusedError(DOCUMENT, "is nested too deeply to be an export") from None
    if not isinstance(raw, dict):
        raise ImportRefusedError(DOCUMENT, "is not a JSON object")
    if raw.get("format") != FORMAT:
        raise ImportRefusedError(
            f"{DOCUMENT}: format", f"is not {FORMAT!r}: this is not a station session export"
        )
    if raw.get("format_version") != FORMAT_VERSION:
        raise ImportRefusedError(
            f"{DOCUMENT}: format_version",
            f"is {str(raw.get('format_version'))[:20]}; this station reads version {FORMAT_VERSION}: "
            "update the station software",
        )
    try:
        doc = ExportDocument.model_validate(raw)
    except ValidationError as exc:
        raise _refused(exc) from None
    _check_finite(doc)
    return doc


def _nonfinite(value: Any) -> tuple[int | str, ...] | None:
    """Where the first NaN or infinity in a JSON value is (keys and indices), or None; iterative."""
    stack: list[tuple[Any, tuple[int | str, ...]]] = [(value, ())]
    while stack:
        node, path = stack.pop()
        items = node.items() if type(node) is dict else enumerate(node)
        for key, v in items:
            kind = type(v)
            if kind is float:
                if not math.isfinite(v):
                    return (*path, key)
            elif kind is dict or kind is list:
                stack.append((v, (*path, key)))
    return None


def _check_finite(doc: ExportDocument) -> None:
    """JSON has no NaN or infinity (Python's writes them, and the record could not show them back)."""
    s = doc.session
    blobs: list[tuple[tuple[int | str, ...], Any]] = [
        (("session", name), getattr(s, name))
        for name in ("params", "config", "identities", "software", "results")
    ]
    blobs += [(("steps", i, "data"), st.data) for i, st in enumerate(doc.steps)]
    blobs += [(("events", i, "data"), e.data) for i, e in enumerate(doc.events)]
    blobs += [(("captures", i, "meta"), c.meta) for i, c in enumerate(doc.captures)]
    blobs += [(("measurements", i, "result"), m.result) for i, m in enumerate(doc.measurements)]
    for where, blob in blobs:
        if blob is not None and (found := _nonfinite(blob)) is not None:
            raise ImportRefusedError(
                f"{DOCUMENT}: {_where((*where, *found))}", "is NaN or infinite: not a number JSON allows"
            )
