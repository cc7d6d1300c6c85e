"""The weave's coverage texture for the far-field surface (fraytool.render.farfield, shaders/farfield.frag).

One repeat of the weave, TEXELS_PER_CROSSING texels a side per crossing, two channels: the share of
each texel covered by a weft yarn (R) and by a warp yarn (G) seen from above. A weft yarn j covers
the band |v - j| < a / 2 of the grid coordinate v, a warp yarn i the band |u - i| < a / 2, with
a = 2 r / s the yarn diameter over the spacing; where the bands cross, the yarn the weave puts on
top covers it (topology `crossing_weft_on_top`, docs/method.md §5). Each texel is the mean of k x k
point samples (k = 4 at 16 texels a crossing, more at fewer: at least 64 a crossing), so the bands'
edges are anti-aliased. GL builds the mipmaps (box filter), so a texel
of level k is the mean of the 4^k texels under it: the coverage averaged over the pixel's footprint,
down to the weave's mean coverage a - a^2 / 2 per family at the coarsest level.
"""
from __future__ import annotations

from typing import Mapping, Optional

import numpy as np

TEXELS_PER_CROSSING = 16
"""Texels a side per crossing of the coverage texture (a repeat over 16 crossings gets fewer, see
texels_per_crossing)."""
MAX_PERIOD = 64
"""Longest weave repeat looked for (crossings), also for the common repeat of several panels (a 3/1
twill seamed to a 5-shaft satin repeats every 20); a cloth with none is drawn without the far field."""
TEXTURE_TEXELS = 256
"""Most texels a side of one repeat's coverage texture."""
_SUB = 4


def texels_per_crossing(period: tuple[int, int]) -> int:
    """Texels a side per crossing for a repeat of (rows, columns) crossings: TEXELS_PER_CROSSING, fewer
    (at least 4) where the repeat would pass TEXTURE_TEXELS."""
    return max(4, min(TEXELS_PER_CROSSING, TEXTURE_TEXELS // max(period)))


def _shift_periods(on_top: np.ndarray, ex: np.ndarray, axis: int) -> list[int]:
    """Shifts d (1..MAX_PERIOD) along `axis` under which every pair of existing crossings d apart agrees:
    the candidates for a repeat along that axis (a repeat needs them; weave_period checks the rest)."""
    n = on_top.shape[axis]
    out = []
    for d in range(1, min(MAX_PERIOD, n) + 1):
        if d == n:
            out.append(d)
            continue
        a = np.take(on_top, np.arange(n - d), axis=axis)
        b = np.take(on_top, np.arange(d, n), axis=axis)
        both = np.take(ex, np.arange(n - d), axis=axis) & np.take(ex, np.arange(d, n), axis=axis)
        if not (both & (a != b)).any():
            out.append(d)
    return out


def weave_period(on_top: np.ndarray, exists: Optional[np.ndarray] = None) -> Optional[tuple[int, int]]:
    """Smallest (rows, columns) repeat, each at most MAX_PERIOD, of the (H, W) on-top pattern over the
    crossings that exist: every crossing agrees with all others of its residue (j mod rows, i mod
    columns); None if there is none. Candidates are first narrowed to the shifts along each axis under
    which neighbours a period apart agree (a few milliseconds for a 512 x 512 cloth with no repeat)."""
    H, W = on_top.shape
    ex = np.ones_like(on_top, dtype=bool) if exists is None else np.asarray(exists, dtype=bool)
    jj, ii = np.nonzero(ex)
    vals = on_top[jj, ii].astype(np.int64)
    for py in _shift_periods(on_top, ex, 0):
        for px in _shift_periods(on_top, ex, 1):
            key = (jj % py) * px + ii % px
            ones = np.bincount(key, weights=vals, minlength=py * px)
            count = np.bincount(key, minlength=py * px)
            if bool(((ones == 0) | (ones == count)).all()):
                return py, px
    return None


def coverage_tile(on_top_tile: np.ndarray, cover: float, texels: int = TEXELS_PER_CROSSING) -> np.ndarray:
    """(py n, px n, 2) uint8 weft and warp coverage of one weave repeat (module docstring), n = `texels`
    per crossing; on_top_tile (py, px) bool, True where the weft is on top; cover: a = yarn diameter /
    spacing."""
    py, px = on_top_tile.shape
    n = texels
    a = min(max(float(cover), 0.0), 1.0)
    # sub-sample offsets inside a texel, and texel positions inside a cell, in cell units [-0.5, 0.5)
    k = max(_SUB, -(-64 // n))                                      # at least 64 samples a crossing
    sub = (np.arange(k) + 0.5) / k
    t = (np.arange(n)[:, None] + sub[None, :]).ravel() / n - 0.5    # (n * k,)
    in_weft = np.abs(t) < 0.5 * a                                   # as a function of v (rows)
    in_warp = np.abs(t) < 0.5 * a                                   # as a function of u (columns)
    weft = np.zeros((py, n * k, px, n * k), dtype=bool)
    warp = np.zeros_like(weft)
    bw = np.broadcast_to(in_weft[None, :, None, None], weft.shape)
    bv = np.broadcast_to(in_warp[None, None, None, :], weft.shape)
    top = np.broadcast_to(on_top_tile[:, None, :, None], weft.shape)
    weft = bw & (~bv | top)
    warp = bv & (~bw | ~top)
    shape = (py, n, k, px, n, k)
    r = weft.reshape(shape).mean(axis=(2, 5)).reshape(py * n, px * n)
    g = warp.reshape(shape).mean(axis=(2, 5)).reshape(py * n, px * n)
    return np.round(np.stack([r, g], axis=-1) * 255.0).astype(np.uint8)


_last_tiles: tuple = (None, None)
"""weave_tiles' last (key, result): a render asks twice for the same cloth (YarnStyle.from_spec, to
decide whether the far field can stand for it, and the Renderer's textures), about 60 ms each on a
512 x 512 cloth. One tuple, read and replaced whole: renders in threads of one worker (the farm) see
a key with its own result."""


def weave_tiles(topology: Mapping[str, np.ndarray]) -> Optional[np.ndarray]:
    """Each panel's on-top repeat on one common period, (P, py, px) bool, True where the weft is on
    top seen from the front (the side the crossing normals point to), phased on the full grid (the
    texture is looked up by grid place); None when a panel has no repeat of at most MAX_PERIOD or the
    panels' periods have no common multiple that short (the far field cannot stand for that cloth:
    YarnStyle turns it off, and every yarn is drawn). Read-only; the last cloth's is kept (by the
    bytes of the arrays it is made from)."""
    key = tuple((k, np.asarray(topology[k]).tobytes()) for k in
                ("warp_yarns", "weft_yarns", "crossing_weft_on_top", "crossing_panel", "crossing_grid_i",
                 "crossing_grid_j") if k in topology)
    global _last_tiles
    last_key, last = _last_tiles
    if last_key == key:
        return last
    tiles = _weave_tiles(topology)
    if tiles is not None:
        tiles.flags.writeable = False
    _last_tiles = (key, tiles)
    return tiles


def _weave_tiles(topology: Mapping[str, np.ndarray]) -> Optional[np.ndarray]:
    from math import lcm

    from fraytool.render.yarns import crossing_places

    W = int(np.asarray(topology["warp_yarns"]).item())
    H = int(np.asarray(topology["weft_yarns"]).item())
    if "crossing_weft_on_top" not in topology:
        return np.array([[[True, False], [False, True]]])
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
        periods.append(weave_period(grid, exists) if exists.any() else (1, 1))
        grids.append((grid, exists))
    if any(q is None for q in periods):
        return None
    py, px = lcm(*(q[0] for q in periods)), lcm(*(q[1] for q in periods))
    if py > MAX_PERIOD or px > MAX_PERIOD:
        return None
    tiles = np.zeros((count, py, px), dtype=bool)
    for p, (grid, exists) in enumerate(grids):
        jj, ii = np.nonzero(exists)
        tiles[p, jj % py, ii % px] = grid[jj, ii]
    return tiles
