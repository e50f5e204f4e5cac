"""PLY I/O: bit-exact INRIA round trip, compressed layout decoded to hand-worked values, clear errors."""

from __future__ import annotations

import math
import tracemalloc

import numpy as np
import pytest

from sagebench.errors import DataError
from sagebench.render.gaussians import SH_C0, Gaussians
from sagebench.splats.ply import read_ply, write_ply


def _random(n: int, degree: int, seed: int = 0) -> Gaussians:
    rng = np.random.default_rng(seed)
    f = lambda *s: rng.normal(size=s).astype(np.float32)  # noqa: E731
    return Gaussians(f(n, 3), f(n, 4), f(n, 3), f(n), f(n, (degree + 1) ** 2, 3), rng.integers(0, 1 << 30, n).astype(np.int32))


@pytest.mark.parametrize("degree", [0, 1, 3])
def test_round_trip_is_bit_exact(tmp_path, degree):
    g = _random(257, degree)
    write_ply(tmp_path / "g.ply", g)
    back = read_ply(tmp_path / "g.ply")
    for name in ("means", "quats_wxyz", "log_scales", "opacity_logits", "sh", "instance_id"):
        a, b = getattr(g, name), getattr(back, name)
        assert a.dtype == b.dtype and a.shape == b.shape
        assert a.tobytes() == b.tobytes(), name


def test_written_layout_is_inria(tmp_path):
    g = _random(3, 1)
    write_ply(tmp_path / "g.ply", g)
    header = (tmp_path / "g.ply").read_bytes().split(b"end_header\n")[0].decode()
    props = [line.split()[-1] for line in header.splitlines() if line.startswith("property")]
    assert props == ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2",
                     *[f"f_rest_{i}" for i in range(9)], "opacity", "scale_0", "scale_1", "scale_2",
                     "rot_0", "rot_1", "rot_2", "rot_3", "instance_id"]
    # f_rest is channel-major: f_rest_0..2 are red's three degree-1 coefficients
    raw = np.frombuffer((tmp_path / "g.ply").read_bytes().split(b"end_header\n")[1], dtype="<f4").reshape(3, -1)
    assert np.array_equal(raw[:, 9:12], g.sh[:, 1:, 0])
    assert np.array_equal(raw[:, 12:15], g.sh[:, 1:, 1])


def _ply(elements: list[tuple[str, np.ndarray]]) -> bytes:
    names = {"<f4": "float", "<u4": "uint", "|u1": "uchar"}
    lines = ["ply", "format binary_little_endian 1.0"]
    for name, table in elements:
        lines.append(f"element {name} {len(table)}")
        lines += [f"property {names[table.dtype[f].str]} {f}" for f in table.dtype.names]
    lines.append("end_header")
    return ("\n".join(lines) + "\n").encode() + b"".join(t.tobytes() for _, t in elements)


def test_compressed_layout_decodes_to_hand_worked_values(tmp_path):
    bounds = ["min_x", "min_y", "min_z", "max_x", "max_y", "max_z", "min_scale_x", "min_scale_y", "min_scale_z",
              "max_scale_x", "max_scale_y", "max_scale_z", "min_r", "min_g", "min_b", "max_r", "max_g", "max_b"]
    chunk = np.zeros(1, dtype=[(b, "<f4") for b in bounds])
    for name, value in zip(bounds, [0, -1, 2, 2, 1, 4, -5, -5, -5, -1, -1, -1, 0.2, 0.0, 0.0, 0.6, 1.0, 1.0]):
        chunk[name] = value
    vertex = np.zeros(2, dtype=[(n, "<u4") for n in ("packed_position", "packed_rotation", "packed_scale", "packed_color")])
    # Gaussian 0: x at the top of its 11 bits, y top of 10, z bottom; rotation: largest is rot_0 (w)
    vertex[0] = ((2047 << 21) | (1023 << 11) | 0, (0 << 30) | (512 << 20) | (512 << 10) | 512,
                 (0 << 21) | (1023 << 11) | 2047, (255 << 24) | (0 << 16) | (51 << 8) | 204)
    # Gaussian 1: the middle-ish; rotation: largest is rot_2 (y), rot_0 = w at the top of its 10 bits
    vertex[1] = ((1023 << 21) | (0 << 11) | 2047, (2 << 30) | (1023 << 20) | (512 << 10) | 512, 0, 0xFFFFFFFF)
    sh = np.zeros(2, dtype=[(f"f_rest_{i}", "u1") for i in range(9)])
    sh[0] = (0, 255, 127, 0, 0, 0, 0, 0, 0)
    path = tmp_path / "3dgs_compressed.ply"
    path.write_bytes(_ply([("chunk", chunk), ("vertex", vertex), ("sh", sh)]))
    g = read_ply(path)

    assert g.means[0].tolist() == pytest.approx([2.0, 1.0, 2.0])
    assert g.means[1].tolist() == pytest.approx([2 * 1023 / 2047, -1.0, 4.0])
    assert g.log_scales[0].tolist() == pytest.approx([-5.0, -1.0, -1.0])
    assert g.log_scales[1].tolist() == pytest.approx([-5.0, -5.0, -5.0])
    eps = (512 / 1023 - 0.5) * math.sqrt(2)  # 10-bit 512 is just above the middle
    big = math.sqrt(1 - 3 * eps**2)
    assert g.quats_wxyz[0].tolist() == pytest.approx([big, eps, eps, eps], abs=1e-6)
    half = math.sqrt(0.5)  # 10-bit 1023 -> 0.5 * sqrt(2)
    assert g.quats_wxyz[1].tolist() == pytest.approx([half, eps, math.sqrt(1 - 0.5 - 2 * eps**2), eps], abs=1e-6)
    # colour bytes lerp within the chunk's min/max colour, then f_dc = (c - 0.5) / SH_C0
    rgb0 = np.array([0.6, 0.0, 51 / 255])
    assert g.sh[0, 0].tolist() == pytest.approx(((rgb0 - 0.5) / SH_C0).tolist(), abs=1e-6)
    assert g.opacity_logits[0] == pytest.approx(math.log(0.8 / 0.2), abs=1e-5)  # alpha byte 204 = 0.8
    assert g.sh_degree == 1
    assert g.sh[0, 1:, 0].tolist() == pytest.approx([-4.0, 4.0, (127.5 / 256 - 0.5) * 8])  # red, channel-major
    assert g.sh[0, 1:, 1].tolist() == pytest.approx([-4.0, -4.0, -4.0])
    assert np.isfinite(g.opacity_logits).all()  # alpha byte 255 stays finite
    assert g.instance_id.tolist() == [0, 0]


def test_truncated_file_is_a_clear_error(tmp_path):
    write_ply(tmp_path / "g.ply", _random(10, 0))
    data = (tmp_path / "g.ply").read_bytes()
    (tmp_path / "cut.ply").write_bytes(data[:-5])
    with pytest.raises(DataError, match=r"cut.ply: truncated: element 'vertex' needs 720 bytes, only 715 left"):
        read_ply(tmp_path / "cut.ply")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (b"PLY\n", "not a PLY file"),
        (b"ply\nformat binary_little_endian 1.0\nelement vertex 1\n", "no 'end_header'"),
        (b"ply\nformat ascii 1.0\nelement vertex 0\nend_header\n", "only binary_little_endian PLY is supported"),
        (b"ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty half x\nend_header\n", "unknown property type 'half'"),
        (b"ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\nend_header\n",
         "vertex: missing properties y, z, f_dc_0"),
        (b"ply\nformat binary_little_endian 1.0\nelement face 0\nend_header\n", "no 'vertex' element"),
    ],
)
def test_malformed_files_name_the_problem(tmp_path, text, message):
    (tmp_path / "bad.ply").write_bytes(text)
    with pytest.raises(DataError, match=message):
        read_ply(tmp_path / "bad.ply")


def test_a_large_compressed_scene_is_read_and_written_without_whole_scene_temporaries(tmp_path):
    """Millions of Gaussians with SH must fit in memory: reading 300,000 (SH degree 3) holds the file and the
    decoded arrays plus one block's working set, and writing them back one block's rows, not copies of it all."""
    n, rng = 300_000, np.random.default_rng(0)
    bounds = ["min_x", "min_y", "min_z", "max_x", "max_y", "max_z", "min_scale_x", "min_scale_y", "min_scale_z",
              "max_scale_x", "max_scale_y", "max_scale_z"]
    chunk = np.zeros(math.ceil(n / 256), dtype=[(b, "<f4") for b in bounds])
    for b in bounds:
        chunk[b] = rng.uniform(-1.0, 0.0, len(chunk)) + (1.5 if b.startswith("max") else 0.0)
    vertex = np.zeros(n, dtype=[(p, "<u4") for p in ("packed_position", "packed_rotation", "packed_scale", "packed_color")])
    sh = np.zeros(n, dtype=[(f"f_rest_{i}", "u1") for i in range(45)])
    for table, top in ((vertex, 1 << 32), (sh, 256)):
        for name in table.dtype.names:
            table[name] = rng.integers(0, top, n, dtype=np.uint64)
    path = tmp_path / "3dgs_compressed.ply"
    path.write_bytes(_ply([("chunk", chunk), ("vertex", vertex), ("sh", sh)]))
    tracemalloc.start()
    try:
        g = read_ply(path)
        _, read_peak = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        held, _ = tracemalloc.get_traced_memory()
        write_ply(tmp_path / "g.ply", g)
        _, write_peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    arrays = sum(a.nbytes for a in (g.means, g.quats_wxyz, g.log_scales, g.opacity_logits, g.sh, g.instance_id))
    assert g.sh.shape == (n, 16, 3)
    assert read_peak - path.stat().st_size - arrays < 32e6
    assert write_peak - held < 32e6
