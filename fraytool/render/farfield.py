"""The far field: intact cloth drawn as one surface over the crossing grid where its yarns are too
small on screen to draw one by one (docs/rendering.md, "Far field: cloth under a few pixels").

Why: where the yarn spacing on screen falls to a couple of pixels, tubes (or ribbons) alias: 4x MSAA
takes 4 point samples of a weave whose period is about a pixel, and the beat between the two makes
moire rings; and every yarn costs its triangles though it covers less than a pixel. Renderers of
woven cloth switch representation with distance: far away the weave is aggregated into a surface
reflectance (Irawan & Marschner 2012, "Specular reflection from woven cloth", ACM TOG 31(1); Zhao et
al. 2016, "Fitting procedural yarn models for realistic cloth rendering", for the yarn-to-surface
hierarchy). Ours is the aggregate of our own near-field model, so the two agree where they meet:
- what covers a pixel: the weave pattern as a mipmapped coverage texture (weft and warp shares of each
  texel, the on-top yarn at each crossing from the weave: fraytool.render.weave_texture), which the
  GPU filters to the average over the pixel's footprint, scaled by the shares a view of the weave
  sees, ray cast through our own yarns (fraytool.render.weave_visibility): a grazing view closes the
  gaps and the family across the view stands in front;
- how it is shaded: the Kajiya-Kay + Lambert yarn model of shaders/yarn.frag averaged over the visible
  part of each family's yarn (shaders/farfield.vert), with the family's own tangent, so the highlight
  runs along the yarn directions;
- what shows through: the uncovered share, alpha-blended in linear light over what lies behind.

Which crossings: the footprint of a crossing is its yarn spacing on screen, in pixels: the geometric
mean of its projected grid edges along the weft and along the warp (the square root of its area on
screen), so a grazing view counts its foreshortened direction without switching cloth whose yarns
are still several pixels long across the view. Its far weight is 0 at NEAR_PX and above (yarns
only), 1 at FAR_PX and below (surface only), smoothstep between: the blend band (a crossing beside
one behind the eye counts as 0 px: weight 1). Crossings outside the view keep their own weight, so
the band never starts at the edge of the frame. The surface's quads are blocks of SURFACE_STEP x
SURFACE_STEP grid cells (the last row and column of blocks take the 1 to SURFACE_STEP cells left
over, so the surface reaches the border), drawn where all their crossings are at base level (not
mass couples), all their structural springs alive and one crossing has weight > 0. The shadow map
takes the surface where its weight is at least a half (shaders/depth.frag, fraytool.render.shadow_pass).
A yarn segment is left out of the yarn mesh where surface quads lie on both its sides and both its
ends have weight 1; segments at the border, at a tear or beside a couple stay yarns (the surface
covers only half their width).
In the band both are drawn and split each pixel's MSAA samples between them (gl_SampleMask): the
surface takes n = floor(w S + dither) of the S samples, the yarns the rest, so the resolved pixel
is the mix (1 - w) yarns + w surface of two complete pictures (each with its own coverage), with no
sorting and no overdraw (shaders/band.glsl).

One numba pass over the grid (projection, footprints, weights, vertices), then NumPy on the blocks; no
Python loop over yarns or crossings.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numba
import numpy as np

from fraytool.render.camera import Camera

NEAR_PX = 4.0
"""Footprint [px of yarn spacing] at and above which intact cloth is drawn as yarns only (the default
band, `[render] far_field_px` = 3: from 4/3 to 2/3 of it)."""
FAR_PX = 2.0
"""Footprint [px] at and below which intact cloth is drawn as surface only (yarns left out)."""
SCREEN_MARGIN = 1.15
"""Crossings inside this multiple of the view's NDC box count as on screen: the camera draws the surface
quads with a corner on screen (the shadow map draws them all)."""

SURFACE_FLOATS = 16
"""Surface vertex layout: position (3), normal (3), weft edge (3), warp edge (3), grid (i, j) (2), far
weight (1), panel (1). The edges are the grid's local spacing vectors [m] along the weft and warp yarns."""
SURFACE_FAR_WEIGHT = 14
"""The far weight's place in a surface vertex (SURFACE_FLOATS)."""


@dataclass(frozen=True)
class FarField:
    """One frame's level-of-detail split: the surface and which yarn links it replaces."""

    vertices: np.ndarray
    """(V, SURFACE_FLOATS) float32, one per grid place (row j * W + i); only those in `triangles` are used."""
    triangles: np.ndarray
    """(F, 3) uint32: two per surface quad (all of them: the shadow map's casters)."""
    shown: np.ndarray
    """(F', 3) uint32: the triangles with a corner on screen (the ones the camera draws)."""
    used: np.ndarray
    """(V,) bool: the vertex is a corner of a surface quad."""
    weight: np.ndarray
    """Far weight per grid place, (H * W,) float64 in [0, 1]."""
    footprint_px: np.ndarray
    """Yarn spacing on screen per grid place [px] (module docstring), (H * W,); inf where it has no
    neighbour."""
    hidden_weft: np.ndarray
    """(H, W - 1) bool: weft links (j, i -> i + 1) drawn by the surface alone."""
    hidden_warp: np.ndarray
    """(W, H - 1) bool: warp links (i, j -> j + 1) drawn by the surface alone."""
    covered_weft: np.ndarray
    """(H, W - 1) bool: weft links with surface quads on both sides (their yarns may blend into it)."""
    covered_warp: np.ndarray
    """(W, H - 1) bool."""

    @property
    def quads(self) -> int:
        return int(self.triangles.shape[0] // 2)


@numba.njit(cache=True, inline="always")
def _band(f, near_px, far_px):  # pragma: no cover - numba
    t = min(max((near_px - f) / (near_px - far_px), 0.0), 1.0)
    return t * t * (3.0 - 2.0 * t)


@numba.njit(cache=True)
def _bands(footprint, near_px, far_px, weight_out):  # pragma: no cover - numba
    for k in range(footprint.shape[0]):
        weight_out[k] = _band(footprint[k], near_px, far_px)


def band_weight(footprint_px: np.ndarray, near_px: float = NEAR_PX, far_px: float = FAR_PX) -> np.ndarray:
    """Far weight of a footprint: 0 at near_px and above, 1 at far_px and below, smoothstep between
    (the grid pass's own rule)."""
    f = np.ascontiguousarray(np.atleast_1d(footprint_px), dtype=np.float64).ravel()
    out = np.empty_like(f)
    _bands(f, float(near_px), float(far_px), out)
    return out.reshape(np.shape(footprint_px))


@numba.njit(cache=True)
def _grid_pass(centre, normal, exists, panel, weft_ok, warp_ok, view, vertices_out, footprint_out, onscreen_out,
               weight_out):  # pragma: no cover - numba
    """One pass over the grid (see grid_pass): screen position of every
    crossing, its footprint (geometric mean of its projected spacings along the two yarns [px]; 0 beside a
    crossing behind the eye, inf with no neighbour), on-screen flag, far weight and surface vertex."""
    vp = view[:16].reshape(4, 4)
    half_w, half_h, near, margin, near_px, far_px = view[16], view[17], view[18], view[19], view[20], view[21]
    H, W = exists.shape
    sx = np.empty((H, W))
    sy = np.empty((H, W))
    ahead = np.zeros((H, W), dtype=np.bool_)
    for j in range(H):
        for i in range(W):
            x, y, z = centre[j, i, 0], centre[j, i, 1], centre[j, i, 2]
            cw = vp[3, 0] * x + vp[3, 1] * y + vp[3, 2] * z + vp[3, 3]
            k = j * W + i
            onscreen_out[k] = False
            if cw > near:
                ahead[j, i] = True
                nx = (vp[0, 0] * x + vp[0, 1] * y + vp[0, 2] * z + vp[0, 3]) / cw
                ny = (vp[1, 0] * x + vp[1, 1] * y + vp[1, 2] * z + vp[1, 3]) / cw
                sx[j, i] = nx * half_w
                sy[j, i] = ny * half_h
                onscreen_out[k] = exists[j, i] and abs(nx) <= margin and abs(ny) <= margin
            else:
                sx[j, i] = 0.0
                sy[j, i] = 0.0
    # projected length of every grid edge between two crossings ahead of the eye, once each
    weft_px = np.empty((H, max(W - 1, 0)))
    for j in range(H):
        for a in range(W - 1):
            dx, dy = sx[j, a + 1] - sx[j, a], sy[j, a + 1] - sy[j, a]
            weft_px[j, a] = np.sqrt(dx * dx + dy * dy)
    warp_px = np.empty((max(H - 1, 0), W))
    for b in range(H - 1):
        for i in range(W):
            dx, dy = sx[b + 1, i] - sx[b, i], sy[b + 1, i] - sy[b, i]
            warp_px[b, i] = np.sqrt(dx * dx + dy * dy)
    for j in range(H):
        for i in range(W):
            k = j * W + i
            fi = np.inf                                     # smaller projected edge along the weft (i)
            fj = np.inf                                     # ... along the warp (j)
            behind = False
            # weft direction (i) edges, then warp direction (j) edges; edge vectors for the surface
            ex, ey, ez, en = 0.0, 0.0, 0.0, 0
            for di in (-1, 0):
                a = i + di
                if a < 0 or a + 1 >= W or not weft_ok[j, a]:
                    continue
                if ahead[j, a] and ahead[j, a + 1]:
                    fi = min(fi, weft_px[j, a])
                else:
                    behind = True
                ex += centre[j, a + 1, 0] - centre[j, a, 0]
                ey += centre[j, a + 1, 1] - centre[j, a, 1]
                ez += centre[j, a + 1, 2] - centre[j, a, 2]
                en += 1
            vx, vy, vz, vn = 0.0, 0.0, 0.0, 0
            for dj in (-1, 0):
                b = j + dj
                if b < 0 or b + 1 >= H or not warp_ok[b, i]:
                    continue
                if ahead[b, i] and ahead[b + 1, i]:
                    fj = min(fj, warp_px[b, i])
                else:
                    behind = True
                vx += centre[b + 1, i, 0] - centre[b, i, 0]
                vy += centre[b + 1, i, 1] - centre[b, i, 1]
                vz += centre[b + 1, i, 2] - centre[b, i, 2]
                vn += 1
            # the crossing's size on screen: the geometric mean of the two directions (the square root
            # of its projected area), or the one direction it has; 0 beside a crossing behind the eye
            if behind:
                f = 0.0
            elif fi < np.inf and fj < np.inf:
                f = np.sqrt(fi * fj)
            else:
                f = min(fi, fj)
            footprint_out[k] = f
            w = _band(f, near_px, far_px) if exists[j, i] else 0.0
            weight_out[k] = w
            en = max(en, 1)
            vn = max(vn, 1)
            vertices_out[k, 0] = centre[j, i, 0]
            vertices_out[k, 1] = centre[j, i, 1]
            vertices_out[k, 2] = centre[j, i, 2]
            vertices_out[k, 3] = normal[j, i, 0]
            vertices_out[k, 4] = normal[j, i, 1]
            vertices_out[k, 5] = normal[j, i, 2]
            vertices_out[k, 6] = ex / en
            vertices_out[k, 7] = ey / en
            vertices_out[k, 8] = ez / en
            vertices_out[k, 9] = vx / vn
            vertices_out[k, 10] = vy / vn
            vertices_out[k, 11] = vz / vn
            vertices_out[k, 12] = i
            vertices_out[k, 13] = j
            vertices_out[k, 14] = w                                    # SURFACE_FAR_WEIGHT
            vertices_out[k, 15] = panel[j, i]


def grid_pass(camera: Camera, image_size: tuple[int, int], centre: np.ndarray, normal: np.ndarray,
              exists: np.ndarray, panel: np.ndarray, weft_edge_ok: np.ndarray, warp_edge_ok: np.ndarray,
              near_px: float = NEAR_PX, far_px: float = FAR_PX):
    """(vertices (H W, SURFACE_FLOATS) float32, footprint [px], on screen, far weight) per grid place.
    centre, normal: (H, W, 3) [m]; exists, panel: (H, W); weft_edge_ok (H, W - 1) / warp_edge_ok
    (H - 1, W): a structural spring joins the two places. The footprint is the geometric mean of the
    crossing's smaller projected edge along the weft and along the warp [px] (one direction where it
    has only one; 0 beside a crossing behind the eye: weight 1);
    the surface vertex's edges are the mean grid edges to those neighbours [m]."""
    Wpx, Hpx = int(image_size[0]), int(image_size[1])
    H, W = exists.shape
    # the view: view-projection (16, row-major), half the image in pixels (2), the near plane, the
    # on-screen margin, and the band's ends [px]
    view = np.concatenate([np.asarray(camera.view_proj(Wpx / Hpx), dtype=np.float64).ravel(),
                           [0.5 * Wpx, 0.5 * Hpx, float(camera.near), SCREEN_MARGIN, float(near_px), float(far_px)]])
    n = H * W
    vertices = np.empty((n, SURFACE_FLOATS), dtype=np.float32)
    footprint = np.empty(n)
    onscreen = np.empty(n, dtype=bool)
    weight = np.empty(n)
    _grid_pass(np.ascontiguousarray(centre, dtype=np.float64), np.ascontiguousarray(normal, dtype=np.float64),
               np.ascontiguousarray(exists), np.ascontiguousarray(panel, dtype=np.float64),
               np.ascontiguousarray(weft_edge_ok), np.ascontiguousarray(warp_edge_ok), view, vertices, footprint, onscreen,
               weight)
    return vertices, footprint, onscreen, weight


SURFACE_STEP = 4
"""Grid cells per surface quad side: the surface is drawn over every 4th crossing (a sixteenth of the
triangles: on llvmpipe a triangle's set-up, not its pixels, was most of the surface's cost; 2 took 117
ms on the tablecloth, 4 took 49, with the same error). A quad spans at most 4 NEAR_PX pixels, where a
drape's curvature between its corners stays under a yarn's radius; the weave texture still carries
every crossing."""


def far_field(camera: Camera, image_size: tuple[int, int], centre: np.ndarray, normal: np.ndarray,
              exists: np.ndarray, base: np.ndarray, panel: np.ndarray, weft_link: np.ndarray,
              warp_link: np.ndarray, weft_edge_ok: np.ndarray, warp_edge_ok: np.ndarray,
              near_px: float = NEAR_PX, far_px: float = FAR_PX, step: int = SURFACE_STEP) -> FarField:
    """The frame's far field (module docstring). Grid arrays, W warp yarns x H weft yarns:
    centre, normal (H, W, 3) [m]; exists (a crossing at that place), base (exists and at base level),
    panel (H, W); weft_link (H, W - 1) / warp_link (W, H - 1): live structural springs;
    weft_edge_ok (H, W - 1) / warp_edge_ok (H - 1, W): a structural spring joins the two places.
    The surface's quads are blocks of `step` x `step` grid cells, drawn where every cell is intact."""
    H, W = exists.shape
    c = int(step)
    vertices, footprint, onscreen, weight = grid_pass(camera, image_size, centre, normal, exists, panel,
                                                      weft_edge_ok, warp_edge_ok, near_px, far_px)
    wg = weight.reshape(H, W)
    warp_link_t = warp_link.T                                         # (H - 1, W)
    cell = (base[:-1, :-1] & base[:-1, 1:] & base[1:, :-1] & base[1:, 1:]
            & weft_link[:-1, :] & weft_link[1:, :] & warp_link_t[:, :-1] & warp_link_t[:, 1:])  # (H - 1, W - 1)
    # blocks of c x c cells from the grid's first crossing; the last row and column of blocks take what
    # is left (1 to c cells), so the surface reaches the cloth's border
    Hb, Wb = -(-(H - 1) // c), -(-(W - 1) // c)
    padded = np.ones((Hb * c, Wb * c), dtype=bool)
    padded[:H - 1, :W - 1] = cell
    block = padded.reshape(Hb, c, Wb, c).all(axis=(1, 3))
    # the largest weight over each block's crossings (its cells' corners)
    wcell = np.zeros((Hb * c, Wb * c))
    wcell[:H - 1, :W - 1] = np.maximum(np.maximum(wg[:-1, :-1], wg[:-1, 1:]), np.maximum(wg[1:, :-1], wg[1:, 1:]))
    block &= wcell.reshape(Hb, c, Wb, c).max(axis=(1, 3)) > 0.0
    # A link is covered where the blocks on both its sides are surface. Weft link (j, i): in block
    # column i // c, between the blocks of cell rows j - 1 and j (one block inside it, two on a
    # boundary; no cell row -1 or H - 1: the grid's border)
    covered_weft = _covered(block, H, W, c)                          # (H, W - 1)
    covered_warp = _covered(block.T, W, H, c)                         # (W, H - 1)
    full = wg >= 1.0
    hidden_weft = covered_weft & full[:, :-1] & full[:, 1:]
    hidden_warp = covered_warp & (full[:-1, :] & full[1:, :]).T
    # two triangles per block, corners (j0, i0), (j0, i1), (j1, i1), (j1, i0): j0 = J c, j1 = min(j0 + c, H - 1)
    bj, bi = np.nonzero(block)
    j0, i0 = bj * c, bi * c
    j1, i1 = np.minimum(j0 + c, H - 1), np.minimum(i0 + c, W - 1)
    a, b, d, e = ((jj * W + ii).astype(np.uint32) for jj, ii in ((j0, i0), (j0, i1), (j1, i1), (j1, i0)))
    tri = np.empty((2 * a.size, 3), dtype=np.uint32)
    tri[0::2, 0], tri[0::2, 1], tri[0::2, 2] = a, b, d
    tri[1::2, 0], tri[1::2, 1], tri[1::2, 2] = a, d, e
    on = onscreen
    seen = on[a] | on[b] | on[d] | on[e]
    shown = np.repeat(seen, 2)
    used = np.zeros(H * W, dtype=bool)
    used[tri.ravel()] = True
    return FarField(vertices, tri, np.ascontiguousarray(tri[shown]), used, weight, footprint, hidden_weft,
                    hidden_warp, covered_weft, covered_warp)


def _covered(block: np.ndarray, H: int, W: int, c: int) -> np.ndarray:
    """(H, W - 1) bool: the links along grid rows (weft links; warp links with `block` transposed and
    H, W swapped) with surface blocks (`block`, (ceil((H - 1) / c), ceil((W - 1) / c))) on both sides."""
    Hb, Wb = block.shape
    qb = np.zeros((Hb + 1, Wb), dtype=bool)                          # row 0: outside the grid
    qb[1:] = block
    row = np.arange(H)[:, None]
    below = np.where(row >= 1, (row - 1) // c + 1, 0)                 # cell row j - 1
    above = np.where(row <= H - 2, row // c + 1, 0)                   # cell row j
    col = np.arange(W - 1)[None, :] // c
    return qb[below, col] & qb[above, col]


def grid_arrays(topology: Mapping[str, np.ndarray], centre_c: np.ndarray, normal_c: np.ndarray,
                yarn_level: np.ndarray, spring_alive: np.ndarray):
    """The per-crossing arrays laid on the full W x H grid for far_field: (centre, normal, exists, base,
    panel, weft_link, warp_link, weft_edge_ok, warp_edge_ok)."""
    from fraytool.render.yarns import crossing_places

    W = int(np.asarray(topology["warp_yarns"]).item())
    H = int(np.asarray(topology["weft_yarns"]).item())
    places = crossing_places(topology)
    C = places.size
    panel_c = np.asarray(topology["crossing_panel"]) if "crossing_panel" in topology else np.zeros(C, np.int32)
    if C == H * W and (places == np.arange(C)).all():  # every place its own crossing: no copies
        centre, normal = np.asarray(centre_c, np.float64), np.asarray(normal_c, np.float64)
        exists = np.ones(C, dtype=bool)
        base = ~np.asarray(yarn_level, dtype=bool)
        panel = np.asarray(panel_c, np.int64)
    else:
        centre = np.zeros((H * W, 3))
        normal = np.zeros((H * W, 3))
        centre[places] = centre_c
        normal[places] = normal_c
        exists = np.zeros(H * W, dtype=bool)
        exists[places] = True
        base = np.zeros(H * W, dtype=bool)
        base[places] = ~np.asarray(yarn_level, dtype=bool)
        panel = np.full(H * W, -1, np.int64)
        panel[places] = panel_c
    alive = np.asarray(spring_alive, dtype=bool)
    weft_s = np.asarray(topology["weft_structural_spring"]).reshape(H, W - 1)
    warp_s = np.asarray(topology["warp_structural_spring"]).reshape(W, H - 1)
    weft_link = (weft_s >= 0) & alive[np.maximum(weft_s, 0)]
    warp_link = (warp_s >= 0) & alive[np.maximum(warp_s, 0)]
    weft_edge_ok = weft_s >= 0                                        # neighbours along a yarn, torn or not
    warp_edge_ok = (warp_s >= 0).T
    return (centre.reshape(H, W, 3), normal.reshape(H, W, 3), exists.reshape(H, W), base.reshape(H, W),
            np.maximum(panel, 0).reshape(H, W), weft_link, warp_link, weft_edge_ok, warp_edge_ok)
