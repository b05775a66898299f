"""What export and import need of the record, as a Protocol: they take the record without importing its
module (``_record.py`` imports them), so the package has no import cycle."""

from __future__ import annotations

from contextlib import AbstractContextManager
from pathlib import Path
from typing import Protocol

import sqlalchemy as sa

from station.record._rows import SessionRow


class RecordLike(Protocol):
    """The record's parts that ``_export.py`` and ``_import.py`` use (``station.record.Record``)."""

    @property
    def data_dir(self) -> Path: ...

    @property
    def url(self) -> str: ...

    @property
    def engine(self) -> sa.Engine: ...

    @property
    def read_only(self) -> bool: ...

    def get_session(self, id_or_prefix: str) -> SessionRow: ...

    def _read(self) -> AbstractContextManager[sa.Connection]: ...

    def _write(self) -> AbstractContextManager[sa.Connection]: ...
