"""Yarns as ribbons that face the viewer, shaded as round tubes (`[render] yarn_shape = "ribbon"`).

A tube of s sides costs 2 s triangles per spline sample step, and on llvmpipe every triangle costs
its set-up and rasterisation whatever its size (fig7 at 1280x720, 4x MSAA: 6-sided tubes about 260 ms
per frame to draw, ribbons about 150). A yarn a few pixels wide can instead be drawn as a flat strip through its centre line, as wide as the yarn and
turned to face the eye: 2 triangles per step, a sixth of a 6-sided tube. yarn.frag (RIBBON) then
finds, per pixel, where the ray through the pixel meets the round tube (from the position across
the strip and the angle between the ray and the yarn) and the tube's normal there, so the shading
(Lambert, Kajiya-Kay, shadows) and the depth are those of the tube, with no facets (a view-facing impostor, as hair and line renderers draw thin strands; here
the strip's shading, shadow lookup and depth are corrected to the cylinder).

Layout of a ribbon mesh of K pieces and M samples: vertices 2 M, sample-major (vertex 2 k is the
sample's left edge, 2 k + 1 its right edge, seen with the tangent pointing right); the normal slot
holds the unit direction across the strip, signed (-S on the left, +S on the right), which the
rasteriser interpolates to v S, v in [-1, 1] across the strip; triangles 2 per consecutive sample
pair inside a piece; no caps (broken ends fade out; ends at the border are cut square).
The shadow pass draws the same strips turned to face the light (`shadow_positions`), through every
other sample where the yarn runs nearly straight (`shadow_casters`): about half the triangles. A
sample is skipped only when it lies within CASTER_SAGITTA_RADII yarn radii of the chord between its
neighbours (about a texel of the figure scenes' maps); at kinks and tight bends every sample casts,
so the shadow's edge follows the drawn yarn there.

Straight steps: where a segment between two crossings is short on screen (fraytool.render.lod,
RIBBON_STRAIGHT_PX), the strip runs straight from one crossing to the next (2 triangles, not 4). Its
shape is then within a pixel of the spline, but interpolating the two crossings' tangents would lose
the yarn's tilt between them (the weave lifts it over one yarn and under the next: up to about 8 degrees in
the tablecloth's, and the highlights follow the tangent). So the spline is sampled at the step's middle
as well (`ribbon_curves`), the middle's tangent T_m goes to the step's end vertices with the start's
tangent T_0 (`step` columns), and yarn.vert/yarn.frag rebuild the tangent and the Kajiya-Kay terms
along the step as the linear blend of its ends plus 4 t (1 - t) times the middle's departure from it:
the tangent exact at both ends and the middle, the Kajiya-Kay terms nearly (the step's three are
evaluated with the eye direction of its end vertex). The per-step values are `flat` outputs of the step's provoking
vertex, the last of both its triangles (vertex 2 k + 2, the end sample's left edge). A segment whose
middle lies off its chord by more than the shadow casters' CASTER_SAGITTA_RADII (a tight bend at a tear
or over a body, not the weave) keeps its middle as a drawn sample.
"""
from __future__ import annotations

import numba
import numpy as np

from fraytool.render.spline import SampledCurves, catmull_rom, polyline_tangents
from fraytool.render.tube import VERTEX_FLOATS, body_pairs


@numba.njit(cache=True)
def _across(points, tangents, eye, direction, out_out):  # pragma: no cover - numba
    """Unit S = T x D per sample, D the direction to `eye` (if `direction` is all zero) or `direction`;
    where T and D are (nearly) parallel, any unit vector perpendicular to T."""
    for k in range(points.shape[0]):
        tx, ty, tz = tangents[k, 0], tangents[k, 1], tangents[k, 2]
        if direction[0] == 0.0 and direction[1] == 0.0 and direction[2] == 0.0:
            dx, dy, dz = eye[0] - points[k, 0], eye[1] - points[k, 1], eye[2] - points[k, 2]
        else:
            dx, dy, dz = direction[0], direction[1], direction[2]
        sx, sy, sz = ty * dz - tz * dy, tz * dx - tx * dz, tx * dy - ty * dx
        n = np.sqrt(sx * sx + sy * sy + sz * sz)
        d = np.sqrt(dx * dx + dy * dy + dz * dz)
        if n <= 1e-9 * d or n == 0.0:  # looking along the yarn: its width does not show
            ax, ay, az = abs(tx), abs(ty), abs(tz)
            if ax <= ay and ax <= az:
                sx, sy, sz = 0.0, tz, -ty
            elif ay <= az:
                sx, sy, sz = -tz, 0.0, tx
            else:
                sx, sy, sz = ty, -tx, 0.0
            n = np.sqrt(sx * sx + sy * sy + sz * sz)
        out_out[k, 0] = sx / n
        out_out[k, 1] = sy / n
        out_out[k, 2] = sz / n


def across(points: np.ndarray, tangents: np.ndarray, eye_m=None, direction=None) -> np.ndarray:
    """Unit vectors across the strip at every sample, (M, 3) float64: T x (eye - x) for a strip facing
    the point `eye_m`, or T x direction for one facing a direction (a directional light)."""
    X = np.ascontiguousarray(points, dtype=np.float64)
    T = np.ascontiguousarray(tangents, dtype=np.float64)
    out = np.zeros_like(X)
    e = np.zeros(3) if eye_m is None else np.asarray(eye_m, dtype=np.float64)
    d = np.zeros(3) if direction is None else np.asarray(direction, dtype=np.float64)
    if len(X):
        _across(X, T, e, d, out)
    return out


def ribbon_vertices(points: np.ndarray, tangents: np.ndarray, radius_m: float, alpha: np.ndarray,
                    warp: np.ndarray, eye_m: np.ndarray) -> np.ndarray:
    """Interleaved vertices (2 M, VERTEX_FLOATS) float32 of strips facing `eye_m` (module docstring)."""
    X = np.ascontiguousarray(points, dtype=np.float64)
    T = np.ascontiguousarray(tangents, dtype=np.float64)
    S = across(X, T, eye_m=eye_m)
    out = np.empty((2 * len(X), VERTEX_FLOATS), dtype=np.float32)
    if len(X):
        _fill_ribbon_vertices(X, T, S, float(radius_m), np.ascontiguousarray(alpha, dtype=np.float32),
                              np.ascontiguousarray(warp, dtype=np.float32), out)
    return out


@numba.njit(cache=True)
def _fill_ribbon_vertices(X, T, S, radius_m, alpha, warp, vertices_out):  # pragma: no cover - numba
    """The two vertices of every sample (module docstring's layout), positions X -+ radius S rounded
    to float32 from float64."""
    for k in range(X.shape[0]):
        left, right = 2 * k, 2 * k + 1
        for c in range(3):
            vertices_out[left, c] = X[k, c] - radius_m * S[k, c]
            vertices_out[right, c] = X[k, c] + radius_m * S[k, c]
            vertices_out[left, 3 + c] = -S[k, c]
            vertices_out[right, 3 + c] = S[k, c]
            vertices_out[left, 6 + c] = T[k, c]
            vertices_out[right, 6 + c] = T[k, c]
        vertices_out[left, 9] = alpha[k]
        vertices_out[right, 9] = alpha[k]
        vertices_out[left, 10] = warp[k]
        vertices_out[right, 10] = warp[k]


@numba.njit(cache=True, inline="always")
def _off_chord(X, k):  # pragma: no cover - numba
    """Distance of sample k from the middle of the chord between its neighbours k - 1 and k + 1 [m]."""
    d0 = X[k, 0] - 0.5 * (X[k - 1, 0] + X[k + 1, 0])
    d1 = X[k, 1] - 0.5 * (X[k - 1, 1] + X[k + 1, 1])
    d2 = X[k, 2] - 0.5 * (X[k - 1, 2] + X[k + 1, 2])
    return np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)


STEP_FLOATS = 7
"""Straight-step layout per ribbon vertex: the start tangent T_0 (3) and middle tangent T_m (3; zero where
it is not a straight step) of the step that ends at the vertex's sample, the sample's index along its
piece (1)."""


def ribbon_curves(points: np.ndarray, offsets: np.ndarray, samples, radius_m: float,
                  tilted: np.ndarray | None = None) -> tuple[SampledCurves, np.ndarray, np.ndarray]:
    """(curves, tangents, steps) of the pieces sampled `samples` per segment (a number or one per segment,
    as catmull_rom), a segment of one sample where `tilted` (bool per segment; None: every one-sample
    segment) drawn as a straight step (module docstring): its middle is
    sampled to find its tangent, then left out of the drawn samples -- unless it lies farther than
    CASTER_SAGITTA_RADII x `radius_m` from the chord (a tight bend, not the weave's rise and fall: the
    step then keeps its middle as a sample). tangents (M, 3): the drawn samples' unit tangents as with
    the middles in (polyline_tangents); steps (2 M, STEP_FLOATS) float32, per ribbon vertex (both of a
    sample alike), the data of the step that ends at the sample."""
    off = np.ascontiguousarray(offsets, dtype=np.int64)
    segments = int(off[-1]) - (len(off) - 1) if len(off) > 1 else 0
    m = np.broadcast_to(np.asarray(samples, dtype=np.int64), (segments,))
    straight = np.ascontiguousarray((m == 1) if tilted is None else (m == 1) & np.asarray(tilted, dtype=bool))
    fine = catmull_rom(points, off, np.where(straight, 2, m))
    fine_t = polyline_tangents(fine.points, fine.offsets)
    n = len(fine.points)
    curves_points, tangents = np.empty((n, 3)), np.empty((n, 3))
    curves_offsets = np.zeros(len(off), dtype=np.int64)
    control_index = np.empty(len(fine.control_index), dtype=np.int64)
    steps = np.zeros((2 * n, STEP_FLOATS), dtype=np.float32)
    M = _drop_middles(fine.points, fine_t, fine.offsets, fine.control_index, straight,
                      CASTER_SAGITTA_RADII * float(radius_m), curves_points, tangents, curves_offsets, control_index,
                      steps)
    return SampledCurves(curves_points[:M], curves_offsets, control_index), tangents[:M], steps[:2 * M]


@numba.njit(cache=True)
def _drop_middles(fine, fine_t, fine_off, fine_control, straight, sagitta_m, points_out, tangents_out, offsets_out,
                  control_out, steps_out):  # pragma: no cover - numba
    """ribbon_curves' samples: the fine samples but the middle of each straight segment within
    `sagitta_m` of its chord, whose tangent goes to the step data of the segment's end sample (and the
    previous drawn sample's tangent to every sample's, and its index along the piece). Returns how many."""
    row = 0
    seg = 0
    c = 0                                               # control point
    for p in range(fine_off.shape[0] - 1):
        first_row = row
        k = fine_off[p]
        end = fine_off[p + 1]
        while k < end:
            at_control = k == fine_control[c]
            if at_control:
                control_out[c] = row
                c += 1
            middle = -1
            if at_control and k + 1 < end:              # a segment starts here
                if straight[seg] and _off_chord(fine, k + 1) <= sagitta_m:
                    middle = k + 1
                seg += 1
            for d in range(3):
                points_out[row, d] = fine[k, d]
                tangents_out[row, d] = fine_t[k, d]
            for v in range(2):
                steps_out[2 * row + v, 6] = row - first_row
                for d in range(3):
                    steps_out[2 * row + v, d] = tangents_out[row - 1 if row > first_row else row, d]
            if middle >= 0:
                # the step ends at the next drawn sample, the fine one after the middle
                for v in range(2):
                    for d in range(3):
                        steps_out[2 * (row + 1) + v, 3 + d] = fine_t[middle, d]
                k += 2
            else:
                k += 1
            row += 1
        offsets_out[p + 1] = row
    return row


def ribbon_shadow_positions(points: np.ndarray, tangents: np.ndarray, radius_m: float,
                            light_dir: np.ndarray) -> np.ndarray:
    """Positions (2 M, 3) float32 of the same strips turned to face the key light (the direction
    towards it), for the shadow map: their depth from the light is the tube's axis, and their width
    the tube's as the light sees it."""
    X = np.asarray(points, dtype=np.float64)
    S = across(X, tangents, direction=light_dir)
    out = np.empty((2 * len(X), 3), dtype=np.float32)
    out[0::2] = X - radius_m * S
    out[1::2] = X + radius_m * S
    return out


CASTER_SAGITTA_RADII = 0.25
"""An odd spline sample is left out of the shadow casters only when it lies within this many yarn
radii of the chord between its neighbours (the golden torn cloth: 0.3 mm, about a texel of a 1024 map)."""


def ribbon_triangles(offsets: np.ndarray) -> np.ndarray:
    """Index buffer (F, 3) uint32 of the strips: for each consecutive sample pair r, r + 1 of a piece,
    (2r, 2r+1, 2r+2) and (2r+1, 2r+3, 2r+2). Depends only on the piece sample counts (cache it)."""
    a = (2 * body_pairs(offsets)).astype(np.uint32)
    tri = np.empty((len(a), 2, 3), dtype=np.uint32)
    for k, (first, second) in enumerate(((0, 1), (1, 3), (2, 2))):
        tri[:, 0, k] = a + first
        tri[:, 1, k] = a + second
    return tri.reshape(-1, 3)


def translucent_ribbon_triangles(offsets: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Mask over `ribbon_triangles(offsets)`: True where a triangle has a vertex with alpha < 1."""
    a = np.asarray(alpha) < 1.0
    r = body_pairs(offsets)
    return np.repeat(a[r] | a[r + 1], 2)


def shadow_casters(points: np.ndarray, tangents: np.ndarray, offsets: np.ndarray, alpha: np.ndarray,
                   radius_m: float, light_dir: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The strips turned to the light through the even samples of each piece, its last, and every odd
    sample farther than CASTER_SAGITTA_RADII x `radius_m` from the chord between its neighbours:
    positions (2 M', 3) float32 as ribbon_shadow_positions, and the opaque triangles over them
    (F', 3) uint32 -- a strip between two kept samples is left out when any sample from the one to
    the other fades (alpha < 1), as fading ends cast no shadow."""
    off = np.ascontiguousarray(offsets, dtype=np.int64)
    M = int(off[-1]) if len(off) else 0
    if M == 0:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint32)
    X = np.ascontiguousarray(points, dtype=np.float64)
    keep = np.empty(M, dtype=np.int64)
    kept = _caster_samples(X, off, CASTER_SAGITTA_RADII * radius_m, keep)
    keep = keep[:kept]
    positions = ribbon_shadow_positions(X[keep], np.asarray(tangents)[keep], radius_m, light_dir)
    triangles = np.empty((2 * kept, 3), dtype=np.uint32)
    count = _caster_triangles(keep, off, np.ascontiguousarray(np.asarray(alpha) < 1.0), triangles)
    return positions, triangles[:count]


@numba.njit(cache=True)
def _caster_samples(X, off, sagitta_m, keep_out):  # pragma: no cover - numba
    """Indices of the samples shadow_casters keeps into keep_out (in order); returns how many: each
    piece's even samples and its last, and an odd one farther than `sagitta_m` from the chord between
    its neighbours."""
    kept = 0
    for p in range(off.shape[0] - 1):
        first, last = off[p], off[p + 1] - 1
        for k in range(first, last + 1):
            use = (k - first) % 2 == 0 or k == last
            if not use:
                use = _off_chord(X, k) > sagitta_m
            if use:
                keep_out[kept] = k
                kept += 1
    return kept


@numba.njit(cache=True)
def _caster_triangles(keep, off, fading, tri_out):  # pragma: no cover - numba
    """The strips between consecutive kept samples of a piece (ribbon_triangles over the kept samples),
    left out where a sample from the one to the other fades; returns how many triangles."""
    count = 0
    a = 0                                               # kept index of the strip's first sample
    for p in range(off.shape[0] - 1):
        end = off[p + 1]
        while a + 1 < keep.shape[0] and keep[a + 1] < end:
            see_through = False
            for k in range(keep[a], keep[a + 1] + 1):
                if fading[k]:
                    see_through = True
                    break
            if not see_through:
                v = 2 * a
                tri_out[count, 0], tri_out[count, 1], tri_out[count, 2] = v, v + 1, v + 2
                tri_out[count + 1, 0], tri_out[count + 1, 1], tri_out[count + 1, 2] = v + 1, v + 3, v + 2
                count += 2
            a += 1
        if a < keep.shape[0] and keep[a] < end:     # the piece's last kept sample starts no strip
            a += 1
    return count
