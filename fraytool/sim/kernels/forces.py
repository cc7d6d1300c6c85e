"""Spring forces of the base and yarn-level models (docs/method.md §3.2).

Hooke springs f = k (|x_b - x_a| - L) u along the unit vector u from a to b. Shear springs
(kinds SHEAR and SHEAR_TWIN) act only in compression: no force when longer than rest. A seam's
stitch (STITCH, a thread) acts only in tension: no force when shorter than rest.
"""
from __future__ import annotations

import math

import numba as nb

from fraytool.kinds import SHEAR, SHEAR_TWIN, STITCH


@nb.njit(cache=True, fastmath=False, inline="always")
def add_spring_force(s, stiffness_n_per_m, spring_kind, spring_rest_length_m, particle_position_m, spring_particle_a,
                     spring_particle_b, particle_force_n_inout):
    """Add spring s's Hooke force, with stiffness `stiffness_n_per_m`, to its two end particles."""
    a = spring_particle_a[s]
    b = spring_particle_b[s]
    dx = particle_position_m[b, 0] - particle_position_m[a, 0]
    dy = particle_position_m[b, 1] - particle_position_m[a, 1]
    dz = particle_position_m[b, 2] - particle_position_m[a, 2]
    d2 = dx * dx + dy * dy + dz * dz
    kind = spring_kind[s]
    shear = kind == SHEAR or kind == SHEAR_TWIN
    rest = spring_rest_length_m[s]
    if shear and d2 > rest * rest * (1.0 + 1e-9):
        return  # a stretched shear spring, without the square root (the test below says the same)
    length = math.sqrt(d2)
    if length < 1e-12:
        return  # no direction to push along
    stretch = length - rest
    if stretch > 0.0 and shear:
        return  # shear springs resist compression only (§3.2)
    if stretch < 0.0 and kind == STITCH:
        return  # a thread goes slack
    f = stiffness_n_per_m * stretch / length
    particle_force_n_inout[a, 0] += f * dx
    particle_force_n_inout[a, 1] += f * dy
    particle_force_n_inout[a, 2] += f * dz
    particle_force_n_inout[b, 0] -= f * dx
    particle_force_n_inout[b, 1] -= f * dy
    particle_force_n_inout[b, 2] -= f * dz


@nb.njit(cache=True, fastmath=False)
def accumulate_spring_forces(
    # model
    spring_kind, spring_rest_length_m,
    # state in
    particle_position_m, spring_particle_a, spring_particle_b, spring_alive, spring_stiffness_n_per_m,
    # state out
    particle_force_n_inout,
):
    """Zero `particle_force_n` and add every live spring's force; serial, so sums are deterministic."""
    particle_force_n_inout[:] = 0.0
    for s in range(spring_kind.shape[0]):
        if not spring_alive[s]:
            continue  # cut springs and unborn shear twins carry no force
        add_spring_force(s, spring_stiffness_n_per_m[s], spring_kind, spring_rest_length_m, particle_position_m,
                         spring_particle_a, spring_particle_b, particle_force_n_inout)
