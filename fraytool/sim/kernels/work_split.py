"""Particle lists and work units for the parallel per-particle kernels.

The per-particle kernels (velocity and position updates, the velocity post-process, damping, rigid
contact) take a sorted list of the particle slots they update and `unit_bounds`: that list cut into
WORK_UNITS runs of equal length (unit u is particles[unit_bounds[u]:unit_bounds[u + 1]]), which
numba's prange hands out to the threads. A list, because most slots are often not work: the second
half of the slots holds the yarn-level partners of the crossings (fraytool.sim.model), inactive
until a split, and in a multi-resolution model most crossings are slaved to coarse nodes
(fraytool.sim.multires), neither integrated nor damped; a plain prange over the slots gave one
thread the whole cloth. Units, because their number does not depend on the thread count: a kernel
that keeps each particle's arithmetic inside its unit gives the same bits on any number of threads,
and a serial sum over a list in order makes the same additions as a scan of every slot that skips
the others."""
from __future__ import annotations

from typing import Callable, Optional

import numpy as np

WORK_UNITS = 64
"""Units per list: a few per thread for balance, few enough that a unit's set-up is noise."""


def even_units(count: int, units: int = WORK_UNITS) -> np.ndarray:
    """Bounds cutting a list of `count` entries into `units` runs of equal length (+-1)."""
    return (np.arange(units + 1, dtype=np.int64) * count) // units


def all_slots(count: int) -> tuple[np.ndarray, np.ndarray]:
    """(every slot 0 .. count - 1, its units): for calling a per-particle kernel outside the solver."""
    return np.arange(count, dtype=np.int32), even_units(count)


class ParticleLists:
    """The solver's lists of particle slots, rebuilt when State.topology_epoch changed.

    - free: slots with inverse mass > 0 (integrated, damped, in contact with bodies);
    - moving: active slots minus the crossings slaved to coarse nodes (positions integrated, velocities
      from positions; a slaved crossing's position is its interpolation, its velocity is set by the
      solver's completion call, SolverExplicitPBD.complete).
    A tool that edits inverse masses or active flags in place calls State.bump_topology after it."""

    def __init__(self) -> None:
        self.slaved_of: Optional[Callable[[object], np.ndarray]] = None
        """slaved_of(state): the crossings slaved to coarse nodes now (multi-resolution model, set by the
        solver from its step context); None: none."""
        self._free_at: Optional[int] = None
        self._moving_at: Optional[int] = None
        self._free = (np.zeros(0, np.int32), even_units(0))
        self._moving = (np.zeros(0, np.int32), even_units(0))

    def free(self, state) -> tuple[np.ndarray, np.ndarray]:
        """(free slots ascending, their units)."""
        if state.topology_epoch != self._free_at:
            listed = np.flatnonzero(state.particle_inv_mass > 0.0).astype(np.int32)
            self._free, self._free_at = (listed, even_units(listed.shape[0])), state.topology_epoch
        return self._free

    def slaved(self, state) -> np.ndarray:
        """The crossings slaved to coarse nodes in `state`, ascending (empty without a coarse model)."""
        return self.slaved_of(state) if self.slaved_of is not None else np.zeros(0, np.int32)

    def moving(self, state) -> tuple[np.ndarray, np.ndarray]:
        """(active slots that are not slaved crossings, ascending, their units)."""
        if state.topology_epoch != self._moving_at:
            mask = state.particle_active.copy()
            mask[self.slaved(state)] = False
            listed = np.flatnonzero(mask).astype(np.int32)
            self._moving, self._moving_at = (listed, even_units(listed.shape[0])), state.topology_epoch
        return self._moving
