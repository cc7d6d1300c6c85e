"""The cloth's arrays of the Model from its panels, seams and the builder's draws: concatenation only.

Each panel was laid out when it was added (fraytool.sim.panel_layout), each cut, weak line and seam was
placed on it then (fraytool.sim.builder). This puts them in the Model's numbering: crossings panel by
panel, springs group by group (panel_layout.GROUPS) and panel by panel within a group, then the stitches
seam by seam; each panel's grid a block of one block-diagonal grid, so that no spring joins two panels."""
from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np

from fraytool.kinds import STITCH, STRUCT_WARP, STRUCT_WEFT
from fraytool.sim.panel_layout import GROUPS, PanelLayout


@dataclasses.dataclass(frozen=True, eq=False)
class Numbering:
    """Where each panel's crossings and springs go in the Model."""

    crossing_start: np.ndarray  # (P + 1,) panel p's crossings are crossing_start[p]:crossing_start[p + 1]
    grid_offset: tuple[tuple[int, int], ...]  # (I, J): panel p's grid place (i, j) is (I + i, J + j)
    spring_index: tuple[np.ndarray, ...]  # per panel: the Model's spring of each of its springs
    spring_count: int  # the cloth's springs (stitches come after)


def numbering(panels: Sequence[PanelLayout]) -> Numbering:
    counts = [p.crossing_count for p in panels]
    crossing_start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    offsets, I, J = [], 0, 0
    for p in panels:
        h, w = p.shape.present.shape
        offsets.append((I, J))
        I, J = I + w, J + h
    sizes = np.array([p.group_sizes for p in panels], np.int64).reshape(len(panels), len(GROUPS))
    group_total = sizes.sum(axis=0)
    group_start = np.concatenate([[0], np.cumsum(group_total)[:-1]])
    before = np.cumsum(sizes, axis=0) - sizes  # springs of the same group in earlier panels
    index = []
    for p, panel in enumerate(panels):
        local_group = np.repeat(np.arange(len(GROUPS)), panel.group_sizes)
        within = np.arange(panel.spring_count) - panel.group_starts[local_group]
        index.append((group_start[local_group] + before[p, local_group] + within).astype(np.int64))
    return Numbering(crossing_start, tuple(offsets), tuple(index), int(group_total.sum()))


def crossing_fields(panels: Sequence[PanelLayout], num: Numbering) -> dict[str, np.ndarray]:
    """The Model's per-crossing arrays, its grid size and the structural spring grids."""
    nx = sum(p.shape.warp_yarns for p in panels)
    ny = sum(p.shape.weft_yarns for p in panels)
    weft_struct = np.full((ny, max(nx - 1, 0)), -1, np.int32)
    warp_struct = np.full((nx, max(ny - 1, 0)), -1, np.int32)
    for p, panel in enumerate(panels):
        (I, J), (h, w) = num.grid_offset[p], panel.grid.shape
        to_model = num.spring_index[p].astype(np.int32)
        for local, out, (r, c) in ((panel.weft_struct, weft_struct, (J, I)), (panel.warp_struct, warp_struct, (I, J))):
            block = np.where(local >= 0, to_model[np.maximum(local, 0)], -1) if to_model.size else local
            out[r:r + local.shape[0], c:c + local.shape[1]] = block
    cat = np.concatenate
    return dict(
        warp_yarns=nx, weft_yarns=ny, crossing_count=int(num.crossing_start[-1]),
        crossing_rest_position_m=cat([p.rest_m for p in panels]),
        crossing_weft_on_top=cat([p.weft_on_top for p in panels]),
        crossing_grid_i=cat([p.crossing_i + num.grid_offset[k][0] for k, p in enumerate(panels)]).astype(np.int32),
        crossing_grid_j=cat([p.crossing_j + num.grid_offset[k][1] for k, p in enumerate(panels)]).astype(np.int32),
        crossing_hemmed=cat([p.hemmed for p in panels]),
        crossing_plane_uv_m=cat([p.uv_m for p in panels]),
        crossing_panel=cat([np.full(p.crossing_count, k, np.int32) for k, p in enumerate(panels)]),
        crossing_mass_kg=cat([np.full(p.crossing_count, p.spec.mass_per_crossing_kg, float) for p in panels]),
        weft_structural_spring=weft_struct,
        warp_structural_spring=warp_struct,
    )


def spread(panels: Sequence[PanelLayout], num: Numbering, per_panel: Sequence[np.ndarray], fill, dtype) -> np.ndarray:
    """One array over the cloth's springs in the Model's order from one array per panel over its springs."""
    out = np.full(num.spring_count, fill, dtype)
    for p in range(len(panels)):
        out[num.spring_index[p]] = per_panel[p]
    return out


def spring_fields(panels: Sequence[PanelLayout], num: Numbering, rest_m: np.ndarray) -> dict[str, np.ndarray]:
    """The cloth's springs in the Model's numbering: kind, ends, stiffness, rest length, twins, and each
    crossing's structural spring slots."""
    start = num.crossing_start
    kind = spread(panels, num, [p.spring_kind for p in panels], 0, np.int8)
    a = spread(panels, num, [p.spring_a + start[k] for k, p in enumerate(panels)], 0, np.int32)
    b = spread(panels, num, [p.spring_b + start[k] for k, p in enumerate(panels)], 0, np.int32)
    twin = np.full(num.spring_count, -1, np.int32)
    for p, panel in enumerate(panels):
        g = panel.group_starts
        shear = num.spring_index[p][g[4]:g[6]]
        twins = num.spring_index[p][g[6]:g[8]]
        twin[shear] = twins
        twin[twins] = shear
    return dict(
        spring_kind=kind, spring_crossing_a=a, spring_crossing_b=b,
        spring_base_stiffness_n_per_m=spread(panels, num, [p.spring_stiffness_n_per_m for p in panels], 0.0, float),
        spring_rest_length_m=np.linalg.norm(rest_m[b] - rest_m[a], axis=1),
        spring_twin=twin,
    )


def with_stitches(cloth: dict, stitches: Sequence, seam_break: Sequence[np.ndarray]) -> dict:
    """The cloth's spring arrays with the seams' stitches after them (docs/panels.md "Seams")."""
    if not stitches:
        return cloth
    cat = np.concatenate
    pairs = cat([s.pairs for s in stitches]).astype(np.int32).reshape(-1, 2)
    count = pairs.shape[0]
    out = dict(cloth)
    out["spring_kind"] = cat([cloth["spring_kind"], np.full(count, STITCH, np.int8)])
    out["spring_crossing_a"] = cat([cloth["spring_crossing_a"], pairs[:, 0]])
    out["spring_crossing_b"] = cat([cloth["spring_crossing_b"], pairs[:, 1]])
    out["spring_rest_length_m"] = cat([cloth["spring_rest_length_m"], cat([s.rest_length_m for s in stitches])])
    out["spring_base_stiffness_n_per_m"] = cat([cloth["spring_base_stiffness_n_per_m"],
                                                cat([s.stiffness_n_per_m for s in stitches])])
    out["spring_twin"] = cat([cloth["spring_twin"], np.full(count, -1, np.int32)])
    out["spring_precut"] = cat([cloth["spring_precut"], np.zeros(count, bool)])
    out["spring_cut_time_s"] = cat([cloth["spring_cut_time_s"], np.full(count, np.inf)])
    out["spring_break_strain"] = cat([cloth["spring_break_strain"], cat(seam_break)])
    out["spring_seam"] = cat([np.full(cloth["spring_kind"].size, -1, np.int32),
                              cat([np.full(len(s.pairs), k, np.int32) for k, s in enumerate(stitches)])])
    if cloth["spring_weak_line"].size:
        out["spring_weak_line"] = cat([cloth["spring_weak_line"], np.full(count, -1, np.int32)])
    if any(s.sew_s > 0.0 for s in stitches):  # seams sewn over time (docs/garments.md)
        cloth_count = cloth["spring_kind"].size
        out["spring_sew_s"] = cat([np.zeros(cloth_count), cat([np.full(len(s.pairs), s.sew_s) for s in stitches])])
        out["spring_sew_start_length_m"] = cat([np.zeros(cloth_count),
                                                cat([s.start_length_m for s in stitches])])
    return out


def is_structural(kind: np.ndarray) -> np.ndarray:
    return (kind == STRUCT_WEFT) | (kind == STRUCT_WARP)
