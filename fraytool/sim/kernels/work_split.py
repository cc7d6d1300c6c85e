"""Work units for the parallel per-particle kernels: the particle slots cut into WORK_UNITS
contiguous ranges of about equal work, which numba's prange hands out to the threads.

A plain prange over the particle slots gives each thread an equal share of slots, but the slots
are not equal work: the second half holds the yarn-level partners of the crossings
(fraytool.sim.model), inactive until a split, so one thread would get the whole cloth. The units
are cut by weight instead (active particles), and their number does not depend on the thread
count: a kernel that keeps each particle's arithmetic inside one unit gives the same bits on any
number of threads."""
from __future__ import annotations

import numba as nb
import numpy as np

WORK_UNITS = 64
"""Units per kernel: a few per thread for balance, few enough that a unit's set-up is noise."""


@nb.njit(cache=True)
def split_by_weight(weight, bounds_out):
    """Cut range(len(weight)) into len(bounds_out) - 1 contiguous units of about equal total weight:
    unit u is [bounds_out[u], bounds_out[u + 1]). Units may be empty; together they cover every slot."""
    n = weight.shape[0]
    units = bounds_out.shape[0] - 1
    total = 0
    for p in range(n):
        total += weight[p]
    bounds_out[0] = 0
    k = 1
    acc = 0
    for p in range(n):
        acc += weight[p]
        while k < units and acc * units >= k * total and total > 0:
            bounds_out[k] = p + 1
            k += 1
    while k <= units:
        bounds_out[k] = n
        k += 1


def whole_range(count: int) -> np.ndarray:
    """One unit covering slots [0, count): for calling a per-particle kernel outside the solver."""
    return np.array([0, count], np.int64)


class ParticleUnits:
    """The solver's split of the particle slots into units of about equal numbers of active
    particles, recomputed when the active set may have changed (another state's arrays, or a split:
    the only thing that activates a slot, raising the count)."""

    def __init__(self, particle_count: int):
        self.bounds = np.zeros(WORK_UNITS + 1, np.int64)
        self._key: tuple = ()
        self.particle_count = particle_count

    def for_state(self, active: np.ndarray) -> np.ndarray:
        key = (active, int(np.count_nonzero(active)))
        if len(self._key) != 2 or key[0] is not self._key[0] or key[1] != self._key[1]:
            split_by_weight(active.view(np.uint8), self.bounds)
            self._key = key
        return self.bounds
