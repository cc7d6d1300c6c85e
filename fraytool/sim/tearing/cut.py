"""Cutting springs over their randomised break strain (docs/method.md §3.4 "random break limits", §4.1).

Runs in stage 7 of the step, after strain limiting (stage 5), yarn contact and collisions, and
after the transitions of the same step. Rules (docs/tearing.md "Cutting"):
- A structural (yarn) spring is *broken* when its strain |x_b - x_a| / L - 1 exceeds its own break
  strain `model.spring_break_strain[s]` (drawn once when the model is built from the scene seed:
  Normal(break_strain, break_strain_spread), floored just above the transition strain), its yarn
  can carry tension there (fraytool.sim.tearing.yarn_runs: at least `ineffective_length` crossings
  to the nearest free yarn end on each side, and not on a run sliding free towards a loose end), and
  it is, of its yarn's springs over their limits, the furthest over (one cut per yarn per step:
  "springs cut one by one"). It gets
  spring_alive = False and spring_broken = True (the source of the `broken_springs` figure).
  Only yarn springs have a limit of their own: bend springs span two yarn springs and carry a
  fraction of their strain, and shear springs carry no tension at all.
- A bend spring is cut (spring_alive = False, not "broken") with either structural spring it
  spans: a cut yarn must not stay joined through its bend spring.
- A shear spring and its twin are cut with any of the four structural springs bordering their
  grid cell: a torn cell has no diagonal left to keep. (The contact pass also cuts the shear
  copies at a couple when it disconnects, `contact.py`.)
An unborn shear twin (alive = broken = False) is never born once its shear spring is cut, since
a split duplicates only a live shear spring. Serial in slot order: deterministic. The kernels take
the argument groups of `groups.py` (model_in: TearModel, particles_in, springs_inout).
"""
from __future__ import annotations

import numba as nb
import numpy as np

from fraytool.kinds import STRUCT_WEFT


@nb.njit(cache=True, fastmath=False)
def cut_spring(s, spring_alive_inout):
    """Cut one spring; returns 1 if it was alive."""
    if not spring_alive_inout[s]:
        return 0  # already cut (or an unborn twin): nothing to do
    spring_alive_inout[s] = False
    return 1


@nb.njit(cache=True, fastmath=False)
def cut_structural(s, model_in, springs_inout):
    """Break structural spring s (spring_broken) and cut the bend springs spanning it and the shear
    springs (and twins) of the cells beside it; returns the number of springs cut. Writes only
    spring_alive and spring_broken."""
    spring_twin = model_in.spring_twin
    structural_bend_start, structural_bend_list = model_in.structural_bend_start, model_in.structural_bend_list
    structural_shear_start, structural_shear_list = model_in.structural_shear_start, model_in.structural_shear_list
    spring_alive, spring_broken = springs_inout.spring_alive, springs_inout.spring_broken
    if not spring_alive[s]:
        return 0  # already cut
    spring_broken[s] = True
    count = cut_spring(s, spring_alive)
    for k in range(structural_bend_start[s], structural_bend_start[s + 1]):
        count += cut_spring(structural_bend_list[k], spring_alive)
    for k in range(structural_shear_start[s], structural_shear_start[s + 1]):
        sh = structural_shear_list[k]
        count += cut_spring(sh, spring_alive)
        count += cut_spring(spring_twin[sh], spring_alive)
    return count


@nb.njit(cache=True, fastmath=False, inline="always")
def squared_length(particle_position_m, a, b):
    """|x_b - x_a|^2 [m^2]: the one expression the per-step length tests (``first_over_length``,
    ``cut_overstrained``, fraytool.sim.tearing.split.transition_overstrained) share, so they round alike."""
    dx = particle_position_m[b, 0] - particle_position_m[a, 0]
    dy = particle_position_m[b, 1] - particle_position_m[a, 1]
    dz = particle_position_m[b, 2] - particle_position_m[a, 2]
    return dx * dx + dy * dy + dz * dz


@nb.njit(cache=True, fastmath=False)
def first_over_length(structural_springs, stretch_of, spring_rest_length_m, spring_particle_a, spring_particle_b,
                      spring_alive, particle_position_m):
    """Index k of the first live spring ``structural_springs[k]`` longer than ``(1 + stretch_of[s]) x`` its rest length
    or of NaN length (``squared_length``, as the length tests of ``cut_overstrained`` and
    fraytool.sim.tearing.split.transition_overstrained, which must stay in step with it), or -1. Takes plain arrays:
    the step's scans call it first and the full kernels, whose argument groups cost about 10 us a call to pass, only
    from there on (most steps have no spring over its limit)."""
    for k in range(structural_springs.shape[0]):
        s = structural_springs[k]
        if not spring_alive[s]:
            continue
        bound = (1.0 + stretch_of[s]) * spring_rest_length_m[s]
        if not squared_length(particle_position_m, spring_particle_a[s], spring_particle_b[s]) <= bound * bound:
            return k  # (NaN too: the transition kernel acts on a NaN length, as it skips only lengths within)
    return -1


@nb.njit(cache=True, fastmath=False)
def cut_overstrained(model_in, particles_in, springs_inout, weft_free_in, warp_free_in, fragment_left_in,
                     fragment_right_in, first=0):
    """Break, on each yarn, the live structural spring furthest over its break strain (ratio of
    length to break length; the lower slot on a tie), with its bend and shear springs: springs are
    cut one by one (docs/method.md §1), so a yarn under tension snaps at its weakest point and the rest
    of it relaxes before the next step instead of shattering into loose bits. Returns (structural
    springs broken, all springs cut). A spring within its limit costs one squared length and a
    compare. Reads the positions, writes only spring_alive and spring_broken. ``first``: the springs before
    ``structural_springs[first]`` are within their limits (``first_over_length``), so the scan starts there."""
    structural_springs, structural_yarn = model_in.structural_springs, model_in.structural_yarn
    yarn_count = model_in.yarn_count
    spring_rest_length_m, spring_break_strain = springs_inout.spring_rest_length_m, model_in.spring_break_strain
    particle_position_m = particles_in.particle_position_m
    spring_particle_a, spring_particle_b = springs_inout.spring_particle_a, springs_inout.spring_particle_b
    spring_alive = springs_inout.spring_alive
    spring_kind, spring_crossing_a, spring_crossing_b = model_in.spring_kind, model_in.spring_crossing_a, model_in.spring_crossing_b
    ineffective_length = model_in.ineffective_length
    worst = np.zeros(yarn_count)
    pick = np.full(yarn_count, -1, np.int64)
    yarn_cuts = 0
    total = 0
    for k in range(first, structural_springs.shape[0]):
        s = structural_springs[k]
        if not spring_alive[s]:
            continue  # already cut
        limit = (1.0 + spring_break_strain[s]) * spring_rest_length_m[s]
        d2 = squared_length(particle_position_m, spring_particle_a[s], spring_particle_b[s])
        if d2 <= limit * limit:
            continue  # within its limit (first: the usual case, and the cheapest; first_over_length matches it)
        if fragment_left_in[s] < ineffective_length or fragment_right_in[s] < ineffective_length:
            continue  # within the ineffective length of a free yarn end: friction has not built up tension
        free = weft_free_in if spring_kind[s] == STRUCT_WEFT else warp_free_in
        if free[spring_crossing_a[s]] or free[spring_crossing_b[s]]:
            continue  # a yarn sliding free towards a loose end here: no tension held by the weave
        ratio = d2 / (limit * limit)
        y = structural_yarn[k]
        if ratio > worst[y]:
            worst[y] = ratio
            pick[y] = s
    for y in range(yarn_count):
        if pick[y] < 0:
            continue
        yarn_cuts += 1
        total += cut_structural(pick[y], model_in, springs_inout)
    return yarn_cuts, total
