"""mobmap.frames reads 16-bit depth PNGs exactly: each of PNG's five row filters, encoded
here from a known image, decodes to that image."""

import struct
import zlib

import numpy as np
import pytest

from mobmap.frames import read_depth_png


def paeth(a, b, c):
    p = a + b - c
    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
    return a if pa <= pb and pa <= pc else b if pb <= pc else c


def encode(image, filters):
    """A PNG of a uint16 image whose row r uses filter filters[r % len(filters)]."""
    h, w = image.shape
    raw = image.astype(">u2").tobytes()
    stride, out, prev = 2 * w, bytearray(), bytes(2 * w)
    for r in range(h):
        row, f = raw[r * stride:(r + 1) * stride], filters[r % len(filters)]
        enc = bytearray()
        for i in range(stride):
            a = row[i - 2] if i >= 2 else 0
            b, c = prev[i], prev[i - 2] if i >= 2 else 0
            pred = [0, a, b, (a + b) // 2, paeth(a, b, c)][f]
            enc.append((row[i] - pred) & 0xFF)
        out += bytes([f]) + enc
        prev = row

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, 0, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(bytes(out))) + chunk(b"IEND", b""))


def test_every_row_filter_decodes_to_the_image(tmp_path):
    rng = np.random.default_rng(7)
    image = rng.integers(0, 65536, size=(12, 9), dtype=np.uint16)
    image[3] = 65535
    image[4] = 0
    for filters in ([0], [1], [2], [3], [4], [0, 1, 2, 3, 4]):
        path = tmp_path / f"f{''.join(map(str, filters))}.png"
        path.write_bytes(encode(image, filters))
        np.testing.assert_array_equal(read_depth_png(path), image)


def test_other_files_are_value_errors(tmp_path):
    (tmp_path / "text.png").write_text("not a png")
    with pytest.raises(ValueError, match="not a PNG"):
        read_depth_png(tmp_path / "text.png")
    png = encode(np.zeros((4, 4), dtype=np.uint16), [0])
    (tmp_path / "cut.png").write_bytes(png[:-30])
    with pytest.raises(ValueError, match="cut short"):
        read_depth_png(tmp_path / "cut.png")
