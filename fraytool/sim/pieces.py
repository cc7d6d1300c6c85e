"""Figures of a torn cloth's pieces and of the strain where it is still woven (simulate --json).

- pieces: connected components over live structural springs and connected couples
  (fraytool.sim.kernels.pieces); `small_pieces` counts those holding fewer than SMALL_PIECE_MASSES
  masses (the "confetti" a real woven cloth does not make);
- woven strain: the largest strain over live structural springs whose two end crossings are still
  woven (base level, or a connected mass couple), i.e. where strain limiting must hold.
"""
from __future__ import annotations

from typing import Optional

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


NEAR_SPACINGS = 4
"""A crossing within this many yarn spacings of a held crossing (on the grid) or of a colliding body's
surface is near a grip or a body: strain there is the grip's or the body's doing."""


def dilate_on_grid(model: Model, marked: np.ndarray, spacings: int = NEAR_SPACINGS) -> np.ndarray:
    """Crossings within `spacings` grid steps (in i and in j) of a `marked` crossing, shape (crossing_count,)."""
    from fraytool.sim.multires import dilate  # (cells or crossings: a grid all the same)

    if model.full_grid:
        return dilate(marked, model.warp_yarns, model.weft_yarns, spacings)
    # a shaped panel: dilate over its whole grid, read back at its crossings' places
    places = model.crossing_grid_j.astype(np.int64) * model.warp_yarns + model.crossing_grid_i
    on_grid = np.zeros(model.warp_yarns * model.weft_yarns, bool)
    on_grid[places[marked]] = True
    return dilate(on_grid, model.warp_yarns, model.weft_yarns, spacings)[places]


def crossings_near_grips(model: Model, spacings: int = NEAR_SPACINGS) -> np.ndarray:
    """Crossings within `spacings` grid steps of a crossing held by an attachment, shape (crossing_count,)."""
    held = np.zeros(model.crossing_count, bool)
    held[model.attachment_particle % model.crossing_count] = True
    return dilate_on_grid(model, held, spacings)


def woven_strain_away(model: Model, state: State, near_grips: np.ndarray, self_contact: Optional[np.ndarray] = None,
                      spacings: int = NEAR_SPACINGS, meshes=None) -> tuple[float, int]:
    """woven_strain over the springs whose two end crossings are farther than `spacings` yarn spacings
    from a grip (`near_grips`, crossings_near_grips), from every colliding body, and (on the grid) from
    the crossings in contact with the cloth itself (`self_contact`, a mask over particle slots, from the
    self-collision stage; `meshes`: the solver's mesh geometry, for the mesh bodies): where strain past the limit is the step's or the limit's doing, not that of
    a grip or a body pulling or pushing (the case a user can act on)."""
    n = model.crossing_count
    near = near_grips.copy()
    if self_contact is not None and self_contact.any():
        touching = np.zeros(n, bool)
        touching[np.flatnonzero(self_contact) % n] = True
        near |= dilate_on_grid(model, touching, spacings)
    if model.body_collide.any():
        from fraytool.sim.kernels.bodies import bodies_in
        from fraytool.sim.kernels.rigid_contact import surface_distances

        bodies, distance = bodies_in(model, state), np.empty(n)
        for k in np.flatnonzero(model.body_collide):  # (a mesh body is at inf here: next)
            surface_distances(int(k), bodies, state.particle_position_m[:n], distance)
            near |= distance < spacings * model.spacing_m
        if meshes is not None:  # the mesh bodies (fraytool.sim.mesh_geometry.MeshGeometry of the solver)
            from fraytool.sim.kernels.mesh_contact import mesh_distances

            meshes_in = meshes.meshes_in(model)
            for m in range(meshes.table.count):
                if model.body_collide[meshes.table.body[m]]:
                    mesh_distances(m, meshes_in, bodies, spacings * model.spacing_m, state.particle_position_m[:n],
                                   distance)
                    near |= distance < spacings * model.spacing_m
    alive = state.spring_alive & ~(near[model.spring_crossing_a] | near[model.spring_crossing_b])
    strain, spring = max_woven_strain(model.spring_kind, model.spring_crossing_a, model.spring_crossing_b,
                                      state.crossing_yarn_level, state.couple_connected, alive,
                                      state.spring_particle_a, state.spring_particle_b, state.spring_rest_length_m,
                                      state.particle_position_m)
    return float(strain), int(spring)


def tear_distance_to_weak_lines(model: Model, state: State, weak_lines) -> np.ndarray:
    """Distance [m] from the middle of every broken yarn spring (at rest, in the cloth's plane) to the
    nearest of `weak_lines` (WeakLineSpec, docs/panels.md "Tear control"), shape (broken springs,)."""
    from fraytool.scene.panel_shape import distance_to_polyline

    broken = np.flatnonzero(state.spring_broken)
    uv = model.crossing_plane_uv_m
    mid = 0.5 * (uv[model.spring_crossing_a[broken]] + uv[model.spring_crossing_b[broken]])
    best = np.full(broken.size, np.inf)
    for line in weak_lines:
        best = np.minimum(best, distance_to_polyline(mid, np.asarray(line.points_m, float)))
    return best
