"""Model: the static arrays of a built cloth scene (never changed by a step).

Layout (see docs/architecture.md):
- crossings c = j * warp_yarns + i, with i the warp yarn (column) and j the weft yarn (row);
- particle slots: 2 * crossing_count. Slot c is the base mass of crossing c and, once the crossing
  has split into a mass couple (docs/method.md §3.4), its **weft** mass; slot crossing_count + c is the
  couple's **warp** mass (inactive while the crossing is at base level);
- springs have fixed slots for their whole life: structural and bend springs along weft and warp,
  shear springs, and for each shear spring a twin slot (dead until a split duplicates it).
What a step changes (positions, alive flags, spring end points after a split) lives in State.
"""
from __future__ import annotations

import math
from dataclasses import MISSING, dataclass, field, fields
from typing import Optional

import numpy as np

from fraytool.kinds import SHEAR_TWIN, STITCH
from fraytool.sim.state import State


def broken_cloth_springs(spring_kind: np.ndarray, spring_broken: np.ndarray) -> int:
    """The `broken_springs` figure: springs of the cloth broken so far. A seam's stitches are not the
    cloth's (they are `broken_stitches`), and springs cut by a scene's [[cuts]] are cut, not broken."""
    return int(np.count_nonzero(spring_broken & (spring_kind != STITCH)))


_DIGEST_SKIPS_EMPTY = ("spring_seam", "spring_weak_line", "attachment_entry_crossings", "seam_reverse_fits",
                       "spring_sew_s", "spring_sew_start_length_m", "attachment_triangle", "attachment_barycentric",
                       "attachment_normal_offset_m", "attachment_release_force_n", "attachment_catch_s",
                       "panel_drag_normal", "panel_drag_tangential")
_DIGEST_SKIPS_DEFAULT = {"gravity_start_s": 0.0, "wind_m_s": np.zeros(3), "air_density_kg_m3": 1.2,
                         "gust_strength_m_s": 0.0, "gust_length_m": 0.5, "gust_time_s": 0.5}
"""Fields left out of the digest at these values: Models from before the fields keep their digest."""


def sewing_progress(time_s: np.ndarray | float, sew_s: np.ndarray) -> np.ndarray:
    """How far each sewn stitch has been pulled in at `time_s`, 0 to 1: smoothstep of time_s / sew_s (no jerk
    at the start or the end of sewing; docs/garments.md)."""
    u = np.clip(np.asarray(time_s, float) / np.where(sew_s > 0.0, sew_s, 1.0), 0.0, 1.0)
    return np.where(sew_s > 0.0, u * u * (3.0 - 2.0 * u), 1.0)


def sewn_rest_length_m(model, time_s: float, springs: Optional[np.ndarray] = None) -> np.ndarray:
    """Every spring's rest length (or the `springs` slots' only) at `time_s` with the seams sewn over time
    pulled in so far: from the stitch's length where the panels are placed to its rest length
    (Model.spring_sew_s)."""
    pick = slice(None) if springs is None else springs
    sew_s, start, rest = model.spring_sew_s[pick], model.spring_sew_start_length_m[pick], model.spring_rest_length_m[pick]
    p = sewing_progress(time_s, sew_s)
    return np.where(sew_s > 0.0, start + p * (rest - start), rest)


def _empty_mesh(name: str) -> np.ndarray:
    from fraytool.meshes import empty_fields

    return empty_fields()[name]



@dataclass(frozen=True, eq=False)
class Model:
    warp_yarns: int
    """Number of warp yarns (columns, index i)."""
    weft_yarns: int
    """Number of weft yarns (rows, index j)."""
    crossing_count: int
    spacing_m: float
    """Yarn spacing at rest [m]."""
    thickness_m: float
    """Cloth thickness T [m]."""
    gravity_m_s2: np.ndarray
    """Gravity [m/s^2], shape (3,), float64."""

    crossing_mass_kg: np.ndarray
    """Mass of each crossing [kg], shape (crossing_count,), float64."""
    crossing_rest_position_m: np.ndarray
    """Rest position of each crossing [m], shape (crossing_count, 3), float64."""
    crossing_weft_on_top: np.ndarray
    """True where the weft lies above the warp (weave pattern), shape (crossing_count,), bool."""
    crossing_weft_springs: np.ndarray
    """Structural weft springs at each crossing (to i-1, to i+1; -1 if none), shape (crossing_count, 2), int32."""
    crossing_warp_springs: np.ndarray
    """Structural warp springs at each crossing (to j-1, to j+1; -1 if none), shape (crossing_count, 2), int32."""
    crossing_grid_i: np.ndarray
    """Warp yarn (grid column) i of each crossing, shape (crossing_count,), int32. A rectangle holds every
    place of the grid, c = j * warp_yarns + i; a shaped panel (docs/panels.md) only the places inside its
    shape, in the same row-major order."""
    crossing_grid_j: np.ndarray
    """Weft yarn (grid row) j of each crossing, shape (crossing_count,), int32."""
    crossing_plane_uv_m: np.ndarray
    """Rest place of each crossing in the cloth's plane [m] from origin_m (u along the plane's first axis, v
    its second), where outline_m, weak lines and scissors are given, shape (crossing_count, 2), float64."""
    crossing_panel: np.ndarray
    """Panel of each crossing ([[cloth]] in order; docs/panels.md), shape (crossing_count,), int32."""
    panel_names: tuple[str, ...]
    """Name of each panel."""
    crossing_hemmed: np.ndarray
    """Crossings on a hemmed border: never split into a mass couple, shape (crossing_count,), bool."""

    spring_kind: np.ndarray
    """Spring kind (STRUCT_WEFT ... SHEAR_TWIN), shape (spring_count,), int8."""
    spring_crossing_a: np.ndarray
    """Crossing at end a, shape (spring_count,), int32."""
    spring_crossing_b: np.ndarray
    """Crossing at end b, shape (spring_count,), int32."""
    spring_rest_length_m: np.ndarray
    """Rest length at build [m] (State.spring_rest_length_m holds the current one)."""
    """Rest length [m], shape (spring_count,), float64."""
    spring_base_stiffness_n_per_m: np.ndarray
    """Stiffness when first created [N/m], shape (spring_count,), float64."""
    spring_break_strain: np.ndarray
    """Randomised strain at which the spring is cut, drawn once from the scene seed, shape (spring_count,)."""
    spring_twin: np.ndarray
    """For a shear spring, the slot of its duplicate (and back); -1 otherwise, shape (spring_count,), int32."""
    spring_precut: np.ndarray
    """Springs cut before the shot by a [[cuts]] line: dead from the first frame, never broken, shape
    (spring_count,), bool."""
    spring_cut_time_s: np.ndarray
    """When scissors ([[cuts]] path_m) cut each structural spring [s], inf for never; such a cut is not a
    break and leaves clean ends, like a snip; shape (spring_count,), float64."""
    weft_structural_spring: np.ndarray
    """Spring joining crossings (i, j) and (i+1, j): shape (weft_yarns, warp_yarns - 1), int32; -1 where a
    shaped panel has no such spring."""
    warp_structural_spring: np.ndarray
    """Spring joining crossings (i, j) and (i, j+1): shape (warp_yarns, weft_yarns - 1), int32; -1 where a
    shaped panel has no such spring."""

    attachment_particle: np.ndarray
    """Particle slots held by a rigid body, shape (attachment_count,), int32."""
    attachment_body: np.ndarray
    """Holding body of each attachment, shape (attachment_count,), int32."""
    attachment_offset_m: np.ndarray
    """Offset from the body centre in the body frame [m], shape (attachment_count, 3), float64."""

    body_names: tuple[str, ...]
    body_shape: np.ndarray
    """The body's kind, SHAPE_* (fraytool.kinds), shape (body_count,), int8."""
    body_motion: np.ndarray
    """MOTION_* per body, shape (body_count,), int8."""
    body_params: np.ndarray
    """Parameters by kind, shape (body_count, 3), float64: sphere (radius [m], 0, 0), box half extents [m],
    plane unit normal in the body frame (fraytool.sim.kernels.bodies)."""
    body_rotation: np.ndarray
    """Orientation at rest (body to world), shape (body_count, 3, 3): rotation_deg, or a kinematic
    body's first orientation key; State.body_rotation is the current one."""
    body_mass_kg: np.ndarray
    """Dynamic body mass [kg], shape (body_count,)."""
    body_gravity: np.ndarray
    """Dynamic body feels gravity, shape (body_count,), bool."""
    body_friction: np.ndarray
    """Friction coefficient against the cloth, shape (body_count,)."""
    body_collide: np.ndarray
    """Cloth collides with the body, shape (body_count,), bool."""
    body_start_s: np.ndarray
    """Time the body starts moving [s], shape (body_count,)."""
    body_initial_position_m: np.ndarray
    """Shape (body_count, 3)."""
    body_initial_velocity_m_s: np.ndarray
    """Shape (body_count, 3)."""
    body_path: tuple[np.ndarray, ...]
    """Per body: kinematic keyframes (t, x, y, z), shape (K, 4); empty for none."""

    strain_limit: float
    """Structural springs are projected to at most (1 + strain_limit) x rest length."""
    strain_max_iterations: int
    strain_tolerance: float
    strain_stiffness_n_per_m: float
    """Stiffness of a structural spring past the strain limit [N/m]; 0: the limit is hard."""
    strain_damping_n_s_per_m: float
    """Dashpot of a structural spring stretching past the strain limit [N s/m]; 0: none."""
    damping: float
    """PBD damping coefficient k_damping per step, in [0, 1]."""
    tearing: bool
    yarn_level: bool
    transition_strain: float
    propagation_inclusive: bool
    """Propagation of a split (docs/method.md §3.4): True splits up to and including the crossing
    where the weave flips (the paper's reading), False stops just before it ([cloth.tearing] propagation)."""
    ineffective_length: int
    """A structural spring breaks only with at least this many yarn crossings on each side of it up to
    the nearest free yarn end ([cloth.tearing] ineffective_length; docs/tearing.md "Cutting")."""
    disconnect_distance_m: float
    """A connected couple disconnects beyond this weft-warp distance [m]."""
    self_collision: bool
    self_collision_iterations: int
    self_collision_friction: float
    seed: int
    coarse_factor: int = 1
    """[cloth.multires] factor: coarse cells of coarse_factor x coarse_factor yarn spacings where the cloth
    is whole (fraytool.sim.multires); 1: yarn resolution everywhere."""
    refine_strain: float = math.inf
    """A coarse cell refines when a structural spring in or next to it passes this strain."""
    refine_band_cells: int = 2
    """Coarse cells refined around a cell past refine_strain (and around a moving body)."""
    refine_near_bodies: bool = True
    body_orientation_path: tuple[np.ndarray, ...] = ()
    """Per body: kinematic orientation keys (t, w, x, y, z), unit and sign-consistent quaternions, shape
    (K, 5); empty for none (fraytool.sim.paths). Empty tuple: no body has any."""
    body_interpolation: tuple[str, ...] = ()
    """Per body: "linear" or "catmull_rom", for its path and orientation keys (fraytool.sim.paths)."""
    mesh_body: np.ndarray = field(default_factory=lambda: _empty_mesh("mesh_body"))
    """Triangle-mesh bodies (fraytool.meshes, docs/meshes.md): body index of each mesh, shape (M,)."""
    mesh_closed: np.ndarray = field(default_factory=lambda: _empty_mesh("mesh_closed"))
    mesh_vertex_start: np.ndarray = field(default_factory=lambda: _empty_mesh("mesh_vertex_start"))
    mesh_triangle_start: np.ndarray = field(default_factory=lambda: _empty_mesh("mesh_triangle_start"))
    mesh_triangles: np.ndarray = field(default_factory=lambda: _empty_mesh("mesh_triangles"))
    mesh_key_start: np.ndarray = field(default_factory=lambda: _empty_mesh("mesh_key_start"))
    mesh_key_time_s: np.ndarray = field(default_factory=lambda: _empty_mesh("mesh_key_time_s"))
    mesh_key_vertex_m: np.ndarray = field(default_factory=lambda: _empty_mesh("mesh_key_vertex_m"))
    mesh_edge_start: np.ndarray = field(default_factory=lambda: _empty_mesh("mesh_edge_start"))
    mesh_sharp_edges: np.ndarray = field(default_factory=lambda: _empty_mesh("mesh_sharp_edges"))
    spring_seam: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    """The [[seams]] entry each spring is a stitch of, -1 for the cloth's own springs, shape (spring_count,),
    int32; empty where the scene has no seam (the per-seam figures, fraytool.sim.tear_control_figures)."""
    attachment_entry_crossings: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    """Crossings each [[attachments]] entry selected when it was added (before a crossing held twice keeps its
    first holder), shape (entries,), int64; an entry of 0 holds nothing (and the builder warned of it)."""
    seam_reverse_fits: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    """Per [[seams]] entry: sewn the other way round (reverse flipped), every stitch would start within its
    the seam's break strain, shape (seams,), bool (the start warning's hint, fraytool.sim.seam_layout)."""
    spring_weak_line: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    """The last [[weak_lines]] entry that weakened each spring, -1 for none, shape (spring_count,), int32;
    empty where the scene has no weak line."""
    spring_sew_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """Seconds over which each stitch is sewn ([[seams]] sew_s), 0 for the cloth's springs and stitches sewn from
    the start, shape (spring_count,); empty where no seam is sewn over time (docs/garments.md)."""
    spring_sew_start_length_m: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """Each sewn stitch's length where the panels are placed [m] (its rest length at time 0, shrinking to
    spring_rest_length_m by its sew_s), shape (spring_count,); empty as spring_sew_s."""
    attachment_triangle: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    """Per held crossing (as attachment_particle): the mesh triangle (into mesh_triangles) whose surface it is
    pinned to, -1 for one held rigidly by its body (fraytool.sim.surface_pins), shape (attachments,), int64;
    empty where every attachment is rigid and never lets go, as the three below."""
    attachment_barycentric: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """Its place on that triangle, barycentric weights, shape (attachments, 3)."""
    attachment_normal_offset_m: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """Its distance off the triangle along the triangle's normal at rest [m], shape (attachments,)."""
    attachment_release_force_n: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """The force above which it lets go [N], 0 for never ([[attachments]] release_force_n), shape (attachments,)."""
    gravity_start_s: float = 0.0
    """Gravity acts from this time on [s] ([world] gravity_start_s; Model.gravity_at_m_s2)."""
    attachment_catch_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """When its body catches it [s] ([[attachments]] catch_s; free before, held from then on where it is then:
    State.attachment_offset_m), 0 for held from the start, shape (attachments,); empty as attachment_triangle."""
    panel_drag_normal: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """Air drag coefficient across each panel ([cloth] drag_normal; docs/wind.md), shape (panels,); empty where no
    panel has drag (no air stage), as panel_drag_tangential."""
    panel_drag_tangential: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """Air drag coefficient along each panel's plane ([cloth] drag_tangential), shape (panels,)."""
    wind_m_s: np.ndarray = field(default_factory=lambda: np.zeros(3))
    """Mean wind [m/s] ([world] wind_m_s), shape (3,)."""
    air_density_kg_m3: float = 1.2
    """Density of the air [kg/m^3] ([world] air_density_kg_m3)."""
    gust_strength_m_s: float = 0.0
    """RMS of each component of the gusts [m/s] ([world] gust_strength_m_s; fraytool.sim.air); 0: steady."""
    gust_length_m: float = 0.5
    """Length scale of the gusts [m]."""
    gust_time_s: float = 0.5
    """Time scale of the gusts [s]."""
    build_warnings: tuple[str, ...] = ()
    """What the builder noticed when each entry was added that no range check can (ModelBuilder.warnings): an
    attachment that holds nothing, a seam whose stitches start torn, an open or oversized mesh. Not part of
    digest(): words about the Model, not the Model."""

    @property
    def particle_count(self) -> int:
        """Number of particle slots (two per crossing)."""
        return 2 * self.crossing_count

    @property
    def spring_count(self) -> int:
        return int(self.spring_kind.shape[0])

    @property
    def body_count(self) -> int:
        return int(self.body_shape.shape[0])

    @property
    def attachment_count(self) -> int:
        return int(self.attachment_particle.shape[0])

    def spring_yarn(self) -> np.ndarray:
        """Yarn of every spring slot: weft yarn j -> j, warp yarn i -> weft_yarns + i, -1 for springs
        that are not yarn segments (bend, shear), shape (spring_count,), int32."""
        yarn = np.full(self.spring_count, -1, np.int32)
        weft, warp = self.weft_structural_spring, self.warp_structural_spring
        weft_yarn = np.repeat(np.arange(weft.shape[0], dtype=np.int32), weft.shape[1])
        warp_yarn = self.weft_yarns + np.repeat(np.arange(warp.shape[0], dtype=np.int32), warp.shape[1])
        yarn[weft.ravel()[weft.ravel() >= 0]] = weft_yarn[weft.ravel() >= 0]
        yarn[warp.ravel()[warp.ravel() >= 0]] = warp_yarn[warp.ravel() >= 0]
        return yarn

    def crossing_grid(self) -> np.ndarray:
        """Crossing at each place of the grid, -1 where a shaped panel has none, shape (weft_yarns,
        warp_yarns), int64."""
        grid = np.full((self.weft_yarns, self.warp_yarns), -1, np.int64)
        grid[self.crossing_grid_j, self.crossing_grid_i] = np.arange(self.crossing_count)
        return grid

    @property
    def full_grid(self) -> bool:
        """Every place of the grid holds a crossing (a rectangle): c = j * warp_yarns + i."""
        return self.crossing_count == self.warp_yarns * self.weft_yarns

    def state(self) -> State:
        """State at rest: base-level crossings at their rest positions, bodies at their start poses."""
        n = self.crossing_count
        pos = np.zeros((2 * n, 3))
        pos[:n] = self.crossing_rest_position_m
        pos[n:] = self.crossing_rest_position_m
        mass = np.zeros(2 * n)
        mass[:n] = self.crossing_mass_kg
        active = np.zeros(2 * n, dtype=bool)
        active[:n] = True
        inv_mass = np.zeros(2 * n)
        inv_mass[:n] = 1.0 / self.crossing_mass_kg
        inv_mass[self.attachment_particle] = 0.0
        if self.attachment_catch_s.size:  # caught later: free until then (fraytool.sim.stages.core.Attachments)
            later = self.attachment_particle[self.attachment_catch_s > 0.0]
            inv_mass[later] = 1.0 / mass[later]
        refined = np.zeros(0, bool)
        if self.coarse_factor > 1:
            from fraytool.sim import multires

            layout = multires.coarse_layout(self)
            refined = multires.initial_refined(self, layout)
        # Shear twins are born dead (a split brings them to life); springs on a [[cuts]] line are not there.
        alive = (self.spring_kind != SHEAR_TWIN) & ~self.spring_precut
        state = State(
            time_s=0.0,
            step_index=0,
            particle_position_m=pos,
            particle_velocity_m_s=np.zeros((2 * n, 3)),
            particle_mass_kg=mass,
            particle_inv_mass=inv_mass,
            particle_active=active,
            crossing_yarn_level=np.zeros(n, dtype=bool),
            couple_connected=np.zeros(n, dtype=bool),
            spring_particle_a=self.spring_crossing_a.copy(),
            spring_particle_b=self.spring_crossing_b.copy(),
            spring_alive=alive,
            spring_broken=np.zeros(self.spring_count, dtype=bool),
            spring_stiffness_n_per_m=np.where(alive, self.spring_base_stiffness_n_per_m, 0.0),
            spring_rest_length_m=sewn_rest_length_m(self, 0.0) if self.spring_sew_s.size else
            self.spring_rest_length_m.copy(),
            body_position_m=self.body_initial_position_m.copy(),
            body_velocity_m_s=np.zeros((self.body_count, 3)),
            body_rotation=self.body_rotation.copy(),
            body_angular_velocity_rad_s=np.zeros((self.body_count, 3)),
            coarse_cell_refined=refined,
            attachment_offset_m=self.attachment_offset_m.copy() if self.attachment_catch_s.size else np.zeros((0, 3)),
        )
        if self.coarse_factor > 1:
            multires.refine_on_meshes_at_start(self, layout, state)
            multires.set_masses(self, layout, state.coarse_cell_refined, state)  # lumped into the nodes, slaved 0
        return state

    def gravity_at_m_s2(self, time_s: float) -> np.ndarray:
        """Gravity over the step that starts at `time_s`: zero before gravity_start_s."""
        return self.gravity_m_s2 if time_s >= self.gravity_start_s else np.zeros(3)

    def arrays(self) -> dict[str, np.ndarray]:
        """All array fields, for saving (topology.npz); the bodies' parameters also as the per-shape arrays
        frame folders have always held (body_radius_m, body_half_extents_m, body_normal)."""
        from fraytool.sim.kernels.bodies import legacy_body_arrays

        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "body_params":
                out.update(legacy_body_arrays(self.body_shape, v))
            if isinstance(v, np.ndarray):
                out[f.name] = v
            elif isinstance(v, (int, float, bool)):
                out[f.name] = np.asarray(v)
            elif f.name == "build_warnings":  # words, saved as they are
                out[f.name] = np.asarray(v, dtype=str).reshape(len(v))
            elif isinstance(v, tuple) and all(isinstance(x, np.ndarray) for x in v):  # one array per body
                out[f"{f.name}.count"] = np.asarray(len(v))
                out.update({f"{f.name}.{k}": x for k, x in enumerate(v)})
            elif isinstance(v, tuple):  # names (panels, bodies)
                out[f.name] = np.asarray(v, dtype=str).reshape(len(v))
        return out

    def digest(self) -> str:
        """SHA-256 over every array of `arrays()` (name, dtype, shape, bytes), in name order: two Models
        with one break strain apart have different digests."""
        import hashlib

        h = hashlib.sha256()
        for name, v in sorted(self.arrays().items()):
            if name in _DIGEST_SKIPS_EMPTY and v.size == 0 or name == "build_warnings" \
                    or name in _DIGEST_SKIPS_DEFAULT and np.array_equal(v, _DIGEST_SKIPS_DEFAULT[name]):
                continue  # Models without seams or weak lines keep the digest they had before these fields
            v = np.ascontiguousarray(v)
            h.update(f"{name}:{v.dtype.str}:{v.shape}".encode())
            h.update(v.tobytes())
        return h.hexdigest()

    @classmethod
    def from_arrays(cls, data) -> "Model":
        """The Model whose `arrays()` are `data` (a frames folder's topology): a shot simulated from a Model
        built or edited in Python resumes, renders and exports without its scene file. Raises ValueError
        naming the fields a topology written before names were saved lacks."""
        import typing

        hints = typing.get_type_hints(cls)
        keys = set(data) | {k.rsplit(".", 1)[0] for k in data if k.endswith(".count")}
        missing = [f.name for f in fields(cls) if f.name not in keys and f.default is MISSING
                   and f.default_factory is MISSING]
        if missing:
            raise ValueError(f"the saved model lacks {', '.join(missing)} (written by an older fraytool): "
                             "simulate it again from its scene")
        args = {}
        for f in fields(cls):
            if f"{f.name}.count" in data:  # one array per body
                count = int(np.asarray(data[f"{f.name}.count"]))
                args[f.name] = tuple(np.array(data[f"{f.name}.{k}"]) for k in range(count))
                continue
            if f.name not in data:
                continue
            v, hint = data[f.name], hints[f.name]
            if hint is np.ndarray:
                args[f.name] = np.array(v)
            elif hint in (int, float, bool):
                args[f.name] = hint(np.asarray(v).item())
            else:
                args[f.name] = tuple(str(x) for x in np.asarray(v).reshape(-1))
        return cls(**args)
