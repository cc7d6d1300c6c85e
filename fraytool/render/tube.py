"""Tubes around sampled yarn centre lines: rotation-minimising frames, sweep, caps, fade alpha.

Frames: a tube swept with Frenet frames twists wherever the curvature changes sign and is
undefined on straight stretches; a rotation-minimising (parallel-transport) frame has neither
problem (Bishop 1975, "There is more than one way to frame a curve"; Hanson & Ma 1995). The frame
is carried from sample to sample by the double-reflection method (Wang, Juttler, Zheng, Liu 2008,
"Computation of rotation minimizing frames", ACM TOG 27(1)), which is cheap and accurate to
fourth order. Transport is inherently sequential along a piece, so it is one numba loop over all
samples of all pieces; everything else (sweep, indices, alpha) is batched NumPy.

Layout of a mesh built from K pieces with M samples in total and s sides:
- ring vertices: M * s, sample-major (vertex k * s + q is side q of sample k);
- cap vertices: 2 K (s + 1): for each piece, the start cap (centre, then s rim vertices) and the
  end cap, with flat normals along -T and +T;
- triangles: 2 s per consecutive sample pair inside a piece, plus s per cap; wound
  counter-clockwise seen from outside (front faces), so back-face culling is valid.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np


@numba.njit(cache=True)
def _transport(points, tangents, offsets, reference, normal_out):  # pragma: no cover - numba
    for p in range(offsets.shape[0] - 1):
        a = offsets[p]
        b = offsets[p + 1]
        if b <= a:
            continue
        t0x, t0y, t0z = tangents[a, 0], tangents[a, 1], tangents[a, 2]
        # Start frame: the reference normal made perpendicular to the tangent; if it is (nearly)
        # parallel, the coordinate axis least aligned with the tangent.
        rx, ry, rz = reference[p, 0], reference[p, 1], reference[p, 2]
        d = rx * t0x + ry * t0y + rz * t0z
        rx -= d * t0x
        ry -= d * t0y
        rz -= d * t0z
        ln = np.sqrt(rx * rx + ry * ry + rz * rz)
        if ln < 1e-6:
            ax, ay, az = abs(t0x), abs(t0y), abs(t0z)
            if ax <= ay and ax <= az:
                rx, ry, rz = 1.0, 0.0, 0.0
            elif ay <= az:
                rx, ry, rz = 0.0, 1.0, 0.0
            else:
                rx, ry, rz = 0.0, 0.0, 1.0
            d = rx * t0x + ry * t0y + rz * t0z
            rx -= d * t0x
            ry -= d * t0y
            rz -= d * t0z
            ln = np.sqrt(rx * rx + ry * ry + rz * rz)
        rx /= ln
        ry /= ln
        rz /= ln
        normal_out[a, 0], normal_out[a, 1], normal_out[a, 2] = rx, ry, rz
        for k in range(a, b - 1):
            # Reflection 1 in the plane bisecting x_k and x_k+1.
            v1x = points[k + 1, 0] - points[k, 0]
            v1y = points[k + 1, 1] - points[k, 1]
            v1z = points[k + 1, 2] - points[k, 2]
            c1 = v1x * v1x + v1y * v1y + v1z * v1z
            tx, ty, tz = tangents[k, 0], tangents[k, 1], tangents[k, 2]
            if c1 > 1e-30:
                f = 2.0 / c1 * (v1x * rx + v1y * ry + v1z * rz)
                rlx, rly, rlz = rx - f * v1x, ry - f * v1y, rz - f * v1z
                f = 2.0 / c1 * (v1x * tx + v1y * ty + v1z * tz)
                tlx, tly, tlz = tx - f * v1x, ty - f * v1y, tz - f * v1z
            else:  # repeated sample: nothing to reflect
                rlx, rly, rlz = rx, ry, rz
                tlx, tly, tlz = tx, ty, tz
            # Reflection 2 mapping the reflected tangent onto t_k+1.
            nx, ny, nz = tangents[k + 1, 0], tangents[k + 1, 1], tangents[k + 1, 2]
            v2x, v2y, v2z = nx - tlx, ny - tly, nz - tlz
            c2 = v2x * v2x + v2y * v2y + v2z * v2z
            if c2 > 1e-30:
                f = 2.0 / c2 * (v2x * rlx + v2y * rly + v2z * rlz)
                rx, ry, rz = rlx - f * v2x, rly - f * v2y, rlz - f * v2z
            else:
                rx, ry, rz = rlx, rly, rlz
            # Re-orthonormalise against round-off drift over long pieces.
            d = rx * nx + ry * ny + rz * nz
            rx -= d * nx
            ry -= d * ny
            rz -= d * nz
            ln = np.sqrt(rx * rx + ry * ry + rz * rz)
            if ln > 1e-12:
                rx /= ln
                ry /= ln
                rz /= ln
            normal_out[k + 1, 0], normal_out[k + 1, 1], normal_out[k + 1, 2] = rx, ry, rz


def transport_frames(points: np.ndarray, tangents: np.ndarray, offsets: np.ndarray,
                     reference_normal: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Rotation-minimising frames (normal U, binormal V = T x U) at every sample.

    points, tangents: (M, 3), unit tangents; offsets: (K + 1,) piece offsets; reference_normal:
    (K, 3) direction the first frame's normal should lean to (e.g. the cloth normal), default
    least-aligned coordinate axis. Returns (U, V), each (M, 3) float64, orthonormal with T.
    """
    X = np.ascontiguousarray(points, dtype=np.float64)
    T = np.ascontiguousarray(tangents, dtype=np.float64)
    off = np.ascontiguousarray(offsets, dtype=np.int64)
    k = len(off) - 1
    ref = (np.zeros((k, 3)) if reference_normal is None
           else np.ascontiguousarray(reference_normal, dtype=np.float64).reshape(k, 3))
    U = np.zeros_like(X)
    if len(X):
        _transport(X, T, off, ref, U)
    V = np.cross(T, U)
    return U, V


def fade_alpha(points: np.ndarray, offsets: np.ndarray, broken_start: np.ndarray, broken_end: np.ndarray,
               fade_length_m: float) -> np.ndarray:
    """Per-sample alpha: 1, falling linearly to 0 over the last `fade_length_m` of arc length
    towards each broken (cut) end; ends at the cloth border stay opaque. Shape (M,), float32."""
    X = np.ascontiguousarray(points, dtype=np.float64)
    off = np.ascontiguousarray(offsets, dtype=np.int64)
    M = len(X)
    alpha = np.ones(M, dtype=np.float32)
    if M == 0 or fade_length_m <= 0:
        return alpha
    _fade(X, off, np.ascontiguousarray(broken_start, dtype=np.bool_), np.ascontiguousarray(broken_end, dtype=np.bool_),
          float(fade_length_m), alpha)
    return alpha


@numba.njit(cache=True)
def _fade(X, off, broken_start, broken_end, fade_length_m, alpha_out):  # pragma: no cover - numba
    """fade_alpha into alpha_out (all ones on entry): the arc length s as a running sum over all samples
    (no length across piece boundaries), then, in each piece with a broken end, the share of the fade
    length to that end, clipped to [0, 1]."""
    M = X.shape[0]
    s = np.empty(M)
    total = 0.0
    p = 0
    for k in range(M):
        while k >= off[p + 1]:
            p += 1
        if k > off[p]:
            dx, dy, dz = X[k, 0] - X[k - 1, 0], X[k, 1] - X[k - 1, 1], X[k, 2] - X[k - 1, 2]
            total += np.sqrt(dx * dx + dy * dy + dz * dz)
        s[k] = total
    for p in range(off.shape[0] - 1):
        if not (broken_start[p] or broken_end[p]):
            continue
        first, last = off[p], off[p + 1] - 1
        for k in range(first, last + 1):
            a = 1.0
            if broken_start[p]:
                a = min(a, (s[k] - s[first]) / fade_length_m)
            if broken_end[p]:
                a = min(a, (s[last] - s[k]) / fade_length_m)
            alpha_out[k] = min(max(a, 0.0), 1.0)


VERTEX_FLOATS = 11
"""Interleaved vertex layout: position (3), normal (3), tangent (3), alpha (1), warp flag (1)."""


@dataclass(frozen=True)
class TubeMesh:
    vertices: np.ndarray
    """Interleaved vertex data, shape (V, VERTEX_FLOATS), float32."""
    triangles: np.ndarray
    """Vertex indices, shape (F, 3), uint32, counter-clockwise from outside."""

    @property
    def position(self) -> np.ndarray:
        """Vertex positions [m], (V, 3) view."""
        return self.vertices[:, 0:3]

    @property
    def normal(self) -> np.ndarray:
        """Unit surface normals, (V, 3) view."""
        return self.vertices[:, 3:6]

    @property
    def tangent(self) -> np.ndarray:
        """Unit yarn tangent (Kajiya-Kay shading), (V, 3) view."""
        return self.vertices[:, 6:9]

    @property
    def alpha(self) -> np.ndarray:
        """Opacity, (V,) view."""
        return self.vertices[:, 9]

    @property
    def warp(self) -> np.ndarray:
        """1 on warp yarns, 0 on weft yarns, (V,) view."""
        return self.vertices[:, 10]


def tube_vertex_count(sample_counts: np.ndarray, sides: int) -> int:
    """Vertices of tubes with these per-piece sample counts: s n + 2 (s + 1) per piece."""
    n = np.asarray(sample_counts, dtype=np.int64)
    return int((sides * n + 2 * (sides + 1)).sum())


def tube_triangle_count(sample_counts: np.ndarray, sides: int) -> int:
    """Triangles of tubes with these per-piece sample counts: 2 s (n - 1) body + 2 s cap per piece."""
    n = np.asarray(sample_counts, dtype=np.int64)
    return int((2 * sides * (n - 1) + 2 * sides).sum())


def tube_triangles(offsets: np.ndarray, sides: int) -> np.ndarray:
    """Index buffer of the tubes (depends only on the piece sample counts; cache it).

    Order: body triangles, 2 s per consecutive sample pair (pairs in sample order, then side, then
    the two triangles of the quad); then the start caps (s per piece); then the end caps.
    """
    off = np.asarray(offsets, dtype=np.int64)
    counts = np.diff(off)
    k = len(counts)
    M = int(off[-1])
    s = int(sides)
    q = np.arange(s)
    qn = (q + 1) % s
    r = body_pairs(off)
    base = (r * s)[:, None]
    a = base + q                       # sample r, side q
    b = base + qn                      # sample r, side q+1
    c = base + s + q                   # sample r+1, side q
    d = base + s + qn
    body = np.stack([np.stack([a, b, c], -1), np.stack([b, d, c], -1)], axis=2).reshape(-1, 3)
    # Caps: centre then rim; start cap faces -T, end cap faces +T.
    cap0 = M * s + np.arange(k) * 2 * (s + 1)
    cap1 = cap0 + (s + 1)
    start = np.stack([np.repeat(cap0, s), (cap0[:, None] + 1 + qn).ravel(), (cap0[:, None] + 1 + q).ravel()], -1)
    end = np.stack([np.repeat(cap1, s), (cap1[:, None] + 1 + q).ravel(), (cap1[:, None] + 1 + qn).ravel()], -1)
    return np.concatenate([body, start, end]).astype(np.uint32)


def body_pairs(offsets: np.ndarray) -> np.ndarray:
    """Index r of every sample that has a successor in its piece (the quads' first samples)."""
    off = np.asarray(offsets, dtype=np.int64)
    M = int(off[-1])
    last = np.zeros(M, dtype=bool)
    last[off[1:] - 1] = True
    return np.nonzero(~last)[0]


def translucent_triangles(offsets: np.ndarray, sides: int, alpha: np.ndarray) -> np.ndarray:
    """Mask over `tube_triangles(offsets, sides)`: True where a triangle has a vertex with alpha < 1.

    Computed per sample pair and per cap from the sample alphas (no gather over triangles)."""
    off = np.asarray(offsets, dtype=np.int64)
    a = np.asarray(alpha) < 1.0
    r = body_pairs(off)
    pair = a[r] | a[r + 1]
    return np.concatenate([np.repeat(pair, 2 * sides), np.repeat(a[off[:-1]], sides),
                           np.repeat(a[off[1:] - 1], sides)])


@numba.njit(cache=True)
def _sweep(points, tangents, normals, alpha, warp, offsets, radius, sides, out_inout):  # pragma: no cover - numba
    M = points.shape[0]
    K = offsets.shape[0] - 1
    for k in range(M):
        tx, ty, tz = tangents[k, 0], tangents[k, 1], tangents[k, 2]
        ux, uy, uz = normals[k, 0], normals[k, 1], normals[k, 2]
        vx, vy, vz = ty * uz - tz * uy, tz * ux - tx * uz, tx * uy - ty * ux     # V = T x U
        for q in range(sides):
            th = 2.0 * np.pi * q / sides
            c, s = np.cos(th), np.sin(th)
            nx, ny, nz = c * ux + s * vx, c * uy + s * vy, c * uz + s * vz
            row = k * sides + q
            out_inout[row, 0] = points[k, 0] + radius * nx
            out_inout[row, 1] = points[k, 1] + radius * ny
            out_inout[row, 2] = points[k, 2] + radius * nz
            out_inout[row, 3], out_inout[row, 4], out_inout[row, 5] = nx, ny, nz
            out_inout[row, 6], out_inout[row, 7], out_inout[row, 8] = tx, ty, tz
            out_inout[row, 9] = alpha[k]
            out_inout[row, 10] = warp[k]
    for p in range(K):
        for end in range(2):
            k = offsets[p] if end == 0 else offsets[p + 1] - 1
            sign = -1.0 if end == 0 else 1.0
            base = M * sides + (2 * p + end) * (sides + 1)
            for j in range(sides + 1):
                row = base + j
                if j == 0:
                    out_inout[row, 0], out_inout[row, 1], out_inout[row, 2] = points[k, 0], points[k, 1], points[k, 2]
                else:
                    src = k * sides + j - 1
                    out_inout[row, 0], out_inout[row, 1], out_inout[row, 2] = out_inout[src, 0], out_inout[src, 1], out_inout[src, 2]
                out_inout[row, 3] = sign * tangents[k, 0]
                out_inout[row, 4] = sign * tangents[k, 1]
                out_inout[row, 5] = sign * tangents[k, 2]
                out_inout[row, 6], out_inout[row, 7], out_inout[row, 8] = tangents[k, 0], tangents[k, 1], tangents[k, 2]
                out_inout[row, 9] = alpha[k]
                out_inout[row, 10] = warp[k]


def sweep_tubes(points: np.ndarray, tangents: np.ndarray, offsets: np.ndarray, radius_m: float, sides: int,
                alpha: np.ndarray, warp: np.ndarray | None = None, reference_normal: np.ndarray | None = None,
                triangles: np.ndarray | None = None) -> TubeMesh:
    """Sweep a circle of `radius_m` with `sides` vertices along every piece and cap both ends.

    points, tangents, alpha, warp: per sample (warp: 1 on warp yarns, 0 on weft); offsets: (K + 1,)
    piece offsets; reference_normal (K, 3) orients the first frame of each piece. `triangles` may
    be a cached `tube_triangles(offsets, sides)` for the same sample counts.
    """
    X = np.ascontiguousarray(points, dtype=np.float64)
    T = np.ascontiguousarray(tangents, dtype=np.float64)
    off = np.ascontiguousarray(offsets, dtype=np.int64)
    k = len(off) - 1
    s = int(sides)
    if s < 3:
        raise ValueError(f"a tube needs at least 3 sides, got {s}")
    U, _ = transport_frames(X, T, off, reference_normal)
    M = len(X)
    a = np.ascontiguousarray(alpha, dtype=np.float32)
    w = np.zeros(M, np.float32) if warp is None else np.ascontiguousarray(warp, dtype=np.float32)
    out = np.empty((M * s + 2 * k * (s + 1), VERTEX_FLOATS), dtype=np.float32)
    if M:
        _sweep(X, T, U, a, w, off, float(radius_m), s, out)
    if triangles is None:
        triangles = tube_triangles(off, s)
    return TubeMesh(out, triangles)
