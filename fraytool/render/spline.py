"""Centripetal Catmull-Rom splines through many polylines at once (docs/method.md §5).

Each yarn piece is a polyline of control points; the curve passes through every control point.
The centripetal parametrisation (knot spacing |P_{k+1} - P_k|^alpha with alpha = 1/2) has no
cusps or self-intersections inside a segment even when points are unevenly spaced, which happens
all the time at a tear (Yuksel, Schaefer, Keyser 2011, "Parameterization and applications of
Catmull-Rom curves", CAD 43(7)). Evaluation uses the Barry-Goldman pyramid.

All pieces are evaluated together: the input is one (N, 3) array of points with piece offsets,
sampled by one compiled loop (numba) with no Python loop over pieces or samples. End segments use a reflected phantom point
(P_-1 = 2 P_0 - P_1), which makes the curve leave its first point towards the second.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

ALPHA = 0.5
"""Centripetal parametrisation exponent (0: uniform, 0.5: centripetal, 1: chordal)."""

_MIN_KNOT_STEP = 1e-9
"""Floor of a knot step (coincident control points would divide by zero)."""


@dataclass(frozen=True)
class SampledCurves:
    points: np.ndarray
    """Samples, shape (M, 3), float64; piece p owns rows offsets[p]:offsets[p+1]."""
    offsets: np.ndarray
    """Row offsets of each piece in `points`, shape (K + 1,), int64."""
    control_index: np.ndarray
    """Row in `points` of every input control point, shape (N,), int64 (the curve passes there)."""


def sample_counts(control_counts: np.ndarray, samples_per_segment: int) -> np.ndarray:
    """Samples of each piece: (n - 1) * m + 1 for a piece of n >= 2 control points."""
    n = np.asarray(control_counts, dtype=np.int64)
    return (n - 1) * samples_per_segment + 1


def catmull_rom(points: np.ndarray, offsets: np.ndarray, samples_per_segment,
                alpha: float = ALPHA) -> SampledCurves:
    """Sample the centripetal Catmull-Rom spline of every piece.

    points: (N, 3) control points of all pieces; offsets: (K + 1,) with piece p owning
    points[offsets[p]:offsets[p+1]]; every piece needs at least 2 points. Each segment is sampled
    at u = 0, 1/m, ..., (m-1)/m, and each piece ends with its last control point, so a piece of
    n points gives (n - 1) m + 1 samples and sample k m of a piece is its control point k.
    samples_per_segment: m for every segment, or an array (N - K,) with each segment's own m, segments
    in piece order (fraytool.render.lod); a piece then has sum(m) + 1 samples and control_index says
    where each control point is.
    """
    P = np.asarray(points, dtype=np.float64)
    off = np.asarray(offsets, dtype=np.int64)
    counts = np.diff(off)
    if counts.size and counts.min() < 2:
        raise ValueError("every piece needs at least 2 control points")
    k_count = counts.size
    seg_count = int((counts - 1).sum())
    given = np.asarray(samples_per_segment, dtype=np.int64)
    if given.size and given.min() < 1:
        raise ValueError(f"samples_per_segment must be >= 1, got {int(given.min())}")
    m = np.broadcast_to(given, (seg_count,)).copy()
    if seg_count == 0:
        return SampledCurves(np.zeros((0, 3)), np.zeros(k_count + 1, np.int64), np.zeros(0, np.int64))

    # Row of control point i: the samples of every segment before it, plus one end row per earlier piece.
    point_piece = np.repeat(np.arange(k_count), counts)
    seg_before = np.arange(len(P)) - point_piece                   # segments (all pieces) before point i
    rows_before = np.concatenate([[0], np.cumsum(m)])
    control_index = rows_before[seg_before] + point_piece
    out_off = np.zeros(k_count + 1, dtype=np.int64)
    out_off[1:] = control_index[off[1:] - 1] + 1
    out = np.empty((out_off[-1], 3))
    _sample_pieces(P, off, m, float(alpha), out)
    return SampledCurves(out, out_off, control_index)


@numba.njit(cache=True, inline="always")
def _knot_step(a, b, alpha):  # pragma: no cover - numba
    """|b - a|^alpha, floored at _MIN_KNOT_STEP (a and b: 3-vectors)."""
    d0, d1, d2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    return max((d0 * d0 + d1 * d1 + d2 * d2) ** (0.5 * alpha), _MIN_KNOT_STEP)


@numba.njit(cache=True)
def _sample_pieces(P, off, m, alpha, out_out):  # pragma: no cover - numba
    """The samples of catmull_rom into `out`, piece after piece: segment s gives m[s] rows and each
    piece ends with its last control point. End segments
    use the reflected phantom points 2 P_0 - P_1 and 2 P_n - P_{n-1}; Barry-Goldman pyramid."""
    p0 = np.empty(3)
    p3 = np.empty(3)
    row = 0
    seg = 0
    for piece in range(off.shape[0] - 1):
        first, last = off[piece], off[piece + 1] - 1
        for i1 in range(first, last):
            mp = m[seg]
            seg += 1
            i2 = i1 + 1
            p1, p2 = P[i1], P[i2]
            for c in range(3):
                p0[c] = 2.0 * p1[c] - p2[c] if i1 == first else P[i1 - 1, c]
                p3[c] = 2.0 * p2[c] - p1[c] if i2 == last else P[i2 + 1, c]
            t0 = 0.0
            t1 = t0 + _knot_step(p0, p1, alpha)
            t2 = t1 + _knot_step(p1, p2, alpha)
            t3 = t2 + _knot_step(p2, p3, alpha)
            for j in range(mp):
                t = t1 + (j / mp) * (t2 - t1)
                w01 = (t - t0) / (t1 - t0)
                w12 = (t - t1) / (t2 - t1)
                w23 = (t - t2) / (t3 - t2)
                w02 = (t - t0) / (t2 - t0)
                w13 = (t - t1) / (t3 - t1)
                for c in range(3):
                    a1 = p0[c] * (1.0 - w01) + p1[c] * w01
                    a2 = p1[c] * (1.0 - w12) + p2[c] * w12
                    a3 = p2[c] * (1.0 - w23) + p3[c] * w23
                    b1 = a1 * (1.0 - w02) + a2 * w02
                    b2 = a2 * (1.0 - w13) + a3 * w13
                    out_out[row, c] = b1 * (1.0 - w12) + b2 * w12
                row += 1
        for c in range(3):
            out_out[row, c] = P[last, c]
        row += 1


def polyline_tangents(points: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Unit tangents of sampled pieces: central differences inside, one-sided at the ends.

    Shape (M, 3) in and out. A zero difference (repeated sample) falls back to the neighbouring
    segment's direction, and to +x if the whole piece has zero length.
    """
    X = np.asarray(points, dtype=np.float64)
    off = np.asarray(offsets, dtype=np.int64)
    out = np.empty((len(X), 3))
    _tangents(X, off, out)
    return out


@numba.njit(cache=True, inline="always")
def _length(x, y, z):  # pragma: no cover - numba
    return np.sqrt(x * x + y * y + z * z)


@numba.njit(cache=True)
def _tangents(X, off, out_out):  # pragma: no cover - numba
    """polyline_tangents into `out`."""
    for piece in range(off.shape[0] - 1):
        first, last = off[piece], off[piece + 1] - 1
        for i in range(first, last + 1):
            nxt = i + 1 if i < last else i
            prv = i - 1 if i > first else i
            dx, dy, dz = X[nxt, 0] - X[prv, 0], X[nxt, 1] - X[prv, 1], X[nxt, 2] - X[prv, 2]
            length = _length(dx, dy, dz)
            if length < 1e-15:
                dx, dy, dz = X[nxt, 0] - X[i, 0], X[nxt, 1] - X[i, 1], X[nxt, 2] - X[i, 2]
                if not _length(dx, dy, dz) > 1e-15:
                    dx, dy, dz = X[i, 0] - X[prv, 0], X[i, 1] - X[prv, 1], X[i, 2] - X[prv, 2]
                length = _length(dx, dy, dz)
                if length < 1e-15:
                    dx, dy, dz, length = 1.0, 0.0, 0.0, 1.0
            out_out[i, 0] = dx / length
            out_out[i, 1] = dy / length
            out_out[i, 2] = dz / length
