"""Transition from the base model to the yarn-level model (docs/method.md §3.4): split and propagate.

Split of a base crossing c into a mass couple
---------------------------------------------
- n_c: the cloth normal of `fraytool.grid.crossing_normals` evaluated at c alone, over crossing
  *centres*: the base mass of a base-level crossing, the midpoint of the couple of a yarn-level one
  (the renderer's rule, `fraytool.render.yarns.yarn_points`), so a split mass lands exactly on the
  base-level yarn point the renderer drew the step before (`fraytool.grid.base_yarn_points`).
- Weft mass (slot c) at x + s T/2 n_c, warp mass (slot C + c) at x - s T/2 n_c, s = +1 where the
  weft lies on top (crossing_weft_on_top), -1 otherwise.
- Each gets half the mass and the original velocity: linear momentum m v = m/2 v + m/2 v exactly,
  angular momentum about the old position R_weft x m/2 v + R_warp x m/2 v = 0 (R_warp = -R_weft).
  Inside a step the velocity is recomputed at the end as (x - x_prev) / dt, so the previous
  positions of both masses are set to x_new - (x - x_prev): their post-processed velocity is the
  original mass's.
- Structural and bend springs: weft kinds stay on slot c (now the weft mass), warp kinds move to
  slot C + c (the warp mass).
- Shear springs are duplicated into their twin slot, each copy at half the stiffness. The copies
  join masses of the same layer (upper to upper, lower to lower: the upper mass of a couple is its
  weft mass where the weft is on top); where the other end is still a base mass both copies attach
  to that same base mass. When the other end splits later, each copy moves to its layer's mass.
- Crossings held by a rigid body (model.attachment_particle) never split: an attachment holds one
  particle slot, and splitting would leave the warp mass unheld. Springs from a held crossing to a
  split one simply attach to the held base mass.

Propagation ("up to and including the crossing where the weave flips")
----------------------------------------------------------------------
A structural spring whose strain exceeds the transition strain splits both of its end crossings.
From each end the split then walks along the spring's own yarn, away from the spring, and splits
each next crossing; it stops *after* splitting the first crossing whose weave flag differs from the
previous one (inclusive, the paper's reading and the default). The exclusive reading
(`model_in.propagation_inclusive` False, scene key `[cloth.tearing] propagation = "exclusive"`)
stops *before* that crossing instead. Either way the walk also stops at the cloth border, at a dead
structural spring (the yarn is cut there) and before a held crossing (never split). Inclusive: plain
weave splits the two ends and the next crossing beyond each (4); a 2/2 twill splits 6 crossings for
a spring between two floats and 4 for a spring inside a float. Exclusive: plain weave splits only
the two ends; a 2/2 twill 4 and 2. The walk is repeated whenever a spring is over the threshold
(crossings already split are skipped), so the split set does not depend on the order in which
springs were found over-strained.

Kernels are serial numba (cache=True, fastmath=False): same inputs, bit-identical results. They take
the argument groups of `groups.py` (model_in: TearModel; particles_inout, crossings_inout,
springs_inout: the State groups) and the step's previous positions, prev_position_m_inout.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from fraytool.kinds import BEND_WARP, SHEAR, STRUCT_WARP, STRUCT_WEFT
from fraytool.sim.tearing.cut import squared_length


@nb.njit(cache=True, fastmath=False)
def _centre(k, d, crossing_count, particle_position_m, crossing_yarn_level):
    """Component d of the centre of crossing k: base mass, or the midpoint of its couple."""
    if crossing_yarn_level[k]:
        return 0.5 * (particle_position_m[k, d] + particle_position_m[crossing_count + k, d])
    return particle_position_m[k, d]


@nb.njit(cache=True, fastmath=False)
def _centre_difference(k1, k0, crossing_count, particle_position_m, crossing_yarn_level):
    """Centre of crossing k1 minus centre of crossing k0."""
    return (_centre(k1, 0, crossing_count, particle_position_m, crossing_yarn_level)
            - _centre(k0, 0, crossing_count, particle_position_m, crossing_yarn_level),
            _centre(k1, 1, crossing_count, particle_position_m, crossing_yarn_level)
            - _centre(k0, 1, crossing_count, particle_position_m, crossing_yarn_level),
            _centre(k1, 2, crossing_count, particle_position_m, crossing_yarn_level)
            - _centre(k0, 2, crossing_count, particle_position_m, crossing_yarn_level))


@nb.njit(cache=True, fastmath=False)
def _yarn_neighbour(c, springs, side, spring_crossing_a, spring_crossing_b):
    """The crossing next to c along a yarn (side 0: towards lower index, 1: higher) through its
    structural spring slot `springs[c, side]`; c itself where there is none (the border)."""
    s = springs[c, side]
    if s < 0:
        return c
    return spring_crossing_a[s] if side == 0 else spring_crossing_b[s]


@nb.njit(cache=True, fastmath=False)
def _raw_normal(c, model_in, particle_position_m, crossing_yarn_level):
    """Un-normalised du x dv at crossing c (one-sided differences at the border, as in grid.py); the
    neighbours are the crossings joined to c by its structural spring slots, so a shaped panel's border
    is a border too."""
    n = model_in.crossing_weft_on_top.shape[0]
    cws, cvs = model_in.crossing_weft_springs, model_in.crossing_warp_springs
    ca, cb = model_in.spring_crossing_a, model_in.spring_crossing_b
    u0 = _yarn_neighbour(c, cws, 0, ca, cb)
    u1 = _yarn_neighbour(c, cws, 1, ca, cb)
    v0 = _yarn_neighbour(c, cvs, 0, ca, cb)
    v1 = _yarn_neighbour(c, cvs, 1, ca, cb)
    dux, duy, duz = _centre_difference(u1, u0, n, particle_position_m, crossing_yarn_level)
    dvx, dvy, dvz = _centre_difference(v1, v0, n, particle_position_m, crossing_yarn_level)
    return duy * dvz - duz * dvy, duz * dvx - dux * dvz, dux * dvy - duy * dvx


@nb.njit(cache=True, fastmath=False)
def crossing_normal_at(c, model_in, particle_position_m, crossing_yarn_level):
    """Unit cloth normal n_c at crossing c: `fraytool.grid.crossing_normals` over crossing centres,
    for one crossing. A degenerate crossing (neighbours collinear) gets the mean normal of the cloth
    (or +z), the same fallback as grid.py."""
    nx, ny, nz = _raw_normal(c, model_in, particle_position_m, crossing_yarn_level)
    length = math.sqrt(nx * nx + ny * ny + nz * nz)
    if length > 1e-300:
        return nx / length, ny / length, nz / length
    # Rare: average the unit normals of every non-degenerate crossing.
    mx, my, mz = 0.0, 0.0, 0.0
    for k in range(model_in.crossing_weft_on_top.shape[0]):
        ax, ay, az = _raw_normal(k, model_in, particle_position_m, crossing_yarn_level)
        la = math.sqrt(ax * ax + ay * ay + az * az)
        if la > 1e-300:
            mx += ax / la
            my += ay / la
            mz += az / la
    ml = math.sqrt(mx * mx + my * my + mz * mz)
    if ml > 0.0:
        return mx / ml, my / ml, mz / ml
    return 0.0, 0.0, 1.0


@nb.njit(cache=True, fastmath=False)
def _spring_length(s, spring_particle_a, spring_particle_b, particle_position_m):
    """Current length of spring s [m]."""
    a, b = spring_particle_a[s], spring_particle_b[s]
    dx = particle_position_m[b, 0] - particle_position_m[a, 0]
    dy = particle_position_m[b, 1] - particle_position_m[a, 1]
    dz = particle_position_m[b, 2] - particle_position_m[a, 2]
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@nb.njit(cache=True, fastmath=False)
def _upper(k, crossing_count, crossing_weft_on_top):
    """Slot of the upper mass of yarn-level crossing k (its weft mass where the weft is on top)."""
    return k if crossing_weft_on_top[k] else crossing_count + k


@nb.njit(cache=True, fastmath=False)
def split_crossing(c, model_in, particles_inout, crossings_inout, springs_inout, prev_position_m_inout):
    """Split base crossing c into a connected weft/warp mass couple (module docstring); returns
    True if it split, False if it was already yarn level or is held by a body.

    Writes the couple's two particles (and their previous positions), the crossing's flags, and the
    ends, stiffnesses and alive flags (a shear twin is born) of the springs at c."""
    thickness_m = model_in.thickness_m
    crossing_weft_on_top, crossing_attached = model_in.crossing_weft_on_top, model_in.crossing_attached
    spring_kind, spring_twin = model_in.spring_kind, model_in.spring_twin
    spring_crossing_a, spring_crossing_b = model_in.spring_crossing_a, model_in.spring_crossing_b
    crossing_spring_start, crossing_spring_list = model_in.crossing_spring_start, model_in.crossing_spring_list
    particle_position_m = particles_inout.particle_position_m
    particle_velocity_m_s = particles_inout.particle_velocity_m_s
    particle_mass_kg = particles_inout.particle_mass_kg
    particle_inv_mass = particles_inout.particle_inv_mass
    particle_active = particles_inout.particle_active
    crossing_yarn_level, couple_connected = crossings_inout.crossing_yarn_level, crossings_inout.couple_connected
    spring_particle_a, spring_particle_b = springs_inout.spring_particle_a, springs_inout.spring_particle_b
    spring_alive, spring_broken = springs_inout.spring_alive, springs_inout.spring_broken
    spring_stiffness_n_per_m = springs_inout.spring_stiffness_n_per_m
    if crossing_yarn_level[c]:
        return False  # already a couple
    if crossing_attached[c]:
        return False  # held crossings stay base level (an attachment holds one slot)
    n = crossing_weft_on_top.shape[0]
    w = n + c
    spring_rest_length_m = springs_inout.spring_rest_length_m
    first, last = crossing_spring_start[c], crossing_spring_start[c + 1]
    length_before = np.empty(last - first)
    twin_before = np.zeros(last - first)  # length of an already born shear twin, 0 if unborn
    for k in range(first, last):
        s = crossing_spring_list[k]
        length_before[k - first] = _spring_length(s, spring_particle_a, spring_particle_b, particle_position_m)
        if spring_kind[s] == SHEAR and (spring_alive[spring_twin[s]] or spring_broken[spring_twin[s]]):
            twin_before[k - first] = _spring_length(spring_twin[s], spring_particle_a, spring_particle_b,
                                                    particle_position_m)
    nx, ny, nz = crossing_normal_at(c, model_in, particle_position_m, crossing_yarn_level)
    half_t = 0.5 * thickness_m if crossing_weft_on_top[c] else -0.5 * thickness_m
    ox, oy, oz = half_t * nx, half_t * ny, half_t * nz
    x0, x1, x2 = particle_position_m[c, 0], particle_position_m[c, 1], particle_position_m[c, 2]
    # Step displacement of the old mass: both new masses keep it, so v = (x - x_prev)/dt is unchanged.
    d0 = x0 - prev_position_m_inout[c, 0]
    d1 = x1 - prev_position_m_inout[c, 1]
    d2 = x2 - prev_position_m_inout[c, 2]
    particle_position_m[c, 0] = x0 + ox
    particle_position_m[c, 1] = x1 + oy
    particle_position_m[c, 2] = x2 + oz
    particle_position_m[w, 0] = x0 - ox
    particle_position_m[w, 1] = x1 - oy
    particle_position_m[w, 2] = x2 - oz
    prev_position_m_inout[c, 0] = particle_position_m[c, 0] - d0
    prev_position_m_inout[c, 1] = particle_position_m[c, 1] - d1
    prev_position_m_inout[c, 2] = particle_position_m[c, 2] - d2
    prev_position_m_inout[w, 0] = particle_position_m[w, 0] - d0
    prev_position_m_inout[w, 1] = particle_position_m[w, 1] - d1
    prev_position_m_inout[w, 2] = particle_position_m[w, 2] - d2
    for d in range(3):
        particle_velocity_m_s[w, d] = particle_velocity_m_s[c, d]
    m = particle_mass_kg[c]
    particle_mass_kg[c] = 0.5 * m
    particle_mass_kg[w] = 0.5 * m
    inv = 1.0 / (0.5 * m) if particle_inv_mass[c] > 0.0 else 0.0
    particle_inv_mass[c] = inv
    particle_inv_mass[w] = inv
    particle_active[w] = True
    crossing_yarn_level[c] = True
    couple_connected[c] = True

    up_c = _upper(c, n, crossing_weft_on_top)
    low_c = c if up_c != c else w
    for k in range(crossing_spring_start[c], crossing_spring_start[c + 1]):
        s = crossing_spring_list[k]
        kind = spring_kind[s]
        at_a = spring_crossing_a[s] == c
        if kind == STRUCT_WARP or kind == BEND_WARP:
            if at_a:
                spring_particle_a[s] = w
            else:
                spring_particle_b[s] = w
            continue
        if kind != SHEAR:
            continue  # weft structural / weft bend: slot c is the weft mass now
        o = spring_crossing_b[s] if at_a else spring_crossing_a[s]
        t = spring_twin[s]
        twin_born = spring_alive[t] or spring_broken[t]
        if spring_alive[s] and not twin_born:
            # First split at this spring: duplicate it, half the stiffness each (§3.4).
            k_half = 0.5 * spring_stiffness_n_per_m[s]
            spring_stiffness_n_per_m[s] = k_half
            spring_stiffness_n_per_m[t] = k_half
            spring_alive[t] = True
            o_up = _upper(o, n, crossing_weft_on_top) if crossing_yarn_level[o] else o
            o_low = (o if o_up != o else n + o) if crossing_yarn_level[o] else o
            if at_a:
                spring_particle_a[s] = up_c
                spring_particle_b[s] = o_up
                spring_particle_a[t] = low_c
                spring_particle_b[t] = o_low
            else:
                spring_particle_b[s] = up_c
                spring_particle_a[s] = o_up
                spring_particle_b[t] = low_c
                spring_particle_a[t] = o_low
        elif twin_born:
            # Already duplicated when the other end split: each copy follows its layer there.
            for copy in (s, t):
                p_o = spring_particle_b[copy] if at_a else spring_particle_a[copy]
                same = up_c if p_o == _upper(o, n, crossing_weft_on_top) else low_c
                if at_a:
                    spring_particle_a[copy] = same
                else:
                    spring_particle_b[copy] = same
        else:
            # Cut before any split: no copy is born; keep the dead spring's end on a live slot.
            if at_a:
                spring_particle_a[s] = up_c
            else:
                spring_particle_b[s] = up_c
    # Every spring at c keeps the strain it had: rest length scaled by new length / old length (a
    # twin born here takes its original's strain).
    for k in range(first, last):
        s = crossing_spring_list[k]
        old = length_before[k - first]
        if old <= 0.0:
            continue  # degenerate: no strain to keep
        ratio = spring_rest_length_m[s] / old
        new = _spring_length(s, spring_particle_a, spring_particle_b, particle_position_m)
        if spring_kind[s] == SHEAR:
            t = spring_twin[s]
            t_old = twin_before[k - first]
            t_ratio = spring_rest_length_m[t] / t_old if t_old > 0.0 else ratio  # born now: the original's
            spring_rest_length_m[t] = _spring_length(t, spring_particle_a, spring_particle_b,
                                                     particle_position_m) * t_ratio
        spring_rest_length_m[s] = new * ratio
    return True


@nb.njit(cache=True, fastmath=False)
def _walk_and_split(start, step, s_dir, model_in, particles_inout, crossings_inout, springs_inout,
                    prev_position_m_inout):
    """From crossing `start`, walk along a weft (s_dir = 0) or warp (1) yarn by `step` (+1/-1) and
    split each next crossing, up to and including the first one whose weave flag differs from the
    previous one (model_in.propagation_inclusive) or up to just before it (exclusive reading); returns
    the number of crossings split."""
    inclusive = model_in.propagation_inclusive
    crossing_weft_on_top, crossing_attached = model_in.crossing_weft_on_top, model_in.crossing_attached
    yarn_springs = model_in.crossing_weft_springs if s_dir == 0 else model_in.crossing_warp_springs
    spring_crossing_a, spring_crossing_b = model_in.spring_crossing_a, model_in.spring_crossing_b
    side = 1 if step > 0 else 0
    spring_alive = springs_inout.spring_alive
    if crossing_attached[start]:
        return 0  # a held crossing is a wall
    count = 0
    k = start
    while True:
        spring = yarn_springs[k, side]
        if spring < 0:
            break  # cloth border (a shaped panel's too)
        k2 = spring_crossing_b[spring] if side == 1 else spring_crossing_a[spring]
        if not spring_alive[spring]:
            break  # the yarn is cut here
        flips = crossing_weft_on_top[k2] != crossing_weft_on_top[k]
        if flips and not inclusive:
            break  # exclusive reading: the crossing where the weave flips stays base level
        if crossing_attached[k2]:
            break  # held: never splits, and the walk stops before it
        if split_crossing(k2, model_in, particles_inout, crossings_inout, springs_inout, prev_position_m_inout):
            count += 1
        if flips:
            break  # inclusive reading (the paper's): the crossing where the weave flips was the last
        k = k2
    return count


@nb.njit(cache=True, fastmath=False)
def transition_spring(s, model_in, particles_inout, crossings_inout, springs_inout, prev_position_m_inout):
    """Split both ends of structural spring s and propagate along its yarn (module docstring);
    returns the number of crossings split. Writes what split_crossing writes."""
    spring_kind = model_in.spring_kind
    spring_crossing_a, spring_crossing_b = model_in.spring_crossing_a, model_in.spring_crossing_b
    kind = spring_kind[s]
    if kind != STRUCT_WEFT and kind != STRUCT_WARP:
        return 0  # only yarn (structural) springs trigger a transition
    ca = spring_crossing_a[s]
    cb = spring_crossing_b[s]  # b is one further along the yarn than a
    s_dir = 0 if kind == STRUCT_WEFT else 1
    count = 0
    for c in (ca, cb):
        if split_crossing(c, model_in, particles_inout, crossings_inout, springs_inout, prev_position_m_inout):
            count += 1
    for start, step in ((cb, 1), (ca, -1)):
        count += _walk_and_split(start, step, s_dir, model_in, particles_inout, crossings_inout, springs_inout,
                                 prev_position_m_inout)
    return count


@nb.njit(cache=True, fastmath=False)
def transition_overstrained(model_in, particles_inout, crossings_inout, springs_inout, prev_position_m_inout, first=0):
    """Transition every live structural spring whose strain exceeds `transition_strain`, in slot
    order; returns the number of crossings split. A spring within the threshold costs one squared
    length and a compare. Writes what split_crossing writes. ``first``: the springs before
    ``structural_springs[first]`` are within the threshold (fraytool.sim.tearing.cut.first_over_length), so the
    scan starts there."""
    structural_springs = model_in.structural_springs
    spring_rest_length_m = springs_inout.spring_rest_length_m
    transition_strain = model_in.transition_strain
    particle_position_m = particles_inout.particle_position_m
    spring_particle_a, spring_particle_b = springs_inout.spring_particle_a, springs_inout.spring_particle_b
    spring_alive = springs_inout.spring_alive
    count = 0
    stretch = 1.0 + transition_strain
    for k in range(first, structural_springs.shape[0]):
        s = structural_springs[k]
        if not spring_alive[s]:
            continue  # a cut yarn carries no strain
        limit = stretch * spring_rest_length_m[s]
        if squared_length(particle_position_m, spring_particle_a[s], spring_particle_b[s]) <= limit * limit:
            continue  # (fraytool.sim.tearing.cut.first_over_length matches this test)
        count += transition_spring(s, model_in, particles_inout, crossings_inout, springs_inout, prev_position_m_inout)
    return count
