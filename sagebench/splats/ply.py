"""3DGS PLY files: the INRIA layout (read and write, plus an int `instance_id`) and the compressed
SuperSplat/PlayCanvas layout (read) used by InteriorGS's `3dgs_compressed.ply`.

INRIA vertex properties: x y z nx ny nz f_dc_0..2 f_rest_0..M-1 opacity scale_0..2 rot_0..3, all float;
f_rest is channel-major (all red coefficients, then green, then blue), opacity is a logit, scales are
logs and rot_0 is w. Only binary little-endian files are read and written.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.lib.recfunctions import structured_to_unstructured

from sagebench.errors import DataError
from sagebench.fileio import staged_file
from sagebench.render.gaussians import SH_C0, Gaussians

_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "<i2", "int16": "<i2", "ushort": "<u2", "uint16": "<u2",
    "int": "<i4", "int32": "<i4", "uint": "<u4", "uint32": "<u4",
    "float": "<f4", "float32": "<f4", "double": "<f8", "float64": "<f8",
}
MAX_LOG_SCALE = 50.0  # log scale (m) of the largest Gaussian read: e^50 m is past any scene, and exp() stays finite
CHUNK_SIZE = 256  # Gaussians per chunk in the compressed layout
DECODE_BLOCK = 256 * CHUNK_SIZE  # Gaussians decoded (read, written) at a time: temporaries of a few MB
_CHUNK_BOUNDS = ["min_x", "min_y", "min_z", "max_x", "max_y", "max_z",
                 "min_scale_x", "min_scale_y", "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z"]
_CHUNK_COLOUR = ["min_r", "min_g", "min_b", "max_r", "max_g", "max_b"]
_PACKED = ["packed_position", "packed_rotation", "packed_scale", "packed_color"]


@dataclass(frozen=True)
class _Element:
    name: str
    count: int
    dtype: np.dtype


def read_ply(path: Path | str) -> Gaussians:
    """Read an INRIA-layout or compressed 3DGS PLY; raises DataError naming what is wrong."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as err:
        raise DataError(f"cannot read: {err.strerror}", path=path) from None
    elements, body = _parse_header(data, path)
    tables = _read_elements(data, body, elements, path)
    names = [e.name for e in elements]
    if "chunk" in names:
        return _checked(_decode_compressed(tables, path), path)
    if "vertex" not in names:
        raise DataError("no 'vertex' element", path=path)
    vertex = tables["vertex"].dtype.names or ()
    if not {"x", "y", "z"} & set(vertex) and not set(_PACKED) & set(vertex):
        raise DataError(f"neither the INRIA 3DGS layout (x, y, z, f_dc_0, ...) nor the compressed SuperSplat layout "
                        f"(a 'chunk' element and packed_position, ...): vertex has {', '.join(vertex[:6]) or 'no properties'}"
                        f"{', ...' if len(vertex) > 6 else ''}", path=path)
    return _checked(_decode_inria(tables["vertex"], path), path)


def _checked(g: Gaussians, path: Path) -> Gaussians:
    """Refuse NaN or infinite values and zero rotations: one would turn a whole rendered frame into NaN."""
    if g.count == 0:
        return g
    for name, values in (("position", g.means), ("rotation", g.quats_wxyz), ("scale", g.log_scales),
                         ("opacity", g.opacity_logits), ("colour", g.sh)):
        if np.isfinite(values.min()) and np.isfinite(values.max()):  # NaN spreads to both, -inf to min, inf to max
            continue
        bad = ~np.isfinite(values.reshape(g.count, int(np.prod(values.shape[1:])))).all(axis=1)  # N may be 0
        if bad.any():
            raise DataError(f"Gaussian {int(np.argmax(bad))} has a non-finite {name} "
                            f"({int(bad.sum())} of {g.count} do)", path=path, field="vertex")
    huge = (g.log_scales > MAX_LOG_SCALE).any(axis=1)
    if huge.any():
        raise DataError(f"Gaussian {int(np.argmax(huge))} has a scale over e^{MAX_LOG_SCALE:g} m "
                        f"({int(huge.sum())} of {g.count} do)", path=path, field="vertex")
    zero = ~(np.abs(g.quats_wxyz) > 0).any(axis=1)
    if zero.any():
        raise DataError(f"Gaussian {int(np.argmax(zero))} has a zero rotation quaternion "
                        f"({int(zero.sum())} of {g.count} do)", path=path, field="vertex")
    return g


def write_ply(path: Path | str, gaussians: Gaussians) -> None:
    """Write the INRIA layout plus `instance_id` (int), atomically; read_ply gives back the same arrays. Written
    DECODE_BLOCK rows at a time, so that no copy of the whole table is ever held."""
    g = gaussians
    k = g.sh.shape[1]
    names = ["x", "y", "z", "nx", "ny", "nz", *[f"f_dc_{c}" for c in range(3)],
             *[f"f_rest_{i}" for i in range(3 * (k - 1))], "opacity", *[f"scale_{i}" for i in range(3)],
             *[f"rot_{i}" for i in range(4)]]
    dtype = np.dtype([(name, "<f4") for name in names] + [("instance_id", "<i4")])
    header = ["ply", "format binary_little_endian 1.0", "comment written by sagebench", f"element vertex {g.count}"]
    header += [f"property float {name}" for name in names] + ["property int instance_id", "end_header"]
    with staged_file(Path(path)) as fh:
        fh.write(("\n".join(header) + "\n").encode("ascii"))
        for a in range(0, g.count, DECODE_BLOCK):
            fh.write(_inria_rows(g.take(slice(a, a + DECODE_BLOCK)), dtype).view(np.uint8))  # no copy


def _inria_rows(g: Gaussians, dtype: np.dtype) -> np.ndarray:
    """The rows of the INRIA table (`dtype`: x y z nx ny nz f_dc_0..2 f_rest_* opacity scale_0..2 rot_0..3, then
    instance_id) for the Gaussians `g`; normals zero, f_rest channel-major. The float columns are filled as
    blocks of a [n, columns] float32 view of the table, not one field at a time."""
    n, k = g.count, g.sh.shape[1]
    table = np.zeros(n, dtype=dtype)
    cols = table.view(np.float32).reshape(n, -1)
    rest = 9 + 3 * (k - 1)
    cols[:, 0:3] = g.means
    cols[:, 6:9] = g.sh[:, 0, :]
    cols[:, 9:rest].reshape(n, 3, k - 1)[:] = g.sh[:, 1:, :].transpose(0, 2, 1)
    cols[:, rest] = g.opacity_logits
    cols[:, rest + 1:rest + 4] = g.log_scales
    cols[:, rest + 4:rest + 8] = g.quats_wxyz
    table["instance_id"] = g.instance_id
    return table


def _parse_header(data: bytes, path: Path) -> tuple[list[_Element], int]:
    if not data.startswith(b"ply\n") and not data.startswith(b"ply\r\n"):
        raise DataError("not a PLY file (no 'ply' magic line)", path=path)
    end = data.find(b"end_header")
    if end < 0:
        raise DataError("PLY header has no 'end_header' line", path=path)
    body = data.index(b"\n", end) + 1 if b"\n" in data[end:] else len(data)
    lines = data[:end].decode("ascii", errors="replace").splitlines()[1:]
    elements: list[tuple[str, int, list[tuple[str, str]]]] = []
    for number, line in enumerate(lines, start=2):
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format":
            if words[1:2] != ["binary_little_endian"]:
                raise DataError(f"header line {number}: only binary_little_endian PLY is supported, got {line!r}", path=path)
        elif words[0] == "element" and len(words) == 3 and words[2].isdigit():
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property" and len(words) == 3 and elements:
            if words[1] not in _TYPES:
                raise DataError(f"header line {number}: unknown property type {words[1]!r}", path=path)
            elements[-1][2].append((words[2], _TYPES[words[1]]))
        elif words[0] == "property" and words[1:2] == ["list"]:
            raise DataError(f"header line {number}: list properties are not 3DGS data ({line!r})", path=path)
        else:
            raise DataError(f"header line {number}: cannot parse {line!r}", path=path)
    return [_Element(name, count, np.dtype(props)) for name, count, props in elements], body


def _read_elements(data: bytes, offset: int, elements: list[_Element], path: Path) -> dict[str, np.ndarray]:
    tables: dict[str, np.ndarray] = {}
    for el in elements:
        size = el.count * el.dtype.itemsize
        if offset + size > len(data):
            raise DataError(
                f"truncated: element '{el.name}' needs {size} bytes, only {len(data) - offset} left", path=path
            )
        tables[el.name] = np.frombuffer(data, dtype=el.dtype, count=el.count, offset=offset)
        offset += size
    return tables


def _require(table: np.ndarray, names: list[str], element: str, path: Path) -> None:
    missing = [n for n in names if n not in (table.dtype.names or ())]
    if missing:
        raise DataError(f"missing propert{'y' if len(missing) == 1 else 'ies'} {', '.join(missing)}",
                        path=path, field=element)


def _f32(table: np.ndarray, names: list[str]) -> np.ndarray:
    return np.stack([table[n].astype(np.float32) for n in names], axis=-1) if names else np.zeros((len(table), 0), np.float32)


def _decode_inria(v: np.ndarray, path: Path) -> Gaussians:
    base = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", *[f"scale_{i}" for i in range(3)],
            *[f"rot_{i}" for i in range(4)]]
    _require(v, base, "vertex", path)
    n_rest = sum(1 for name in v.dtype.names if name.startswith("f_rest_"))
    _require(v, [f"f_rest_{i}" for i in range(n_rest)], "vertex", path)
    k = n_rest // 3 + 1
    if n_rest % 3 or k not in (1, 4, 9, 16):
        raise DataError(f"{n_rest} f_rest properties; expected 0, 9, 24 or 45 (SH degree 0-3)", path=path, field="vertex")
    n = len(v)
    sh = np.empty((n, k, 3), np.float32)
    sh[:, 0, :] = _f32(v, ["f_dc_0", "f_dc_1", "f_dc_2"])
    sh[:, 1:, :] = _f32(v, [f"f_rest_{i}" for i in range(n_rest)]).reshape(n, 3, k - 1).transpose(0, 2, 1)
    ids = v["instance_id"].astype(np.int32) if "instance_id" in v.dtype.names else np.zeros(n, np.int32)
    return Gaussians(
        means=_f32(v, ["x", "y", "z"]),
        quats_wxyz=_f32(v, [f"rot_{i}" for i in range(4)]),
        log_scales=_f32(v, [f"scale_{i}" for i in range(3)]),
        opacity_logits=v["opacity"].astype(np.float32),
        sh=sh,
        instance_id=ids,
    )


def _unorm(bits: np.ndarray, shift: int, width: int) -> np.ndarray:
    top = (1 << width) - 1
    return ((bits >> np.uint32(shift)) & np.uint32(top)).astype(np.float64) / top


def _lerp(lo: np.ndarray, hi: np.ndarray, t: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", over="ignore"):  # non-finite chunk bounds: _checked names them, once
        return lo * (1.0 - t) + hi * t


def _in_chunks(lo: np.ndarray, hi: np.ndarray, t: np.ndarray, n: int) -> np.ndarray:
    """The first `n` of the values `t` [chunks * CHUNK_SIZE (, k)] lerped within their chunk's bounds `lo`, `hi`
    [chunks, 1, 1 or k], as [n, 1 or k]: each chunk's bounds broadcast over its Gaussians, not repeated for each."""
    return _lerp(lo, hi, t.reshape(len(lo), CHUNK_SIZE, -1)).reshape(len(t), -1)[:n]


def _decode_compressed(tables: dict[str, np.ndarray], path: Path) -> Gaussians:
    """Chunks of 256 Gaussians share min/max bounds; each Gaussian packs four uint32 words:

    position and log-scale 11-10-11 bits lerped within the chunk bounds; rotation 2 bits for the index
    of the largest of (rot_0..rot_3) = (w, x, y, z) and 10 bits each for the other three in order,
    scaled by sqrt(2) around 0.5; colour 8-8-8-8 RGBA where RGB is 0.5 + SH_C0 * f_dc (lerped within
    min_r..max_r when the chunk has them) and A the opacity. Optional `sh` element: uchar f_rest_* with
    (n - 0.5) * 8, n = 0, 1 or (v + 0.5) / 256.

    Decoded DECODE_BLOCK Gaussians at a time into the float32 arrays: the float64 temporaries of a whole
    scene (several GB for millions of Gaussians with SH) would cost more in page faults than the arithmetic.
    """
    if "vertex" not in tables:
        raise DataError("compressed PLY has a 'chunk' element but no 'vertex' element", path=path)
    chunk, vertex = tables["chunk"], tables["vertex"]
    _require(chunk, _CHUNK_BOUNDS, "chunk", path)
    _require(vertex, _PACKED, "vertex", path)
    n = len(vertex)
    if len(chunk) != math.ceil(n / CHUNK_SIZE):
        raise DataError(f"{len(chunk)} chunks for {n} Gaussians; expected {math.ceil(n / CHUNK_SIZE)}", path=path,
                        field="chunk")
    sh_table = tables.get("sh")
    if sh_table is not None:
        n_rest = len(sh_table.dtype.names)
        if len(sh_table) != n or n_rest not in (9, 24, 45):
            raise DataError(f"'sh' element has {len(sh_table)} rows of {n_rest} coefficients; expected {n} rows of "
                            f"9, 24 or 45", path=path, field="sh")
        _require(sh_table, [f"f_rest_{i}" for i in range(n_rest)], "sh", path)
    k = 1 if sh_table is None else len(sh_table.dtype.names) // 3 + 1
    g = Gaussians(means=np.empty((n, 3), np.float32), quats_wxyz=np.empty((n, 4), np.float32),
                  log_scales=np.empty((n, 3), np.float32), opacity_logits=np.empty(n, np.float32),
                  sh=np.empty((n, k, 3), np.float32), instance_id=np.zeros(n, np.int32))
    for a in range(0, n, DECODE_BLOCK):
        b = min(n, a + DECODE_BLOCK)
        _decode_block(chunk[a // CHUNK_SIZE:math.ceil(b / CHUNK_SIZE)], vertex[a:b],
                      None if sh_table is None else sh_table[a:b], g.take(slice(a, b)))
    return g


def _decode_block(chunk: np.ndarray, vertex: np.ndarray, sh_table: np.ndarray | None, out: Gaussians) -> None:
    """Decode the Gaussians `vertex` (starting at `chunk`'s first) into `out` (views of the arrays to fill)."""
    n, chunks = len(vertex), len(chunk)
    c = {name: chunk[name].astype(np.float64)[:, None, None] for name in chunk.dtype.names}  # [chunks, 1, 1]
    words = {name: np.zeros(chunks * CHUNK_SIZE, np.uint32) for name in _PACKED}  # whole chunks: the last may be short
    for name, bits in words.items():
        bits[:n] = vertex[name]

    pos, scl = words["packed_position"], words["packed_scale"]
    for j, (a, s, w) in enumerate((("x", 21, 11), ("y", 11, 10), ("z", 0, 11))):
        out.means[:, j] = _in_chunks(c[f"min_{a}"], c[f"max_{a}"], _unorm(pos, s, w), n)[:, 0]
        out.log_scales[:, j] = _in_chunks(c[f"min_scale_{a}"], c[f"max_scale_{a}"], _unorm(scl, s, w), n)[:, 0]

    rot = words["packed_rotation"][:n]
    abc = np.stack([(_unorm(rot, s, 10) - 0.5) * math.sqrt(2.0) for s in (20, 10, 0)], axis=-1)
    largest = (rot >> np.uint32(30)).astype(np.int64)
    m = np.sqrt(np.maximum(0.0, 1.0 - (abc**2).sum(axis=1)))
    rows = np.arange(n)
    others = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])[largest]
    out.quats_wxyz[rows, largest] = m
    for j in range(3):
        out.quats_wxyz[rows, others[:, j]] = abc[:, j]

    col = words["packed_color"]
    rgb = np.stack([_unorm(col, s, 8) for s in (24, 16, 8)], axis=-1)
    if all(name in c for name in _CHUNK_COLOUR):
        lo, hi = (np.concatenate([c[f"{e}_{k}"] for k in "rgb"], axis=-1) for e in ("min", "max"))
        rgb = _in_chunks(lo, hi, rgb, n)
    rgb = rgb[:n]
    alpha = np.clip(_unorm(col[:n], 0, 8), 1e-6, 1.0 - 1e-6)
    out.opacity_logits[:] = np.log(alpha / (1.0 - alpha))
    out.sh[:, 0, :] = (rgb - 0.5) / SH_C0
    k = out.sh.shape[1]
    if sh_table is not None:  # channel-major: every red coefficient, then green...; one [n, 3 (k - 1)] array
        q = structured_to_unstructured(sh_table[[f"f_rest_{i}" for i in range(3 * (k - 1))]])
        rest = _SH_OF_UCHAR[q] if q.dtype == np.uint8 else _sh_value(q)
        out.sh[:, 1:, :] = rest.reshape(n, 3, k - 1).transpose(0, 2, 1)


def _sh_value(q: np.ndarray) -> np.ndarray:
    """A quantised SH coefficient's value: (n - 0.5) * 8, n = 0, 1 or (q + 0.5) / 256 for q = 0, 255 or between."""
    q = np.asarray(q, dtype=np.float64)
    return (np.where(q == 0, 0.0, np.where(q == 255, 1.0, (q + 0.5) / 256.0)) - 0.5) * 8.0


_SH_OF_UCHAR = _sh_value(np.arange(256)).astype(np.float32)  # the layout's uchar coefficients, looked up
