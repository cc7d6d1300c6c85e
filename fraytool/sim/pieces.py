"""Figures of a torn cloth's pieces and of the strain where it is still woven (simulate --json).

- pieces: connected components over live structural springs and connected couples
  (fraytool.sim.kernels.pieces); `small_pieces` counts those holding fewer than SMALL_PIECE_MASSES
  masses (the "confetti" a real woven cloth does not make);
- woven strain: the largest strain over live structural springs whose two end crossings are still
  woven (base level, or a connected mass couple), i.e. where strain limiting must hold.
"""
from __future__ import annotations

import numpy as np

from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from fraytool.sim.kernels.pieces import label_pieces, piece_masses
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
    """(largest strain over live structural springs between woven crossings, its spring slot or -1)."""
    structural = (model.spring_kind == STRUCT_WEFT) | (model.spring_kind == STRUCT_WARP)
    woven = ~state.crossing_yarn_level | state.couple_connected
    ca, cb = model.spring_crossing_a, model.spring_crossing_b
    sel = np.flatnonzero(structural & state.spring_alive & woven[ca] & woven[cb])
    if sel.size == 0:
        return 0.0, -1
    x = state.particle_position_m
    d = x[state.spring_particle_b[sel]] - x[state.spring_particle_a[sel]]
    strain = np.sqrt((d * d).sum(axis=1)) / state.spring_rest_length_m[sel] - 1.0
    k = int(np.argmax(strain))
    return float(strain[k]), int(sel[k])
