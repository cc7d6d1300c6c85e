"""Figures of a torn cloth's pieces and of the strain where it is still woven (simulate --json).

- pieces: connected components over live structural springs and connected couples
  (fraytool.sim.kernels.pieces); `small_pieces` counts those holding fewer than SMALL_PIECE_MASSES
  masses (the "confetti" a real woven cloth does not make);
- woven strain: the largest strain over live structural springs whose two end crossings are still
  woven (base level, or a connected mass couple), i.e. where strain limiting must hold.
"""
from __future__ import annotations

import numpy as np

from fraytool.sim.kernels.pieces import label_pieces, max_woven_strain, piece_masses
from fraytool.sim.model import Model
from fraytool.sim.state import State

SMALL_PIECE_MASSES = 5
"""A piece with fewer masses than this is a loose snippet (issue: no confetti)."""


def particle_pieces(model: Model, state: State) -> tuple[np.ndarray, int]:
    """(piece label per particle slot, -1 if inactive; number of pieces)."""
    labels = np.empty(model.particle_count, np.int64)
    count = label_pieces(model.spring_kind, model.crossing_count, state.particle_active, state.crossing_yarn_level,
                         state.couple_connected, state.spring_particle_a, state.spring_particle_b,
                         state.spring_alive, labels)
    return labels, int(count)


def piece_figures(model: Model, state: State) -> dict:
    """pieces, largest_piece_fractions (mass fractions of the two largest), small_pieces."""
    labels, count = particle_pieces(model, state)
    mass, masses = piece_masses(labels, state.particle_mass_kg, count)
    total = float(mass.sum())
    order = np.argsort(-mass, kind="stable")
    fractions = [float(mass[k] / total) for k in order[:2]] if total > 0 else []
    while len(fractions) < 2:
        fractions.append(0.0)
    return {"pieces": count, "largest_piece_fractions": fractions,
            "small_pieces": int((masses < SMALL_PIECE_MASSES).sum())}


def woven_strain(model: Model, state: State) -> tuple[float, int]:
    """(largest strain over live structural springs between woven crossings, its spring slot or -1).
    Every frame (Simulation): one numba pass (fraytool.sim.kernels.pieces.max_woven_strain; the numpy
    version with its index arrays took 4.5 ms a frame on the 256 x 256 tablecloth)."""
    strain, spring = max_woven_strain(model.spring_kind, model.spring_crossing_a, model.spring_crossing_b,
                                      state.crossing_yarn_level, state.couple_connected, state.spring_alive,
                                      state.spring_particle_a, state.spring_particle_b, state.spring_rest_length_m,
                                      state.particle_position_m)
    return float(strain), int(spring)
