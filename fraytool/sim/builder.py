"""ModelBuilder: SceneSpec -> Model (METHOD.md §3.2 base model at yarn resolution).

One mass per crossing on a quad grid; springs:
- structural between grid neighbours along weft (i, i+1) and warp (j, j+1);
- bend between masses two apart (skip one) along weft and warp;
- shear between diagonal neighbours, acting only in compression;
- one dead twin slot per shear spring, brought to life when a split duplicates it (§3.4).
Break strains are drawn here, once, from numpy.random.default_rng(seed) (§3.4 "random break limits").
"""
from __future__ import annotations

import math

import numpy as np

from fraytool.scene.spec import AttachmentSpec, SceneSpec
from fraytool.sim.model import (
    BEND_WARP,
    BEND_WEFT,
    MOTION_NAMES,
    SHAPE_NAMES,
    SHEAR,
    SHEAR_TWIN,
    STRUCT_WARP,
    STRUCT_WEFT,
    Model,
)

_PLANE_AXES = {"xz": (0, 2), "xy": (0, 1), "yz": (2, 1)}


def crossing_index(i: int | np.ndarray, j: int | np.ndarray, warp_yarns: int):
    """Crossing of warp yarn i and weft yarn j."""
    return j * warp_yarns + i


def euler_rotation(deg: tuple[float, float, float]) -> np.ndarray:
    """Rotation matrix R = Rz @ Ry @ Rx from x, y, z Euler angles in degrees."""
    ax, ay, az = (math.radians(d) for d in deg)
    cx, sx, cy, sy, cz, sz = math.cos(ax), math.sin(ax), math.cos(ay), math.sin(ay), math.cos(az), math.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def select_crossings(att: AttachmentSpec, nx: int, ny: int, rest: np.ndarray) -> np.ndarray:
    """Crossings chosen by an attachment: an edge, a corner block, index ranges or a region."""
    ii, jj = np.meshgrid(np.arange(nx), np.arange(ny))
    ii, jj = ii.ravel(), jj.ravel()  # crossing order c = j * nx + i
    if att.edge is not None:
        mask = {"left": ii == 0, "right": ii == nx - 1, "bottom": jj == 0, "top": jj == ny - 1}[att.edge]
    elif att.corner is not None:
        k = att.corner_size
        left = ii < k
        right = ii >= nx - k
        bottom = jj < k
        top = jj >= ny - k
        mask = {"bottom_left": left & bottom, "bottom_right": right & bottom,
                "top_left": left & top, "top_right": right & top}[att.corner]
    elif att.warp_range is not None:
        (i0, i1), (j0, j1) = att.warp_range, att.weft_range
        mask = (ii >= i0) & (ii <= i1) & (jj >= j0) & (jj <= j1)
    else:
        d = np.linalg.norm(rest - np.asarray(att.region_center_m), axis=1)
        mask = d <= att.region_radius_m
    return np.nonzero(mask)[0].astype(np.int32)


class ModelBuilder:
    """Collects crossings, springs, bodies and attachments, then `finalize()`s them into a Model."""

    def __init__(self, spec: SceneSpec):
        self.spec = spec

    def _grid(self):
        c = self.spec.cloth
        nx, ny = c.warp_yarns, c.weft_yarns
        a0, a1 = _PLANE_AXES[c.plane]
        ii, jj = np.meshgrid(np.arange(nx), np.arange(ny))
        rest = np.zeros((nx * ny, 3))
        rest[:, a0] = ii.ravel() * c.spacing_m
        rest[:, a1] = jj.ravel() * c.spacing_m
        rest += np.asarray(c.origin_m)
        table = np.asarray(c.weave_table, dtype=bool)
        top = table[jj.ravel() % table.shape[0], ii.ravel() % table.shape[1]]
        return nx, ny, rest, top

    def _springs(self, nx: int, ny: int, rest: np.ndarray):
        k = self.spec.cloth.springs
        kinds, a_list, b_list, stiff = [], [], [], []
        weft_struct = np.full((ny, max(nx - 1, 0)), -1, np.int32)
        warp_struct = np.full((nx, max(ny - 1, 0)), -1, np.int32)

        def add(kind, a, b, ks):
            start = len(kinds)
            kinds.extend([kind] * len(a))
            a_list.extend(a)
            b_list.extend(b)
            stiff.extend([ks] * len(a))
            return np.arange(start, len(kinds), dtype=np.int32)

        idx = crossing_index
        jj, ii = np.meshgrid(np.arange(ny), np.arange(nx - 1), indexing="ij")
        weft_struct[:, :] = add(STRUCT_WEFT, idx(ii, jj, nx).ravel(), idx(ii + 1, jj, nx).ravel(),
                                k.structural_n_per_m).reshape(ny, nx - 1)
        ii, jj = np.meshgrid(np.arange(nx), np.arange(ny - 1), indexing="ij")
        warp_struct[:, :] = add(STRUCT_WARP, idx(ii, jj, nx).ravel(), idx(ii, jj + 1, nx).ravel(),
                                k.structural_n_per_m).reshape(nx, ny - 1)
        if k.bend_n_per_m > 0:
            jj, ii = np.meshgrid(np.arange(ny), np.arange(nx - 2), indexing="ij")
            add(BEND_WEFT, idx(ii, jj, nx).ravel(), idx(ii + 2, jj, nx).ravel(), k.bend_n_per_m)
            ii, jj = np.meshgrid(np.arange(nx), np.arange(ny - 2), indexing="ij")
            add(BEND_WARP, idx(ii, jj, nx).ravel(), idx(ii, jj + 2, nx).ravel(), k.bend_n_per_m)
        shear_twin_pairs = None
        if k.shear_n_per_m > 0:
            jj, ii = np.meshgrid(np.arange(ny - 1), np.arange(nx - 1), indexing="ij")
            ii, jj = ii.ravel(), jj.ravel()
            s1 = add(SHEAR, idx(ii, jj, nx), idx(ii + 1, jj + 1, nx), k.shear_n_per_m)
            s2 = add(SHEAR, idx(ii + 1, jj, nx), idx(ii, jj + 1, nx), k.shear_n_per_m)
            shear = np.concatenate([s1, s2])
            twins = add(SHEAR_TWIN, [a_list[s] for s in shear], [b_list[s] for s in shear], 0.5 * k.shear_n_per_m)
            shear_twin_pairs = (shear, twins)
        kind = np.asarray(kinds, np.int8)
        a = np.asarray(a_list, np.int32)
        b = np.asarray(b_list, np.int32)
        twin = np.full(len(kinds), -1, np.int32)
        if shear_twin_pairs is not None:
            twin[shear_twin_pairs[0]] = shear_twin_pairs[1]
            twin[shear_twin_pairs[1]] = shear_twin_pairs[0]
        rest_len = np.linalg.norm(rest[b] - rest[a], axis=1)
        return kind, a, b, np.asarray(stiff, float), rest_len, twin, weft_struct, warp_struct

    def _break_strains(self, count: int) -> np.ndarray:
        """Per-spring break strain ~ Normal(break_strain, spread), clipped above the transition strain.

        The floor does not depend on yarn_level, so a base-model-only run of a scene (yarn_level =
        false, for comparison) tears a cloth with exactly the same break strains."""
        t = self.spec.cloth.tearing
        rng = np.random.default_rng(self.spec.scene.seed)
        draw = t.break_strain + t.break_strain_spread * rng.standard_normal(count)
        floor = t.transition_strain * 1.01 if t.transition_strain < t.break_strain else 1e-3
        return np.maximum(draw, floor)

    def finalize(self) -> Model:
        spec = self.spec
        c = spec.cloth
        nx, ny, rest, top = self._grid()
        n = nx * ny
        kind, a, b, stiff, rest_len, twin, weft_struct, warp_struct = self._springs(nx, ny, rest)

        cw = np.full((n, 2), -1, np.int32)
        cv = np.full((n, 2), -1, np.int32)
        s = weft_struct.ravel()
        cw[a[s], 1] = s
        cw[b[s], 0] = s
        s = warp_struct.ravel()
        cv[a[s], 1] = s
        cv[b[s], 0] = s

        bodies = spec.bodies
        names = tuple(bd.name for bd in bodies)
        rot = np.array([euler_rotation(bd.rotation_deg) for bd in bodies]).reshape(-1, 3, 3)
        normals = np.array([np.asarray(bd.normal) / np.linalg.norm(bd.normal) for bd in bodies]).reshape(-1, 3)
        body_pos0 = np.array([bd.position_m for bd in bodies], float).reshape(-1, 3)
        for k, bd in enumerate(bodies):
            if bd.motion == "kinematic" and bd.path:
                body_pos0[k] = bd.path[0][1:]

        att_p, att_b, att_off = [], [], []
        for att in spec.attachments:
            body = names.index(att.body)
            sel = select_crossings(att, nx, ny, rest)
            att_p.extend(sel.tolist())
            att_b.extend([body] * len(sel))
            att_off.extend((rot[body].T @ (rest[sel] - body_pos0[body]).T).T.tolist())
        # A crossing held twice keeps its first holder.
        att_p_arr = np.asarray(att_p, np.int32)
        _, first = np.unique(att_p_arr, return_index=True)
        first = np.sort(first)

        t = c.tearing
        return Model(
            warp_yarns=nx,
            weft_yarns=ny,
            crossing_count=n,
            spacing_m=c.spacing_m,
            thickness_m=c.thickness_m,
            gravity_m_s2=np.asarray(spec.gravity_m_s2, float),
            crossing_mass_kg=np.full(n, c.mass_per_crossing_kg),
            crossing_rest_position_m=rest,
            crossing_weft_on_top=top,
            crossing_weft_springs=cw,
            crossing_warp_springs=cv,
            spring_kind=kind,
            spring_crossing_a=a,
            spring_crossing_b=b,
            spring_rest_length_m=rest_len,
            spring_base_stiffness_n_per_m=stiff,
            spring_break_strain=self._break_strains(len(kind)),
            spring_twin=twin,
            weft_structural_spring=weft_struct,
            warp_structural_spring=warp_struct,
            attachment_particle=att_p_arr[first],
            attachment_body=np.asarray(att_b, np.int32)[first],
            attachment_offset_m=np.asarray(att_off, float).reshape(-1, 3)[first],
            body_names=names,
            body_shape=np.array([SHAPE_NAMES.index(bd.shape) for bd in bodies], np.int8),
            body_motion=np.array([MOTION_NAMES.index(bd.motion) for bd in bodies], np.int8),
            body_radius_m=np.array([bd.radius_m for bd in bodies], float),
            body_half_extents_m=np.array([bd.half_extents_m for bd in bodies], float).reshape(-1, 3),
            body_normal=normals,
            body_rotation=rot,
            body_mass_kg=np.array([bd.mass_kg for bd in bodies], float),
            body_gravity=np.array([bd.gravity for bd in bodies], bool),
            body_friction=np.array([bd.friction for bd in bodies], float),
            body_collide=np.array([bd.collide for bd in bodies], bool),
            body_start_s=np.array([bd.start_s for bd in bodies], float),
            body_initial_position_m=body_pos0,
            body_initial_velocity_m_s=np.array([bd.velocity_m_s for bd in bodies], float).reshape(-1, 3),
            body_path=tuple(np.asarray(bd.path, float).reshape(-1, 4) for bd in bodies),
            strain_limit=c.strain.limit,
            strain_max_iterations=c.strain.max_iterations,
            strain_tolerance=c.strain.tolerance,
            damping=c.springs.damping,
            tearing=t.enabled,
            yarn_level=t.enabled and t.yarn_level,
            transition_strain=t.transition_strain,
            disconnect_distance_m=t.disconnect_factor * c.thickness_m,
            self_collision=spec.self_collision.enabled,
            self_collision_iterations=spec.self_collision.iterations,
            self_collision_friction=spec.self_collision.friction,
            seed=spec.scene.seed,
        )


def build_model(spec: SceneSpec) -> Model:
    """Build the immutable Model of a scene."""
    return ModelBuilder(spec).finalize()
