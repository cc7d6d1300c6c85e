"""The weave's coverage texture for the far-field surface (fraytool.render.farfield, shaders/farfield.frag).

One repeat of the weave, TEXELS_PER_CROSSING texels a side per crossing, two channels: the share of
each texel covered by a weft yarn (R) and by a warp yarn (G) seen from above. A weft yarn j covers
the band |v - j| < a / 2 of the grid coordinate v, a warp yarn i the band |u - i| < a / 2, with
a = 2 r / s the yarn diameter over the spacing; where the bands cross, the yarn the weave puts on
top covers it (topology `crossing_weft_on_top`, docs/method.md §5). Each texel is the mean of 4 x 4
point samples, so the bands' edges are anti-aliased. GL builds the mipmaps (box filter), so a texel
of level k is the mean of the 4^k texels under it: the coverage averaged over the pixel's footprint,
down to the weave's mean coverage a - a^2 / 2 per family at the coarsest level.
"""
from __future__ import annotations

from typing import Mapping, Optional

import numpy as np

TEXELS_PER_CROSSING = 16
MAX_PERIOD = 16
"""Longest weave repeat looked for (crossings); a cloth with none repeats the plain weave's coverage."""
_SUB = 4


def weave_period(on_top: np.ndarray, exists: Optional[np.ndarray] = None) -> Optional[tuple[int, int]]:
    """Smallest (rows, columns) repeat, each at most MAX_PERIOD, of the (H, W) on-top pattern over the
    crossings that exist; None if there is none."""
    H, W = on_top.shape
    ex = np.ones_like(on_top, dtype=bool) if exists is None else exists
    for py in range(1, min(MAX_PERIOD, H) + 1):
        for px in range(1, min(MAX_PERIOD, W) + 1):
            jj, ii = np.nonzero(ex)
            key = (jj % py) * px + ii % px
            vals = on_top[jj, ii].astype(np.int8)
            first = np.full(py * px, -1, np.int8)
            order = np.argsort(key, kind="stable")
            k_sorted, v_sorted = key[order], vals[order]
            starts = np.r_[True, k_sorted[1:] != k_sorted[:-1]]
            first[k_sorted[starts]] = v_sorted[starts]
            if bool((first[key] == vals).all()):
                return py, px
    return None


def coverage_tile(on_top_tile: np.ndarray, cover: float, texels: int = TEXELS_PER_CROSSING) -> np.ndarray:
    """(py n, px n, 2) uint8 weft and warp coverage of one weave repeat (module docstring);
    on_top_tile (py, px) bool, True where the weft is on top; cover: a = yarn diameter / spacing."""
    py, px = on_top_tile.shape
    n = texels
    a = min(max(float(cover), 0.0), 1.0)
    # sub-sample offsets inside a texel, and texel positions inside a cell, in cell units [-0.5, 0.5)
    sub = (np.arange(_SUB) + 0.5) / _SUB
    t = (np.arange(n)[:, None] + sub[None, :]).ravel() / n - 0.5    # (n * _SUB,)
    in_weft = np.abs(t) < 0.5 * a                                   # as a function of v (rows)
    in_warp = np.abs(t) < 0.5 * a                                   # as a function of u (columns)
    weft = np.zeros((py, n * _SUB, px, n * _SUB), dtype=bool)
    warp = np.zeros_like(weft)
    bw = np.broadcast_to(in_weft[None, :, None, None], weft.shape)
    bv = np.broadcast_to(in_warp[None, None, None, :], weft.shape)
    top = np.broadcast_to(on_top_tile[:, None, :, None], weft.shape)
    weft = bw & (~bv | top)
    warp = bv & (~bw | ~top)
    shape = (py, n, _SUB, px, n, _SUB)
    r = weft.reshape(shape).mean(axis=(2, 5)).reshape(py * n, px * n)
    g = warp.reshape(shape).mean(axis=(2, 5)).reshape(py * n, px * n)
    return np.round(np.stack([r, g], axis=-1) * 255.0).astype(np.uint8)


def weave_tiles(topology: Mapping[str, np.ndarray]) -> np.ndarray:
    """Each panel's on-top repeat on one common period, (P, py, px) bool, True where the weft is on
    top seen from the front (the side the crossing normals point to), phased on the full grid (the
    texture is looked up by grid place). A panel with no repeat of at most MAX_PERIOD, or periods
    whose common multiple is longer, is drawn with the plain weave's."""
    from math import lcm

    from fraytool.render.yarns import crossing_places

    plain = np.array([[True, False], [False, True]])
    W = int(np.asarray(topology["warp_yarns"]).item())
    H = int(np.asarray(topology["weft_yarns"]).item())
    if "crossing_weft_on_top" not in topology:
        return plain[None]
    places = crossing_places(topology)
    on_top = np.asarray(topology["crossing_weft_on_top"], dtype=bool)
    panel = np.asarray(topology["crossing_panel"]) if "crossing_panel" in topology else np.zeros(places.size, np.int64)
    count = int(panel.max(initial=0)) + 1
    periods, grids = [], []
    for p in range(count):
        grid = np.zeros(H * W, dtype=bool)
        exists = np.zeros(H * W, dtype=bool)
        mine = panel == p
        grid[places[mine]] = on_top[mine]
        exists[places[mine]] = True
        grid, exists = grid.reshape(H, W), exists.reshape(H, W)
        periods.append(weave_period(grid, exists) if exists.any() else (2, 2))
        grids.append((grid, exists))
    good = [q for q in periods if q is not None]
    py = lcm(*(q[0] for q in good)) if good else 2
    px = lcm(*(q[1] for q in good)) if good else 2
    if py > MAX_PERIOD or px > MAX_PERIOD:
        py, px = 2, 2
        periods = [None] * count
    tiles = np.zeros((count, py, px), dtype=bool)
    for p, ((grid, exists), period) in enumerate(zip(grids, periods)):
        if period is None or not exists.any():
            tiles[p] = np.tile(plain, (py // 2, px // 2)) if py % 2 == 0 and px % 2 == 0 else \
                (np.add.outer(np.arange(py), np.arange(px)) % 2 == 0)
            continue
        jj, ii = np.nonzero(exists)
        tiles[p, jj % py, ii % px] = grid[jj, ii]
    return tiles
