"""Hostile input: an image file whose header claims a huge size is refused before
decoding (``localizer.image.io.read_image_grey``)."""
import struct
import zlib

import cv2
import numpy as np
import pytest

from localizer.image.io import MAX_IMAGE_PIXELS, PNG_END, image_size, read_image_grey


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def png_bomb(width: int, height: int) -> bytes:
    """A valid-looking 8-bit grey PNG header of ``width x height`` with one row of data."""
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    row = b"\x00" + bytes(width)  # filter byte + one row of zeros
    return b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr) + _chunk(b"IDAT", zlib.compress(row, 9)) + _chunk(b"IEND", b"")


def test_png_bomb_refused_before_decoding(tmp_path, monkeypatch):
    path = tmp_path / "bomb.png"
    path.write_bytes(png_bomb(60000, 60000))
    assert path.stat().st_size < 1000
    decoded = []
    monkeypatch.setattr(cv2, "imdecode", lambda *a: decoded.append(a))
    with pytest.raises(ValueError) as e:
        read_image_grey(path)
    msg = str(e.value)
    assert str(path) in msg and "60000 x 60000" in msg and f"{MAX_IMAGE_PIXELS:,}" in msg, msg
    assert decoded == []


def test_limit_is_a_parameter(tmp_path):
    path = tmp_path / "small.png"
    assert cv2.imwrite(str(path), np.zeros((40, 50), np.uint8))
    assert read_image_grey(path).shape == (40, 50)
    with pytest.raises(ValueError, match="50 x 40 pixels"):
        read_image_grey(path, max_pixels=1999)
    with pytest.raises(ValueError, match="max_pixels"):
        read_image_grey(path, max_pixels=0)


@pytest.mark.parametrize("ext, colour", [(e, c) for e in (".png", ".jpg", ".bmp", ".tif", ".webp")
                                          for c in (False, True)] + [(".pgm", False), (".ppm", True)])
def test_header_sizes_of_common_formats(tmp_path, ext, colour):
    img = (np.arange(37 * 53 * 3) % 251).astype(np.uint8).reshape(37, 53, 3)
    if not colour:
        img = img[:, :, 0].copy()
    path = tmp_path / f"frame{ext}"
    if not cv2.imwrite(str(path), img):
        pytest.skip(f"OpenCV cannot write {ext}")
    with open(path, "rb") as f:
        assert image_size(f) == (53, 37)
    grey = read_image_grey(path)
    assert grey.shape == (37, 53) and grey.dtype == np.uint8


def test_bad_files(tmp_path):
    with pytest.raises(ValueError, match="no such file"):
        read_image_grey(tmp_path / "none.png")
    with pytest.raises(ValueError, match="a folder"):
        read_image_grey(tmp_path)
    junk = tmp_path / "junk.png"
    junk.write_bytes(b"not an image at all")
    with pytest.raises(ValueError, match="cannot read the image size"):
        read_image_grey(junk)
    cut = tmp_path / "cut.png"
    cut.write_bytes(png_bomb(64, 64)[:40])  # header fine, data cut short
    with pytest.raises(ValueError, match="cut off; a PNG file ends with its IEND chunk"):
        read_image_grey(cut)
    broken = tmp_path / "broken.png"
    broken.write_bytes(png_bomb(64, 64)[:40] + PNG_END)  # ends as a PNG does, its data broken
    with pytest.raises(ValueError, match="not an image OpenCV can decode"):
        read_image_grey(broken)
    empty = tmp_path / "empty.jpg"
    empty.write_bytes(b"")
    with pytest.raises(ValueError, match="cannot read the image size"):
        read_image_grey(empty)


def test_jpeg_bomb_refused(tmp_path):
    # SOI, an APP0 segment, then a baseline SOF0 claiming 60000 x 60000
    sof = b"\xff\xc0" + struct.pack(">HBHHB", 11, 8, 60000, 60000, 1) + b"\x01\x11\x00"
    path = tmp_path / "bomb.jpg"
    path.write_bytes(b"\xff\xd8" + b"\xff\xe0" + struct.pack(">H", 16) + b"JFIF\x00" + bytes(9) + sof + b"\xff\xd9")
    with pytest.raises(ValueError, match="60000 x 60000 pixels"):
        read_image_grey(path)
