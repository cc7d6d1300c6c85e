"""How much of each yarn family a view of the weave sees: a table over view directions, ray cast
through our own yarn geometry, for the far-field surface (fraytool.render.farfield).

From straight above, weft and warp yarns of diameter D at spacing s each show a - a^2 / 2 of the cloth
(a = D / s; the crossings split between them by the weave) and a share (1 - a)^2 is gap. From a
grazing view the gaps close and the family that runs across the view stands in front, but not
completely: the yarns run over and under each other, so the one along the view still shows on top
of the crossings where the weave puts it there. Rather than guess a formula, we measure it: one weave
repeat built as the renderer builds the yarns (docs/method.md §5: each yarn passes its crossings at
+-T/2 from the cloth's middle, as the weave says, here between them on a half cosine; solid round
yarns of the render radius, so a slanting ray may pass under one through a gap), and orthographic
rays from each direction of a table (elevation above the cloth x azimuth from the weft direction)
cast through it. The table holds, per direction,
the share of rays that first meet a weft yarn and a warp yarn; the rest pass through the gaps.
farfield.vert looks it up (linear filtering between directions).

The same rays say which part of each yarn's round surface the view sees: at a hit, the yarn's normal
lies in its cross-section at an angle phi from the cloth's normal, positive towards the eye's side of
the yarn. A second table holds, per direction and family, the share of that family's hits in each of
NORMAL_BINS bins of phi over [-90, 90] degrees (the rare hits beyond count in the end bins).
farfield.vert shades each family at the bins' normals, weighted so (a yarn's upper part where the
neighbours hide its flanks, the flank facing the eye from a grazing view), instead of guessing which
part is seen.

The yarns are sampled at SAMPLES_PER_SPACING columns per spacing (each column: the span of the weft
and of the warp yarn there, with the yarn's axis height and offset across it); rays start on a grid
of the same density over the repeat (every k-th column where the repeat is large: at most RAY_BUDGET
rays per direction) and march in steps of a tenth of a column until they enter a yarn (a hit) or pass
below the lowest (a gap). numba, about 0.2 s per table.
"""
from __future__ import annotations

import math

import numba
import numpy as np

ELEVATIONS = 16
"""Table rows: elevation above the cloth, sin(elevation) from 1 / ELEVATIONS to 1 in even steps."""
AZIMUTHS = 16
"""Table columns: azimuth from the weft direction, 0 to 180 degrees (a view and its opposite are alike)."""
SAMPLES_PER_SPACING = 24
"""Columns per yarn spacing of the yarn field (a repeat over 16 crossings gets fewer, at least 12)."""
RAY_BUDGET = 96 * 96
"""Most rays per direction: a larger repeat (over 4 x 4 crossings) casts from every k-th column."""
NORMAL_BINS = 8
"""Bins of the seen normal's angle around the yarn (phi in [-90, 90] degrees, module docstring)."""


@numba.njit(cache=True, inline="always")
def _yarn_span(along, across, up0, up1, radius, half_thickness):  # pragma: no cover - numba
    """(bottom, top, axis height, axis slope) of a round yarn's cross-section at a point `along` its
    length (its crossings at integer + 0.5, up or down by up0 / up1 at the two either side, a half cosine
    between) and `across` it from its axis; bottom, top (inf, -inf) off it."""
    t = along - 0.5 - math.floor(along - 0.5)
    a0 = half_thickness if up0 else -half_thickness
    a1 = half_thickness if up1 else -half_thickness
    centre = a0 + (a1 - a0) * 0.5 * (1.0 - math.cos(math.pi * t))
    slope = (a1 - a0) * 0.5 * math.pi * math.sin(math.pi * t)
    if abs(across) >= radius:
        return 1e9, -1e9, centre, slope
    half = math.sqrt(radius * radius - across * across)
    return centre - half, centre + half, centre, slope


@numba.njit(cache=True)
def _yarn_field(on_top, radius, half_thickness, n):  # pragma: no cover - numba
    """Where the yarns are over one weave repeat, in spacing units: (py n, px n, 2, 5) float64, for each
    column the (bottom, top, axis height, offset from the axis across the yarn, axis slope along +u for
    the weft, +z for the warp) of the weft yarn there ([..., 0, :]) and of the warp yarn ([..., 1, :]);
    bottom, top (inf, -inf) where there is none. The yarns are solid round tubes, open below as above."""
    py, px = on_top.shape
    Ny, Nx = py * n, px * n
    span = np.zeros((Ny, Nx, 2, 5))
    span[:, :, :, 0] = 1e9
    span[:, :, :, 1] = -1e9
    for y in range(Ny):
        z = (y + 0.5) / n                               # position across the weft yarns (j direction)
        for x in range(Nx):
            u = (x + 0.5) / n                           # position along the weft yarns (i direction)
            for d in range(-1, 2):                      # weft yarns j near z, along u
                j = int(math.floor(z)) + d
                i0 = int(math.floor(u - 0.5))
                lo, hi, axis, slope = _yarn_span(u, z - (j + 0.5), on_top[j % py, i0 % px],
                                                 on_top[j % py, (i0 + 1) % px], radius, half_thickness)
                if hi > span[y, x, 0, 1]:
                    span[y, x, 0, 0], span[y, x, 0, 1] = lo, hi
                    span[y, x, 0, 2], span[y, x, 0, 3], span[y, x, 0, 4] = axis, z - (j + 0.5), slope
            for d in range(-1, 2):                      # warp yarns i near u, along z: up where the weft is not
                i = int(math.floor(u)) + d
                j0 = int(math.floor(z - 0.5))
                lo, hi, axis, slope = _yarn_span(z, u - (i + 0.5), not on_top[j0 % py, i % px],
                                                 not on_top[(j0 + 1) % py, i % px], radius, half_thickness)
                if hi > span[y, x, 1, 1]:
                    span[y, x, 1, 0], span[y, x, 1, 1] = lo, hi
                    span[y, x, 1, 2], span[y, x, 1, 3], span[y, x, 1, 4] = axis, u - (i + 0.5), slope
    return span


@numba.njit(cache=True, inline="always")
def _seen_normal(span, iz, ix, family, height, across_eye, along_eye, bins, seen_inout):  # pragma: no cover - numba
    """Count a ray entering a yarn of `family` (0 weft, 1 warp) in column (iz, ix) at `height` in
    `seen_inout` (2, 2, bins): its bin of the normal's angle phi (module docstring) in [0], the normal's
    part along the yarn towards the eye (the axis' slope tilts it) summed in [1]. `across_eye`, `along_eye`: +1
    or -1, the signs of the across offsets and of the yarn's direction on the eye's side."""
    phi = math.atan2(across_eye * span[iz, ix, family, 3], height - span[iz, ix, family, 2])
    b = min(max(int(math.floor((phi / math.pi + 0.5) * bins)), 0), bins - 1)
    slope = span[iz, ix, family, 4]
    seen_inout[0, family, b] += 1.0
    seen_inout[1, family, b] += -along_eye * slope * math.cos(phi) / math.sqrt(1.0 + slope * slope)


@numba.njit(cache=True)
def _cast(span, n, stride, sin_elevation, azimuth, bottom, top, normals_out):  # pragma: no cover - numba
    """(weft, warp) shares of orthographic rays going down at `sin_elevation`, heading `azimuth`
    [rad] from the weft direction, over one repeat of the yarn field (a ray from every `stride`-th
    column each way): the first yarn a ray enters;
    rays that pass below every yarn go through a gap. normals_out (2, 2, bins) receives each family's
    hits per bin of the seen normal (module docstring) as a share of that family's hits ([0, family]),
    and the mean part of those normals along the yarn towards the eye ([1, family])."""
    Ny, Nx = span.shape[0], span.shape[1]
    bins = normals_out.shape[2]
    cos_e = math.sqrt(max(0.0, 1.0 - sin_elevation * sin_elevation))
    dx, dz = cos_e * math.cos(azimuth), cos_e * math.sin(azimuth)
    dy = -sin_elevation
    # the eye is where the rays come from: across the weft (z) on the side -dz, across the warp (x) -dx
    eye_x = -1.0 if dx > 0.0 else 1.0
    eye_z = -1.0 if dz > 0.0 else 1.0
    step = 0.1 / n                                      # [spacings] along the ray
    hits_weft = 0
    hits_warp = 0
    normals_out[:, :, :] = 0.0
    rays = 0
    for y0 in range(0, Ny, stride):
        for x0 in range(0, Nx, stride):
            rays += 1
            # start above the highest yarn, on the ray through this sample's centre on the top plane
            px_ = (x0 + 0.5) / n
            pz_ = (y0 + 0.5) / n
            py_ = top
            while py_ > bottom:
                ix = int(math.floor(px_ * n)) % Nx
                iz = int(math.floor(pz_ * n)) % Ny
                if span[iz, ix, 0, 0] <= py_ <= span[iz, ix, 0, 1]:
                    hits_weft += 1
                    _seen_normal(span, iz, ix, 0, py_, eye_z, eye_x, bins, normals_out)
                    break
                if span[iz, ix, 1, 0] <= py_ <= span[iz, ix, 1, 1]:
                    hits_warp += 1
                    _seen_normal(span, iz, ix, 1, py_, eye_x, eye_z, bins, normals_out)
                    break
                px_ += dx * step
                pz_ += dz * step
                py_ += dy * step
    total = max(rays, 1)
    for f in range(2):
        for b in range(bins):
            normals_out[1, f, b] /= max(normals_out[0, f, b], 1.0)
    normals_out[0, 0, :] /= max(hits_weft, 1)
    normals_out[0, 1, :] /= max(hits_warp, 1)
    return hits_weft / total, hits_warp / total


def samples_per_spacing(tile_shape: tuple[int, int]) -> int:
    """Yarn-field columns per spacing for a repeat of `tile_shape` crossings: SAMPLES_PER_SPACING, fewer
    (at least 12) over 16 crossings, so the field stays under 800 x 800 columns."""
    return max(12, min(SAMPLES_PER_SPACING, 384 // max(tile_shape)))


def view_tables(on_top_tile: np.ndarray, radius_m: float, spacing_m: float, thickness_m: float,
                elevations: int = ELEVATIONS, azimuths: int = AZIMUTHS, samples: int | None = None,
                bins: int = NORMAL_BINS) -> tuple[np.ndarray, np.ndarray]:
    """(shares, normals): shares (elevations, azimuths, 2) float32, the weft and warp shares seen from
    each table direction; normals (elevations, azimuths, 2, 2, bins) float32: [..., 0, family, :] each
    family's seen normals per bin of phi (module docstring; they sum to 1 where it is seen at all),
    [..., 1, family, :] their mean part along the yarn towards the eye. Row e:
    sin(elevation) = (e + 1) / elevations (the last row straight above); column a: azimuth a /
    azimuths x 180 degrees."""
    tile = np.ascontiguousarray(on_top_tile, dtype=np.bool_)
    samples = samples_per_spacing(tile.shape) if samples is None else int(samples)
    r = float(radius_m) / float(spacing_m)
    half_t = 0.5 * float(thickness_m) / float(spacing_m)
    span = _yarn_field(tile, r, half_t, samples)
    stride = max(1, math.ceil(math.sqrt(span.shape[0] * span.shape[1] / RAY_BUDGET)))
    shares = np.zeros((elevations, azimuths, 2), dtype=np.float32)
    normals = np.zeros((elevations, azimuths, 2, 2, bins), dtype=np.float32)
    seen = np.zeros((2, 2, bins))
    for e in range(elevations):
        s = (e + 1.0) / elevations
        for a in range(azimuths):
            shares[e, a] = _cast(span, samples, stride, s, math.pi * a / azimuths, -r - half_t - 1e-6,
                                 r + half_t + 1e-6, seen)
            normals[e, a] = seen
    return shares, normals


def bin_angles(bins: int = NORMAL_BINS) -> np.ndarray:
    """The angle phi [rad] at the middle of each bin of `view_tables`' normals."""
    return (np.arange(bins) + 0.5) * math.pi / bins - 0.5 * math.pi


def visibility_table(on_top_tile: np.ndarray, radius_m: float, spacing_m: float, thickness_m: float,
                     elevations: int = ELEVATIONS, azimuths: int = AZIMUTHS,
                     samples: int | None = None) -> np.ndarray:
    """The shares of `view_tables` alone: (elevations, azimuths, 2) float32."""
    return view_tables(on_top_tile, radius_m, spacing_m, thickness_m, elevations, azimuths, samples)[0]
