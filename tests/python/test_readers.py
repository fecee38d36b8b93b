"""mobmap.open_recording reads folders and files as `mobmap build` does: 16-bit depth PNGs
(each of PNG's five row filters, encoded here from a known image), TUM RGB-D folders and
.pcd clouds, written here by hand."""

import struct
import zlib

import numpy as np
import pytest

import mobmap


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


def metres(mm):
    """What a 16-bit depth PNG's millimetres read as: float32 metres, 0 for 0 and 65535."""
    return np.where((mm == 0) | (mm == 65535), np.float32(0), mm.astype(np.float32) * np.float32(1e-3))


def test_every_row_filter_decodes_to_the_image(tmp_path):
    rng = np.random.default_rng(7)
    image = rng.integers(0, 65536, size=(12, 9), dtype=np.uint16)
    image[3] = 65535
    image[4] = 0
    for filters in ([0], [1], [2], [3], [4], [0, 1, 2, 3, 4]):
        path = tmp_path / f"f{''.join(map(str, filters))}.png"
        path.write_bytes(encode(image, filters))
        rec = mobmap.open_recording(str(path), intrinsics=(10.0, 10.0, 4.5, 6.0))
        assert rec.format == "depth PNG" and not rec.posed and rec.frames == [0]
        (frame,) = list(rec)
        assert frame["pose"] is None and frame["stamp"] is None
        assert frame["intrinsics"] == (10.0, 10.0, 4.5, 6.0)
        np.testing.assert_array_equal(frame["depth"], metres(image))


def test_other_files_are_recording_errors(tmp_path):
    (tmp_path / "text.png").write_text("not a png")
    with pytest.raises(mobmap.RecordingError, match="text.png: not a PNG"):
        mobmap.open_recording(str(tmp_path / "text.png"), intrinsics=(10.0, 10.0, 2.0, 2.0))
    png = encode(np.zeros((4, 4), dtype=np.uint16), [0])
    (tmp_path / "cut.png").write_bytes(png[:-30])
    with pytest.raises(mobmap.RecordingError, match="cut.png"):
        mobmap.open_recording(str(tmp_path / "cut.png"), intrinsics=(10.0, 10.0, 2.0, 2.0))
    with pytest.raises(ValueError, match="^`intrinsics` .* is needed for a depth PNG"):
        mobmap.open_recording(str(tmp_path / "cut.png"))
    with pytest.raises(ValueError, match="intrinsics"):
        mobmap.open_recording(str(tmp_path / "text.png"), intrinsics=(10.0, 10.0, 2.0))


def quaternion_matrix(qx, qy, qz, qw):
    return np.array([[1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
                     [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
                     [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)]])


def test_a_tum_folder_gives_depth_at_5000_per_metre_stamps_and_poses(tmp_path):
    """TUM RGB-D: depth.txt lists the images by time, groundtruth.txt the poses; a depth
    image takes the pose interpolated at its stamp, and one with none near is left out."""
    rng = np.random.default_rng(3)
    images = [rng.integers(1, 40000, size=(6, 8), dtype=np.uint16) for _ in range(3)]
    (tmp_path / "depth").mkdir()
    lines = []
    for i, (t, image) in enumerate(zip([10.0, 10.5, 20.0], images)):
        name = f"depth/{t:.6f}.png"
        (tmp_path / name).write_bytes(encode(image, [i % 5]))
        lines.append(f"{t:.6f} {name}")
    (tmp_path / "depth.txt").write_text("# depth maps\n" + "\n".join(lines) + "\n")
    s = np.sqrt(0.5)
    (tmp_path / "groundtruth.txt").write_text(
        "# timestamp tx ty tz qx qy qz qw\n"
        "9.9 1.0 2.0 3.0 0 0 0 1\n"
        "10.1 1.2 2.0 3.0 0 0 0 1\n"
        "10.49 0.0 0.0 1.0 0 0 %.17g %.17g\n"
        "10.51 0.0 0.0 1.0 0 0 %.17g %.17g\n" % (s, s, s, s))
    rec = mobmap.open_recording(str(tmp_path), intrinsics=(500.0, 500.0, 3.5, 2.5), max_pose_gap=0.3)
    assert rec.format == "TUM RGB-D"
    assert rec.frames == [0, 1] and "1 of 3 depth frames" in rec.skipped
    # The library's field, as the keyword that set it.
    assert "within `max_pose_gap` 0.3 s" in rec.skipped and "max_pose_gap_s" not in rec.skipped
    got = list(rec)
    assert [f["stamp"] for f in got] == [10.0, 10.5]
    for frame, image in zip(got, images):
        want = image.astype(np.float32) / np.float32(5000)
        np.testing.assert_allclose(frame["depth"], want, rtol=1e-6)
    want0 = np.eye(4)
    want0[:3, 3] = (1.1, 2.0, 3.0)  # halfway between the poses at 9.9 and 10.1
    np.testing.assert_allclose(got[0]["pose"], want0, atol=1e-9)
    want1 = np.eye(4)
    want1[:3, :3] = quaternion_matrix(0, 0, s, s)
    want1[:3, 3] = (0.0, 0.0, 1.0)
    np.testing.assert_allclose(got[1]["pose"], want1, atol=1e-9)


def test_an_unorganized_pcd_gives_its_points(tmp_path):
    points = np.array([[0.1, -0.2, 1.5], [0.0, 0.0, 2.0], [-1.25, 0.5, 3.0]], dtype=np.float32)
    body = "\n".join(" ".join(f"{v:.9g}" for v in p) for p in points)
    (tmp_path / "cloud.pcd").write_text(
        "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
        f"WIDTH {len(points)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(points)}\nDATA ascii\n{body}\n")
    rec = mobmap.open_recording(str(tmp_path / "cloud.pcd"))
    assert rec.format == ".pcd file" and rec.intrinsics is None
    frame = rec[0]
    assert frame["depth"] is None and frame["intrinsics"] is None
    np.testing.assert_array_equal(frame["points"], points)
    with pytest.raises(IndexError):
        rec[1]


def test_unknown_options_are_type_errors(tmp_path):
    with pytest.raises(TypeError, match="unexpected keyword argument 'topic'"):
        mobmap.open_recording(str(tmp_path), topic="/depth")


def test_sun_rgbd_depth_is_decoded(tmp_path):
    """SUN RGB-D stores millimetres rotated left by 3 bits; depth_format undoes it."""
    rng = np.random.default_rng(9)
    mm = rng.integers(1, 65535, size=(5, 7), dtype=np.uint16)
    stored = ((mm.astype(np.uint32) << 3 | mm.astype(np.uint32) >> 13) & 0xFFFF).astype(np.uint16)
    path = tmp_path / "sun.png"
    path.write_bytes(encode(stored, [4]))
    rec = mobmap.open_recording(str(path), intrinsics=(5.0, 5.0, 3.0, 2.0), depth_format="sunrgbd")
    np.testing.assert_array_equal(rec[0]["depth"], metres(mm))
    with pytest.raises(ValueError, match="sunrgbd"):
        mobmap.open_recording(str(path), intrinsics=(5.0, 5.0, 3.0, 2.0), depth_format="rotated")
