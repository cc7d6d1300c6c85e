"""Multi-resolution base model: a coarse base model where the cloth is whole (docs/multires.md).

The paper (Metaaphanon et al., §7) leaves "simulating the untorn parts at a coarser resolution" as
future work. Here the cloth's crossings keep their slots, and the grid is cut into **cells** of
factor x factor yarn spacings by coarse lines at every factor-th yarn (and the last yarn) of each panel
(a panel is a block of the Model's block-diagonal grid; fraytool.sim.cloth_assembly). A cell is either
*coarse* or *refined*; cells only refine, never coarsen. Only a *whole* cell (a crossing at every place of
it) can be coarse: the cells an outline or a mask cuts, and the grid between panels, are refined always.

- The crossings on coarse lines' intersections are the **nodes**; they are always simulated.
- A crossing is **free** (simulated) when it is a node or every cell whose closed rectangle holds it
  is refined; otherwise it is **slaved**: its position and velocity are the bilinear interpolation
  of its cell's four nodes (on a cell edge this is the linear interpolation of the edge's two nodes,
  whichever cell is used, so a slaved crossing between a refined and a coarse cell, a *hanging
  node*, is continuous with both). (In a step only the ones something reads are put there; every
  one at the end of a frame: fraytool.sim.stages.multires.)
- A slaved crossing's mass is lumped into its nodes with the interpolation weights (so gravity,
  total mass and momentum are those of the whole cloth), and it has mass and inverse mass 0 in the
  State (constraints, contacts and damping leave it alone); the forces on it go to its nodes with
  the same weights (the transpose of the interpolation).
- Coarse springs (structural, bend, shear) join the nodes with the cloth's stiffnesses; each spring
  (fine or coarse) counts with the share of the cells it borders (by its midpoint) that are at its
  own resolution, so that on a border between a refined and a coarse cell the two models each
  carry the half strip on their side.

This module is plain numpy: the layout of a model's cells (`coarse_layout`) and the bookkeeping of
a refinement (`apply_refinement`). The per-step kernels are in fraytool.sim.kernels.multires, the
stages in fraytool.sim.stages.multires.
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import Optional

import numpy as np

from fraytool.kinds import BEND_WARP, BEND_WEFT, SHEAR, STITCH, STRUCT_WARP, STRUCT_WEFT


@dataclass(frozen=True, eq=False)
class CoarseLayout:
    """The cells of a model with coarse_factor > 1 and everything static about them."""

    factor: int
    lines_i: np.ndarray
    """Grid columns on coarse lines, ascending: each panel's every factor-th column from its first, and its
    last (panel_lines; a rectangle's 0, factor, ..., warp_yarns - 1), int64."""
    lines_j: np.ndarray
    """Grid rows on coarse lines, ascending, likewise, int64."""
    crossing_cells: np.ndarray
    """Cells whose closed rectangle holds each crossing, -1 padded, shape (crossing_count, 4), int32."""
    crossing_node: np.ndarray
    """Nodes each crossing interpolates (bilinear in a whole cell holding it, crossing_weight_cell), shape
    (crossing_count, 4), int32; a crossing in no whole cell (always free) names itself, with weight 1."""
    crossing_weight: np.ndarray
    """Their weights (sum 1; a node weighs 1 on itself), shape (crossing_count, 4), float64."""
    crossing_is_node: np.ndarray
    """Shape (crossing_count,), bool."""
    crossing_weight_cell: np.ndarray
    """The cell whose nodes crossing_node names, shape (crossing_count,), int32."""
    spring_cells: np.ndarray
    """Cells whose closed rectangle holds each fine spring's midpoint, -1 padded, shape (spring_count, 4)."""
    coarse_kind: np.ndarray
    coarse_a: np.ndarray
    """Crossing (a node) at end a of each coarse spring, int32."""
    coarse_b: np.ndarray
    coarse_rest_length_m: np.ndarray
    coarse_stiffness_n_per_m: np.ndarray
    coarse_cells: np.ndarray
    """Cells each coarse spring borders, -1 padded, shape (coarse_spring_count, 4), int32."""
    coarse_cell_weight: np.ndarray
    """Weight of each of those cells in the spring's share: a structural spring on a cell edge stands
    for half of each cell beside it, so its cells weigh their extent across it; 1 for the others
    (shape (coarse_spring_count, 4), 0 on padding)."""
    cell_whole: np.ndarray
    """True where every place of the cell's closed rectangle holds a crossing of one panel: only such a
    cell can be coarse. A cell that a shaped panel's outline or mask crosses, or that lies between two
    panels' blocks of the grid, is refined from the start (initial_refined). Shape (cell_count,), bool."""
    cell_nodes: np.ndarray
    """The four nodes of every cell, (i0, j0), (i1, j0), (i0, j1), (i1, j1) as crossings (the order of
    crossing_node), -1 for a cell that is not whole, shape (cell_count, 4), int64."""

    @property
    def cells_x(self) -> int:
        return int(self.lines_i.shape[0] - 1)

    @property
    def cells_y(self) -> int:
        return int(self.lines_j.shape[0] - 1)

    @property
    def cell_count(self) -> int:
        return self.cells_x * self.cells_y


def coarse_lines(yarns: int, factor: int) -> np.ndarray:
    """Yarn indices of the coarse lines along one axis: every factor-th yarn, and the last."""
    lines = np.arange(0, yarns, factor, dtype=np.int64)
    return lines if lines[-1] == yarns - 1 else np.append(lines, yarns - 1)


def _intervals(x: np.ndarray, lines: np.ndarray) -> np.ndarray:
    """Indices of the intervals [lines[q], lines[q+1]] holding each coordinate x (closed): the lower in
    column 0, the upper in column 1 where x is on an inner line, else -1; shape (len(x), 2)."""
    count = lines.shape[0] - 1
    q = np.searchsorted(lines, x, side="right") - 1  # lines[q] <= x
    on = lines[np.clip(q, 0, count)] == x
    lower = np.where(on, q - 1, q)
    upper = np.where(on, q, -1)
    out = np.stack([lower, upper], axis=1)
    out[(out < 0) | (out >= count)] = -1
    # keep the valid one first
    swap = out[:, 0] < 0
    out[swap] = out[swap][:, ::-1]
    return out


def _cells_of(xi: np.ndarray, yj: np.ndarray, lines_i: np.ndarray, lines_j: np.ndarray) -> np.ndarray:
    """Cells (closed rectangles) holding the grid points (xi, yj), -1 padded, shape (N, 4), int32."""
    cx = lines_i.shape[0] - 1
    ii, jj = _intervals(xi, lines_i), _intervals(yj, lines_j)
    out = np.full((xi.shape[0], 4), -1, np.int64)
    k = 0
    for a in range(2):
        for b in range(2):
            ok = (ii[:, a] >= 0) & (jj[:, b] >= 0)
            out[:, k] = np.where(ok, jj[:, b] * cx + ii[:, a], -1)
            k += 1
    out.sort(axis=1)
    out = out[:, ::-1]  # valid (>= 0) first, then the -1 padding
    return out.astype(np.int32)


_LAYOUTS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()
"""coarse_layout of each live Model (a Model never changes; its layout takes most of a second at
512 x 512, and the initial State, the solver's stages and `check` all need it)."""


def coarse_layout(model) -> CoarseLayout:
    """The cells, interpolation weights and coarse springs of a model (coarse_factor > 1); computed once
    per Model."""
    layout = _LAYOUTS.get(model)
    if layout is None:
        layout = _LAYOUTS[model] = _build_layout(model)
    return layout


def panel_lines(model, factor: int) -> tuple[np.ndarray, np.ndarray]:
    """The coarse lines of the Model's grid: each panel's own (`coarse_lines` over the columns and rows
    its crossings span, from its first), together. Panels are blocks of one block-diagonal grid
    (fraytool.sim.cloth_assembly), so no panel's lines cross another's crossings; a rectangle's lines
    are coarse_lines(warp_yarns, factor) and coarse_lines(weft_yarns, factor)."""
    gi, gj, panel = model.crossing_grid_i, model.crossing_grid_j, model.crossing_panel
    li, lj = [], []
    for p in np.unique(panel):
        mine = panel == p
        for lines, g in ((li, gi[mine]), (lj, gj[mine])):
            lo, hi = int(g.min()), int(g.max())
            lines.append(lo + coarse_lines(hi - lo + 1, factor))
    return np.unique(np.concatenate(li)).astype(np.int64), np.unique(np.concatenate(lj)).astype(np.int64)


def whole_cells(grid: np.ndarray, li: np.ndarray, lj: np.ndarray) -> np.ndarray:
    """Cells whose closed rectangle holds a crossing at every place of the grid (`grid`: the crossing at
    each place, -1 where none), shape (cells,), bool. Panels are apart in the grid, so a whole cell's
    crossings are one panel's."""
    absent = np.zeros((grid.shape[0] + 1, grid.shape[1] + 1), np.int64)
    absent[1:, 1:] = np.cumsum(np.cumsum(grid < 0, axis=0), axis=1)  # absent places in [0, j) x [0, i)
    i0, j0 = np.meshgrid(li[:-1], lj[:-1])
    i1, j1 = np.meshgrid(li[1:] + 1, lj[1:] + 1)
    count = absent[j1, i1] - absent[j0, i1] - absent[j1, i0] + absent[j0, i0]
    return (count == 0).ravel()


def _build_layout(model) -> CoarseLayout:
    k = int(model.coarse_factor)
    grid = model.crossing_grid()
    li, lj = panel_lines(model, k)
    cx, cy = li.shape[0] - 1, lj.shape[0] - 1
    n = model.crossing_count
    i = model.crossing_grid_i.astype(np.int64)
    j = model.crossing_grid_j.astype(np.int64)
    crossing_cells = _cells_of(i.astype(float), j.astype(float), li.astype(float), lj.astype(float))
    whole = whole_cells(grid, li, lj)
    ci, cj = (g.ravel() for g in np.meshgrid(np.arange(cx), np.arange(cy)))
    cell_node = np.stack([grid[lj[cj], li[ci]], grid[lj[cj], li[ci + 1]],
                          grid[lj[cj + 1], li[ci]], grid[lj[cj + 1], li[ci + 1]]], axis=1)
    cell_node[~whole] = -1

    # bilinear weights in the lowest cell holding each crossing, or else in another whole cell holding it (on a
    # cell's edge the weights are the edge's linear ones, whichever cell); a crossing in no whole cell is
    # always free, and interpolates itself
    qi = np.clip(np.searchsorted(li, i, side="right") - 1, 0, cx - 1)
    qj = np.clip(np.searchsorted(lj, j, side="right") - 1, 0, cy - 1)
    cell = qj * cx + qi
    for q in range(crossing_cells.shape[1]):
        other = crossing_cells[:, q].astype(np.int64)
        use = ~whole[cell] & (other >= 0) & whole[np.maximum(other, 0)]
        cell = np.where(use, other, cell)
    qi, qj = cell % cx, cell // cx
    t = (i - li[qi]) / (li[qi + 1] - li[qi])
    u = (j - lj[qj]) / (lj[qj + 1] - lj[qj])
    node = cell_node[cell].astype(np.int32)
    weight = np.stack([(1 - t) * (1 - u), t * (1 - u), (1 - t) * u, t * u], axis=1)
    alone = ~whole[cell]
    node[alone] = np.arange(n, dtype=np.int32)[alone, None]
    weight[alone] = (1.0, 0.0, 0.0, 0.0)
    is_node = np.isin(i, li) & np.isin(j, lj)
    weight_cell = cell.astype(np.int32)

    a, b = model.spring_crossing_a, model.spring_crossing_b
    mid_x = 0.5 * (i[a] + i[b])
    mid_y = 0.5 * (j[a] + j[b])
    spring_cells = _cells_of(mid_x, mid_y, li.astype(float), lj.astype(float))
    # a stitch joins two panels: its midpoint is nowhere on the grid. It works at yarn resolution: the cells
    # of its crossings are refined from the start (initial_refined), so it borders those of its end a
    stitch = model.spring_kind == STITCH
    spring_cells[stitch] = crossing_cells[a[stitch]]

    ck, ca, cb, cs, ccells, cweight = _coarse_springs(model, grid, li, lj, whole)
    rest = model.crossing_rest_position_m
    coarse_rest = np.linalg.norm(rest[cb] - rest[ca], axis=1)
    return CoarseLayout(factor=k, lines_i=li, lines_j=lj, crossing_cells=crossing_cells, crossing_node=node,
                        crossing_weight=weight, crossing_is_node=is_node, crossing_weight_cell=weight_cell, spring_cells=spring_cells,
                        coarse_kind=ck, coarse_a=ca, coarse_b=cb, coarse_rest_length_m=coarse_rest,
                        coarse_stiffness_n_per_m=cs, coarse_cells=ccells, coarse_cell_weight=cweight,
                        cell_whole=whole, cell_nodes=cell_node)


def _coarse_springs(model, grid: np.ndarray, li: np.ndarray, lj: np.ndarray, whole: np.ndarray):
    """Structural, bend and shear springs between the nodes, with the kinds and stiffnesses of the
    cloth's own springs of those kinds (a spring grid's membrane stiffness does not depend on its
    spacing: docs/multires.md "Coarse springs"), and the cells each borders. Only springs that border a
    whole cell (one that can be coarse) are made; every such spring's ends are crossings of that cell's
    panel."""
    px, py = li.shape[0], lj.shape[0]
    cx, cy = px - 1, py - 1
    stiff = {}
    for kind in (STRUCT_WEFT, STRUCT_WARP, BEND_WEFT, BEND_WARP, SHEAR):
        sel = model.spring_kind == kind
        stiff[kind] = float(model.spring_base_stiffness_n_per_m[sel][0]) if sel.any() else 0.0

    def crossing(p, q):
        return grid[lj[q], li[p]]

    absent = grid < 0  # places without a crossing, counted along rows and along columns
    row_absent = np.concatenate([np.zeros((grid.shape[0], 1), np.int64), np.cumsum(absent, axis=1)], axis=1)
    col_absent = np.concatenate([np.zeros((1, grid.shape[1]), np.int64), np.cumsum(absent, axis=0)], axis=0)

    def along_crossings(pa, qa, pb, qb):
        """Every place on the straight grid line from node (pa, qa) to node (pb, qb) holds a crossing (a line
        along a row or a column: structural and bend springs; a shear spring's ends are a whole cell's)."""
        ia, ib, ja, jb = li[pa], li[pb], lj[qa], lj[qb]
        on_row = ja == jb
        lo_i, hi_i = np.minimum(ia, ib), np.maximum(ia, ib)
        lo_j, hi_j = np.minimum(ja, jb), np.maximum(ja, jb)
        row_count = row_absent[ja, hi_i + 1] - row_absent[ja, lo_i]
        col_count = col_absent[hi_j + 1, ia] - col_absent[lo_j, ia]
        straight = np.where(on_row, row_count, np.where(ia == ib, col_count, 0)) == 0
        return straight & (crossing(pa, qa) >= 0) & (crossing(pb, qb) >= 0)

    def cell(p, q):
        ok = (p >= 0) & (p < cx) & (q >= 0) & (q < cy)
        return np.where(ok, q * cx + p, -1)

    kinds, ends_a, ends_b, cells, weights, scales = [], [], [], [], [], []
    width = np.diff(li).astype(float)   # cell extents in yarn spacings: along i (columns) ...
    height = np.diff(lj).astype(float)  # ... and along j (rows)

    def add(kind, pa, qa, pb, qb, cell_list, across=None, length=None):
        """across: per cell of cell_list, its extent across the spring (structural springs); length:
        the spring's length in spacings."""
        if stiff[kind] <= 0.0 or pa.size == 0:
            return
        cl = np.stack(cell_list, axis=1).astype(np.int64)
        # a spring borders a whole cell and runs along crossings only: a bend spring spans two cells, and
        # must not bridge a slit or a notch of a shaped panel (the yarn model has no bend spring there)
        keep = ((cl >= 0) & whole[np.maximum(cl, 0)]).any(axis=1) & along_crossings(pa, qa, pb, qb)
        if not keep.all():
            pa, qa, pb, qb = pa[keep], qa[keep], pb[keep], qb[keep]
            cell_list = [c[keep] for c in cell_list]
            across = None if across is None else [x[keep] for x in across]
            length = None if length is None else length[keep]
            if pa.size == 0:
                return
        kinds.append(np.full(pa.size, kind, np.int8))
        ends_a.append(crossing(pa, qa))
        ends_b.append(crossing(pb, qb))
        cl = np.stack(cell_list, axis=1).astype(np.int64)
        wt = np.ones(cl.shape) if across is None else np.stack(across, axis=1)
        wt = np.where(cl >= 0, wt, 0.0)
        order = np.argsort(-cl, axis=1, kind="stable")  # valid cells first, then the -1 padding
        cl = np.take_along_axis(cl, order, axis=1)
        wt = np.take_along_axis(wt, order, axis=1)
        pad = 4 - cl.shape[1]
        cells.append(np.pad(cl, ((0, 0), (0, pad)), constant_values=-1))
        weights.append(np.pad(wt, ((0, 0), (0, pad))))
        if across is None:
            scales.append(np.ones(pa.size))
        else:
            # the fine grid's yarns are springs of stiffness k in series, k / L' for a chain of length L'
            # spacings; a coarse spring of length L standing for S yarns needs K = k S / L. S is half of
            # each bordering cell's extent, plus half a yarn at the cloth's edge (N yarns span N - 1
            # spacings), so the coarse springs of a uniform line of cells add up to the fine yarns
            n = (cl >= 0).sum(axis=1)
            scales.append((0.5 * wt.sum(axis=1) + np.where(n == 1, 0.5, 0.0)) / length)

    def ext(values, index):
        ok = (index >= 0) & (index < values.shape[0])
        return np.where(ok, values[np.clip(index, 0, values.shape[0] - 1)], 0.0)

    p, q = (g.ravel() for g in np.meshgrid(np.arange(px - 1), np.arange(py)))
    add(STRUCT_WEFT, p, q, p + 1, q, [cell(p, q - 1), cell(p, q)], [ext(height, q - 1), ext(height, q)], width[p])
    p, q = (g.ravel() for g in np.meshgrid(np.arange(px), np.arange(py - 1)))
    add(STRUCT_WARP, p, q, p, q + 1, [cell(p - 1, q), cell(p, q)], [ext(width, p - 1), ext(width, p)], height[q])
    p, q = (g.ravel() for g in np.meshgrid(np.arange(px - 2), np.arange(py)))
    add(BEND_WEFT, p, q, p + 2, q, [cell(p, q - 1), cell(p, q), cell(p + 1, q - 1), cell(p + 1, q)])
    p, q = (g.ravel() for g in np.meshgrid(np.arange(px), np.arange(py - 2)))
    add(BEND_WARP, p, q, p, q + 2, [cell(p - 1, q), cell(p, q), cell(p - 1, q + 1), cell(p, q + 1)])
    p, q = (g.ravel() for g in np.meshgrid(np.arange(px - 1), np.arange(py - 1)))
    add(SHEAR, p, q, p + 1, q + 1, [cell(p, q)])
    add(SHEAR, p + 1, q, p, q + 1, [cell(p, q)])
    if not kinds:
        return (np.zeros(0, np.int8), np.zeros(0, np.int32), np.zeros(0, np.int32), np.zeros(0),
                np.zeros((0, 4), np.int32), np.zeros((0, 4)))
    kind = np.concatenate(kinds)
    return (kind, np.concatenate(ends_a).astype(np.int32), np.concatenate(ends_b).astype(np.int32),
            _stiff_of(kind, stiff) * np.concatenate(scales),
            np.concatenate(cells).astype(np.int32), np.concatenate(weights))


def _stiff_of(kind: np.ndarray, stiff: dict) -> np.ndarray:
    table = np.zeros(8)
    for k_, v in stiff.items():
        table[k_] = v
    return table[kind.astype(np.int64)]


def initial_refined(model, layout: CoarseLayout) -> np.ndarray:
    """Cells refined from the first step: those holding a held crossing that its interpolation would not
    keep on its body (`followed_by_interpolation`) or a spring cut by a [[cuts]] line or scissors (a cut
    cloth is torn there), and a band of refine_band_cells around them; with refine_near_bodies, those with a
    node within a moving body's reach at the start (as the Refinement stage tests every step after). A
    grid with no crossing between its nodes (cells of one spacing) is refined whole: it is already as
    coarse as it gets."""
    if layout.crossing_is_node.all():
        return np.ones(layout.cell_count, bool)
    refined = np.zeros(layout.cell_count, bool)
    unfollowed = model.attachment_particle[~followed_by_interpolation(model, layout)]
    held = layout.crossing_cells[unfollowed].ravel()
    refined[held[held >= 0]] = True
    cut = layout.spring_cells[model.spring_precut | np.isfinite(model.spring_cut_time_s)].ravel()  # and scissors
    refined[cut[cut >= 0]] = True
    stitch = model.spring_kind == STITCH  # a seam's crossings: the stitches pull on them at yarn resolution
    sewn = layout.crossing_cells[np.concatenate([model.spring_crossing_a[stitch], model.spring_crossing_b[stitch]])]
    refined[sewn[sewn >= 0]] = True
    refined = dilate(refined, layout.cells_x, layout.cells_y, int(model.refine_band_cells))
    refined |= ~layout.cell_whole  # a panel's outline, mask or the grid between panels
    for k, reach in zip(*moving_body_reach(model, layout)):
        near = np.linalg.norm(model.crossing_rest_position_m - model.body_initial_position_m[k], axis=1) <= reach
        cells = layout.crossing_cells[layout.crossing_is_node & near].ravel()
        refined[cells[cells >= 0]] = True
    return refined


THIN_SEGMENTS = 1.5
"""A closed mesh without sharp edges is tested by distance, not depth, where its tightest bend radius
(fraytool.meshes.tightest_bend_radius_m, over its keys) is under this many yarn segments: so thin a part (a
rod, a needle, a finger) can pass between the crossings with none of them inside it."""


def colliding_meshes(model) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The colliding mesh bodies' meshes (fraytool.meshes.MeshTable order) as cells_on_meshes takes them:
    (meshes, the least distance a slaved crossing may come to each [m], whether that distance is unsigned).
    A closed mesh without sharp edges and no part thinner than THIN_SEGMENTS yarn segments is tested by depth
    (0, signed); the others (open, sharp edges, thin parts) by distance: half the longest yarn segment at rest
    plus the contact margin (fraytool.sim.kernels.multires_mesh)."""
    from fraytool.meshes import MeshTable, tightest_bend_radius_m
    from fraytool.sim.mesh_geometry import longest_yarn_segment_m

    table = MeshTable(model)
    segment = longest_yarn_segment_m(model)
    meshes = [m for m in range(table.count) if model.body_collide[table.body[m]]]

    def by_distance(m: int) -> bool:
        if not table.closed[m] or table.edge_start[m + 1] > table.edge_start[m]:
            return True
        faces = table.local_triangles(m)
        tightest = min(tightest_bend_radius_m(table.key_vertices(m, k), faces) for k in range(table.key_count(m)))
        return tightest < THIN_SEGMENTS * segment

    unsigned = np.array([by_distance(m) for m in meshes], np.bool_)
    floor = np.where(unsigned, 0.5 * segment + 0.5 * model.thickness_m, 0.0)
    return np.array(meshes, np.int64), floor, unsigned


def mixed_segments(model, free: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(free end, slaved end) of each yarn segment (structural spring of the Model) with one end of each:
    the mesh segment pass leaves them out, so cells_on_meshes tests their free ends (a node, or a crossing
    beside a hanging node) against meshes tested by distance."""
    from fraytool.sim.cloth_assembly import is_structural

    s = is_structural(model.spring_kind)
    a, b = model.spring_crossing_a[s].astype(np.int64), model.spring_crossing_b[s].astype(np.int64)
    one = free[a] != free[b]
    f = np.where(free[a], a, b)[one]
    return f.astype(np.int32), np.where(free[a], b, a)[one].astype(np.int32)


def slaved_by_cell(layout: CoarseLayout, slaved: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(the slaved crossings grouped by the cell whose nodes they interpolate, in index order within a
    group; start of each cell's group, shape (cell_count + 1,), int64)."""
    order = np.argsort(layout.crossing_weight_cell[slaved], kind="stable")
    grouped = slaved[order]
    start = np.searchsorted(layout.crossing_weight_cell[grouped], np.arange(layout.cell_count + 1)).astype(np.int64)
    return grouped, start


class CoarseMeshTest:
    """The coarse cells' test against the colliding meshes (fraytool.sim.kernels.multires_mesh.cells_on_meshes,
    docs/multires.md "Against a mesh"), with its distance bounds kept from call to call."""

    def __init__(self, model, layout: CoarseLayout):
        from fraytool.sim.kernels.mesh_contact import STACK
        from fraytool.sim.kernels.multires_mesh import empty_bounds

        self.model, self.layout = model, layout
        self.tested = colliding_meshes(model)
        self.bounds = empty_bounds(self.tested[0].size, model.crossing_count, layout.cell_count)
        self._scratch = (np.zeros(STACK, np.int64), np.zeros(3), np.zeros((4, 3)))

    @property
    def any(self) -> bool:
        return bool(self.tested[0].size)

    def mark(self, geometry, state, cell_start: np.ndarray, cell_slaved: np.ndarray,
             mixed: tuple[np.ndarray, np.ndarray], new: np.ndarray) -> int:
        """Mark in `new` the coarse cells of `state` that a mesh (`geometry`, a MeshGeometry at the step's end)
        makes refine; the slaved crossings grouped by cell (slaved_by_cell) and the mixed segments
        (mixed_segments) are the state's. Returns how many."""
        from fraytool.sim.kernels.bodies import bodies_in
        from fraytool.sim.kernels.multires_mesh import cells_on_meshes

        lay = self.layout
        cells = (cell_start, cell_slaved, lay.cell_nodes, lay.crossing_cells, lay.crossing_node, lay.crossing_weight,
                 mixed)
        return cells_on_meshes(self.tested, geometry.meshes_in(self.model), bodies_in(self.model, state),
                               geometry.clearance.travel_m, cells, state.particle_position_m,
                               state.coarse_cell_refined, self.bounds, self._scratch, new)


def refine_on_meshes_at_start(model, layout: CoarseLayout, state) -> None:
    """Refine in `state` (at time 0) the cells a colliding mesh makes refine (CoarseMeshTest, as the
    Refinement stage tests every step after contact): a crossing that starts below a mesh's surface is
    free from the first step, so the mass pass puts it back on the margin."""
    test = CoarseMeshTest(model, layout)
    if not test.any:
        return
    from fraytool.sim.mesh_geometry import MeshGeometry

    free = free_crossings(layout, state.coarse_cell_refined)
    grouped, start = slaved_by_cell(layout, np.flatnonzero(~free).astype(np.int32))
    new = np.zeros(layout.cell_count, bool)
    test.mark(MeshGeometry(model), state, start, grouped, mixed_segments(model, free), new)
    state.coarse_cell_refined |= new


def moving_body_reach(model, layout: CoarseLayout) -> tuple[np.ndarray, np.ndarray]:
    """(moving colliding analytic bodies, their reach [m]) for refine_near_bodies: a body's bounding radius
    (with the contact margin) plus refine_band_cells + 1 of the widest cell's diagonals at rest; none
    without refine_near_bodies. Mesh bodies are not in: a cell refines near a mesh by its own test
    (fraytool.sim.kernels.multires_mesh, every step, whatever refine_near_bodies says)."""
    from fraytool.kinds import MOTION_STATIC, SHAPE_MESH
    from fraytool.sim.kernels.rigid_contact import bounding_radius

    if not model.refine_near_bodies:
        return np.zeros(0, np.int64), np.zeros(0)
    bodies = np.flatnonzero((model.body_motion != MOTION_STATIC) & (model.body_shape != SHAPE_MESH)
                            & model.body_collide)
    nodes = layout.cell_nodes[layout.cell_whole]
    rest = model.crossing_rest_position_m
    diagonal = float(np.max(np.linalg.norm(rest[nodes[:, 3]] - rest[nodes[:, 0]], axis=1), initial=0.0))
    reach = np.array([bounding_radius(model.body_shape[k], model.body_params[k], 0.5 * model.thickness_m)
                      + (model.refine_band_cells + 1) * diagonal
                      for k in bodies])
    return bodies, reach


def followed_by_interpolation(model, layout: CoarseLayout) -> np.ndarray:
    """For each attachment: True where its crossing, slaved, stays on the body anyway, so its cells
    need not refine: every node it interpolates (nonzero weight) is held by the same body.

    A body moves its held points by one rigid map x = c + R o, and the interpolation weights reproduce
    affine maps of the rest grid (sum w_q = 1, sum w_q o_q = o), so the interpolation of the nodes'
    attached positions is the crossing's own: a clipped edge between held nodes stays coarse. A grip
    on a few crossings inside a cell (its nodes free) does not, and refines its cells. Nor does a pin on
    a mesh's surface (it follows a triangle of a mesh that may bend), or an attachment caught later or that
    can let go (each on its own)."""
    n = model.crossing_count
    body_of = np.full(n, -1, np.int64)
    body_of[model.attachment_particle] = model.attachment_body
    held = model.attachment_particle
    nodes = layout.crossing_node[held]
    same = (layout.crossing_weight[held] == 0.0) | (body_of[nodes] == body_of[held][:, None])
    followed = same.all(axis=1)
    if model.attachment_triangle.size:  # pinned to a mesh's surface, which need not move rigidly
        followed &= model.attachment_triangle < 0
    return followed & ~held_changes(model)  # each caught or let go on its own: not one rigid map


def held_changes(model) -> np.ndarray:
    """For each attachment: True where it is caught later (catch_s) or can let go (release_force_n), so
    whether it holds is the State's (inverse mass 0), not the Model's."""
    out = np.zeros(model.attachment_count, bool)
    if model.attachment_catch_s.size:
        out |= model.attachment_catch_s > 0.0
    if model.attachment_release_force_n.size:
        out |= model.attachment_release_force_n > 0.0
    return out


def dilate(cells: np.ndarray, cells_x: int, cells_y: int, band: int) -> np.ndarray:
    """Cells within `band` cells (Chebyshev) of a True cell (a grid of cells or of crossings)."""
    grid = cells.reshape(cells_y, cells_x)
    out = grid.copy()
    for dj in range(-min(band, cells_y - 1), min(band, cells_y - 1) + 1):  # (a shift past the grid reaches nothing)
        for di in range(-min(band, cells_x - 1), min(band, cells_x - 1) + 1):
            src = grid[max(0, -dj):cells_y - max(0, dj), max(0, -di):cells_x - max(0, di)]
            out[max(0, dj):cells_y - max(0, -dj), max(0, di):cells_x - max(0, -di)] |= src
    return out.ravel()


def free_crossings(layout: CoarseLayout, refined: np.ndarray) -> np.ndarray:
    """Crossings that are simulated: nodes, and those whose every holding cell is refined."""
    from fraytool.sim.kernels.multires import free_mask

    out = np.empty(layout.crossing_cells.shape[0], bool)
    free_mask(layout.crossing_cells, layout.crossing_is_node, refined, out)
    return out


def share(cells: np.ndarray, refined: np.ndarray, at_fine: bool, weight: Optional[np.ndarray] = None) -> np.ndarray:
    """The share of each spring's bordering cells (rows of `cells`, -1 padded) that are at the spring's
    own resolution: refined cells for fine springs (at_fine), coarse cells for coarse springs; with
    `weight` (same shape), each cell counts with its weight instead of 1."""
    from fraytool.sim.kernels.multires import cell_shares

    out = np.empty(cells.shape[0])
    cell_shares(cells, np.zeros((0, 4)) if weight is None else weight, weight is not None, refined, bool(at_fine), out)
    return out


def lumped_masses(model, layout: CoarseLayout, free: np.ndarray) -> np.ndarray:
    """Mass of each base slot: a free crossing's own mass plus the shares (interpolation weights) of
    the slaved crossings that interpolate it; 0 for a slaved crossing. Shape (crossing_count,)."""
    from fraytool.sim.kernels.multires import lump_masses

    out = np.empty(model.crossing_count)
    lump_masses(model.crossing_mass_kg, free, layout.crossing_node, layout.crossing_weight, out)
    return out


def set_masses(model, layout: CoarseLayout, refined: np.ndarray, state) -> np.ndarray:
    """Set the base slots' masses and inverse masses of `state` for the refined cells `refined`;
    returns the free crossings. Held crossings keep inverse mass 0."""
    free = free_crossings(layout, refined)
    n = model.crossing_count
    mass = lumped_masses(model, layout, free)
    # a split crossing (only ever free) keeps the masses of its couple as tearing set them
    base = ~state.crossing_yarn_level
    state.particle_mass_kg[:n][base] = mass[base]
    held = np.zeros(n, bool)
    changing = held_changes(model)  # caught or let go during the run: held now where its inverse mass is 0
    held[model.attachment_particle[~changing]] = True
    moving = model.attachment_particle[changing]
    held[moving] = state.particle_inv_mass[moving] == 0.0
    inv = np.where(free & (mass > 0.0), 1.0 / np.where(mass > 0.0, mass, 1.0), 0.0)
    inv[held] = 0.0
    state.particle_inv_mass[:n][base] = inv[base]
    return free


def interpolate_slaved(layout: CoarseLayout, free: np.ndarray, values: np.ndarray) -> None:
    """values[slaved] = the weighted sum of their nodes' values (positions or velocities), in place
    (the kernel the step uses, fraytool.sim.kernels.multires.sync_slaved)."""
    from fraytool.sim.kernels.multires import sync_slaved

    sync_slaved(np.flatnonzero(~free).astype(np.int32), layout.crossing_node, layout.crossing_weight, values)
