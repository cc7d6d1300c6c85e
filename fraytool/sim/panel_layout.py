"""One cloth panel laid out when the builder adds it: its crossings, its springs, its border (docs/panels.md).

`lay_out_panel` turns a panel's keys (a ClothSpec), its shape (which places of its grid hold a crossing) and
its tear map into a PanelLayout: everything about the panel that does not depend on the others. The base
model it builds is the one of docs/method.md §3.2: one mass per crossing on a quad grid, structural springs
between grid neighbours, bend springs over one crossing, shear springs across each cell acting only in
compression, and a dead twin slot per shear spring for a split to bring to life (§3.4).

Spring groups. A panel's springs come in GROUPS, in this order, and so does the Model's list of springs: all
panels' structural weft springs first (panel by panel), then all structural warp springs, and so on. That is
the order the springs had when every panel was laid on one block-diagonal grid and each kind built over
all of it, so the Model (and every frame) is the same as it was.
"""
from __future__ import annotations

import dataclasses
from typing import Any, Optional

import numpy as np

from fraytool.geometry.rotations import euler_rotation
from fraytool.kinds import BEND_WARP, BEND_WEFT, SHEAR, SHEAR_TWIN, STRUCT_WARP, STRUCT_WEFT
from fraytool.scene.panel_shape import sample_map
from fraytool.scene.spec import ClothSpec
from fraytool.sim.seam_layout import border_crossings

PLANE_AXES = {"xz": (0, 2), "xy": (0, 1), "yz": (1, 2)}
"""[cloth] plane -> (the weft's axis, the warp's axis): the first letter's and the second's
(docs/scene-format.md; scene_hash marks "yz", whose frames once ran the weft along z)."""

GROUPS = ("weft", "warp", "bend_weft", "bend_warp", "shear_a", "shear_b", "twin_a", "twin_b")
"""The spring groups in the Model's order. shear_a joins (i, j)-(i+1, j+1) of each cell, shear_b
(i+1, j)-(i, j+1); twin_a and twin_b are their twins, one per shear spring, in the same order."""

GROUP_KIND = (STRUCT_WEFT, STRUCT_WARP, BEND_WEFT, BEND_WARP, SHEAR, SHEAR, SHEAR_TWIN, SHEAR_TWIN)


@dataclasses.dataclass(frozen=True, eq=False)
class PanelLayout:
    """A panel as laid out: its crossings in its own numbering (row by row over the places of its grid that
    hold one), its springs in panel-local crossing numbers grouped as GROUPS, and the facts read from them."""

    spec: ClothSpec
    shape: Any  # fraytool.scene.panel_shape.PanelShape
    tear_map: Optional[np.ndarray]
    grid: np.ndarray  # (weft_yarns, warp_yarns): the crossing at each place, -1 where none
    uv_m: np.ndarray  # (C, 2) place in the panel's plane [m]
    rest_m: np.ndarray  # (C, 3) rest position [m]
    weft_on_top: np.ndarray  # (C,) bool
    crossing_i: np.ndarray  # (C,) int32, the crossing's warp yarn in the panel's grid
    crossing_j: np.ndarray  # (C,) int32, its weft yarn
    spring_a: np.ndarray  # (S,) int32, panel-local crossings
    spring_b: np.ndarray
    spring_kind: np.ndarray  # (S,) int8
    spring_stiffness_n_per_m: np.ndarray  # (S,)
    group_sizes: tuple[int, ...]  # springs per GROUPS entry; the springs are in that order
    weft_struct: np.ndarray  # (weft_yarns, warp_yarns - 1): local spring of each weft structural place, -1 none
    warp_struct: np.ndarray  # (warp_yarns, weft_yarns - 1)
    border: np.ndarray  # (C,) bool: a structural neighbour missing
    hemmed: np.ndarray  # (C,) bool: border crossings of a hemmed panel
    spring_mean_break_strain: Optional[np.ndarray]  # (S,) from the tear map; None without one

    @property
    def crossing_count(self) -> int:
        return int(self.uv_m.shape[0])

    @property
    def spring_count(self) -> int:
        return int(self.spring_a.size)

    @property
    def spring_uv_m(self) -> np.ndarray:
        """The middle of each spring's rest segment in the panel's plane [m] (where tear maps and weak lines
        are read)."""
        return 0.5 * (self.uv_m[self.spring_a] + self.uv_m[self.spring_b])

    @property
    def group_starts(self) -> np.ndarray:
        return np.concatenate([[0], np.cumsum(self.group_sizes)]).astype(np.int64)


def panel_rest(c: ClothSpec, uv: np.ndarray) -> np.ndarray:
    """World rest positions [m] of a panel's crossings from their places in its plane (u, v) [m]: along the
    plane's axes from origin_m, wrapped around a cylinder of wrap_radius_m (its axis along the second
    axis, the panel bending towards first axis x second axis), then turned by rotation_deg about origin_m."""
    a0, a1 = PLANE_AXES[c.plane]
    rest = np.zeros((uv.shape[0], 3))
    if c.wrap_radius_m == 0.0 and not any(c.rotation_deg):
        rest[:, a0] = uv[:, 0]
        rest[:, a1] = uv[:, 1]
        return rest + np.asarray(c.origin_m)
    e0, e1 = np.eye(3)[a0], np.eye(3)[a1]
    if c.wrap_radius_m > 0.0:
        r, theta = c.wrap_radius_m, uv[:, 0] / c.wrap_radius_m
        local = (r * np.sin(theta))[:, None] * e0 + uv[:, 1:2] * e1 \
            + (r * (1.0 - np.cos(theta)))[:, None] * np.cross(e0, e1)
    else:
        local = uv[:, 0:1] * e0 + uv[:, 1:2] * e1
    return np.asarray(c.origin_m) + local @ euler_rotation(c.rotation_deg).T


def lay_out_panel(cloth: ClothSpec, shape, tear_map: Optional[np.ndarray]) -> PanelLayout:
    """The panel's crossings, springs, border and tear-map means (module docstring)."""
    present = shape.present
    grid = np.full(present.shape, -1, np.int64)
    grid[present] = np.arange(int(present.sum()))
    jj, ii = np.nonzero(present)
    uv = shape.uv_m[present]
    rest = panel_rest(cloth, uv)
    table = np.asarray(cloth.weave_table, dtype=bool)
    top = table[jj % table.shape[0], ii % table.shape[1]]
    a, b, kind, stiff, sizes, weft_struct, warp_struct = _springs(grid, cloth.springs)
    border = border_crossings(*structural_slots(weft_struct, warp_struct, a, b, uv.shape[0]))
    mean = None
    if tear_map is not None:
        lo, hi = cloth.tear_map_strain
        mean = lo + (hi - lo) * sample_map(tear_map, shape.extent_uv_m, 0.5 * (uv[a] + uv[b]))
    return PanelLayout(cloth, shape, tear_map, grid, uv, rest, top, ii.astype(np.int32), jj.astype(np.int32),
                       a, b, kind, stiff, sizes, weft_struct, warp_struct, border,
                       border & (cloth.edge == "hemmed"), mean)


def structural_slots(weft_struct: np.ndarray, warp_struct: np.ndarray, a: np.ndarray, b: np.ndarray,
                     crossing_count: int) -> tuple[np.ndarray, np.ndarray]:
    """Each crossing's weft and warp structural springs (before, after), -1 where none."""
    cw = np.full((crossing_count, 2), -1, np.int32)
    cv = np.full((crossing_count, 2), -1, np.int32)
    for slots, out in ((weft_struct, cw), (warp_struct, cv)):
        s = slots[slots >= 0]
        out[a[s], 1] = s
        out[b[s], 0] = s
    return cw, cv


def _springs(grid: np.ndarray, springs) -> tuple:
    """The panel's springs over its grid (ny, nx; -1 where it has no crossing): a spring is built where all
    the crossings it joins or spans are there (a bend over its middle crossing, a shear spring over its whole
    cell) and its kind's stiffness is above 0. Returns (a, b, kind, stiffness, sizes per GROUPS entry,
    weft structural slots (ny, nx - 1), warp structural slots (nx, ny - 1))."""
    ny, nx = grid.shape
    parts: list[tuple[np.ndarray, np.ndarray, float]] = []
    count = 0

    def add(a, b, ks, *also):
        """Springs a-b of grid places (arrays of crossings, -1 for none) where a, b and `also` exist; returns
        their slots, -1 where not built, in the shape of a."""
        nonlocal count
        ok = (a >= 0) & (b >= 0)
        for x in also:
            ok &= x >= 0
        if not ks > 0:
            ok &= False
        slots = np.full(a.shape, -1, np.int32)
        a, b = np.asarray(a[ok], np.int32).ravel(), np.asarray(b[ok], np.int32).ravel()
        parts.append((a, b, ks))
        count += a.size
        slots[ok] = np.arange(count - a.size, count, dtype=np.int32)
        return slots

    g = grid
    k = springs
    weft_struct = np.full((ny, max(nx - 1, 0)), -1, np.int32)
    warp_struct = np.full((nx, max(ny - 1, 0)), -1, np.int32)
    weft_struct[:, :] = add(g[:, :-1], g[:, 1:], k.structural_n_per_m)
    warp_struct[:, :] = add(g[:-1, :].T, g[1:, :].T, k.structural_n_per_m)
    add(g[:, :-2], g[:, 2:], k.bend_n_per_m, g[:, 1:-1])
    add(g[:-2, :].T, g[2:, :].T, k.bend_n_per_m, g[1:-1, :].T)
    cell = (g[:-1, :-1], g[:-1, 1:], g[1:, :-1], g[1:, 1:])  # (i, j), (i+1, j), (i, j+1), (i+1, j+1)
    add(cell[0], cell[3], k.shear_n_per_m, cell[1], cell[2])
    add(cell[1], cell[2], k.shear_n_per_m, cell[0], cell[3])
    for shear in (parts[4], parts[5]):  # a twin per shear spring, at half its stiffness
        parts.append((shear[0], shear[1], 0.5 * k.shear_n_per_m))
    sizes = tuple(p[0].size for p in parts)
    a = np.concatenate([p[0] for p in parts]).astype(np.int32)
    b = np.concatenate([p[1] for p in parts]).astype(np.int32)
    kind = np.concatenate([np.full(size, GROUP_KIND[g], np.int8) for g, size in enumerate(sizes)])
    stiff = np.concatenate([np.full(p[0].size, p[2], float) for p in parts])
    return a, b, kind, stiff, sizes, weft_struct, warp_struct
