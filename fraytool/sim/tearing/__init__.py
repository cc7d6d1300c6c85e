"""Tearing with frayed edges: the yarn-level model (docs/method.md §3.3, §3.4, §4.1).

`YarnTearing` holds the passes; the solver runs them as two stages (fraytool.sim.stages.tearing),
built only for scenes with [cloth.tearing] enabled, so nothing here runs or compiles otherwise:
- step 5, `YarnTearing.contact`: contact projection at connected mass couples (`contact.py`);
- step 7, `YarnTearing.__call__`: transitions of over-strained springs to the yarn level with
  propagation (`split.py`), then cuts of springs over their break strain (`cut.py`).
With yarn_level = false (a base-model-only tear, kept for comparison) only the cuts run: no couples,
no contact, clean edges. `YarnTearing.summary(state)` adds the tear and fray figures to the
`fraytool simulate --json` summary (`fray.py`). Slow NumPy references of the kernels live in
tests/tearing_reference.py; the design choices are in docs/tearing.md.

Module map: topology.py (static lookup tables), groups.py (the kernels' argument groups: TearModel and
the State groups, as named tuples of array references), split.py, contact.py, cut.py, fray.py.
"""
from __future__ import annotations

from typing import Iterable, Optional

import numpy as np

from fraytool.sim.kernels.bodies import bodies_in
from fraytool.sim.kernels.rigid_contact import place_outside_bodies
from fraytool.sim.model import Model, broken_cloth_springs
from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from fraytool.sim.state import State
from fraytool.sim.tearing.contact import disconnect_couple, project_couples, settle_crosses_yarns
from fraytool.sim.tearing.cut import cut_overstrained, cut_structural, first_over_length
from fraytool.sim.tearing.yarn_runs import free_yarn_runs, yarn_fragments
from fraytool.sim.tearing.fray import fray_lengths, fray_summary
from fraytool.sim.tearing.groups import (TearCrossings, TearModel, TearParticles, TearSprings, state_groups,
                                         tear_model)
from fraytool.sim.tearing.split import split_crossing, transition_overstrained, transition_spring
from fraytool.sim.tearing.topology import TearTopology, build_tear_topology, topology_problems

__all__ = ["YarnTearing", "TearTopology", "build_tear_topology", "fray_lengths", "topology_problems",
           "TearModel", "TearParticles", "TearCrossings", "TearSprings", "tear_model", "state_groups"]


SETTLE_PASSES = 4
"""Rounds of contact projection and placement outside bodies given to couples as they split (YarnTearing.settle)."""


class YarnTearing:
    """The tearing passes of one model: `contact` (stage 5) and `__call__` (stage 7).

    What is kept between steps is derived from the State's topology and keyed on State.topology_epoch,
    which every pass here bumps when it changes the topology (a split, a cut, a disconnection): the
    compact list of connected couples (ascending crossing index, from State.couple_connected) and
    the scans of free yarn runs. So a resumed run or a replay from a copy matches an unbroken one.
    """

    def __init__(self, model: Model, meshes=None):
        """`meshes`: the solver's mesh bodies (fraytool.sim.mesh_geometry.MeshGeometry), where the scene has
        colliding ones: a split's masses are placed outside them too (settle)."""
        self.model = model
        self.meshes = meshes
        self.topology = build_tear_topology(model)
        self.model_in = tear_model(model, self.topology)
        """The kernels' read-only group: the model's arrays and the topology tables (references)."""
        self.model_scan = self.model_in
        """model_in for the per-step scans for transitions and cuts: the same, or with the structural
        springs restricted by `restrict_scans`."""
        self.yarn_level = bool(model.yarn_level)
        self._couples = np.zeros(model.crossing_count, np.int32)
        self._weft_free = np.zeros(model.crossing_count, np.bool_)
        """Scratch of the cut rule: crossings whose weft (warp) lies on a free run (contact.free_yarn_runs)."""
        self._runs_at: Optional[int] = None
        """State.topology_epoch of the free-run and fragment scans."""
        # crossings to the yarn end on each side of a spring (yarn_runs.yarn_fragments): at most
        # ANCHORED (1 << 30) + a yarn's length, so int32
        self._fragment_left = np.full(model.spring_count, 1 << 30, np.int32)
        self._fragment_right = np.full(model.spring_count, 1 << 30, np.int32)
        self._warp_free = np.zeros(model.crossing_count, np.bool_)
        self._couple_count = 0
        self._couples_at: Optional[int] = None
        """State.topology_epoch the couple list belongs to."""
        self._scans_at = -1
        """Epoch of the working-spring mask the scans are restricted to (`restrict_scans`)."""
        self.splits_last = 0
        """Crossings split in the last step."""
        self.cuts_last = 0
        """Springs (of any kind) cut in the last step."""
        self._yarn_segments = np.flatnonzero((model.spring_kind == STRUCT_WEFT) | (model.spring_kind == STRUCT_WARP))
        self._yarn_level_before = np.zeros(model.crossing_count, np.bool_)
        """Scratch: crossing_yarn_level before this step's transitions (which crossings just split)."""
        self._transition_strain_of = np.full(model.spring_count, model.transition_strain)
        """The transition strain for every spring slot, for the pre-scan (`first_over_length`)."""
        self.settle_reverts = 0
        """Settles undone because they would have carried a yarn segment through another."""
        cut_time = model.spring_cut_time_s
        self._scissored = np.flatnonzero(np.isfinite(cut_time)) if cut_time.size else np.zeros(0, np.int64)
        """Structural springs that scissors cut during the shot ([[cuts]] path_m), with their times."""
        self._scissor_time_s = cut_time[self._scissored] if cut_time.size else np.zeros(0)

    def restrict_scans(self, working: Optional[np.ndarray], made_at: int = -1) -> None:
        """Scan only the structural springs where `working` (a mask over spring slots, made at topology
        epoch `made_at`) is True for transitions and cuts (None: all). The multi-resolution model
        (docs/multires.md, StepContext.working_springs) gives the springs of refined cells: the others
        are slaved, below the refine strain by construction. A mask already applied is not re-applied."""
        if made_at == self._scans_at and made_at != -1:
            return
        self._scans_at = made_at
        m = self.model_in
        if working is None:
            self.model_scan = m
            return
        keep = working[m.structural_springs]
        self.model_scan = m._replace(structural_springs=m.structural_springs[keep],
                                     structural_yarn=m.structural_yarn[keep])

    # -- couple list -------------------------------------------------------------------------
    def _rebuild(self, state: State) -> None:
        idx = np.flatnonzero(state.couple_connected)
        self._couples[: idx.size] = idx
        self._couple_count = int(idx.size)
        self._couples_at = state.topology_epoch

    def _sync(self, state: State) -> None:
        if state.topology_epoch != self._couples_at:
            self._rebuild(state)

    def _changed(self, state: State) -> None:
        """The topology of `state` changed here: a new epoch, and the couple list rebuilt for it."""
        state.bump_topology()
        self._rebuild(state)

    @property
    def connected_couples(self) -> np.ndarray:
        """Crossings of the couples the contact pass visits (a copy)."""
        return self._couples[: self._couple_count].copy()

    # -- stage 5 -----------------------------------------------------------------------------
    def contact(self, state: State, prev_position_m: np.ndarray, dt_s: float) -> None:
        """Contact projection at every connected couple; disconnects couples that have parted."""
        self._sync(state)
        if self._couple_count == 0:
            return
        particles, crossings, springs = state_groups(state)
        count = project_couples(self.model_in, particles, crossings, springs, self._couples, self._couple_count,
                                prev_position_m)
        if count != self._couple_count:  # couples disconnected: the list is compacted in place (order kept)
            self._couple_count = count
            state.bump_topology()
            self._couples_at = state.topology_epoch

    # -- stage 7 -----------------------------------------------------------------------------
    def __call__(self, state: State, prev_position_m: np.ndarray, dt_s: float) -> None:
        """Scissors due by now, transitions (yarn-level model only), then cuts."""
        self._sync(state)
        if self._scissored.size:
            self._scissor(state, dt_s)
        particles, crossings, springs = state_groups(state)
        splits = cuts = 0
        # Each scan first finds its first spring over the limit with plain arrays (first_over_length); the full
        # kernel, and the free-run and fragment scans the cut rule reads, run only when there is one.
        scanned = self.model_scan.structural_springs
        lengths = (state.spring_rest_length_m, state.spring_particle_a, state.spring_particle_b, state.spring_alive,
                   state.particle_position_m)
        if self.yarn_level:
            first = first_over_length(scanned, self._transition_strain_of, *lengths)
            if first >= 0:
                np.copyto(self._yarn_level_before, state.crossing_yarn_level)  # no allocation per step
                splits = transition_overstrained(self.model_scan, particles, crossings, springs, prev_position_m,
                                                 first)
            if splits:
                self.settle(state, np.flatnonzero(state.crossing_yarn_level & ~self._yarn_level_before),
                            prev_position_m)
                self._changed(state)
        first = first_over_length(scanned, self.model_in.spring_break_strain, *lengths)
        if first >= 0:
            # the scans read spring_alive and crossing_yarn_level: topology
            if state.topology_epoch != self._runs_at:
                free_yarn_runs(self.model_in, crossings, springs, self._weft_free, self._warp_free)
                yarn_fragments(self.model_in, springs, self._fragment_left, self._fragment_right)
                self._runs_at = state.topology_epoch
            _, cuts = cut_overstrained(self.model_scan, particles, springs, self._weft_free, self._warp_free,
                                       self._fragment_left, self._fragment_right, first)
        if cuts:
            state.bump_topology()
        self.splits_last = int(splits)
        self.cuts_last = int(cuts)

    def _scissor(self, state: State, dt_s: float) -> None:
        """Cut the springs the scissors have reached by the end of this step (their bend and shear
        springs with them, as any cut); a scissor cut is not a break. Read from the state alone, so a
        resumed run cuts the same springs at the same steps."""
        due = self._scissored[(self._scissor_time_s <= state.time_s + dt_s) & state.spring_alive[self._scissored]]
        if not due.size:
            return
        _, _, springs = state_groups(state)
        for s in due:
            cut_structural(int(s), self.model_in, springs)
            state.spring_broken[s] = False
        self._changed(state)

    # -- single operations (tests, tools) -------------------------------------------------------
    def split(self, state: State, crossings: Iterable[int], prev_position_m: Optional[np.ndarray] = None) -> int:
        """Split the given base crossings (no propagation); returns how many split. Without
        prev_position_m the split keeps State.particle_velocity_m_s (prev = x - v, dt = 1)."""
        prev = state.particle_position_m - state.particle_velocity_m_s if prev_position_m is None else prev_position_m
        particles, crossing_flags, springs = state_groups(state)
        count = 0
        for c in crossings:
            count += bool(split_crossing(int(c), self.model_in, particles, crossing_flags, springs, prev))
        self._changed(state)
        return count

    def settle(self, state: State, crossings: np.ndarray, prev_position_m: np.ndarray) -> None:
        """Place the couples just split at `crossings` where the contact and the rigid bodies want
        them, without changing any velocity (docs/tearing.md, "Transition"): SETTLE_PASSES rounds of
        the contact projection of these couples and of moving their masses out of colliding bodies,
        then every moved particle's previous position is moved by the same amount.

        The split puts the masses at x +- T/2 n_c, where the couple's 4 pairs are only about T apart
        (crimp) and a mass next to a ball may lie inside it. Corrected by the next step's contact or
        collision pass instead, that offset (up to T/2) would become a velocity offset / dt: energy
        from nothing, growing as the step shrinks (it doubled the torn region at a sixteenth of the
        figure scenes' step).

        This runs after the step's self-collision pass, so a settle that would carry a yarn segment
        through another (exact edge-edge CCD over the moved segments, `settle_crosses_yarns`) is
        undone as a whole and left to the next step's contact (counted in settle_reverts)."""
        if len(crossings) == 0:
            return
        crossings = np.asarray(crossings, np.int32)
        m = self.model
        particles, crossing_flags, springs = state_groups(state)
        slots = np.concatenate([crossings, crossings + m.crossing_count]).astype(np.int64)
        x = state.particle_position_m
        start = x.copy()
        bodies = bool(m.body_collide.any())
        for _ in range(SETTLE_PASSES):
            project_couples(self.model_in, particles, crossing_flags, springs, crossings.copy(), crossings.size,
                            prev_position_m)
            if bodies:
                place_outside_bodies(bodies_in(m, state), 0.5 * m.thickness_m, slots, state.particle_inv_mass, x)
            if self.meshes is not None:
                from fraytool.sim.kernels.mesh_contact import place_outside_meshes

                place_outside_meshes(self.meshes.meshes_in(m), bodies_in(m, state), 0.5 * m.thickness_m, slots,
                                     state.particle_inv_mass, x)
        if settle_crosses_yarns(start, x, state.spring_particle_a, state.spring_particle_b,
                                self._yarn_segments[state.spring_alive[self._yarn_segments]]):
            x[:] = start  # rare: left to the next step's contact rather than through another yarn
            self.settle_reverts += 1
            return
        prev_position_m += x - start

    def transition(self, state: State, spring: int, prev_position_m: Optional[np.ndarray] = None) -> int:
        """Transition one structural spring (both ends + propagation); returns crossings split."""
        prev = state.particle_position_m - state.particle_velocity_m_s if prev_position_m is None else prev_position_m
        particles, crossings, springs = state_groups(state)
        count = transition_spring(int(spring), self.model_in, particles, crossings, springs, prev)
        self._changed(state)
        return int(count)

    def disconnect(self, state: State, crossing: int) -> None:
        """Disconnect the couple at `crossing` (and cut its shear copies), as the contact pass does."""
        if not state.couple_connected[crossing]:
            return
        _, crossings, springs = state_groups(state)
        disconnect_couple(int(crossing), self.model_in, crossings, springs)
        self._changed(state)

    def cut(self, state: State, spring: int) -> int:
        """Cut one structural spring with its bend and shear springs; returns springs cut."""
        if int(self.model.spring_kind[spring]) not in (STRUCT_WEFT, STRUCT_WARP):
            raise ValueError(f"spring {spring} is not a structural spring")
        _, _, springs = state_groups(state)
        count = int(cut_structural(int(spring), self.model_in, springs))
        state.bump_topology()
        return count

    # -- summary -----------------------------------------------------------------------------
    def summary(self, state: State) -> dict:
        """Tear and fray figures of `state` (merged into Simulation.summary / `simulate --json`)."""
        m = self.model
        yarn_level = int(state.crossing_yarn_level.sum())
        connected = int(state.couple_connected.sum())
        out = {
            "broken_springs": broken_cloth_springs(m.spring_kind, state.spring_broken),
            "yarn_level_masses": 2 * yarn_level,
            "yarn_level_crossings": yarn_level,
            "connected_couples": connected,
            "disconnected_couples": yarn_level - connected,
        }
        out.update(fray_summary(m, self.topology, state))
        return out
