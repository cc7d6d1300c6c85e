"""The cloth's pieces: connected components of the active masses over live structural (yarn)
springs and connected mass couples (docs/tearing.md, "Pieces").

A base-level crossing is one mass; a connected couple joins its weft and warp masses; a live
structural spring joins its two end masses. Bend and shear springs do not join pieces: a bend spring
is cut with the structural spring it spans, and shear springs alone do not hold yarns together.
Labels are numbered by their lowest particle slot (deterministic), -1 for inactive slots.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT


@nb.njit(cache=True, fastmath=False, inline="always")
def _find(parent_inout, p):
    while parent_inout[p] != p:
        parent_inout[p] = parent_inout[parent_inout[p]]  # path halving
        p = parent_inout[p]
    return p


@nb.njit(cache=True, fastmath=False)
def label_pieces(
    # model
    spring_kind, crossing_count,
    # state in
    particle_active, crossing_yarn_level, couple_connected, spring_particle_a, spring_particle_b, spring_alive,
    # out
    particle_piece_out,
):
    """Label every active particle with its piece (0..K-1, by lowest slot); returns K."""
    n = particle_active.shape[0]
    parent = np.arange(n)
    for s in range(spring_kind.shape[0]):
        if not spring_alive[s] or (spring_kind[s] != STRUCT_WEFT and spring_kind[s] != STRUCT_WARP):
            continue
        ra = _find(parent, spring_particle_a[s])
        rb = _find(parent, spring_particle_b[s])
        if ra != rb:
            if ra < rb:
                parent[rb] = ra
            else:
                parent[ra] = rb
    for c in range(crossing_count):
        if crossing_yarn_level[c] and couple_connected[c]:
            ra = _find(parent, c)
            rb = _find(parent, crossing_count + c)
            if ra != rb:
                if ra < rb:
                    parent[rb] = ra
                else:
                    parent[ra] = rb
    root_label = np.full(n, -1, np.int64)
    count = 0
    for p in range(n):
        if not particle_active[p]:
            particle_piece_out[p] = -1
            continue
        r = _find(parent, p)
        if root_label[r] < 0:
            root_label[r] = count
            count += 1
        particle_piece_out[p] = root_label[r]
    return count


@nb.njit(cache=True, fastmath=False)
def piece_masses(particle_piece, particle_mass_kg, piece_count):
    """(mass [kg], mass count) of every piece, each shape (piece_count,)."""
    mass = np.zeros(piece_count)
    count = np.zeros(piece_count, np.int64)
    for p in range(particle_piece.shape[0]):
        k = particle_piece[p]
        if k >= 0:
            mass[k] += particle_mass_kg[p]
            count[k] += 1
    return mass, count


@nb.njit(cache=True, fastmath=False)
def max_woven_strain(spring_kind, spring_crossing_a, spring_crossing_b, crossing_yarn_level, couple_connected,
                     spring_alive, spring_particle_a, spring_particle_b, spring_rest_length_m, particle_position_m):
    """(largest strain |x_b - x_a| / L - 1 over live structural springs whose two end crossings are woven:
    base level, or a connected couple; its spring slot, the lowest on a tie), (0.0, -1) if none. One
    pass, nothing allocated (fraytool.sim.pieces.woven_strain)."""
    best = 0.0
    where = -1
    for s in range(spring_kind.shape[0]):
        kind = spring_kind[s]
        if not spring_alive[s] or (kind != STRUCT_WEFT and kind != STRUCT_WARP):
            continue
        ca = spring_crossing_a[s]
        cb = spring_crossing_b[s]
        if (crossing_yarn_level[ca] and not couple_connected[ca]) or (crossing_yarn_level[cb] and not couple_connected[cb]):
            continue
        a = spring_particle_a[s]
        b = spring_particle_b[s]
        dx = particle_position_m[b, 0] - particle_position_m[a, 0]
        dy = particle_position_m[b, 1] - particle_position_m[a, 1]
        dz = particle_position_m[b, 2] - particle_position_m[a, 2]
        strain = math.sqrt(dx * dx + dy * dy + dz * dz) / spring_rest_length_m[s] - 1.0
        if where < 0 or strain > best:
            best = strain
            where = s
    return best, where
