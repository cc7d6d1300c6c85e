"""The explicit stability bound of the step (METHOD.md §4; issue "numerical stability").

Symplectic (semi-implicit) Euler on a linear spring network is stable while dt <= 2 / ω_max, with
ω_max^2 the largest eigenvalue of M^-1 K. Gershgorin's circle theorem bounds it from the springs:
for a spring of stiffness k between masses i and j the stiffness matrix has k on both diagonal
entries and -k off the diagonal, so

    ω_max^2 <= max_i (2 / m_i) Σ_{springs s at i} k_s.

The bound is exact for an infinite chain (ω_max = 2 sqrt(k/m)). `power_iteration_omega_max`
gives a sharper estimate for finite systems.
"""
from __future__ import annotations

import math

import numpy as np

from fraytool.sim.model import Model


def gershgorin_omega_max(model: Model) -> float:
    """Upper bound of the highest angular frequency ω_max [rad/s] of the base-model cloth."""
    n = model.crossing_count
    alive = model.spring_kind != 5
    row = np.zeros(n)
    k = model.spring_base_stiffness_n_per_m[alive]
    np.add.at(row, model.spring_crossing_a[alive], k)
    np.add.at(row, model.spring_crossing_b[alive], k)
    free = np.ones(n, bool)
    free[model.attachment_particle[model.attachment_particle < n]] = False
    if not free.any():
        return 0.0
    return float(math.sqrt(np.max(2.0 * row[free] / model.crossing_mass_kg[free])))


def stable_step_bound_s(model: Model) -> float:
    """Largest stable explicit step, 2 / ω_max [s] (inf for a cloth without springs)."""
    w = gershgorin_omega_max(model)
    return math.inf if w == 0.0 else 2.0 / w
