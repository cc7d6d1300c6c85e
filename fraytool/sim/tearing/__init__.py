"""Tearing with frayed edges: the yarn-level model (METHOD.md §3.3, §3.4, §4.1).

`attach_tearing(solver)` plugs it into `SolverExplicitPBD` (called by `make_solver` only for scenes
with [cloth.tearing] enabled, so nothing here runs or compiles otherwise):
- stage 5, `solver.yarn_contact`: contact projection at connected mass couples (`contact.py`);
- stage 7, `solver.tearing`: transitions of over-strained springs to the yarn level with
  propagation (`split.py`), then cuts of springs over their break strain (`cut.py`).
With yarn_level = false (a base-model-only tear, kept for comparison) only the cuts run: no couples,
no contact, clean edges. `solver.tearing.summary(state)` adds the tear and fray figures to the
`fraytool simulate --json` summary (`fray.py`). Slow NumPy references of the kernels live in
`reference.py`; the design choices are in docs/tearing.md.

Module map: topology.py (static lookup tables), split.py, contact.py, cut.py, fray.py, reference.py.
"""
from __future__ import annotations

from typing import Iterable, Optional

import numpy as np

from fraytool.sim.model import STRUCT_WARP, STRUCT_WEFT, Model
from fraytool.sim.state import State
from fraytool.sim.tearing.contact import disconnect_couple, project_couples
from fraytool.sim.tearing.cut import cut_overstrained, cut_structural
from fraytool.sim.tearing.fray import fray_lengths, fray_summary
from fraytool.sim.tearing.split import split_crossing, transition_overstrained, transition_spring
from fraytool.sim.tearing.topology import TearTopology, build_tear_topology, topology_problems

__all__ = ["YarnTearing", "attach_tearing", "TearTopology", "build_tear_topology", "fray_lengths",
           "topology_problems"]


class YarnTearing:
    """The tearing passes of one model: `contact` (stage 5) and `__call__` (stage 7).

    The only thing kept between steps is the compact list of connected couples (ascending crossing
    index), derived from State.couple_connected: it is rebuilt whenever a different State or a
    non-consecutive step is seen, and after any split, so a resumed run matches an unbroken one.
    """

    def __init__(self, model: Model):
        self.model = model
        self.topology = build_tear_topology(model)
        self.yarn_level = bool(model.yarn_level)
        self._couples = np.zeros(model.crossing_count, np.int32)
        self._couple_count = 0
        self._owner: Optional[State] = None
        self._step = -2
        self.splits_last = 0
        """Crossings split in the last step."""
        self.cuts_last = 0
        """Springs (of any kind) cut in the last step."""

    # -- couple list -------------------------------------------------------------------------
    def _rebuild(self, state: State) -> None:
        idx = np.flatnonzero(state.couple_connected)
        self._couples[: idx.size] = idx
        self._couple_count = int(idx.size)

    def _sync(self, state: State) -> None:
        if state is not self._owner or state.step_index not in (self._step, self._step + 1):
            self._rebuild(state)
            self._owner = state
        self._step = state.step_index

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
        m, t = self.model, self.topology
        self._couple_count = project_couples(
            m.thickness_m, m.disconnect_distance_m, m.crossing_weft_on_top, m.crossing_weft_springs,
            m.crossing_warp_springs, m.spring_kind, m.spring_crossing_a, m.spring_crossing_b, m.spring_twin,
            t.crossing_spring_start, t.crossing_spring_list, state.particle_inv_mass,
            state.spring_particle_a, state.spring_particle_b, state.crossing_yarn_level,
            state.particle_position_m, state.couple_connected, state.spring_alive, self._couples,
            self._couple_count)

    # -- stage 7 -----------------------------------------------------------------------------
    def __call__(self, state: State, prev_position_m: np.ndarray, dt_s: float) -> None:
        """Transitions (yarn-level model only), then cuts."""
        self._sync(state)
        m, t = self.model, self.topology
        splits = 0
        if self.yarn_level:
            splits = transition_overstrained(
                t.structural_springs, m.spring_rest_length_m, m.transition_strain, *self._split_model_args(),
                *self._split_state_args(state, prev_position_m))
            if splits:
                self._rebuild(state)
        _, cuts = cut_overstrained(
            t.structural_springs, t.structural_yarn, m.warp_yarns + m.weft_yarns, m.spring_rest_length_m, m.spring_break_strain, m.spring_twin,
            t.structural_bend_start, t.structural_bend_list, t.structural_shear_start, t.structural_shear_list,
            state.particle_position_m, state.spring_particle_a, state.spring_particle_b, state.spring_alive,
            state.spring_broken)
        self.splits_last = int(splits)
        self.cuts_last = int(cuts)

    # -- single operations (tests, tools) -------------------------------------------------------
    def _crossing_model_args(self) -> tuple:
        """Model arguments of split_crossing, in order."""
        m, t = self.model, self.topology
        return (m.warp_yarns, m.weft_yarns, m.thickness_m, m.crossing_weft_on_top, t.crossing_attached,
                m.spring_kind, m.spring_crossing_a, m.spring_crossing_b, m.spring_twin, t.crossing_spring_start,
                t.crossing_spring_list)

    def _split_model_args(self) -> tuple:
        """Model arguments of transition_spring / transition_overstrained (after their own)."""
        m = self.model
        return self._crossing_model_args() + (m.weft_structural_spring, m.warp_structural_spring)

    @staticmethod
    def _split_state_args(state: State, prev_position_m: np.ndarray) -> tuple:
        return (state.particle_position_m, prev_position_m, state.particle_velocity_m_s, state.particle_mass_kg,
                state.particle_inv_mass, state.particle_active, state.crossing_yarn_level, state.couple_connected,
                state.spring_particle_a, state.spring_particle_b, state.spring_alive, state.spring_broken,
                state.spring_stiffness_n_per_m)

    def split(self, state: State, crossings: Iterable[int], prev_position_m: Optional[np.ndarray] = None) -> int:
        """Split the given base crossings (no propagation); returns how many split. Without
        prev_position_m the split keeps State.particle_velocity_m_s (prev = x - v, dt = 1)."""
        prev = state.particle_position_m - state.particle_velocity_m_s if prev_position_m is None else prev_position_m
        model_args = self._crossing_model_args()
        count = 0
        for c in crossings:
            count += bool(split_crossing(int(c), *model_args, *self._split_state_args(state, prev)))
        self._rebuild(state)
        return count

    def transition(self, state: State, spring: int, prev_position_m: Optional[np.ndarray] = None) -> int:
        """Transition one structural spring (both ends + propagation); returns crossings split."""
        prev = state.particle_position_m - state.particle_velocity_m_s if prev_position_m is None else prev_position_m
        count = transition_spring(int(spring), *self._split_model_args(), *self._split_state_args(state, prev))
        self._rebuild(state)
        return int(count)

    def disconnect(self, state: State, crossing: int) -> None:
        """Disconnect the couple at `crossing` (and cut its shear copies), as the contact pass does."""
        m, t = self.model, self.topology
        if not state.couple_connected[crossing]:
            return
        disconnect_couple(int(crossing), m.spring_kind, m.spring_twin, t.crossing_spring_start,
                          t.crossing_spring_list, state.couple_connected, state.spring_alive)
        self._rebuild(state)

    def cut(self, state: State, spring: int) -> int:
        """Cut one structural spring with its bend and shear springs; returns springs cut."""
        m, t = self.model, self.topology
        if int(m.spring_kind[spring]) not in (STRUCT_WEFT, STRUCT_WARP):
            raise ValueError(f"spring {spring} is not a structural spring")
        return int(cut_structural(int(spring), m.spring_twin, t.structural_bend_start, t.structural_bend_list,
                                  t.structural_shear_start, t.structural_shear_list, state.spring_alive,
                                  state.spring_broken))

    # -- summary -----------------------------------------------------------------------------
    def summary(self, state: State) -> dict:
        """Tear and fray figures of `state` (merged into Simulation.summary / `simulate --json`)."""
        m = self.model
        yarn_level = int(state.crossing_yarn_level.sum())
        connected = int(state.couple_connected.sum())
        out = {
            "broken_springs": int(state.spring_broken.sum()),
            "yarn_level_masses": 2 * yarn_level,
            "yarn_level_crossings": yarn_level,
            "connected_couples": connected,
            "disconnected_couples": yarn_level - connected,
        }
        out.update(fray_summary(m, self.topology, state))
        return out


def attach_tearing(solver) -> YarnTearing:
    """Plug the tearing passes into `solver` (stage 5 contact only with the yarn-level model)."""
    tearing = YarnTearing(solver.model)
    solver.tearing = tearing
    if tearing.yarn_level:
        solver.yarn_contact = tearing.contact
    return tearing
