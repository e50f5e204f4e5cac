"""The fast CPU splat renderer: numba kernels, 16x16 tiles, tiles spread over all cores.

Same conventions and results as splat_reference (tested to agree): per-Gaussian projection in a parallel
loop, one global stable depth sort (so every tile's list is in depth order), a counting sort of
(tile, Gaussian) pairs (both sorts count and place slices of their input in parallel), then each tile
composites its list front to back, stopping once every pixel's transmittance is spent. A Gaussian adds
nothing outside its reach ellipse (3 sigma, less for faint ones: `_reach2`), so it is binned to the tiles of
that ellipse's bounding box and, within a tile, visits only the pixels of that box in the rows that cross the
ellipse and still take colour. Several cameras render side by side, one per thread. Each kernel is written
once and compiled twice: exactly, for the float64 reference, and with FAST_MATH, for the float32 frames.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from functools import cache

import numba
import numpy as np
from numba import types
from numba.extending import overload

from sagebench.render.camera import Camera
from sagebench.render.chunks import PackedGaussians, visible_index
from sagebench.render.gaussians import Gaussians
from sagebench.render.sh import C0, C1, C2, C3
from sagebench.render.splat_reference import (
    CUTOFF,
    DILATION,
    FOV_CLAMP,
    MAX_ALPHA,
    MIN_ALPHA,
    MIN_TRANSMITTANCE,
    NEAR,
    Frame,
)

TILE = 16
MAX_SIDE = np.iinfo(np.int16).max * TILE  # px: the tile rectangles are int16
SLACK = 1e-6  # relative widening of each Gaussian's reach, so rounding never drops a pixel the per-pixel test keeps
FAST_MATH = {"contract", "arcp"}  # how the float32 frames' kernels compile: a * b + c fused into one rounding
# (a fused multiply-add on CPUs that have one) and x / y as x * (1 / y) (docs/rendering.md)
REFERENCE = np.float64  # the precision of the reference frames (and of build-scene's pruning): bit for bit the
# float64 renderer of before float32 frames (docs/rendering.md)
# columns of the projected record [n, RECORD] of each Gaussian, in the frame's precision
U, V, CA, CB, CC, DEPTH, OPAC, HX, HY, RED = range(10)  # HX, HY: half the reach ellipse's width and height, px
RECORD = 12  # RED, RED + 1, RED + 2: colour; 48 bytes in float32
_FULL_REACH = math.exp(CUTOFF) * (1.0 + 1e-12)  # above it, log() >= CUTOFF whatever the rounding
EXP_STEPS = 64  # table points per unit of the float32 exp
_EXP_TABLE = np.exp(-np.arange(int(CUTOFF * EXP_STEPS) + 2) / EXP_STEPS).astype(np.float32)


def _exp(x):
    """exp(x) for -CUTOFF <= x <= 0, in x's precision: math.exp for float64; for float32 a table of
    exp(-k / 64) times a cubic Taylor polynomial of the remainder r (-1/64 < r <= 0; truncation r^4 / 24 <
    2.5e-9), within 2.4e-7 of exp (relative; 4 float32 ulps, measured over the whole range in the tests)."""
    return math.exp(x)


@numba.njit(cache=True, inline="always")
def _exp32(x):
    k = int(-x * np.float32(EXP_STEPS))
    r = x + np.float32(k) * np.float32(1.0 / EXP_STEPS)
    return _EXP_TABLE[k] * (np.float32(1.0) + r * (np.float32(1.0) + r * (np.float32(0.5) + r * np.float32(1.0 / 6.0))))


@overload(_exp, inline="always")
def _exp_typed(x):
    if x == types.float32:
        return lambda x: _exp32(x)
    return lambda x: math.exp(x)


@numba.njit(cache=True, inline="always")
def _reach2(o: float) -> float:
    """Squared Mahalanobis radius beyond which a Gaussian of opacity `o` adds nothing: there power < -CUTOFF or
    o exp(power) < MIN_ALPHA (the 3-sigma ellipse, shrunk for faint Gaussians), widened by SLACK."""
    if o / MIN_ALPHA >= _FULL_REACH:  # log(o / MIN_ALPHA) >= CUTOFF: no log needed (most Gaussians)
        return 2.0 * CUTOFF * (1.0 + SLACK) + SLACK
    return 2.0 * min(CUTOFF, math.log(o / MIN_ALPHA)) * (1.0 + SLACK) + SLACK


@numba.njit(cache=True, inline="always")
def _pixels(lo: float, hi: float, n: int) -> tuple[int, int]:
    """First and last of the n pixel columns (or rows) whose centres k + 0.5 lie in [lo, hi], widened by a
    hundredth of a pixel against rounding; first > last if none."""
    return max(int(math.ceil(max(lo - 0.51, -1.0))), 0), min(int(math.floor(min(hi - 0.49, n))), n - 1)


@numba.njit(cache=True, inline="always")
def _tiles(lo: float, hi: float, n: int) -> tuple[int, int]:
    """Tile range [first, end) holding the pixels `_pixels(lo, hi, n)`; first >= end if none."""
    a, b = _pixels(lo, hi, n)
    return (a // TILE, b // TILE + 1) if a <= b else (0, 0)


@numba.njit(cache=True, inline="always")
def _sh_colour(sh: np.ndarray, i: int, c: int, k: int, x: float, y: float, z: float) -> float:
    v = C0 * sh[i, 0, c]
    if k > 1:
        v += -C1 * y * sh[i, 1, c] + C1 * z * sh[i, 2, c] - C1 * x * sh[i, 3, c]
    if k > 4:
        xx, yy, zz = x * x, y * y, z * z
        v += (C2[0] * x * y * sh[i, 4, c] + C2[1] * y * z * sh[i, 5, c] + C2[2] * (2 * zz - xx - yy) * sh[i, 6, c]
              + C2[3] * x * z * sh[i, 7, c] + C2[4] * (xx - yy) * sh[i, 8, c])
        if k > 9:
            v += (C3[0] * y * (3 * xx - yy) * sh[i, 9, c] + C3[1] * x * y * z * sh[i, 10, c]
                  + C3[2] * y * (4 * zz - xx - yy) * sh[i, 11, c] + C3[3] * z * (2 * zz - 3 * xx - 3 * yy) * sh[i, 12, c]
                  + C3[4] * x * (4 * zz - xx - yy) * sh[i, 13, c] + C3[5] * z * (xx - yy) * sh[i, 14, c]
                  + C3[6] * x * (xx - 3 * yy) * sh[i, 15, c])
    return max(v + 0.5, 0.0)


@numba.njit(inline="always")
def _projection(index, means, quats, log_scales, logits, sh, w2c, fx, fy, cx, cy, width, height,
                rec):  # pragma: no cover - jit
    """Per Gaussian of `index` [n], computed in float64 and stored in rec [n, RECORD] (rows follow `index`):
    image centre, conic, depth, opacity, reach and colour; returns the tile rectangles, rect[r, 0] = -1 if
    culled. Inlined into `_project` and `_project_fast`, which differ only in how numba compiles it."""
    n = index.shape[0]
    k = sh.shape[1]
    rect = np.full((n, 4), -1, np.int16)  # 8 bytes a row: the binning's random reads stay in L2
    limx, limy = FOV_CLAMP * width / (2 * fx), FOV_CLAMP * height / (2 * fy)
    r00, r01, r02, t0 = w2c[0, 0], w2c[0, 1], w2c[0, 2], w2c[0, 3]
    r10, r11, r12, t1 = w2c[1, 0], w2c[1, 1], w2c[1, 2], w2c[1, 3]
    r20, r21, r22, t2 = w2c[2, 0], w2c[2, 1], w2c[2, 2], w2c[2, 3]
    # camera centre -R^T t, for view directions
    ox = -(r00 * t0 + r10 * t1 + r20 * t2)
    oy = -(r01 * t0 + r11 * t1 + r21 * t2)
    oz = -(r02 * t0 + r12 * t1 + r22 * t2)
    for r in numba.prange(n):
        i = index[r]
        mx, my, mz = float(means[i, 0]), float(means[i, 1]), float(means[i, 2])
        pz = r20 * mx + r21 * my + r22 * mz + t2
        if pz <= NEAR:
            continue
        o = 1.0 / (1.0 + math.exp(-float(logits[i])))
        if o < MIN_ALPHA:
            continue
        px = r00 * mx + r01 * my + r02 * mz + t0
        py = r10 * mx + r11 * my + r12 * mz + t1
        # cheap conservative cull of Gaussians whose 3-sigma extent cannot reach the image: the projected
        # sigma is at most the largest scale times the Frobenius norm of the (clamped) Jacobian
        u, v = fx * px / pz + cx, fy * py / pz + cy
        sx, sy, sz = math.exp(log_scales[i, 0]), math.exp(log_scales[i, 1]), math.exp(log_scales[i, 2])
        smax = max(sx, sy, sz)
        rx, ry = min(abs(px / pz), limx), min(abs(py / pz), limy)
        jnorm = math.sqrt(fx * fx * (1.0 + rx * rx) + fy * fy * (1.0 + ry * ry)) / pz
        reach = 3.0 * math.sqrt(smax * smax * jnorm * jnorm + DILATION) + 1.0
        if u + reach < 0.0 or u - reach > width or v + reach < 0.0 or v - reach > height:
            continue
        # R S, with R from the normalised quaternion
        qw, qx, qy, qz = float(quats[i, 0]), float(quats[i, 1]), float(quats[i, 2]), float(quats[i, 3])
        qn = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        qw, qx, qy, qz = qw / qn, qx / qn, qy / qn, qz / qn
        m00, m01, m02 = (1 - 2 * (qy * qy + qz * qz)) * sx, 2 * (qx * qy - qw * qz) * sy, 2 * (qx * qz + qw * qy) * sz
        m10, m11, m12 = 2 * (qx * qy + qw * qz) * sx, (1 - 2 * (qx * qx + qz * qz)) * sy, 2 * (qy * qz - qw * qx) * sz
        m20, m21, m22 = 2 * (qx * qz - qw * qy) * sx, 2 * (qy * qz + qw * qx) * sy, (1 - 2 * (qx * qx + qy * qy)) * sz
        # T = J W (2 x 3), then A = T M (2 x 3); cov2d = A A^T
        tx = min(max(px / pz, -limx), limx) * pz
        ty = min(max(py / pz, -limy), limy) * pz
        j00, j02 = fx / pz, -fx * tx / (pz * pz)
        j11, j12 = fy / pz, -fy * ty / (pz * pz)
        a00, a01, a02 = j00 * r00 + j02 * r20, j00 * r01 + j02 * r21, j00 * r02 + j02 * r22
        a10, a11, a12 = j11 * r10 + j12 * r20, j11 * r11 + j12 * r21, j11 * r12 + j12 * r22
        b00 = a00 * m00 + a01 * m10 + a02 * m20
        b01 = a00 * m01 + a01 * m11 + a02 * m21
        b02 = a00 * m02 + a01 * m12 + a02 * m22
        b10 = a10 * m00 + a11 * m10 + a12 * m20
        b11 = a10 * m01 + a11 * m11 + a12 * m21
        b12 = a10 * m02 + a11 * m12 + a12 * m22
        ca = b00 * b00 + b01 * b01 + b02 * b02 + DILATION
        cb = b00 * b10 + b01 * b11 + b02 * b12
        cc = b10 * b10 + b11 * b11 + b12 * b12 + DILATION
        det = ca * cc - cb * cb
        if det <= 0.0:
            continue
        r2 = _reach2(o)
        hx, hy = math.sqrt(r2 * ca), math.sqrt(r2 * cc)
        x0, x1 = _tiles(u - hx, u + hx, width)
        y0, y1 = _tiles(v - hy, v + hy, height)
        if x1 <= x0 or y1 <= y0:
            continue
        dx, dy, dz = mx - ox, my - oy, mz - oz
        dn = max(math.sqrt(dx * dx + dy * dy + dz * dz), 1e-12)
        dx, dy, dz = dx / dn, dy / dn, dz / dn
        for c in range(3):
            rec[r, RED + c] = _sh_colour(sh, i, c, k, dx, dy, dz)
        rec[r, U], rec[r, V] = u, v
        rec[r, CA], rec[r, CB], rec[r, CC] = cc / det, -cb / det, ca / det
        rec[r, DEPTH], rec[r, OPAC], rec[r, HX], rec[r, HY] = pz, o, hx, hy
        rect[r, 0], rect[r, 1], rect[r, 2], rect[r, 3] = x0, x1, y0, y1
    return rect


@numba.njit(parallel=True, nogil=True, cache=True)
def _project(index, means, quats, log_scales, logits, sh, w2c, fx, fy, cx, cy, width, height,
             rec):  # pragma: no cover - jit
    """`_projection` compiled exactly: each operation rounded on its own (the float64 reference)."""
    return _projection(index, means, quats, log_scales, logits, sh, w2c, fx, fy, cx, cy, width, height, rec)


@numba.njit(parallel=True, nogil=True, cache=True, fastmath=FAST_MATH, error_model="numpy")
def _project_fast(index, means, quats, log_scales, logits, sh, w2c, fx, fy, cx, cy, width, height,
                  rec):  # pragma: no cover - jit
    """`_projection` compiled with FAST_MATH (float32 frames)."""
    return _projection(index, means, quats, log_scales, logits, sh, w2c, fx, fy, cx, cy, width, height, rec)


@numba.njit(cache=True)
def _parts(n, threads):  # pragma: no cover - jit
    """[P + 1] bounds of P near-equal slices of range(n), one per thread (one slice below 8192 items)."""
    p = max(1, min(threads, n // 8192))
    return (np.arange(p + 1) * n) // p


@numba.njit(cache=True)
def _starts(count):  # pragma: no cover - jit
    """Exclusive prefix sums of count [P, K] taken key-major (key 0 of every slice, then key 1, ...), in place: a
    stable counting sort's first output slot for each (slice, key); returns the total."""
    run = 0
    for d in range(count.shape[1]):
        for p in range(count.shape[0]):
            c = count[p, d]
            count[p, d] = run
            run += c
    return run


@numba.njit(parallel=True, nogil=True, cache=True)
def _depth_order(bits, threads):  # pragma: no cover - jit
    """np.argsort(depth, kind="stable") for positive depths given as their IEEE bits `bits` (depth.view of the
    unsigned integers of its width), whose unsigned order is the value order for positive floats: an LSD radix
    sort (stable) on 11-bit digits, 3 passes for float32, 6 for float64; each pass counts and scatters slices of
    the array in parallel."""
    n = bits.shape[0]
    bounds = _parts(n, threads)
    idx = np.arange(n)
    tmp = np.empty(n, np.int64)
    for shift in range(0, 8 * bits.itemsize, 11):
        count = np.zeros((len(bounds) - 1, 2048), np.int64)
        for p in numba.prange(len(bounds) - 1):
            for r in range(bounds[p], bounds[p + 1]):
                count[p, (bits[idx[r]] >> shift) & 0x7FF] += 1
        _starts(count)
        for p in numba.prange(len(bounds) - 1):
            for r in range(bounds[p], bounds[p + 1]):
                g = idx[r]
                d = (bits[g] >> shift) & 0x7FF
                tmp[count[p, d]] = g
                count[p, d] += 1
        idx, tmp = tmp, idx
    return idx


@numba.njit(parallel=True, nogil=True, cache=True)
def _bin(order, rect, gx, n_tiles, threads):  # pragma: no cover - jit
    """Counting sort of (tile, Gaussian) pairs, slices of `order` counted and placed in parallel; `order` is
    depth-sorted so each tile's run is too. Returns [n_tiles + 1] run starts and the pairs' Gaussians."""
    bounds = _parts(len(order), threads)
    count = np.zeros((len(bounds) - 1, n_tiles), np.int64)
    for p in numba.prange(len(bounds) - 1):
        for r in range(bounds[p], bounds[p + 1]):
            g = order[r]
            for ty in range(rect[g, 2], rect[g, 3]):
                for tx in range(rect[g, 0], rect[g, 1]):
                    count[p, ty * gx + tx] += 1
    offsets = np.empty(n_tiles + 1, np.int64)
    offsets[n_tiles] = _starts(count)
    offsets[:n_tiles] = count[0]
    pairs = np.empty(offsets[n_tiles], np.int32)  # rows of the frame's index (fewer than 2^31)
    for p in numba.prange(len(bounds) - 1):
        for r in range(bounds[p], bounds[p + 1]):
            g = order[r]
            for ty in range(rect[g, 2], rect[g, 3]):
                for tx in range(rect[g, 0], rect[g, 1]):
                    t = ty * gx + tx
                    pairs[count[p, t]] = g
                    count[p, t] += 1
    return offsets, pairs


@numba.njit(inline="always")
def _composite(offsets, pairs, rec, inst, width, height, bg,
               out_rgb, out_depth, out_alpha, out_inst, pair_weight):  # pragma: no cover - jit
    """Composite each tile's pairs front to back in the precision of `rec` (float32 frames, float64 reference):
    tile buffers, alpha and blending in that precision; each reach ellipse's box and rows in float64. The
    instance ids are drawn when out_inst has pixels, each pair's summed weight kept when pair_weight has room.
    Inlined into `_rasterise` and `_rasterise_fast`, which differ only in how numba compiles it."""
    real = rec.dtype.type
    zero, one, half, cut = real(0.0), real(1.0), real(0.5), real(CUTOFF)
    max_alpha, min_alpha, min_trans = real(MAX_ALPHA), real(MIN_ALPHA), real(MIN_TRANSMITTANCE)
    gx = (width + TILE - 1) // TILE
    n_tiles = offsets.shape[0] - 1
    ids, weights = out_inst.size > 0, pair_weight.size > 0
    for t in numba.prange(n_tiles):
        tx0, ty0 = (t % gx) * TILE, (t // gx) * TILE
        tw, th = min(TILE, width - tx0), min(TILE, height - ty0)
        trans = np.ones((th, tw), rec.dtype)
        acc = np.zeros((th, tw, 3), rec.dtype)
        dacc = np.zeros((th, tw), rec.dtype)
        best = np.zeros((th, tw), rec.dtype)
        bid = np.zeros((th, tw), np.int32)
        live = np.full(th, (1 << tw) - 1, np.int64)  # bit j of row i: pixel (i, j) still takes colour
        active = th * tw
        for k in range(offsets[t], offsets[t + 1]):
            g = pairs[k]
            u, v = rec[g, U], rec[g, V]
            ca, cb, cc = rec[g, CA], rec[g, CB], rec[g, CC]
            o, depth = rec[g, OPAC], rec[g, DEPTH]
            red, green, blue = rec[g, RED], rec[g, RED + 1], rec[g, RED + 2]
            # only the pixels of the reach ellipse's bounding box (its half width and height: projected in float64,
            # widened by _pixels): the per-pixel tests below drop the box's corners, at less cost than each row's
            # chord (a square root and a division per row; most boxes are 2-5 px a side)
            fu, fv, hx, hy = float(u), float(v), float(rec[g, HX]), float(rec[g, HY])
            i0, i1 = _pixels(fv - hy - ty0, fv + hy - ty0, th)
            j0, j1 = _pixels(fu - hx - tx0, fu + hx - tx0, tw)
            wsum = 0.0
            for i in range(i0, i1 + 1):
                row = live[i]
                if row == 0:
                    continue
                dy = v - (real(ty0 + i) + half)
                for j in range(j0, j1 + 1):
                    if not (row >> j) & 1:
                        continue
                    dx = u - (real(tx0 + j) + half)
                    power = -half * (ca * dx * dx + cc * dy * dy) - cb * dx * dy
                    if power > zero or power < -cut:
                        continue
                    alpha = min(max_alpha, o * _exp(power))
                    if alpha < min_alpha:
                        continue
                    tr = trans[i, j]
                    t_next = tr * (one - alpha)
                    if t_next < min_trans:
                        row &= ~(1 << j)
                        active -= 1
                        continue
                    w = alpha * tr
                    acc[i, j, 0] += w * red
                    acc[i, j, 1] += w * green
                    acc[i, j, 2] += w * blue
                    dacc[i, j] += w * depth
                    if ids and w > best[i, j]:
                        best[i, j] = w
                        bid[i, j] = inst[g]
                    trans[i, j] = t_next
                    if weights:
                        wsum += w
                live[i] = row
            if weights:
                pair_weight[k] = wsum
            if active == 0:
                break
        for i in range(th):
            for j in range(tw):
                tr = trans[i, j]
                for c in range(3):
                    out_rgb[ty0 + i, tx0 + j, c] = acc[i, j, c] + tr * bg[c]
                out_alpha[ty0 + i, tx0 + j] = one - tr
                out_depth[ty0 + i, tx0 + j] = dacc[i, j] / (one - tr) if tr < one else zero
                if ids:
                    out_inst[ty0 + i, tx0 + j] = bid[i, j]


@numba.njit(parallel=True, nogil=True, cache=True)
def _rasterise(offsets, pairs, rec, inst, width, height, bg,
               out_rgb, out_depth, out_alpha, out_inst, pair_weight):  # pragma: no cover - jit
    """`_composite` compiled exactly: each operation rounded on its own (the float64 reference)."""
    _composite(offsets, pairs, rec, inst, width, height, bg, out_rgb, out_depth, out_alpha, out_inst, pair_weight)


@numba.njit(parallel=True, nogil=True, cache=True, fastmath=FAST_MATH, error_model="numpy")
def _rasterise_fast(offsets, pairs, rec, inst, width, height, bg,
                    out_rgb, out_depth, out_alpha, out_inst, pair_weight):  # pragma: no cover - jit
    """`_composite` compiled with FAST_MATH (float32 frames)."""
    _composite(offsets, pairs, rec, inst, width, height, bg, out_rgb, out_depth, out_alpha, out_inst, pair_weight)


def _run(g: Gaussians, cam: Camera, background: tuple[float, float, float], index: np.ndarray | None = None,
         real: type = np.float32, weights: bool = False, ids: bool = True
         ) -> tuple[Frame, np.ndarray | None, np.ndarray | None]:
    """Render the Gaussians at `index` [M] (all when None) in precision `real` (float32 with the FAST_MATH
    kernels); with `weights`, also each (tile, Gaussian) pair's Gaussian (a row of g) and its blending weight
    summed over the tile; without `ids`, the frame's instance is None (and costs nothing)."""
    if max(cam.width, cam.height) > MAX_SIDE:
        raise ValueError(f"a {cam.width}x{cam.height} view: the renderer draws at most {MAX_SIDE} pixels a side")
    index = np.arange(g.count, dtype=np.int64) if index is None else np.asarray(index, dtype=np.int64)
    project, rasterise = (_project_fast, _rasterise_fast) if real == np.float32 else (_project, _rasterise)
    rec = np.empty((len(index), RECORD), real)
    rect = project(index, g.means, g.quats_wxyz, g.log_scales, g.opacity_logits, g.sh,
                    np.ascontiguousarray(cam.world_to_camera, np.float64),
                    float(cam.fx), float(cam.fy), float(cam.cx), float(cam.cy), cam.width, cam.height, rec)
    visible = np.flatnonzero(rect[:, 0] >= 0)
    threads = numba.get_num_threads()  # this thread's: 1 in render_packed's workers
    depth = np.ascontiguousarray(rec[visible, DEPTH])  # > NEAR > 0
    order = visible[_depth_order(depth.view(np.uint32 if real == np.float32 else np.uint64), threads)]
    gx, gy = (cam.width + TILE - 1) // TILE, (cam.height + TILE - 1) // TILE
    offsets, pairs = _bin(order, rect, gx, gx * gy, threads)
    h, w = cam.height, cam.width
    out_rgb = np.empty((h, w, 3), np.float32)
    out_depth = np.empty((h, w), np.float32)
    out_alpha = np.empty((h, w), np.float32)
    out_inst = np.empty((h, w) if ids else (0, 0), np.int32)
    pair_weight = np.zeros(len(pairs) if weights else 0)
    inst = g.instance_id[index] if ids else np.zeros(0, np.int32)
    rasterise(offsets, pairs, rec, inst, w, h, np.asarray(background, real),
               out_rgb, out_depth, out_alpha, out_inst, pair_weight)
    frame = Frame(rgb=out_rgb, depth=out_depth, alpha=out_alpha, instance=out_inst if ids else None)
    return (frame, index[pairs], pair_weight) if weights else (frame, None, None)


def render(g: Gaussians, cam: Camera, *, background: tuple[float, float, float] = (0.0, 0.0, 0.0),
           real: type = np.float32, ids: bool = True) -> Frame:
    """Render `g` through `cam`: RGB, expected depth, alpha and (with `ids`) the instance-id image;
    `real=REFERENCE` gives the float64 reference frame."""
    return _run(g, cam, background, real=real, ids=ids)[0]


def render_packed(packed: PackedGaussians, cams: Sequence[Camera], *,
                  background: tuple[float, float, float] = (0.0, 0.0, 0.0), real: type = np.float32,
                  ids: bool = True) -> list[Frame]:
    """One frame per camera of packed Gaussians, projecting only the chunks each camera may see; every frame
    equals `render(packed.gaussians, cam)` (chunks.py). Several cameras render concurrently, each frame on one
    thread: no barrier between a frame's passes and no core idling on a frame's serial sort and binning."""
    def one(cam: Camera) -> Frame:
        return _run(packed.gaussians, cam, background, visible_index(packed, cam), real, ids=ids)[0]

    threads = min(len(cams), numba.get_num_threads())
    if threads < 2 or not _concurrent_launches():
        return [one(cam) for cam in cams]
    return list(_pool(threads).map(one, cams))


def _concurrent_launches() -> bool:
    """Whether numba's threading layer takes kernel launches from several threads at once (omp and tbb do,
    workqueue aborts); False until the first parallel kernel has picked a layer."""
    try:
        return numba.threading_layer() in ("omp", "tbb")
    except ValueError:
        return False


@cache
def _pool(threads: int) -> ThreadPoolExecutor:
    """Worker threads whose kernels each run on one thread (numba's thread count is per calling thread)."""
    return ThreadPoolExecutor(threads, thread_name_prefix="splat", initializer=numba.set_num_threads,
                              initargs=(1,))


def contributions(g: Gaussians, cam: Camera) -> np.ndarray:
    """[N] float64: each Gaussian's blending weight alpha * T summed over the pixels of this view, rendered in the
    reference precision (build-scene prunes by it: its outputs do not depend on the frames' precision)."""
    _, pairs, pair_weight = _run(g, cam, (0.0, 0.0, 0.0), real=REFERENCE, weights=True, ids=False)
    return np.bincount(pairs, weights=pair_weight, minlength=g.count)
