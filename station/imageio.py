"""The one front door for image files: every image the station measures is read through here.

The command line, the API's uploads and the record's re-analysis all call :func:`load_image` (a path)
or :func:`decode_image` (bytes already in memory). A hostile file cannot hang, exhaust memory or
crash the caller:

* only regular files are opened: FIFOs, devices and sockets are refused by ``stat`` before anything
  is opened or read (opening a FIFO blocks; reading ``/dev/zero`` never ends);
* a byte cap (64 MiB by default) is checked from ``stat`` and enforced by a bounded read;
* a pixel cap (50 Mpx by default) and a decoded-size cap (width x height x channels x bytes per
  sample, 256 MiB by default) are checked from the format's header before anything is decoded (a
  1.5 MB PNG can declare 40000 x 40000 pixels, or 7000 x 7000 of 16-bit colour: 280 MiB decoded);
  only formats whose header is parsed here are decoded: PNG, JPEG, TIFF, BMP and PGM/PPM;
* JPEG is decoded by libjpeg-turbo through ``simplejpeg`` in strict mode, which turns libjpeg's
  "Corrupt JPEG data" warnings into a per-call error (OpenCV only prints them on the process's
  stderr and returns the damaged image); the process's stderr is never redirected;
* every decoder error becomes an :class:`ImageFileError` naming the file and the cause.
"""

from __future__ import annotations

import errno
import os
import re
import stat
import struct
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
import simplejpeg

Image = npt.NDArray[np.uint8] | npt.NDArray[np.uint16]

#: Defaults of :class:`ImageLimits`.
DEFAULT_MAX_BYTES = 64 * 1024 * 1024
DEFAULT_MAX_PIXELS = 50_000_000
DEFAULT_MAX_DECODED_BYTES = 256 * 1024 * 1024
#: Output formats that keep every grey level (``station camera grab``).
LOSSLESS_SUFFIXES = (".png", ".tif", ".tiff")


class ImageFileError(ValueError):
    """An image file cannot be read; ``str()`` names the file and the cause, ``reason`` the cause."""

    code = "bad_file"

    def __init__(self, path: Path | str, reason: str) -> None:
        super().__init__(f"{path}: {reason}")
        self.path = path
        self.reason = reason


@dataclass(frozen=True)
class ImageLimits:
    """How large an image file may be: bytes on disk, pixels declared by its header, and the size of
    the decoded array its header implies (:attr:`ImageHeader.decoded_bytes`)."""

    max_bytes: int = DEFAULT_MAX_BYTES
    max_pixels: int = DEFAULT_MAX_PIXELS
    max_decoded_bytes: int = DEFAULT_MAX_DECODED_BYTES

    def __post_init__(self) -> None:
        if self.max_bytes < 1 or self.max_pixels < 1 or self.max_decoded_bytes < 1:
            raise ValueError(
                f"image limits must be positive, got {self.max_bytes} B, {self.max_pixels} px, "
                f"{self.max_decoded_bytes} B decoded"
            )


@dataclass(frozen=True)
class ImageHeader:
    """What a file's header declares: format, size (px), channels as decoded (a palette or a grey
    image with alpha decodes to 4), bits per sample, and the significant bits per sample where the
    format records them (PNG's sBIT chunk)."""

    format: str
    width: int
    height: int
    channels: int
    bits: int
    significant_bits: int | None = None

    @property
    def decoded_bytes(self) -> int:
        """The decoded array's size: width x height x channels x bytes per sample."""
        return self.width * self.height * self.channels * max(1, -(-self.bits // 8))


@dataclass(frozen=True)
class LoadedImage:
    """A decoded image as stored (8 or 16 bit, grey or colour) and its header."""

    image: Image
    header: ImageHeader

    @property
    def significant_bits(self) -> int | None:
        return self.header.significant_bits


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_END = b"IEND\xaeB`\x82"
_JPEG_START = b"\xff\xd8"
_JPEG_END = b"\xff\xd9"
_PNG_CHANNELS = {0: 1, 2: 3, 3: 4, 4: 4, 6: 4}  # as OpenCV decodes them: palette, grey+alpha -> BGRA
_FORMATS = "PNG, JPEG, TIFF, BMP, PGM/PPM"


def _mib(n: int) -> str:
    return f"{n / 2**20:.1f} MiB" if n >= 2**20 else f"{n} bytes"


def _kind(mode: int) -> str:
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def read_file_bytes(path: str | Path, *, max_bytes: int = DEFAULT_MAX_BYTES, what: str = "file") -> bytes:
    """The bytes of a regular file of at most ``max_bytes``; ImageFileError otherwise.

    ``stat`` decides before anything is opened: FIFOs, devices, sockets and directories are refused
    (opening a FIFO blocks until a writer comes; ``/dev/zero`` has no end). The file is then opened
    non-blocking, checked again (it may have been swapped) and read with a bound.
    """
    p = Path(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise ImageFileError(p, "no such file") from None
    except OSError as exc:
        raise ImageFileError(p, f"cannot be read: {exc.strerror or exc}") from None
    if stat.S_ISDIR(st.st_mode):
        raise ImageFileError(p, f"is a directory, not an {what}")
    if not stat.S_ISREG(st.st_mode):
        raise ImageFileError(p, f"is {_kind(st.st_mode)}, not a regular file: only {what}s are read")
    if st.st_size > max_bytes:
        raise ImageFileError(p, f"file is {_mib(st.st_size)}, over the {_mib(max_bytes)} limit")
    flags = os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(p, flags)
    except OSError as exc:
        raise ImageFileError(p, f"cannot be opened: {exc.strerror or exc}") from None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):  # replaced between stat and open
            raise ImageFileError(p, "is no longer a regular file")
        chunks = []
        left = max_bytes + 1
        while left > 0:
            chunk = os.read(fd, min(left, 1 << 20))
            if not chunk:
                break
            chunks.append(chunk)
            left -= len(chunk)
    except OSError as exc:
        if exc.errno == errno.EAGAIN:  # pragma: no cover - only non-regular files do this
            raise ImageFileError(p, "would block: not a regular file") from None
        raise ImageFileError(p, f"cannot be read: {exc.strerror or exc}") from None
    finally:
        os.close(fd)
    data = b"".join(chunks)
    if len(data) > max_bytes:
        raise ImageFileError(p, f"file grew beyond the {_mib(max_bytes)} limit while being read")
    return data


# ---------------------------------------------------------------------------------------- headers


def _png_header(data: bytes) -> ImageHeader:
    if len(data) < 33 or data[12:16] != b"IHDR":
        raise ValueError("PNG file has no IHDR header chunk")
    width, height, bits, colour = struct.unpack(">IIBB", data[16:26])
    if colour not in _PNG_CHANNELS or bits not in (1, 2, 4, 8, 16):
        raise ValueError(f"PNG header is invalid (colour type {colour}, bit depth {bits})")
    channels = _PNG_CHANNELS[colour]
    significant = None
    pos = 33
    while pos + 8 <= len(data):  # chunks before the image data: sBIT is one of them
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind = data[pos + 4 : pos + 8]
        if kind in (b"IDAT", b"IEND") or length > len(data):
            break
        if kind == b"sBIT" and bits == 16 and 1 <= length <= 4:
            values = data[pos + 8 : pos + 8 + length]
            if values and all(1 <= v <= 16 for v in values):
                significant = max(values)
        pos += 12 + length
    return ImageHeader("PNG", width, height, channels, bits, significant)


def _jpeg_header(data: bytes) -> ImageHeader:
    height, width, colorspace, _ = simplejpeg.decode_jpeg_header(data)
    channels = 1 if str(colorspace).lower() == "gray" else 3
    return ImageHeader("JPEG", int(width), int(height), channels, 8)


def _tiff_header(data: bytes) -> ImageHeader:
    order = "<" if data[:2] == b"II" else ">"
    if struct.unpack(order + "H", data[2:4])[0] != 42:
        raise ValueError("BigTIFF and other TIFF variants are not supported; save as classic TIFF or PNG")
    (ifd,) = struct.unpack(order + "I", data[4:8])
    if ifd + 2 > len(data):
        raise ValueError("TIFF file is truncated (no image directory)")
    (count,) = struct.unpack(order + "H", data[ifd : ifd + 2])
    tags: dict[int, tuple[int, int, bytes]] = {}
    for i in range(min(count, 512)):
        entry = data[ifd + 2 + 12 * i : ifd + 14 + 12 * i]
        if len(entry) < 12:
            raise ValueError("TIFF file is truncated (image directory cut short)")
        tag, kind, n = struct.unpack(order + "HHI", entry[:8])
        tags[tag] = (kind, n, entry[8:12])

    def first(tag: int, default: int | None = None) -> int:
        if tag not in tags:
            if default is None:
                raise ValueError(f"TIFF image directory lacks tag {tag}")
            return default
        kind, n, value = tags[tag]
        if kind == 3 and n <= 2:  # SHORT, stored in place
            return int(struct.unpack(order + "H", value[:2])[0])
        if kind == 4 and n == 1:  # LONG
            return int(struct.unpack(order + "I", value)[0])
        if kind == 3 and n > 0:  # SHORTs stored elsewhere: the first
            (offset,) = struct.unpack(order + "I", value)
            if offset + 2 <= len(data):
                return int(struct.unpack(order + "H", data[offset : offset + 2])[0])
        raise ValueError(f"TIFF tag {tag} has an unexpected type")

    width, height = first(256), first(257)
    samples = max(1, first(277, 1))
    return ImageHeader("TIFF", width, height, 4 if samples == 2 else samples, first(258, 1))


def _bmp_header(data: bytes) -> ImageHeader:
    if len(data) < 30:
        raise ValueError("BMP file is truncated (header cut short)")
    (dib,) = struct.unpack("<I", data[14:18])
    if dib == 12:
        width, height, _, bpp = struct.unpack("<HHHH", data[18:26])
    else:
        width, height, _, bpp = struct.unpack("<iiHH", data[18:30])
    channels = 4 if bpp == 32 else 3  # a palette decodes to BGR
    return ImageHeader("BMP", abs(width), abs(height), channels, 8)


def _pnm_header(data: bytes) -> ImageHeader:
    magic = data[1:2]
    tokens: list[bytes] = []
    pos = 2
    head = data[:4096]
    want = 2 if magic in (b"1", b"4") else 3
    while len(tokens) < want and pos < len(head):
        c = head[pos : pos + 1]
        if c == b"#":
            end = head.find(b"\n", pos)
            pos = len(head) if end < 0 else end + 1
        elif c.isspace():
            pos += 1
        else:
            start = pos
            while pos < len(head) and not head[pos : pos + 1].isspace() and head[pos : pos + 1] != b"#":
                pos += 1
            tokens.append(head[start:pos])
    if len(tokens) < want or not all(t.isdigit() for t in tokens):
        raise ValueError("PGM/PPM header is invalid (expected width, height and maximum value)")
    width, height = int(tokens[0]), int(tokens[1])
    maxval = int(tokens[2]) if want == 3 else 1
    if not 0 < maxval < 65536:
        raise ValueError(f"PGM/PPM maximum value {maxval} is outside 1-65535")
    return ImageHeader("PNM", width, height, 3 if magic in (b"3", b"6") else 1, 16 if maxval > 255 else 8)


def read_header(data: bytes) -> ImageHeader:
    """The header of an image in memory; ValueError for formats this door does not open."""
    if data.startswith(_PNG_SIGNATURE):
        return _png_header(data)
    if data.startswith(_JPEG_START):
        return _jpeg_header(data)
    if data[:4] in (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+"):
        return _tiff_header(data)
    if data.startswith(b"BM"):
        return _bmp_header(data)
    if len(data) > 2 and data[:1] == b"P" and data[1:2] in b"123456" and data[2:3].isspace():
        return _pnm_header(data)
    raise ValueError(f"not an image format the station reads ({_FORMATS})")


# ---------------------------------------------------------------------------------------- decoding


def _check_complete(name: Path | str, data: bytes) -> None:
    """Detect truncated PNG/JPEG files before decoding (decoders may return half an image)."""
    if data.startswith(_PNG_SIGNATURE) and not data.rstrip(b"\x00").endswith(_PNG_END):
        raise ImageFileError(name, "PNG file is truncated (no IEND chunk): copy it again from its source")
    if data.startswith(_JPEG_START) and _JPEG_END not in data[-64:]:
        raise ImageFileError(name, "JPEG file is truncated (no end-of-image marker)")


def _decode(data: bytes, header: ImageHeader) -> Image | None:
    if header.format == "JPEG":
        colorspace = "GRAY" if header.channels == 1 else "BGR"
        image: Image = simplejpeg.decode_jpeg(data, colorspace=colorspace, strict=True)
        return image[:, :, 0] if image.ndim == 3 and image.shape[2] == 1 else image
    return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)  # type: ignore[return-value]


def decode_image(
    data: bytes, *, name: Path | str = "<upload>", limits: ImageLimits | None = None
) -> LoadedImage:
    """Decode an image file's bytes, checking its header against ``limits`` first.

    Raises
    ------
    ImageFileError
        Empty, over the byte or pixel cap, truncated, corrupt, or not a format this door reads.
    """
    lim = limits or ImageLimits()
    if not data:
        raise ImageFileError(name, "file is empty (0 bytes)")
    if len(data) > lim.max_bytes:
        raise ImageFileError(name, f"file is {_mib(len(data))}, over the {_mib(lim.max_bytes)} limit")
    try:
        header = read_header(data)
    except (ValueError, struct.error) as exc:
        raise ImageFileError(name, f"not a readable image: {exc}") from None
    pixels = header.width * header.height
    if header.width < 1 or header.height < 1:
        raise ImageFileError(name, f"{header.format} header declares {header.width}x{header.height} px")
    if pixels > lim.max_pixels:
        raise ImageFileError(
            name,
            f"{header.format} header declares {header.width}x{header.height} px = {pixels / 1e6:.0f} Mpx, "
            f"over the {lim.max_pixels / 1e6:g} Mpx limit",
        )
    if header.decoded_bytes > lim.max_decoded_bytes:
        raise ImageFileError(
            name,
            f"{header.format} header declares {header.width}x{header.height} px x {header.channels} "
            f"channel(s) x {header.bits} bit = {_mib(header.decoded_bytes)} decoded, over the "
            f"{_mib(lim.max_decoded_bytes)} limit: send a smaller, grey or 8-bit image",
        )
    _check_complete(name, data)
    try:
        image = _decode(data, header)
    except (ValueError, cv2.error, MemoryError, OverflowError) as exc:
        detail = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
        detail = re.sub(r"^(.+?)\1+$", r"\1", detail)  # libjpeg repeats its message per warning
        raise ImageFileError(name, f"{header.format} data is corrupt or unreadable: {detail}") from None
    if image is None:
        raise ImageFileError(name, f"{header.format} data is corrupt or unreadable (the decoder gave up)")
    if image.size > lim.max_pixels * 4 or image.nbytes > lim.max_decoded_bytes:
        raise ImageFileError(name, "decoded image is larger than its header declared")
    return LoadedImage(image, header)


def load_image(path: str | Path, *, limits: ImageLimits | None = None) -> LoadedImage:
    """Read and decode one image file (see the module's docstring for what is refused)."""
    lim = limits or ImageLimits()
    p = Path(path)
    return decode_image(read_file_bytes(p, max_bytes=lim.max_bytes, what="image file"), name=p, limits=lim)


def read_image(path: str | Path, *, limits: ImageLimits | None = None) -> Image:
    """Read an image file as stored (8 or 16 bit, grey or colour); conversion is the core's job.

    Raises
    ------
    ImageFileError
        Missing, not a regular file, empty, too large, truncated, corrupt, or not a supported format.
    """
    return load_image(path, limits=limits).image


def check_output_path(path: str | Path) -> Path:
    """Check, before anything is captured, that a lossless image can be written at ``path``.

    Raises ImageFileError when the suffix is not PNG or TIFF, the directory is missing or not
    writable, or ``path`` is a directory, FIFO or socket.
    """
    p = Path(path)
    if p.suffix.lower() not in LOSSLESS_SUFFIXES:
        raise ImageFileError(
            p, f"{p.suffix or 'no suffix'!s} is not a lossless format: name the file .png, .tif or .tiff"
        )
    parent = p.parent
    if not parent.is_dir():
        raise ImageFileError(p, f"the directory {parent} does not exist: create it first")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ImageFileError(p, f"the directory {parent} is not writable")
    try:
        st = os.stat(p)
    except FileNotFoundError:
        return p
    except OSError as exc:
        raise ImageFileError(p, f"cannot be written: {exc.strerror or exc}") from None
    if stat.S_ISDIR(st.st_mode) or stat.S_ISFIFO(st.st_mode) or stat.S_ISSOCK(st.st_mode):
        raise ImageFileError(p, f"is {'a directory' if stat.S_ISDIR(st.st_mode) else _kind(st.st_mode)}")
    if not os.access(p, os.W_OK):
        raise ImageFileError(p, "exists and is not writable")
    return p


def write_image(path: str | Path, image: Image) -> Path:
    """Write ``image`` losslessly (PNG by default); raises ImageFileError when it cannot."""
    p = Path(path)
    try:
        ok, buf = cv2.imencode(p.suffix or ".png", image)
    except cv2.error:
        ok = False
    if not ok:
        raise ImageFileError(p, f"OpenCV cannot encode an image as {p.suffix!r}")
    try:
        with open(p, "wb") as f:
            f.write(buf.tobytes())
    except OSError as exc:
        if p.is_file() and not p.is_symlink():  # a half-written image is worse than none
            p.unlink(missing_ok=True)
        raise ImageFileError(p, f"cannot be written: {exc.strerror or exc}") from None
    return p
