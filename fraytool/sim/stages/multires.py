"""Stages of the multi-resolution base model ([cloth.multires] factor > 1; docs/multires.md).

- MultiresForces replaces SpringForces: the springs at work (fine springs bordering a refined cell,
  coarse springs bordering a coarse cell, each with its share), then the forces on slaved crossings
  handed to their nodes.
- CoarseSync puts slaved crossings back on their cells' interpolation mid-step. It is never placed by
  hand: build_stages inserts one before each stage that declares it reads a coarse view (the hanging
  nodes, every slaved crossing, the ones near hot cells) when a stage since the last sync wrote
  positions or topology (fraytool.sim.stages.base).
- SlavedContact (after rigid contact): slaved crossings kept out of bodies through their nodes.
- Refinement (before tearing): coarse cells near a strain that could tear, or near a moving body,
  refine; the crossings that become free take their mass back from their nodes (total mass and
  momentum kept exactly: the crossing moves with the interpolated velocity its mass had while lumped).

One CoarseWork, in the step context (StepContext.coarse), keeps the lists derived from
State.coarse_cell_refined. It is checked whenever State.topology_epoch changes and rebuilt when the
refined cells differ from the ones it was built for (an exact comparison of the flags).
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from fraytool.kinds import SHAPE_MESH, STRUCT_WARP, STRUCT_WEFT
from fraytool.sim import multires
from fraytool.sim.kernels.bodies import bodies_in
from fraytool.sim.kernels.integrate import velocities_from_positions
from fraytool.sim.kernels.multires import (
    add_listed_spring_forces,
    cells_to_refine,
    collide_slaved,
    gather_slaved_forces,
    sync_near_hot,
    sync_slaved,
    sync_slaved_parallel,
    zero_rows,
)
from fraytool.sim.kernels.work_split import even_units
from fraytool.sim.model import Model
from fraytool.sim.stages.base import (BODIES, FORCES, HANGING, POSITIONS, SELF_CONTACT, SLAVED, SLAVED_NEAR_HOT,
                                      START_POSITIONS, TOPOLOGY, StepContext)
from fraytool.sim.state import State


PARALLEL_SYNC_MIN = 16384
"""Slaved crossings from which `CoarseWork.sync_all` runs in parallel (below it, waking the threads costs more
than the serial loop; a 1 mm garment has 58,000)."""


class CoarseWork:
    """The layout of a model's cells and the work lists of its current refinement (StepContext.coarse)."""

    def __init__(self, model: Model):
        self.model = model
        self.layout = multires.coarse_layout(model)
        lay = self.layout
        structural = (model.spring_kind == STRUCT_WEFT) | (model.spring_kind == STRUCT_WARP)
        self._structural = structural
        self._coarse_structural = (lay.coarse_kind == STRUCT_WEFT) | (lay.coarse_kind == STRUCT_WARP)
        self.coarse_alive = np.ones(lay.coarse_kind.shape[0], bool)
        self.cell_nodes = lay.cell_nodes
        self.hot = np.zeros(lay.cell_count, bool)
        """Cells with a spring past the refine strain in the last refinement pass (cells_to_refine)."""
        self.new = np.zeros(lay.cell_count, bool)
        """Cells the last refinement pass refined."""
        self._near = np.zeros(lay.cell_count, bool)
        self.moving_bodies, self.body_reach_m = multires.moving_body_reach(model, lay)
        self.working: Optional[np.ndarray] = None
        """Mask over spring slots: the structural springs of refined cells (strain limiting and the tear
        scans look at these only; the others are slaved, below the refine strain by construction)."""
        self.built_at = -1
        """State.topology_epoch at the last rebuild of the lists (what caches derived from them key on)."""
        self._seen_epoch: Optional[int] = None
        self._refined: Optional[np.ndarray] = None
        self.self_contact: Optional[np.ndarray] = None
        """Per particle: held or slaved, and within the contact distance of another yarn segment at the end of
        this step's self-collision (SELF_CONTACT; None in a scene without self-collision)."""

    def ensure(self, state: State) -> None:
        """The lists of `state`'s refinement: checked when its topology epoch changed, rebuilt when its
        refined cells are not the ones the lists were built for."""
        if state.topology_epoch == self._seen_epoch:
            return
        if self._refined is None or not np.array_equal(self._refined, state.coarse_cell_refined):
            self._rebuild(state)
        self._seen_epoch = state.topology_epoch

    def slaved_now(self, state: State) -> np.ndarray:
        """The crossings slaved to coarse nodes in `state` (ascending)."""
        self.ensure(state)
        return self.slaved

    # -- syncs (CoarseSync and the completion call) ------------------------------------------------
    def sync_all(self, state: State, prev_position_m: np.ndarray) -> None:
        """Every slaved crossing on its interpolation: positions, and start-of-step positions from the
        nodes' (the interpolation of a node's move over the step is the slaved crossing's move)."""
        lay = self.layout
        sync = sync_slaved_parallel if self.slaved.shape[0] >= PARALLEL_SYNC_MIN else sync_slaved
        sync(self.slaved, lay.crossing_node, lay.crossing_weight, state.particle_position_m)
        sync(self.slaved, lay.crossing_node, lay.crossing_weight, prev_position_m)

    def sync_hanging(self, state: State, prev_position_m: np.ndarray) -> None:
        """The hanging nodes (slaved crossings a working fine spring pulls on) on their interpolation."""
        lay = self.layout
        sync_slaved(self.loaded_slaved, lay.crossing_node, lay.crossing_weight, state.particle_position_m)
        sync_slaved(self.loaded_slaved, lay.crossing_node, lay.crossing_weight, prev_position_m)

    def sync_near_hot(self, state: State, prev_position_m: np.ndarray) -> None:
        """The slaved crossings within band + 1 cells of a hot cell of the last refinement pass."""
        if not self.hot.any():
            return
        lay = self.layout
        sync_near_hot(self.hot, self.model.refine_band_cells + 1, lay.cells_x, lay.cells_y, self.cell_start,
                      self.cell_slaved, lay.crossing_node, lay.crossing_weight, self._near,
                      state.particle_position_m, prev_position_m)

    def _rebuild(self, state: State) -> None:
        lay, refined = self.layout, state.coarse_cell_refined
        self._refined = refined.copy()
        self.built_at = state.topology_epoch
        free = multires.free_crossings(lay, refined)
        self.slaved = np.flatnonzero(~free).astype(np.int32)
        # the slaved crossings grouped by the cell they interpolate (SlavedContact's cell test)
        self.cell_slaved, self.cell_start = multires.slaved_by_cell(lay, self.slaved)
        self.is_free = free
        """Per crossing: free (simulated) in the current refinement."""
        self._mixed = None
        fine_share = multires.share(lay.spring_cells, refined, at_fine=True)
        self.fine_listed = np.flatnonzero(fine_share > 0.0).astype(np.int32)
        self.fine_share = fine_share[self.fine_listed]
        coarse_share = multires.share(lay.coarse_cells, refined, at_fine=False, weight=lay.coarse_cell_weight)
        self.coarse_listed = np.flatnonzero(coarse_share > 0.0).astype(np.int32)
        self.coarse_share = coarse_share[self.coarse_listed]
        working = np.zeros(self.model.spring_count, bool)
        working[self.fine_listed] = True
        working &= self._structural
        self.working = working
        self.fine_structural = np.flatnonzero(working).astype(np.int32)
        self.coarse_structural = self.coarse_listed[self._coarse_structural[self.coarse_listed]]
        # slaved crossings that a fine spring at work pulls on (hanging nodes): the only ones with a force
        m = self.model
        ends = np.concatenate([m.spring_crossing_a[self.fine_listed], m.spring_crossing_b[self.fine_listed]])
        loaded = np.zeros(m.crossing_count, bool)
        loaded[ends] = True
        self.loaded_slaved = np.flatnonzero(loaded & ~free).astype(np.int32)

    @property
    def mixed(self) -> tuple[np.ndarray, np.ndarray]:
        """The yarn segments with one free and one slaved end (multires.mixed_segments), for the coarse mesh
        test: made when first asked for after a rebuild (scenes without a mesh never ask)."""
        if self._mixed is None:
            self._mixed = multires.mixed_segments(self.model, self.is_free)
        return self._mixed

    def refine(self, state: State, new: np.ndarray) -> None:
        """Refine the cells `new`: free crossings take their own mass back (set_masses), at the
        interpolated position and velocity they already have. A change of topology."""
        state.coarse_cell_refined |= new
        multires.set_masses(self.model, self.layout, state.coarse_cell_refined, state)
        state.bump_topology()
        self.ensure(state)

    def complete(self, state: State, ctx: StepContext, dt_s: float, speed_limit_m_s: float) -> None:
        """Every slaved crossing on its interpolation, with the velocity of its last step
        v = (x - x_prev) / dt: what the steps leave out (they sync only what they read)."""
        if state.coarse_cell_refined.all():
            return
        self.ensure(state)
        self.sync_all(state, ctx.prev_position_m)
        slaved = self.slaved
        if slaved.shape[0]:
            velocities_from_positions(slaved, even_units(slaved.shape[0]), state.particle_position_m,
                                      ctx.prev_position_m, state.particle_active, state.particle_velocity_m_s,
                                      dt_s, speed_limit_m_s)


class CoarseSync:
    """Slaved crossings back on their cells' interpolation before a stage that reads them (inserted by
    build_stages from the stages' declared reads, never by hand; timed in the reader's bucket)."""

    kernel = "sync_slaved"
    reads = frozenset({POSITIONS, START_POSITIONS, TOPOLOGY})

    def __init__(self, views: tuple, before: str):
        self.views = tuple(views)
        self.name = before
        self.writes = frozenset(self.views)

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None:
        coarse = ctx.coarse
        coarse.ensure(state)
        if SLAVED in self.views:
            coarse.sync_all(state, ctx.prev_position_m)
            return
        if HANGING in self.views:
            coarse.sync_hanging(state, ctx.prev_position_m)
        if SLAVED_NEAR_HOT in self.views:
            coarse.sync_near_hot(state, ctx.prev_position_m)

    def summary(self, state: State) -> dict:
        return {}

    def __repr__(self) -> str:
        return f"CoarseSync({', '.join(self.views)} before {self.name})"


class MultiresForces:
    """Step 1 with the multi-resolution model: the springs at work, then slaved forces to the nodes."""

    name = "forces"
    kernel = "add_listed_spring_forces, gather_slaved_forces"
    reads = frozenset({POSITIONS, TOPOLOGY, HANGING})
    writes = frozenset({FORCES})

    def __init__(self, model: Model):
        self.model = model
        self._cleared_at = None

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None:
        rt, m = ctx.coarse, self.model
        lay = rt.layout
        rt.ensure(state)
        # Every row a spring writes to: the moving particles (spring ends are active; the slaved ones
        # among them are the hanging nodes, which gather_slaved_forces zeroes after use). The other rows
        # are read by nothing; they are cleared whenever the lists are rebuilt, so that a state with more
        # slaved crossings than the rows last written (a resume, the guard's replay) starts clean.
        if self._cleared_at != rt.built_at:
            ctx.force_n[:] = 0.0
            self._cleared_at = rt.built_at
        zero_rows(ctx.lists.moving(state)[0], ctx.force_n)
        zero_rows(rt.loaded_slaved, ctx.force_n)
        add_listed_spring_forces(rt.fine_listed, rt.fine_share, m.spring_kind, state.spring_rest_length_m,
                                 state.particle_position_m, state.spring_particle_a, state.spring_particle_b,
                                 state.spring_alive, state.spring_stiffness_n_per_m, ctx.force_n)
        add_listed_spring_forces(rt.coarse_listed, rt.coarse_share, lay.coarse_kind, lay.coarse_rest_length_m,
                                 state.particle_position_m, lay.coarse_a, lay.coarse_b, rt.coarse_alive,
                                 lay.coarse_stiffness_n_per_m, ctx.force_n)
        gather_slaved_forces(rt.loaded_slaved, lay.crossing_node, lay.crossing_weight, ctx.force_n)

    def summary(self, state: State) -> dict:
        return {}


class SlavedContact:
    """Step 6, after rigid contact: slaved crossings kept out of the bodies through their nodes
    (fraytool.sim.kernels.multires.collide_slaved, with the body's friction), so that a coarse cell
    lying on a body does not sag into it between its nodes. No reaction on dynamic bodies (the nodes'
    own contacts give that). Moving bodies are left out when refine_near_bodies is on: the cells within
    (band_cells + 1) cell diagonals of their bounding sphere are refined a step before they could reach
    them, so every slaved crossing is farther than that from them."""

    name = "collisions"
    kernel = "collide_slaved"
    reads = frozenset({POSITIONS, START_POSITIONS, BODIES, TOPOLOGY})
    writes = frozenset({POSITIONS})

    def __init__(self, model: Model):
        self.model = model
        lay = multires.coarse_layout(model)
        moving_bodies, _ = multires.moving_body_reach(model, lay)
        self._point = np.zeros(3)
        # Moving bodies refine the cells within their reach (Refinement, refine_near_bodies) before they
        # get there, so no slaved crossing is within a cell's width of them: only the other bodies here.
        self.collide = model.body_collide.copy()
        self.collide[moving_bodies] = False
        self.collide[model.body_shape == SHAPE_MESH] = False  # (Refinement: cells_on_meshes)
        self.any = bool(self.collide.any())
        self._nodes = np.unique(lay.cell_nodes[lay.cell_whole]).astype(np.int32)
        self._outside = np.zeros(model.crossing_count, np.uint8)

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None:
        if not self.any:
            return
        rt, m = ctx.coarse, self.model
        lay = rt.layout
        rt.ensure(state)
        cells = (rt.cell_start, rt.cell_slaved, rt.cell_nodes, self._nodes, lay.crossing_node, lay.crossing_weight)
        collide_slaved(cells, bodies_in(m, state, self.collide), 0.5 * m.thickness_m, dt_s, state.particle_inv_mass,
                       ctx.prev_position_m, state.particle_position_m, self._point, self._outside)

    def summary(self, state: State) -> dict:
        return {}


class Refinement:
    """Before tearing: coarse cells refined ahead of any strain that could tear them (cells_to_refine
    reads the hanging nodes, which the step keeps on their interpolation where read). A refinement
    frees crossings at their interpolated positions and start-of-step positions (every slaved crossing
    is synced first), so the step ends with the velocity their mass had while lumped. The cells found
    hot stay in StepContext.coarse.hot, for the sync of the slaved crossings a split may read."""

    name = "refinement"
    kernel = "cells_to_refine"
    reads = frozenset({POSITIONS, HANGING, BODIES, TOPOLOGY, SELF_CONTACT})
    writes = frozenset({TOPOLOGY})

    def __init__(self, model: Model):
        self.model = model
        lay = multires.coarse_layout(model)
        self._centre = np.zeros((multires.moving_body_reach(model, lay)[0].shape[0], 3))
        self.mesh_test = multires.CoarseMeshTest(model, lay)

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None:
        rt, m = ctx.coarse, self.model
        lay = rt.layout
        rt.ensure(state)
        if state.coarse_cell_refined.all():
            return  # everything refined
        self._centre[:] = state.body_position_m[rt.moving_bodies]
        fine = (rt.fine_structural, lay.spring_cells, state.spring_rest_length_m, state.spring_particle_a,
                state.spring_particle_b, state.spring_alive)
        coarse = (rt.coarse_structural, lay.coarse_cells, lay.coarse_rest_length_m, lay.coarse_a, lay.coarse_b,
                  rt.coarse_alive)
        count = cells_to_refine(fine, coarse, state.particle_position_m, m.refine_strain, m.refine_band_cells,
                                lay.cells_x, lay.cells_y, (self._centre, rt.body_reach_m), rt.cell_nodes,
                                state.coarse_cell_refined, rt.hot, rt.new)
        if self.mesh_test.any:  # after the mesh contact of this step (ctx.meshes is at the step's end)
            count += self.mesh_test.mark(ctx.meshes, state, rt.cell_start, rt.cell_slaved, rt.mixed, rt.new)
        if rt.self_contact is not None:  # a slaved crossing touching a yarn: its cells refine (docs/multires.md)
            count += self._refine_self_contact(rt, state)
        if count:
            # a crossing freed now starts from its interpolation, and its velocity at the step's end
            # is (x - x_prev) / dt of the interpolated positions: the velocity its mass had while lumped
            rt.sync_all(state, ctx.prev_position_m)
            rt.refine(state, rt.new)

    def _refine_self_contact(self, rt: CoarseWork, state: State) -> int:
        """Mark in rt.new the coarse cells holding a slaved crossing that self-collision found in contact
        (rt.self_contact); returns how many more cells are marked."""
        touching = rt.self_contact[:self.model.crossing_count]
        if not touching.any():
            return 0
        crossings = np.flatnonzero(touching & ~rt.is_free)
        cells = rt.layout.crossing_cells[crossings].ravel()
        cells = np.unique(cells[cells >= 0])
        cells = cells[~state.coarse_cell_refined[cells] & ~rt.new[cells]]
        rt.new[cells] = True
        return int(cells.shape[0])

    def summary(self, state: State) -> dict:
        refined = state.coarse_cell_refined
        free = multires.free_crossings(multires.coarse_layout(self.model), refined)
        return {"coarse_factor": int(self.model.coarse_factor), "cells": int(refined.shape[0]),
                "refined_cells": int(np.count_nonzero(refined)), "free_crossings": int(np.count_nonzero(free))}
