"""Step 6 for triangle-mesh bodies (docs/meshes.md): masses against the triangles, yarn segments against
the sharp edges, with friction. Only scenes with a colliding mesh body run it (it is imported only then)."""
from __future__ import annotations

import numpy as np

from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from fraytool.sim.kernels.bodies import bodies_in
from fraytool.sim.kernels.mesh_clearance import empty_segment_clearance, grown_segment_clearance
from fraytool.sim.kernels.mesh_contact import collide_mesh_segments, collide_meshes, segments_touching
from fraytool.sim.kernels.work_split import even_units
from fraytool.sim.mesh_geometry import MeshGeometry
from fraytool.sim.model import Model
from fraytool.sim.stages.base import BODIES, POSITIONS, START_POSITIONS, TOPOLOGY, StepContext
from fraytool.sim.state import State


class MeshContact:
    """Masses and yarn segments against the colliding mesh bodies (fraytool.sim.kernels.mesh_contact).
    Adds its contacts to ctx.counters.rigid_contacts_last (set by the analytic bodies' pass before it,
    or by this one when the scene has no other body)."""

    name = "collisions"
    kernel = "collide_meshes, segments_touching, collide_mesh_segments"
    segments_too = True
    reads = frozenset({POSITIONS, START_POSITIONS, BODIES, TOPOLOGY})
    writes = frozenset({POSITIONS})

    def __init__(self, model: Model, geometry: MeshGeometry, after_analytic: bool):
        self.model = model
        self.geometry = geometry
        self.after_analytic = after_analytic
        self._segments_key = None
        self._segments = np.zeros((0, 3), np.int64)
        self._segment_units = even_units(0)
        self._ends = (np.zeros(0, np.int64), even_units(0))
        """The segments' end particles (ascending, each once) and their units."""
        self._end_body_m = np.zeros((0, 2, 3))
        self._end_left_m = np.zeros(0)
        """segments_touching's scratch, a row per particle slot: each end's body-frame points at the step's start
        and end, and its bound."""
        self._touching = np.zeros((0, 0), np.bool_)
        self.segment_clearance = empty_segment_clearance(geometry.table.body.shape[0], 0)
        """Each segment's own distance bound from each mesh (fraytool.sim.kernels.mesh_clearance), a row per
        spring slot, kept as the segments change (made with the first segment list: the masses-only pass before
        the strain limit never needs it)."""
        self._structural = (model.spring_kind == STRUCT_WEFT) | (model.spring_kind == STRUCT_WARP)

    def segments(self, state: State, ctx: StepContext) -> np.ndarray:
        """Alive yarn segments (structural springs) as (S, 3): end particles a, b and the spring slot, kept per
        topology epoch. In a multi-resolution model, only those between free crossings: a segment with a slaved end
        is inside a coarse cell or on its border, where the cell's nodes and cells_on_meshes answer for the cloth
        (docs/multires.md, "Against a mesh"); and moving its free end alone to push a point near the
        slaved end out would take an unbounded lever."""
        key = state.topology_epoch  # a cut or a split bumps it (State.bump_topology); so does a refinement
        if key != self._segments_key:
            use = self._structural & state.spring_alive
            slaved = ctx.slaved(state)
            if slaved.size:
                is_slaved = np.zeros(state.particle_position_m.shape[0], bool)
                is_slaved[slaved] = True
                use &= ~(is_slaved[state.spring_particle_a] | is_slaved[state.spring_particle_b])
            s = np.flatnonzero(use)
            self.segment_clearance = grown_segment_clearance(self.segment_clearance, use.shape[0])
            self._segments = np.ascontiguousarray(np.stack([state.spring_particle_a[s], state.spring_particle_b[s], s],
                                                           axis=1).astype(np.int64))
            self._segments_key = key
            self._segment_units = even_units(self._segments.shape[0])
            is_end = np.zeros(state.particle_position_m.shape[0], np.bool_)
            is_end[self._segments[:, :2]] = True
            ends = np.flatnonzero(is_end)
            self._ends = (ends, even_units(ends.shape[0]))
            if self._end_left_m.shape[0] != is_end.shape[0]:
                self._end_body_m = np.zeros((is_end.shape[0], 2, 3))
                self._end_left_m = np.zeros(is_end.shape[0])
            self._touching = np.zeros((self.geometry.table.body.shape[0], self._segments.shape[0]), np.bool_)
        return self._segments

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None:
        m = self.model
        self.geometry.at_step(state.time_s, state.time_s + dt_s)
        meshes, bodies = self.geometry.meshes_in(m), bodies_in(m, state)
        margin = 0.5 * m.thickness_m
        clear = self.geometry.clearance
        hits = collide_meshes(*ctx.lists.free(state), meshes, bodies, margin, dt_s, state.particle_inv_mass,
                              ctx.prev_position_m, state.particle_position_m, clear, self.geometry.leaf_cache)
        if self.segments_too:
            segments = self.segments(state, ctx)
            segments_touching((segments, self._segment_units) + self._ends, meshes, bodies, margin, dt_s,
                              (state.particle_inv_mass, ctx.prev_position_m, state.particle_position_m), clear,
                              self.segment_clearance, self._touching, self._end_body_m, self._end_left_m)
            hits += collide_mesh_segments(segments, self._touching, meshes, bodies, margin, dt_s,
                                          state.particle_inv_mass, ctx.prev_position_m, state.particle_position_m,
                                          (clear, self.segment_clearance))
        if self.after_analytic:
            ctx.counters.rigid_contacts_last += hits
        else:
            ctx.counters.rigid_contacts_last = hits

    def summary(self, state: State) -> dict:
        return {}


class MeshContactBeforeLimit(MeshContact):
    """The mesh pass of step 5 in scenes that tear (as core.RigidContactBeforeLimit): the masses only, so
    that the strain limit sees the mesh's push; the yarn segments are resolved once, in step 6 (they are
    most of the mesh contact's cost, and the limit does not read them)."""

    name = "contact_before_limit"
    kernel = "collide_meshes"
    segments_too = False
