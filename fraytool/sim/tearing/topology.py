"""TearTopology: static lookup tables of the yarn-level model, derived once from a Model.

They answer the questions the tearing kernels ask without searching:
- which springs touch crossing c (to re-attach them when c splits, docs/method.md §3.4);
- which bend springs span a structural spring, and which shear springs lie in the two grid cells
  beside it (to cut them with it, docs/tearing.md "Cutting");
- which crossings are held by a rigid body (they never split).
Nothing here changes during a run; the arrays are computed with NumPy from the Model's static
arrays (no State), so they could equally live in the Model.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fraytool.sim.model import Model
from fraytool.kinds import BEND_WARP, BEND_WEFT, SHEAR, SHEAR_TWIN, STRUCT_WARP, STRUCT_WEFT


@dataclass(frozen=True, eq=False)
class TearTopology:
    crossing_spring_start: np.ndarray
    """CSR offsets into crossing_spring_list, shape (crossing_count + 1,), int32."""
    crossing_spring_list: np.ndarray
    """Springs (every kind but SHEAR_TWIN; a twin follows its shear spring) with an end at the
    crossing, grouped by crossing, shape (nnz,), int32."""
    crossing_attached: np.ndarray
    """True where the crossing's base mass is held by a rigid body or lies on a hemmed border (it never
    splits, and anchors its yarns), shape (crossing_count,), bool."""
    crossing_grid: np.ndarray
    """Crossing at each place of the grid, -1 where a shaped panel has none (Model.crossing_grid), shape
    (weft_yarns, warp_yarns), int64."""
    structural_springs: np.ndarray
    """Slots of all structural springs (weft and warp), ascending, shape (K,), int32."""
    structural_yarn: np.ndarray
    """Yarn of each entry of structural_springs: weft yarn j -> j, warp yarn i -> weft_yarns + i, (K,), int32."""
    structural_bend_start: np.ndarray
    """CSR offsets into structural_bend_list per spring slot, shape (spring_count + 1,), int32."""
    structural_bend_list: np.ndarray
    """Bend springs spanning each structural spring (at most 2), shape (nnz,), int32."""
    structural_shear_start: np.ndarray
    """CSR offsets into structural_shear_list per spring slot, shape (spring_count + 1,), int32."""
    structural_shear_list: np.ndarray
    """Shear springs (not twins) of the grid cells on either side of each structural spring
    (at most 2 cells x 2 diagonals), shape (nnz,), int32."""


def _csr(keys: np.ndarray, values: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Group `values` by `keys` (0 <= key < size), stable in value order."""
    order = np.lexsort((values, keys))
    counts = np.bincount(keys, minlength=size)
    start = np.zeros(size + 1, np.int32)
    start[1:] = np.cumsum(counts)
    return start, values[order].astype(np.int32)


def spanned_structural_springs(model: Model) -> tuple[np.ndarray, np.ndarray]:
    """(bend_span, shear_cell_border): the 2 structural springs each bend spring spans, shape
    (spring_count, 2), and the 4 structural springs bordering the grid cell of each shear spring or
    twin, shape (spring_count, 4); int32, -1 for springs of other kinds. The CSR tables of
    build_tear_topology are made from them and they are dropped (24 bytes per spring slot);
    topology_problems makes them again."""
    S = model.spring_count
    kind = model.spring_kind
    ca, cb = model.spring_crossing_a, model.spring_crossing_b
    weft = model.weft_structural_spring
    warp = model.warp_structural_spring
    ia, ja = model.crossing_grid_i[ca], model.crossing_grid_j[ca]
    ib, jb = model.crossing_grid_i[cb], model.crossing_grid_j[cb]

    # Bend springs: (i, j)-(i+2, j) spans weft[j, i], weft[j, i+1]; (i, j)-(i, j+2) spans warp[i, j], warp[i, j+1].
    bend_span = np.full((S, 2), -1, np.int32)
    bw = np.nonzero(kind == BEND_WEFT)[0]
    i0, j0 = np.minimum(ia[bw], ib[bw]), ja[bw]
    bend_span[bw, 0] = weft[j0, i0]
    bend_span[bw, 1] = weft[j0, i0 + 1]
    bv = np.nonzero(kind == BEND_WARP)[0]
    i0, j0 = ia[bv], np.minimum(ja[bv], jb[bv])
    bend_span[bv, 0] = warp[i0, j0]
    bend_span[bv, 1] = warp[i0, j0 + 1]

    # Shear springs and twins: cell (i0, j0) = lower-left corner of the quad they cross.
    cell_border = np.full((S, 4), -1, np.int32)
    sh = np.nonzero((kind == SHEAR) | (kind == SHEAR_TWIN))[0]
    i0, j0 = np.minimum(ia[sh], ib[sh]), np.minimum(ja[sh], jb[sh])
    cell_border[sh, 0] = weft[j0, i0]
    cell_border[sh, 1] = weft[j0 + 1, i0]
    cell_border[sh, 2] = warp[i0, j0]
    cell_border[sh, 3] = warp[i0 + 1, j0]
    return bend_span, cell_border


def build_tear_topology(model: Model) -> TearTopology:
    """Derive the lookup tables of `model` (pure NumPy, O(springs))."""
    n = model.crossing_count
    S = model.spring_count
    kind = model.spring_kind
    ca = model.spring_crossing_a.astype(np.int64)
    cb = model.spring_crossing_b.astype(np.int64)
    ids = np.arange(S, dtype=np.int64)

    not_twin = kind != SHEAR_TWIN
    keys = np.concatenate([ca[not_twin], cb[not_twin]])
    vals = np.concatenate([ids[not_twin], ids[not_twin]])
    c_start, c_list = _csr(keys, vals, n)
    del keys, vals, ids, ca, cb

    attached = np.zeros(n, bool)
    held = model.attachment_particle[model.attachment_particle < n]
    attached[held] = True
    attached |= model.crossing_hemmed

    bend_span, cell_border = spanned_structural_springs(model)
    bends = np.nonzero((kind == BEND_WEFT) | (kind == BEND_WARP))[0]
    b_start, b_list = _csr(bend_span[bends].ravel().astype(np.int64), np.repeat(bends, 2), S)
    del bend_span
    orig = np.nonzero(kind == SHEAR)[0]
    s_start, s_list = _csr(cell_border[orig].ravel().astype(np.int64), np.repeat(orig, 4), S)
    del cell_border

    structural = np.nonzero((kind == STRUCT_WEFT) | (kind == STRUCT_WARP))[0].astype(np.int32)
    return TearTopology(
        crossing_spring_start=c_start,
        crossing_spring_list=c_list,
        crossing_attached=attached,
        crossing_grid=model.crossing_grid(),
        structural_springs=structural,
        structural_yarn=model.spring_yarn()[structural],
        structural_bend_start=b_start,
        structural_bend_list=b_list,
        structural_shear_start=s_start,
        structural_shear_list=s_list,
    )


def topology_problems(model: Model, state, topo: TearTopology | None = None) -> list[str]:
    """Everything wrong with the tear topology of `state` (empty when valid). Checked:
    indices in range; every spring end on an active particle of its own crossing and on the right
    yarn (weft kinds on slot c, warp kinds on the warp mass once split, both-level rules for shear
    copies); no spring joining a particle to itself; no two live springs joining the same pair; rest
    lengths > 0; mass conserved and halved exactly at couples; couples only at yarn-level, unheld
    crossings; no live bend spring over a cut yarn, no live shear copy in a torn cell or at a
    disconnected couple; broken only for cut structural springs; live twins only beside a split;
    shear copies on one layer, the two copies of a diagonal on different masses."""
    topo = topo or build_tear_topology(model)
    n = model.crossing_count
    P = 2 * n
    out: list[str] = []
    a, b = state.spring_particle_a.astype(np.int64), state.spring_particle_b.astype(np.int64)
    alive = state.spring_alive
    kind = model.spring_kind
    lvl = state.crossing_yarn_level
    if a.min() < 0 or b.min() < 0 or a.max() >= P or b.max() >= P:
        return ["spring end index out of range"]
    act = state.particle_active
    if not (act[a].all() and act[b].all()):
        out.append(f"springs on inactive particles: {np.nonzero(~(act[a] & act[b]))[0][:5].tolist()}")
    ca, cb = model.spring_crossing_a, model.spring_crossing_b
    if not ((a % n == ca).all() and (b % n == cb).all()):
        out.append("spring end on another crossing's particle")
    for p, c in ((a, ca), (b, cb)):
        weft = (kind == STRUCT_WEFT) | (kind == BEND_WEFT)
        warp = (kind == STRUCT_WARP) | (kind == BEND_WARP)
        if (p[weft] >= n).any():
            out.append("weft spring on a warp mass")
        want = np.where(lvl[c], n + c, c)
        if (p[warp] != want[warp]).any():
            out.append("warp spring not on its crossing's warp mass")
        shear = (kind == SHEAR) | (kind == SHEAR_TWIN)
        if (p[shear & ~lvl[c]] >= n).any():
            out.append("shear spring on a warp slot of a base crossing")
    if (alive & (a == b)).any():
        out.append("spring joining a particle to itself")
    if (model.spring_rest_length_m <= 0).any():
        out.append("zero rest length")
    lo, hi = np.minimum(a, b)[alive], np.maximum(a, b)[alive]
    keys = lo * P + hi
    if np.unique(keys).size != keys.size:
        out.append("two live springs join the same particles")
    mass = state.particle_mass_kg
    if not np.isclose(mass.sum(), model.crossing_mass_kg.sum(), rtol=1e-12, atol=0.0):
        out.append("total mass changed")
    if (act[n:] != lvl).any() or not act[:n].all():
        out.append("active particles do not match the yarn-level crossings")
    if (mass[n:][~lvl] != 0).any() or (state.particle_inv_mass[~act] != 0).any():
        out.append("inactive slot with mass")
    if (mass[:n][lvl] != mass[n:][lvl]).any() or (mass[:n][lvl] != 0.5 * model.crossing_mass_kg[lvl]).any():
        out.append("couple masses are not halves")
    if (state.couple_connected & ~lvl).any():
        out.append("connected couple at a base crossing")
    if (lvl & topo.crossing_attached).any():
        out.append("held crossing split")
    bend = (kind == BEND_WEFT) | (kind == BEND_WARP)
    span, border = spanned_structural_springs(model)
    if (alive[bend] & ~(alive[span[bend, 0]] & alive[span[bend, 1]])).any():
        out.append("live bend spring over a cut yarn")
    shear = (kind == SHEAR) | (kind == SHEAR_TWIN)
    if (alive[shear] & ~alive[border[shear]].all(axis=1)).any():
        out.append("live shear spring in a torn cell")
    parted = lvl & ~state.couple_connected
    if (alive[shear] & (parted[ca[shear]] | parted[cb[shear]])).any():
        out.append("live shear spring at a disconnected couple")
    structural = (kind == STRUCT_WEFT) | (kind == STRUCT_WARP)
    if (state.spring_broken & (alive | ~structural)).any():
        out.append("broken flag on a live or non-structural spring")
    twin = kind == SHEAR_TWIN
    if (alive[twin] & ~(lvl[ca[twin]] | lvl[cb[twin]])).any():
        out.append("live shear twin between base crossings")
    # Shear copies join masses of the same layer; the two live copies of one diagonal use both
    # masses of every split crossing they touch.
    top = model.crossing_weft_on_top
    upper_a = np.where(top[ca], a == ca, a == n + ca)
    upper_b = np.where(top[cb], b == cb, b == n + cb)
    both = alive & shear & lvl[ca] & lvl[cb]
    if (upper_a[both] != upper_b[both]).any():
        out.append("shear copy joining an upper to a lower mass")
    orig = np.nonzero(kind == SHEAR)[0]
    tw = model.spring_twin[orig]
    pair = alive[orig] & alive[tw]
    for end, crossing in ((a, ca), (b, cb)):
        split = pair & lvl[crossing[orig]]
        if (end[orig][split] == end[tw][split]).any():
            out.append("both shear copies on the same mass of a split crossing")
    return out
