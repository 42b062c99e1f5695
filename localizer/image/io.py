"""Reading a camera frame from an image file, refusing decompression bombs before decoding.

A PNG of 60,000 x 60,000 pixels with one row of data is a few hundred bytes on disk, and
decoding it asks for 3.6 GB (10.8 GB in colour). OpenCV has no header-only call in Python,
and its own limit (the environment variable ``OPENCV_IO_MAX_IMAGE_PIXELS``, default 2^30
pixels) is read once when OpenCV loads and is far above any camera frame. So
:func:`image_size` reads the size from the file's header itself -- PNG (IHDR), JPEG (SOF
segment), BMP, TIFF (first IFD, classic and BigTIFF), WebP (VP8, VP8L, VP8X) and the
Netpbm formats (PBM, PGM, PPM, PAM) -- and :func:`read_image_grey` refuses a file whose
size is unknown or above :data:`MAX_IMAGE_PIXELS` before OpenCV decodes it.
"""
from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np

from localizer.numeric import check_number

__all__ = ["FORMATS", "MAX_IMAGE_PIXELS", "PNG_END", "PNG_SIGNATURE", "image_size", "read_image_grey"]

#: the most pixels (width x height) :func:`read_image_grey` decodes by default: 64 Mpx
#: (8192 x 8192; 64 MB as 8-bit grey, 192 MB while OpenCV decodes a colour file). Camera
#: frames are a few Mpx (2048 x 1920 is 3.9 Mpx).
MAX_IMAGE_PIXELS = 64 * 1024 * 1024
#: the formats whose size :func:`image_size` reads from the header
FORMATS = ("PNG", "JPEG", "BMP", "TIFF", "WebP", "PBM/PGM/PPM/PAM")
#: bytes read for the header of the formats other than JPEG and TIFF (whose headers are
#: found by seeking through the file)
_HEAD = 64 * 1024


#: the first 8 bytes of every PNG file, and its last 12: the IEND chunk (length 0, type, CRC)
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"


def read_image_grey(path: str | os.PathLike, max_pixels: int = MAX_IMAGE_PIXELS) -> np.ndarray:
    """The image file ``path`` as an ``(H, W)`` uint8 grey array, or one ``ValueError``
    naming the file and why not: no such file, a folder, unreadable, a format whose size
    cannot be read from its header (:data:`FORMATS`), more than ``max_pixels`` pixels
    (:data:`MAX_IMAGE_PIXELS`; refused before decoding), or not decodable by OpenCV.

    Colour files are converted to grey by OpenCV (``IMREAD_GRAYSCALE``; 16-bit ones scaled to
    8 bits)."""
    max_pixels = check_number("read_image_grey max_pixels", max_pixels, low=1, integer=True, unit="pixels")
    name = os.fspath(path)
    p = Path(name)
    if p.is_dir():
        raise ValueError(f"{name}: a folder, expected an image file")
    if not p.exists():
        raise ValueError(f"{name}: no such file")
    try:
        with open(p, "rb") as f:
            size = image_size(f)
    except OSError as exc:
        raise ValueError(f"{name}: cannot read ({exc.strerror or exc})") from None
    if size is None:
        raise ValueError(f"{name}: cannot read the image size from its header; expected one of "
                         f"{', '.join(FORMATS)} (the size is checked before decoding)")
    w, h = size
    if w <= 0 or h <= 0:
        raise ValueError(f"{name}: the header gives an empty image ({w} x {h} pixels)")
    if w * h > max_pixels:
        raise ValueError(f"{name}: {w} x {h} pixels ({w * h:,}) is more than the limit of {max_pixels:,} "
                         f"pixels (localizer.image.io.MAX_IMAGE_PIXELS); not decoded")
    import cv2

    try:
        data = np.fromfile(p, dtype=np.uint8)
    except OSError as exc:
        raise ValueError(f"{name}: cannot read ({exc.strerror or exc})") from None
    if data[:8].tobytes() == PNG_SIGNATURE and data[-12:].tobytes() != PNG_END:
        # (a PNG cut short: refused here, before libpng writes its own complaint on stderr)
        raise ValueError(f"{name}: cut off; a PNG file ends with its IEND chunk and this one's {data.size:,} bytes "
                         f"do not (its header says {w} x {h} pixels)")
    img = cv2.imdecode(data, cv2.IMREAD_GRAYSCALE) if data.size else None
    if img is None:
        raise ValueError(f"{name}: not an image OpenCV can decode (its header says {w} x {h} pixels)")
    if img.ndim != 2 or img.dtype != np.uint8 or img.size > max_pixels:  # pragma: no cover - belt and braces
        raise ValueError(f"{name}: decoded to {img.dtype} {img.shape}, expected a uint8 grey image of at most "
                         f"{max_pixels:,} pixels")
    return img


def image_size(f) -> tuple[int, int] | None:
    """``(width, height)`` in pixels from the header of the image file open for binary reading
    as ``f`` (seekable), or None if it is not one of :data:`FORMATS` or its header is cut short."""
    f.seek(0)
    head = f.read(_HEAD)
    try:
        if head.startswith(b"\x89PNG\r\n\x1a\n"):
            if head[12:16] != b"IHDR":
                return None
            return struct.unpack(">II", head[16:24])
        if head.startswith(b"\xff\xd8"):
            return _jpeg_size(f)
        if head.startswith(b"BM"):
            (hsize,) = struct.unpack("<I", head[14:18])
            if hsize == 12:  # BITMAPCOREHEADER
                return struct.unpack("<HH", head[18:22])
            w, h = struct.unpack("<ii", head[18:26])
            return w, abs(h)  # negative height: rows top-down
        if head[:4] in (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+"):
            return _tiff_size(f, head)
        if head[:4] == b"RIFF" and head[8:12] == b"WEBP":
            return _webp_size(head)
        if head[:1] == b"P" and head[1:2] in b"1234567" and len(head) > 2:
            return _pnm_size(head)
    except (struct.error, IndexError, ValueError):
        return None
    return None


#: JPEG start-of-frame markers (baseline, progressive, lossless, arithmetic...): not C4
#: (Huffman tables), C8 (reserved) or CC (arithmetic conditioning)
_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}


def _jpeg_size(f) -> tuple[int, int] | None:
    """The size in the first SOF segment, walking the segments from the SOI marker."""
    f.seek(2)
    while True:
        b = f.read(1)
        if not b:
            return None
        if b != b"\xff":
            return None  # not at a marker: corrupt
        m = f.read(1)
        while m == b"\xff":  # fill bytes
            m = f.read(1)
        if not m:
            return None
        marker = m[0]
        if marker == 0x01 or 0xD0 <= marker <= 0xD8:  # standalone markers
            continue
        if marker == 0xD9:  # EOI before any frame
            return None
        seg = f.read(2)
        if len(seg) < 2:
            return None
        (length,) = struct.unpack(">H", seg)
        if length < 2:
            return None
        if marker in _SOF:
            body = f.read(5)
            if len(body) < 5:
                return None
            h, w = struct.unpack(">HH", body[1:5])
            if h == 0:  # height given later (DNL): OpenCV cannot decode it
                return None
            return w, h
        f.seek(length - 2, os.SEEK_CUR)


def _tiff_size(f, head: bytes) -> tuple[int, int] | None:
    """ImageWidth (256) and ImageLength (257) of the first IFD (what OpenCV decodes)."""
    e = "<" if head[:2] == b"II" else ">"
    big = head[2:4] in (b"+\x00", b"\x00+")
    if big:
        (off,) = struct.unpack(e + "Q", head[8:16])
        cnt_fmt, cnt_size, entry = "Q", 8, 20
    else:
        (off,) = struct.unpack(e + "I", head[4:8])
        cnt_fmt, cnt_size, entry = "H", 2, 12
    f.seek(off)
    raw = f.read(cnt_size)
    if len(raw) < cnt_size:
        return None
    (n,) = struct.unpack(e + cnt_fmt, raw)
    if n > 4096:
        return None
    table = f.read(n * entry)
    if len(table) < n * entry:
        return None
    size = {}
    for k in range(n):
        ent = table[k * entry:(k + 1) * entry]
        tag, typ = struct.unpack(e + "HH", ent[:4])
        if tag not in (256, 257):
            continue
        val = ent[12:] if big else ent[8:]
        if typ == 3:  # SHORT
            (v,) = struct.unpack(e + "H", val[:2])
        elif typ == 4:  # LONG
            (v,) = struct.unpack(e + "I", val[:4])
        elif typ == 16 and big:  # LONG8
            (v,) = struct.unpack(e + "Q", val[:8])
        else:
            return None
        size[tag] = v
    if 256 not in size or 257 not in size:
        return None
    return size[256], size[257]


def _webp_size(head: bytes) -> tuple[int, int] | None:
    kind, data = head[12:16], head[20:]
    if kind == b"VP8 ":
        if data[3:6] != b"\x9d\x01\x2a":
            return None
        w, h = struct.unpack("<HH", data[6:10])
        return w & 0x3FFF, h & 0x3FFF
    if kind == b"VP8L":
        if data[:1] != b"\x2f":
            return None
        (bits,) = struct.unpack("<I", data[1:5])
        return (bits & 0x3FFF) + 1, ((bits >> 14) & 0x3FFF) + 1
    if kind == b"VP8X":
        w = int.from_bytes(data[4:7], "little") + 1
        h = int.from_bytes(data[7:10], "little") + 1
        return w, h
    return None


def _pnm_size(head: bytes) -> tuple[int, int] | None:
    """Width and height of a Netpbm header: ``P1``-``P6`` (whitespace-separated tokens,
    ``#`` comments to the end of a line) or ``P7`` (PAM: ``WIDTH`` and ``HEIGHT`` lines)."""
    if head[1:2] == b"7":
        fields = {}
        for line in head[3:].split(b"\n"):
            parts = line.split(b"#")[0].split()
            if parts and parts[0] == b"ENDHDR":
                break
            if len(parts) == 2:
                fields[parts[0]] = parts[1]
        if b"WIDTH" not in fields or b"HEIGHT" not in fields:
            return None
        return int(fields[b"WIDTH"]), int(fields[b"HEIGHT"])
    tokens: list[bytes] = []
    text = head[2:]
    i = 0
    while len(tokens) < 2 and i < len(text):
        c = text[i:i + 1]
        if c == b"#":
            j = text.find(b"\n", i)
            if j < 0:
                return None
            i = j + 1
        elif c.isspace():
            i += 1
        else:
            j = i
            while j < len(text) and not text[j:j + 1].isspace() and text[j:j + 1] != b"#":
                j += 1
            tokens.append(text[i:j])
            i = j
    if len(tokens) < 2:
        return None
    return int(tokens[0]), int(tokens[1])
