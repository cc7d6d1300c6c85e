"""The fray metric: how far loose yarn ends stick out of the weave along a tear.

Definition (docs/tearing.md "Fray metric"):
- A *cut end* is one of the two yarn ends left by a cut structural spring (spring_broken of a
  STRUCT_WEFT or STRUCT_WARP slot): the yarn's masses at the crossings on either side of the cut.
- A crossing is *woven* when it is at base level (weft and warp are one mass) or when it is a
  connected mass couple (§3.3).
- The *free length* of a cut end is the length of yarn, in metres along the yarn's current
  polyline (the sum of the current lengths of its structural springs), from the cut end to the
  first woven crossing met walking away from the cut. It is 0 when the end crossing itself is
  woven (the yarn stops exactly at the edge of the weave: a clean cut). If the walk reaches the
  other end of the yarn piece without meeting a woven crossing (a loose fragment), the free length
  is the whole fragment, counted from each of its cut ends.
A base-model-only tear (yarn_level = false) has no couples, so every free length is 0: a clean edge.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from fraytool.kinds import STRUCT_WEFT
from fraytool.sim.tearing.groups import state_groups, tear_model


@nb.njit(cache=True, fastmath=False)
def _woven(k, crossing_yarn_level, couple_connected):
    return (not crossing_yarn_level[k]) or couple_connected[k]


@nb.njit(cache=True, fastmath=False)
def _free_length(start, step, along_weft, model_in, particles_in, crossings_in, springs_in):
    """Yarn length from cut-end crossing `start`, walking by `step` (+1/-1) along a weft
    (along_weft) or warp yarn, to the first woven crossing or the end of the piece."""
    yarn_springs = model_in.crossing_weft_springs if along_weft else model_in.crossing_warp_springs
    side = 1 if step > 0 else 0
    crossing_yarn_level, couple_connected = crossings_in.crossing_yarn_level, crossings_in.couple_connected
    spring_particle_a, spring_particle_b = springs_in.spring_particle_a, springs_in.spring_particle_b
    spring_alive = springs_in.spring_alive
    x = particles_in.particle_position_m
    length = 0.0
    k = start
    while not _woven(k, crossing_yarn_level, couple_connected):
        s = yarn_springs[k, side]
        if s < 0:
            break  # cloth border (a shaped panel's too): the piece ends
        k2 = model_in.spring_crossing_b[s] if side == 1 else model_in.spring_crossing_a[s]
        if not spring_alive[s]:
            break  # another cut: the piece ends
        a = spring_particle_a[s]
        b = spring_particle_b[s]
        dx = x[b, 0] - x[a, 0]
        dy = x[b, 1] - x[a, 1]
        dz = x[b, 2] - x[a, 2]
        length += math.sqrt(dx * dx + dy * dy + dz * dz)
        k = k2
    return length


@nb.njit(cache=True, fastmath=False)
def free_end_lengths(model_in, particles_in, crossings_in, springs_in, length_out, crossing_out):
    """Free length [m] of every cut end (module docstring) into length_out, the crossing of the
    end into crossing_out; returns the number of cut ends (2 per cut structural spring). Reads the
    groups of `groups.py` (model_in: TearModel; the State groups), writes only the two outputs."""
    structural_springs, spring_kind = model_in.structural_springs, model_in.spring_kind
    spring_crossing_a, spring_crossing_b = model_in.spring_crossing_a, model_in.spring_crossing_b
    spring_broken = springs_in.spring_broken
    count = 0
    for k in range(structural_springs.shape[0]):
        s = structural_springs[k]
        if not spring_broken[s]:
            continue  # intact yarn
        along_weft = spring_kind[s] == STRUCT_WEFT
        ca = spring_crossing_a[s]
        cb = spring_crossing_b[s]
        # a lies before the cut (walk backwards), b after it (walk forwards).
        length_out[count] = _free_length(ca, -1, along_weft, model_in, particles_in, crossings_in, springs_in)
        crossing_out[count] = ca
        count += 1
        length_out[count] = _free_length(cb, 1, along_weft, model_in, particles_in, crossings_in, springs_in)
        crossing_out[count] = cb
        count += 1
    return count


def fray_lengths(model, topo, state) -> tuple[np.ndarray, np.ndarray]:
    """(free length [m], crossing) of every cut end of `state`, in structural-slot order."""
    particles_in, crossings_in, springs_in = state_groups(state)
    k = topo.structural_springs.shape[0]
    lengths = np.zeros(2 * k)
    crossings = np.zeros(2 * k, np.int32)
    count = free_end_lengths(tear_model(model, topo), particles_in, crossings_in, springs_in, lengths, crossings)
    return lengths[:count], crossings[:count]


def fray_summary(model, topo, state) -> dict:
    """The fray figures of the `--json` summary (docs/tearing.md)."""
    lengths, _ = fray_lengths(model, topo, state)
    free = lengths[lengths > 0.0]
    return {
        "fray_cut_ends": int(lengths.size),
        "fray_free_end_count": int(free.size),
        "fray_mean_free_end_m": float(free.mean()) if free.size else 0.0,
        "fray_max_free_end_m": float(lengths.max()) if lengths.size else 0.0,
        "fray_total_free_end_m": float(lengths.sum()),
        "fray_free_end_fraction": float(free.size / lengths.size) if lengths.size else 0.0,
    }

