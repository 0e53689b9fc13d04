"""Atomic writes and PNG encoding (photomodel.exchange.files).

PNG files are checked against the PNG specification (signature, IHDR fields, read with
:mod:`struct`) and decoded with Pillow, a decoder independent of the OpenCV one under test.
"""

from __future__ import annotations

import io
import os
import stat
import struct

import numpy as np
import pytest
from PIL import Image

from photomodel.exchange.files import atomic_write_bytes, decode_png, encode_png, write_files

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"  # PNG spec §5.2


def ihdr(png: bytes) -> tuple[int, int, int, int]:
    """(width, height, bit depth, colour type) from the IHDR chunk, which must come first."""
    assert png[:8] == PNG_SIGNATURE
    length, kind = struct.unpack(">I4s", png[8:16])
    assert (length, kind) == (13, b"IHDR")
    width, height, depth, colour = struct.unpack(">IIBB", png[16:26])
    return width, height, depth, colour


# ----------------------------------------------------------------------------- PNG


@pytest.mark.parametrize(("channels", "colour_type", "mode"), [(None, 0, "L"), (3, 2, "RGB"), (4, 6, "RGBA")])
def test_png_known_header_and_pixels(channels, colour_type, mode):
    rng = np.random.default_rng(channels or 1)
    shape = (2, 3) if channels is None else (2, 3, channels)  # 3 wide, 2 high
    img = rng.integers(0, 256, shape, dtype=np.uint8)
    png = encode_png(img)
    assert ihdr(png) == (3, 2, 8, colour_type)  # PNG colour types: 0 grey, 2 RGB, 6 RGBA
    pil = Image.open(io.BytesIO(png))
    assert pil.mode == mode
    np.testing.assert_array_equal(np.asarray(pil), img)  # row 0 on top, channels in RGB(A) order
    np.testing.assert_array_equal(decode_png(png), img)


def test_png_of_a_float_image_and_a_single_channel():
    # ×255, rounded half to even (0.5 → 127.5 → 128), clipped to [0, 1], NaN → 0
    img = np.array([[[0.0, 0.5, 1.0], [1.5, -0.2, np.nan]]])
    np.testing.assert_array_equal(np.asarray(Image.open(io.BytesIO(encode_png(img)))), [[[0, 128, 255], [255, 0, 0]]])
    assert ihdr(encode_png(np.zeros((4, 5, 1), np.uint8))) == (5, 4, 8, 0)  # (H, W, 1) is grey


def test_png_refuses_what_it_cannot_store():
    for bad in (np.zeros((2, 2, 2), np.uint8), np.zeros((0, 3), np.uint8), np.zeros(5, np.uint8)):
        with pytest.raises(ValueError, match="a PNG needs an"):
            encode_png(bad)
    with pytest.raises(ValueError, match="uint8 or float"):
        encode_png(np.zeros((2, 2), np.int32))
    with pytest.raises(ValueError, match="not a PNG"):
        decode_png(b"not an image at all")


# ----------------------------------------------------------------------------- atomic writes


def test_atomic_write_creates_folders_and_leaves_only_the_file(tmp_path):
    path = tmp_path / "a" / "b" / "out.bin"
    assert atomic_write_bytes(path, b"\x00\x01payload") == path
    assert path.read_bytes() == b"\x00\x01payload"
    assert sorted(p.name for p in path.parent.iterdir()) == ["out.bin"]  # no temporary left behind
    assert stat.S_IMODE(path.stat().st_mode) == 0o644  # an ordinary document, not mkstemp's 0600
    atomic_write_bytes(path, b"second")
    assert path.read_bytes() == b"second"
    assert sorted(p.name for p in path.parent.iterdir()) == ["out.bin"]


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path):
    path = tmp_path / "keep.txt"
    path.write_bytes(b"old")
    with pytest.raises(TypeError):
        atomic_write_bytes(path, "text, not bytes")  # fails inside the write
    assert path.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.txt"]


def test_write_files_in_the_given_order(tmp_path, monkeypatch):
    replaced = []
    real_replace = os.replace

    def recording_replace(src, dst):
        replaced.append(os.fspath(dst))
        real_replace(src, dst)

    monkeypatch.setattr(os, "replace", recording_replace)
    files = {tmp_path / "tex.png": b"1", tmp_path / "m.mtl": b"22", tmp_path / "m.obj": b"333"}
    assert write_files(files) == list(files)
    assert replaced == [os.fspath(p) for p in files]  # the referenced file before the one referring to it
    assert [p.read_bytes() for p in files] == [b"1", b"22", b"333"]
