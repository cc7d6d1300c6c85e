"""Stages of the multi-resolution base model ([cloth.multires] factor > 1; docs/multires.md).

- MultiresForces replaces SpringForces: the springs at work (fine springs bordering a refined cell,
  coarse springs bordering a coarse cell, each with its share), then the forces on slaved crossings
  handed to their nodes.
- SyncSlaved (after the position update: the hanging nodes; before self-collision: all) puts slaved
  crossings back on their interpolation mid-step.
- SlavedContact (after rigid contact): slaved crossings kept out of bodies through their nodes.
- Refinement (before tearing): the hanging nodes put back on their cells' bilinear interpolation
  (the constraints and collisions moved the nodes; every slaved crossing once per frame, for the
  record); then coarse cells near a strain that could tear, or near a moving body, refine; the
  crossings that become free take their mass back from their nodes (total mass and momentum kept
  exactly: the crossing moves with the interpolated velocity its mass had while lumped).

One MultiresRuntime, shared by these stages, keeps the lists derived from State.coarse_cell_refined;
it rebuilds them whenever it sees another State or another refined count (cells only refine, so
within a run the count names the set), which is what a resumed run or a guard's replay needs.
"""
from __future__ import annotations

import weakref
from typing import Optional

import numpy as np

from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from fraytool.sim import multires
from fraytool.sim.kernels.multires import (
    add_listed_spring_forces,
    cells_to_refine,
    collide_slaved,
    gather_slaved_forces,
    sync_near_hot,
    sync_slaved,
    zero_rows,
)
from fraytool.sim.model import Model
from fraytool.sim.stages.base import StepBuffers
from fraytool.sim.state import State


class MultiresRuntime:
    """The layout of a model's cells and the work lists of its current refinement."""

    def __init__(self, model: Model):
        self.model = model
        self.layout = multires.coarse_layout(model)
        lay = self.layout
        self.strain_stage = None
        """The StrainLimiting stage, told which structural springs are at work after each rebuild."""
        self.tearing = None
        """The YarnTearing of a tearing scene, told which structural springs to scan after each rebuild."""
        structural = (model.spring_kind == STRUCT_WEFT) | (model.spring_kind == STRUCT_WARP)
        self._structural = structural
        self._coarse_structural = (lay.coarse_kind == STRUCT_WEFT) | (lay.coarse_kind == STRUCT_WARP)
        self.coarse_alive = np.ones(lay.coarse_kind.shape[0], bool)
        self.cell_nodes = lay.cell_nodes(model.warp_yarns)
        self._hot = np.zeros(lay.cell_count, bool)
        self._new = np.zeros(lay.cell_count, bool)
        self._near = np.zeros(lay.cell_count, bool)
        self.moving_bodies, self.body_reach_m = multires.moving_body_reach(model, lay)
        self._owner: Optional[State] = None
        self._count = -1

    def ensure(self, state: State) -> None:
        """Rebuild the work lists if `state` is not the one they were built for."""
        count = int(np.count_nonzero(state.coarse_cell_refined))
        if state is not self._owner or count != self._count:
            self._rebuild(state)

    def sync_all(self, state: State, prev_position_m: np.ndarray) -> None:
        """Every slaved crossing on its interpolation: positions, and start-of-step positions from the
        nodes' (the interpolation of a node's move over the step is the slaved crossing's move)."""
        lay = self.layout
        sync_slaved(self.slaved, lay.crossing_node, lay.crossing_weight, state.particle_position_m)
        sync_slaved(self.slaved, lay.crossing_node, lay.crossing_weight, prev_position_m)

    def slaved_now(self, state: State) -> np.ndarray:
        """The crossings slaved to coarse nodes in `state` (ascending)."""
        self.ensure(state)
        return self.slaved

    def _rebuild(self, state: State) -> None:
        lay, refined = self.layout, state.coarse_cell_refined
        self._owner, self._count = state, int(np.count_nonzero(refined))
        free = multires.free_crossings(lay, refined)
        self.slaved = np.flatnonzero(~free).astype(np.int32)
        # the slaved crossings grouped by the cell they interpolate (SlavedContact's cell test)
        order = np.argsort(lay.crossing_weight_cell[self.slaved], kind="stable")
        self.cell_slaved = self.slaved[order]
        self.cell_start = np.searchsorted(lay.crossing_weight_cell[self.cell_slaved],
                                          np.arange(lay.cell_count + 1)).astype(np.int64)
        fine_share = multires.share(lay.spring_cells, refined, at_fine=True)
        self.fine_listed = np.flatnonzero(fine_share > 0.0).astype(np.int32)
        self.fine_share = fine_share[self.fine_listed]
        coarse_share = multires.share(lay.coarse_cells, refined, at_fine=False, weight=lay.coarse_cell_weight)
        self.coarse_listed = np.flatnonzero(coarse_share > 0.0).astype(np.int32)
        self.coarse_share = coarse_share[self.coarse_listed]
        working = np.zeros(self.model.spring_count, bool)
        working[self.fine_listed] = True
        working &= self._structural
        self.fine_structural = np.flatnonzero(working).astype(np.int32)
        self.coarse_structural = self.coarse_listed[self._coarse_structural[self.coarse_listed]]
        # slaved crossings that a fine spring at work pulls on (hanging nodes): the only ones with a force
        m = self.model
        ends = np.concatenate([m.spring_crossing_a[self.fine_listed], m.spring_crossing_b[self.fine_listed]])
        loaded = np.zeros(m.crossing_count, bool)
        loaded[ends] = True
        self.loaded_slaved = np.flatnonzero(loaded & ~free).astype(np.int32)
        if self.strain_stage is not None:
            self.strain_stage.restrict(working)
        if self.tearing is not None:
            self.tearing.restrict_scans(working)

    def refine(self, state: State, new: np.ndarray) -> None:
        """Refine the cells `new`: free crossings take their own mass back (set_masses), at the
        interpolated position and velocity they already have."""
        state.coarse_cell_refined |= new
        multires.set_masses(self.model, self.layout, state.coarse_cell_refined, state)
        self._rebuild(state)


class MultiresForces:
    """Step 1 with the multi-resolution model: the springs at work, then slaved forces to the nodes."""

    name = "forces"
    kernel = "add_listed_spring_forces, gather_slaved_forces"

    def __init__(self, model: Model, runtime: MultiresRuntime):
        self.model = model
        self.runtime = runtime
        self._cleared_for = lambda: None  # a weak reference to the state last cleared for

    def run(self, state: State, buffers: StepBuffers, dt_s: float) -> None:
        rt, m, lay = self.runtime, self.model, self.runtime.layout
        rt.ensure(state)
        # Every row a spring writes to: the moving particles (spring ends are active; the slaved ones
        # among them are the hanging nodes, which gather_slaved_forces zeroes after use). The other rows
        # stay 0 (crossings only go from slaved to free) once cleared for this state: a state the solver
        # has not stepped before (a resume, the guard's replay from a copy) may have more slaved
        # crossings than the rows last written. (Clearing every slot each step cost the 256 x 256
        # tablecloth 0.1 ms of its 1.8.)
        if self._cleared_for() is not state:
            buffers.force_n[:] = 0.0
            self._cleared_for = weakref.ref(state)
        zero_rows(buffers.lists.moving(state)[0], buffers.force_n)
        zero_rows(rt.loaded_slaved, buffers.force_n)
        add_listed_spring_forces(rt.fine_listed, rt.fine_share, m.spring_kind, state.spring_rest_length_m,
                                 state.particle_position_m, state.spring_particle_a, state.spring_particle_b,
                                 state.spring_alive, state.spring_stiffness_n_per_m, buffers.force_n)
        add_listed_spring_forces(rt.coarse_listed, rt.coarse_share, lay.coarse_kind, lay.coarse_rest_length_m,
                                 state.particle_position_m, lay.coarse_a, lay.coarse_b, rt.coarse_alive,
                                 lay.coarse_stiffness_n_per_m, buffers.force_n)
        gather_slaved_forces(rt.loaded_slaved, lay.crossing_node, lay.crossing_weight, buffers.force_n)

    def summary(self, state: State) -> dict:
        return {}


class SyncSlaved:
    """Slaved crossings back on their cells' interpolation, positions and start-of-step positions,
    mid-step: after the position update only the hanging nodes (the slaved crossings a working fine
    spring pulls on: strain limiting reads them as anchors, and its dashpot their moves over the step),
    before self-collision all of them (it reads them as obstacles, swept over the step). The step does not move them (integration leaves them
    out), so by then they are off their interpolation by the node moves since the last sync."""

    kernel = "sync_slaved"

    def __init__(self, runtime: MultiresRuntime, name: str, hanging_only: bool):
        self.runtime = runtime
        self.name = name
        self.hanging_only = hanging_only

    def run(self, state: State, buffers: StepBuffers, dt_s: float) -> None:
        rt = self.runtime
        rt.ensure(state)
        if self.hanging_only:
            lay = rt.layout
            sync_slaved(rt.loaded_slaved, lay.crossing_node, lay.crossing_weight, state.particle_position_m)
            sync_slaved(rt.loaded_slaved, lay.crossing_node, lay.crossing_weight, buffers.prev_position_m)
        else:
            rt.sync_all(state, buffers.prev_position_m)

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

    def __init__(self, model: Model, runtime: MultiresRuntime):
        self.model = model
        self.runtime = runtime
        self._point = np.zeros(3)
        # Moving bodies refine the cells within their reach (Refinement, refine_near_bodies) before they
        # get there, so no slaved crossing is within a cell's width of them: only the other bodies here.
        self.collide = model.body_collide.copy()
        self.collide[runtime.moving_bodies] = False
        self.any = bool(self.collide.any())
        self._nodes = np.unique(runtime.cell_nodes).astype(np.int32)
        self._outside = np.zeros(model.crossing_count, np.uint8)

    def run(self, state: State, buffers: StepBuffers, dt_s: float) -> None:
        if not self.any:
            return
        rt, m, lay = self.runtime, self.model, self.runtime.layout
        rt.ensure(state)
        collide_slaved(rt.cell_start, rt.cell_slaved, rt.cell_nodes, self._nodes, lay.crossing_node,
                       lay.crossing_weight, m.body_shape, m.body_rotation, m.body_radius_m, m.body_half_extents_m,
                       m.body_normal, m.body_friction, self.collide, 0.5 * m.thickness_m, dt_s,
                       state.body_position_m, state.body_velocity_m_s, state.particle_inv_mass,
                       buffers.prev_position_m, state.particle_position_m, self._point, self._outside)

    def summary(self, state: State) -> dict:
        return {}


class Refinement:
    """Before tearing: the hanging nodes back on their interpolation (the constraints and collisions
    moved the nodes), then coarse cells refined ahead of any strain that could tear them. The other
    slaved crossings are read in a step only by self-collision (SyncSlaved, which syncs them first)
    and by a split (its couple's normal reads the neighbouring crossings, its settle the yarn segments
    it could carry through), which needs a spring past the refine strain: so the ones within the band
    + 1 cells of a hot cell are synced here, all of them when a refinement frees some, and every one
    once per frame (`end_frame`)."""

    name = "refinement"
    kernel = "cells_to_refine"

    def __init__(self, model: Model, runtime: MultiresRuntime):
        self.model = model
        self.runtime = runtime
        self._centre = np.zeros((runtime.moving_bodies.shape[0], 3))

    def run(self, state: State, buffers: StepBuffers, dt_s: float) -> None:
        rt, m, lay = self.runtime, self.model, self.runtime.layout
        rt.ensure(state)
        # the hanging nodes: the fine springs whose strains decide what refines (and then what tears)
        sync_slaved(rt.loaded_slaved, lay.crossing_node, lay.crossing_weight, state.particle_position_m)
        if state.coarse_cell_refined.all():
            return  # everything refined
        self._centre[:] = state.body_position_m[rt.moving_bodies]
        count = cells_to_refine(rt.fine_structural, lay.spring_cells, state.spring_rest_length_m,
                                state.spring_particle_a, state.spring_particle_b, state.spring_alive,
                                rt.coarse_structural, lay.coarse_cells, lay.coarse_a, lay.coarse_b,
                                lay.coarse_rest_length_m, rt.coarse_alive, state.particle_position_m,
                                m.refine_strain, m.refine_band_cells, lay.cells_x, lay.cells_y, self._centre,
                                rt.body_reach_m, rt.cell_nodes, state.coarse_cell_refined, rt._hot, rt._new)
        if count:
            # a crossing freed now starts from its interpolation, and its velocity at the step's end
            # is (x - x_prev) / dt of the interpolated positions: the velocity its mass had while lumped
            rt.sync_all(state, buffers.prev_position_m)
            rt.refine(state, rt._new)
        elif rt._hot.any():
            # a hot cell (a spring past the refine strain, below every tearing strain): tearing may split
            # this step, and a split reads its neighbours (the couple's normal) and its settle the yarn
            # segments it may carry through: the slaved crossings near the hot cells are synced
            sync_near_hot(rt._hot, m.refine_band_cells + 1, lay.cells_x, lay.cells_y, rt.cell_start,
                          rt.cell_slaved, lay.crossing_node, lay.crossing_weight, rt._near,
                          state.particle_position_m, buffers.prev_position_m)

    def end_frame(self, state: State, buffers: StepBuffers, dt_s: float) -> None:
        """Every slaved crossing on its interpolation for the frame's record (the steps sync only the
        hanging nodes); their velocities follow in VelocityPostProcess.end_frame."""
        if state.coarse_cell_refined.all():
            return
        self.runtime.ensure(state)
        self.runtime.sync_all(state, buffers.prev_position_m)

    def summary(self, state: State) -> dict:
        refined = state.coarse_cell_refined
        free = multires.free_crossings(self.runtime.layout, refined)
        return {"coarse_factor": int(self.model.coarse_factor), "cells": int(refined.shape[0]),
                "refined_cells": int(np.count_nonzero(refined)), "free_crossings": int(np.count_nonzero(free))}
