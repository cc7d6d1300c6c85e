"""Centripetal Catmull-Rom splines through many polylines at once (docs/method.md §5).

Each yarn piece is a polyline of control points; the curve passes through every control point.
The centripetal parametrisation (knot spacing |P_{k+1} - P_k|^alpha with alpha = 1/2) has no
cusps or self-intersections inside a segment even when points are unevenly spaced, which happens
all the time at a tear (Yuksel, Schaefer, Keyser 2011, "Parameterization and applications of
Catmull-Rom curves", CAD 43(7)). Evaluation uses the Barry-Goldman pyramid.

All pieces are evaluated together: the input is one (N, 3) array of points with piece offsets,
so there is no Python loop over pieces or samples. End segments use a reflected phantom point
(P_-1 = 2 P_0 - P_1), which makes the curve leave its first point towards the second.
"""
from __future__ import annotations

from dataclasses import dataclass

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


def catmull_rom(points: np.ndarray, offsets: np.ndarray, samples_per_segment: int,
                alpha: float = ALPHA) -> SampledCurves:
    """Sample the centripetal Catmull-Rom spline of every piece.

    points: (N, 3) control points of all pieces; offsets: (K + 1,) with piece p owning
    points[offsets[p]:offsets[p+1]]; every piece needs at least 2 points. Each segment is sampled
    at u = 0, 1/m, ..., (m-1)/m, and each piece ends with its last control point, so a piece of
    n points gives (n - 1) m + 1 samples and sample k m of a piece is its control point k.
    """
    if samples_per_segment < 1:
        raise ValueError(f"samples_per_segment must be >= 1, got {samples_per_segment}")
    P = np.asarray(points, dtype=np.float64)
    off = np.asarray(offsets, dtype=np.int64)
    counts = np.diff(off)
    if counts.size and counts.min() < 2:
        raise ValueError("every piece needs at least 2 control points")
    m = int(samples_per_segment)
    k_count = counts.size
    seg_count = int((counts - 1).sum())
    if seg_count == 0:
        return SampledCurves(np.zeros((0, 3)), np.zeros(k_count + 1, np.int64), np.zeros(0, np.int64))

    # Segment s joins control points i and i+1 of its piece; seg_piece[s] is the piece.
    seg_piece = np.repeat(np.arange(k_count), counts - 1)
    seg_first = off[:-1][seg_piece]                      # first control point of the piece
    seg_last = off[1:][seg_piece] - 1                    # last control point of the piece
    i1 = np.arange(seg_count) + seg_piece                # control index of the segment start
    i2 = i1 + 1
    p1, p2 = P[i1], P[i2]
    at_start = i1 == seg_first
    at_end = i2 == seg_last
    p0 = np.where(at_start[:, None], 2.0 * p1 - p2, P[np.maximum(i1 - 1, 0)])
    p3 = np.where(at_end[:, None], 2.0 * p2 - p1, P[np.minimum(i2 + 1, len(P) - 1)])

    def step(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        d2 = np.einsum("ij,ij->i", b - a, b - a)
        return np.maximum(d2 ** (0.5 * alpha), _MIN_KNOT_STEP)

    t0 = np.zeros(seg_count)
    t1 = t0 + step(p0, p1)
    t2 = t1 + step(p1, p2)
    t3 = t2 + step(p2, p3)
    u = np.arange(m, dtype=np.float64) / m
    t = t1[:, None] + u[None, :] * (t2 - t1)[:, None]    # (S, m)

    a1 = _lerp_pts(p0[:, None, :], p1[:, None, :], t, t0, t1)
    a2 = _lerp_pts(p1[:, None, :], p2[:, None, :], t, t1, t2)
    a3 = _lerp_pts(p2[:, None, :], p3[:, None, :], t, t2, t3)
    b1 = _lerp_pts(a1, a2, t, t0, t2)
    b2 = _lerp_pts(a2, a3, t, t1, t3)
    c = _lerp_pts(b1, b2, t, t1, t2)                     # (S, m, 3)

    # Output rows: piece p's samples start at seg_start(p) * m + p (each earlier piece adds its
    # end point), and its last control point follows its last segment.
    out_off = np.zeros(k_count + 1, dtype=np.int64)
    out_off[1:] = np.cumsum((counts - 1) * m + 1)
    out = np.empty((out_off[-1], 3))
    rows = (np.arange(seg_count) * m + seg_piece)[:, None] + np.arange(m)[None, :]
    out[rows.ravel()] = c.reshape(-1, 3)
    out[out_off[1:] - 1] = P[off[1:] - 1]
    point_piece = np.repeat(np.arange(k_count), counts)
    control_index = (np.arange(len(P)) - point_piece) * m + point_piece
    return SampledCurves(out, out_off, control_index)


def _lerp_pts(pa: np.ndarray, pb: np.ndarray, t: np.ndarray, ta: np.ndarray, tb: np.ndarray) -> np.ndarray:
    """Barry-Goldman blend of two point sets ((S, m, 3) or (S, 1, 3)) at parameters t (S, m)
    between knots ta and tb (S,)."""
    w = ((t - ta[:, None]) / (tb - ta)[:, None])[..., None]
    return pa * (1.0 - w) + pb * w


def polyline_tangents(points: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Unit tangents of sampled pieces: central differences inside, one-sided at the ends.

    Shape (M, 3) in and out. A zero difference (repeated sample) falls back to the neighbouring
    segment's direction, and to +x if the whole piece has zero length.
    """
    X = np.asarray(points, dtype=np.float64)
    off = np.asarray(offsets, dtype=np.int64)
    M = len(X)
    if M == 0:
        return np.zeros((0, 3))
    nxt = np.minimum(np.arange(M) + 1, M - 1)
    prv = np.maximum(np.arange(M) - 1, 0)
    first = np.zeros(M, dtype=bool)
    last = np.zeros(M, dtype=bool)
    first[off[:-1]] = True
    last[off[1:] - 1] = True
    nxt[last] = np.arange(M)[last]
    prv[first] = np.arange(M)[first]
    d = X[nxt] - X[prv]
    length = np.linalg.norm(d, axis=1)
    bad = length < 1e-15
    if bad.any():
        fwd = X[nxt] - X[np.arange(M)]
        bwd = X[np.arange(M)] - X[prv]
        alt = np.where((np.linalg.norm(fwd, axis=1) > 1e-15)[:, None], fwd, bwd)
        d[bad] = alt[bad]
        length = np.linalg.norm(d, axis=1)
        still = length < 1e-15
        d[still] = (1.0, 0.0, 0.0)
        length[still] = 1.0
    return d / length[:, None]
