"""Where an import reads an export from: a folder (``station export``'s) or a zip archive (``export.zip``,
or a zipped folder). Both are untrusted; each gives the same two reads, bounded and checked:
``document()`` (``session.json``'s bytes) and ``file(path, field)`` (a capture's image bytes).

A folder is read without following symbolic links: each part of a capture's path is opened relative
to its parent's descriptor with ``O_NOFOLLOW`` (a link anywhere is refused, nothing outside the
folder is reachable), and only regular files are read, up to a cap checked on the open descriptor.

A zip archive's central directory is sized from its end record before it is parsed (entry count and
directory size capped); every entry name is checked (relative, no ``..``, no backslash, no drive, no
NUL, unique) and links and devices are refused, whether read or not; the declared sizes are capped in
total, and each entry read must give exactly its declared size (and CRC). Nothing is extracted: the
bytes go to the importer, which checks them before writing them into its staging directory.
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import struct
import zipfile
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import BinaryIO, Protocol, Self

from station.record._errors import ArchiveRefusedError, ImportRefusedError
from station.record._format import DOCUMENT, MAX_DOCUMENT_BYTES

_READ_FLAGS = os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_NOCTTY | os.O_CLOEXEC
_DIR_FLAGS = os.O_RDONLY | os.O_NOFOLLOW | os.O_DIRECTORY | os.O_CLOEXEC


class ExportSource(Protocol):
    """An export to import: its document and its files, read with bounds (see the module notes)."""

    name: str

    def document(self) -> bytes:
        """``session.json``'s bytes."""
        ...

    def file(self, path: str, field: str, *, max_bytes: int) -> bytes:
        """The bytes of the file at ``path`` (relative, ``/``-separated); ``field`` names it in a refusal."""
        ...

    def check_rest(self) -> None:
        """Check what was not read (a zip's other entries: sizes and CRC), before anything is kept."""
        ...

    def close(self) -> None: ...


def _mib(n: int) -> str:
    return f"{n / 2**20:.1f} MiB"


def _read_fd(fd: int, field: str, what: str, max_bytes: int) -> bytes:
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode):
        raise ImportRefusedError(field, f"{what} is not a regular file")
    if st.st_size > max_bytes:
        raise ImportRefusedError(field, f"{what} is {_mib(st.st_size)}, over the {_mib(max_bytes)} limit")
    chunks = []
    left = max_bytes + 1
    while left > 0:
        chunk = os.read(fd, min(left, 1 << 20))
        if not chunk:
            break
        chunks.append(chunk)
        left -= len(chunk)
    data = b"".join(chunks)
    if len(data) > max_bytes:
        raise ImportRefusedError(field, f"{what} grew beyond the {_mib(max_bytes)} limit while being read")
    return data


class FolderSource:
    """An export folder (``OUT/<id>/`` of ``station export``), read without following links."""

    def __init__(self, folder: Path) -> None:
        self.name = str(folder)
        try:
            self._fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
        except FileNotFoundError:
            raise ImportRefusedError(str(folder), "no such folder") from None
        except NotADirectoryError:
            raise ImportRefusedError(str(folder), "is not a folder") from None
        except OSError as exc:
            raise ImportRefusedError(str(folder), f"cannot be opened: {exc.strerror}") from None

    def _open(self, parts: list[str], field: str, what: str) -> int:
        fd = self._fd
        opened: list[int] = []
        try:
            for i, part in enumerate(parts):
                last = i == len(parts) - 1
                try:
                    fd = os.open(part, _READ_FLAGS if last else _DIR_FLAGS, dir_fd=fd)
                except OSError as exc:
                    raise ImportRefusedError(
                        field, _open_failure(exc, what, "/".join(parts[: i + 1]))
                    ) from None
                opened.append(fd)
            return opened.pop()
        finally:
            for d in opened:
                os.close(d)

    def _read(self, path: str, field: str, what: str, max_bytes: int) -> bytes:
        parts = path.split("/")
        if not path or any(p in ("", ".", "..") for p in parts) or "\x00" in path:
            raise ImportRefusedError(field, f"{path[:80]!r} is not a relative path inside the folder")
        fd = self._open(parts, field, what)
        try:
            return _read_fd(fd, field, what, max_bytes)
        finally:
            os.close(fd)

    def document(self) -> bytes:
        try:
            fd = os.open(DOCUMENT, _READ_FLAGS, dir_fd=self._fd)
        except FileNotFoundError:
            raise ImportRefusedError(self.name, f"is not an exported session: it has no {DOCUMENT}") from None
        except OSError as exc:
            raise ImportRefusedError(DOCUMENT, _open_failure(exc, DOCUMENT, DOCUMENT)) from None
        try:
            return _read_fd(fd, DOCUMENT, f"{self.name}/{DOCUMENT}", MAX_DOCUMENT_BYTES)
        finally:
            os.close(fd)

    def file(self, path: str, field: str, *, max_bytes: int) -> bytes:
        return self._read(path, field, path, max_bytes)

    def check_rest(self) -> None:
        """Nothing to check: a folder's other files are never read."""

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _open_failure(exc: OSError, what: str, part: str) -> str:
    if exc.errno == errno.ENOENT:
        return f"{what} is not in the folder ({part} is missing)"
    if exc.errno in (errno.ELOOP, errno.EMLINK):
        return f"{part} is a symbolic link: an export holds its files themselves"
    if exc.errno == errno.ENOTDIR:
        return f"{part} is not a folder (or is a symbolic link)"
    return f"{what} cannot be opened: {exc.strerror}"


@dataclass(frozen=True)
class ArchiveLimits:
    """What a zip upload may hold: entries, their declared total size, the central directory's size."""

    max_entries: int = 100_000
    max_total_bytes: int = 2 * 1024**3
    max_directory_bytes: int = 64 * 1024**2


_EOCD = struct.Struct("<4s4H2LH")
_ZIP64_LOCATOR = struct.Struct("<4sLQL")
_ZIP64_EOCD = struct.Struct("<4sQ2H2L4Q")


def _directory_size(f: BinaryIO) -> tuple[int, int]:
    """(entries, central directory bytes) from the archive's end records, read before zipfile parses
    the directory (whose size bounds the memory it takes)."""
    f.seek(0, os.SEEK_END)
    size = f.tell()
    tail_len = min(size, _EOCD.size + 65535)
    f.seek(size - tail_len)
    tail = f.read(tail_len)
    at = tail.rfind(b"PK\x05\x06")
    if at < 0 or len(tail) - at < _EOCD.size:
        raise ArchiveRefusedError("archive", "is not a zip archive (it has no end of central directory)")
    _, _, _, _, entries, dir_size, dir_offset, _ = _EOCD.unpack(tail[at : at + _EOCD.size])
    if entries != 0xFFFF and dir_size != 0xFFFFFFFF and dir_offset != 0xFFFFFFFF:
        return entries, dir_size
    locator_at = size - tail_len + at - _ZIP64_LOCATOR.size
    record_at = locator_at - _ZIP64_EOCD.size
    if record_at < 0:
        raise ArchiveRefusedError("archive", "its zip64 end records are missing")
    f.seek(record_at)
    head = f.read(_ZIP64_EOCD.size + _ZIP64_LOCATOR.size)
    record, locator = head[: _ZIP64_EOCD.size], head[_ZIP64_EOCD.size :]
    if locator[:4] != b"PK\x06\x07" or record[:4] != b"PK\x06\x06":
        raise ArchiveRefusedError("archive", "its zip64 end records are not where the zip format puts them")
    fields = _ZIP64_EOCD.unpack(record)
    return fields[7], fields[8]


def _check_name(info: zipfile.ZipInfo) -> None:
    name = info.filename
    field = f"archive entry {name[:80]!r}"
    parts = name.rstrip("/").split("/")
    if (
        not name
        or name.startswith("/")
        or "\\" in name
        or "\x00" in name
        or (len(name) > 1 and name[1] == ":")
        or any(p in ("", ".", "..") for p in parts)
    ):
        raise ArchiveRefusedError(field, "is not a plain relative path (absolute, '..', '\\' or a drive)")
    mode = info.external_attr >> 16
    if info.create_system == 3 and mode and stat.S_IFMT(mode) not in (0, stat.S_IFREG, stat.S_IFDIR):
        kind = "a symbolic link" if stat.S_ISLNK(mode) else "not a regular file"
        raise ArchiveRefusedError(field, f"is {kind}: an export holds its files themselves")
    if info.flag_bits & 0x1:
        raise ArchiveRefusedError(field, "is encrypted")
    if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
        raise ArchiveRefusedError(field, "uses a compression method other than stored or deflated")


class ZipSource:
    """A zip archive holding one export (``<id>/session.json`` and ``<id>/images/...``, or the same at
    the top level)."""

    def __init__(
        self,
        file: BinaryIO,
        *,
        limits: ArchiveLimits | None = None,
        name: str = "archive",
        owned: BinaryIO | None = None,
    ) -> None:
        self.name = name
        self._owned = owned
        lim = limits or ArchiveLimits()
        entries, dir_size = _directory_size(file)
        if entries > lim.max_entries:
            raise ArchiveRefusedError("archive", f"has {entries} entries, over the {lim.max_entries} limit")
        if dir_size > lim.max_directory_bytes:
            raise ArchiveRefusedError(
                "archive",
                f"its central directory is {_mib(dir_size)}, over the {_mib(lim.max_directory_bytes)} limit",
            )
        file.seek(0)
        try:
            self._zip = zipfile.ZipFile(file)
        except (
            zipfile.BadZipFile,
            zipfile.LargeZipFile,
            EOFError,
            OSError,
            ValueError,
            struct.error,
            NotImplementedError,
            KeyError,
            IndexError,
        ) as exc:
            raise ArchiveRefusedError("archive", f"is not a readable zip archive: {exc}") from None
        try:
            self._entries = self._index(lim)
            documents = [n for n in self._entries if n.rsplit("/", 1)[-1] == DOCUMENT and n.count("/") <= 1]
            if len(documents) != 1:
                raise ArchiveRefusedError(
                    "archive", f"must hold one exported session (one {DOCUMENT}), found {len(documents)}"
                )
            self._root = documents[0][: -len(DOCUMENT)]
            self._read_names: set[str] = set()
        except BaseException:
            self._zip.close()
            raise

    def _index(self, lim: ArchiveLimits) -> dict[str, zipfile.ZipInfo]:
        infos = self._zip.infolist()
        if len(infos) > lim.max_entries:
            raise ArchiveRefusedError(
                "archive", f"has {len(infos)} entries, over the {lim.max_entries} limit"
            )
        entries: dict[str, zipfile.ZipInfo] = {}
        total = 0
        for info in infos:
            _check_name(info)
            if info.filename in entries:
                raise ArchiveRefusedError(f"archive entry {info.filename[:80]!r}", "appears twice")
            entries[info.filename] = info
            total += info.file_size
            if total > lim.max_total_bytes:
                raise ArchiveRefusedError(
                    "archive", f"declares more than {_mib(lim.max_total_bytes)} of content, over the limit"
                )
        return entries

    def _stream(self, info: zipfile.ZipInfo) -> Iterator[bytes]:
        """The entry's bytes in chunks, its declared size and CRC checked (ArchiveRefusedError)."""
        name = info.filename
        size = 0
        try:
            with self._zip.open(info) as f:
                while chunk := f.read(min(1 << 20, info.file_size - size + 1)):
                    size += len(chunk)
                    if size > info.file_size:
                        break
                    yield chunk
        except (zipfile.BadZipFile, EOFError, zlib.error, OSError, ValueError, NotImplementedError) as exc:
            raise ArchiveRefusedError(f"archive entry {name[:80]!r}", f"cannot be read: {exc}") from None
        if size != info.file_size:
            raise ArchiveRefusedError(
                f"archive entry {name[:80]!r}", f"declares {info.file_size} bytes but holds {size} or more"
            )

    def check_rest(self) -> None:
        for name, info in self._entries.items():
            if name not in self._read_names and not info.is_dir():
                for _ in self._stream(info):
                    pass

    def _read(self, name: str, field: str, max_bytes: int) -> bytes:
        info = self._entries.get(name)
        if info is None or info.is_dir():
            raise ImportRefusedError(field, f"{name[len(self._root) :][:80]!r} is not in the archive")
        if info.file_size > max_bytes:
            raise ImportRefusedError(
                field, f"{name[:80]!r} declares {_mib(info.file_size)}, over the {_mib(max_bytes)} limit"
            )
        data = b"".join(self._stream(info))
        self._read_names.add(name)
        return data

    def document(self) -> bytes:
        return self._read(self._root + DOCUMENT, DOCUMENT, MAX_DOCUMENT_BYTES)

    def file(self, path: str, field: str, *, max_bytes: int) -> bytes:
        return self._read(self._root + path, field, max_bytes)

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self._zip.close()
        if self._owned is not None:
            self._owned.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


def open_source(path: Path) -> FolderSource | ZipSource:
    """An export folder, or a zip file of one."""
    if path.is_dir():
        return FolderSource(path)
    try:
        f = path.open("rb")
    except FileNotFoundError:
        raise ImportRefusedError(str(path), "no such folder or zip file") from None
    except OSError as exc:
        raise ImportRefusedError(str(path), f"cannot be opened: {exc.strerror}") from None
    try:
        return ZipSource(f, name=str(path), owned=f)
    except BaseException:
        f.close()
        raise
