"""PBD velocity damping, Müller et al., "Position Based Dynamics" (2007) §3.5.

    x_cm = Σ m_i x_i / Σ m_i,  v_cm = Σ m_i v_i / Σ m_i,  r_i = x_i - x_cm
    L = Σ r_i × m_i v_i,       I = Σ m_i [r_i]_x [r_i]_x^T,  ω = I^-1 L
    v_i += k (v_cm + ω × r_i - v_i)

It removes only the non-rigid part of the motion: linear and angular momentum are unchanged.

The kernels take the free particles as an ascending list (`particles`, fraytool.sim.kernels.work_split;
the ones the sums would not skip). The sums run over it in order on one thread (a parallel sum would
round differently with the thread count); the last pass, each particle's own update, runs in
parallel over its units (`unit_bounds`), so the result is the same, bit for bit, on any number of
threads.
"""
from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, fastmath=False)
def pbd_damping(particles, unit_bounds, particle_position_m, particle_velocity_m_s_inout, particle_mass_kg, particle_inv_mass,
                k_damping):
    """Damp the velocities of all free particles (inverse mass > 0) together, in place."""
    m_sum = 0.0
    xc = np.zeros(3)
    vc = np.zeros(3)
    for i in range(particles.shape[0]):
        p = particles[i]
        if particle_inv_mass[p] == 0.0:
            continue  # held or inactive: not part of the damped body
        m = particle_mass_kg[p]
        m_sum += m
        for d in range(3):
            xc[d] += m * particle_position_m[p, d]
            vc[d] += m * particle_velocity_m_s_inout[p, d]
    if m_sum == 0.0:
        return
    xc /= m_sum
    vc /= m_sum
    L = np.zeros(3)
    I = np.zeros((3, 3))
    for i in range(particles.shape[0]):
        p = particles[i]
        if particle_inv_mass[p] == 0.0:
            continue
        m = particle_mass_kg[p]
        rx = particle_position_m[p, 0] - xc[0]
        ry = particle_position_m[p, 1] - xc[1]
        rz = particle_position_m[p, 2] - xc[2]
        vx, vy, vz = particle_velocity_m_s_inout[p, 0], particle_velocity_m_s_inout[p, 1], particle_velocity_m_s_inout[p, 2]
        L[0] += m * (ry * vz - rz * vy)
        L[1] += m * (rz * vx - rx * vz)
        L[2] += m * (rx * vy - ry * vx)
        # [r]_x [r]_x^T = |r|^2 Id - r r^T
        I[0, 0] += m * (ry * ry + rz * rz)
        I[1, 1] += m * (rx * rx + rz * rz)
        I[2, 2] += m * (rx * rx + ry * ry)
        I[0, 1] -= m * rx * ry
        I[0, 2] -= m * rx * rz
        I[1, 2] -= m * ry * rz
    I[1, 0] = I[0, 1]
    I[2, 0] = I[0, 2]
    I[2, 1] = I[1, 2]
    w = _solve3(I, L)
    _damp_toward(particles, unit_bounds, particle_position_m, particle_velocity_m_s_inout, particle_inv_mass, xc, vc, w,
                 k_damping)


@nb.njit(cache=True, fastmath=False, parallel=True)
def _damp_toward(particles, unit_bounds, particle_position_m, particle_velocity_m_s_inout, particle_inv_mass, xc, vc, w,
                 k_damping):
    """The last pass of `pbd_damping`, particle by particle in parallel over the units."""
    for u in nb.prange(unit_bounds.shape[0] - 1):
        for i in range(unit_bounds[u], unit_bounds[u + 1]):
            p = particles[i]
            if particle_inv_mass[p] == 0.0:
                continue
            rx = particle_position_m[p, 0] - xc[0]
            ry = particle_position_m[p, 1] - xc[1]
            rz = particle_position_m[p, 2] - xc[2]
            particle_velocity_m_s_inout[p, 0] += k_damping * (vc[0] + w[1] * rz - w[2] * ry - particle_velocity_m_s_inout[p, 0])
            particle_velocity_m_s_inout[p, 1] += k_damping * (vc[1] + w[2] * rx - w[0] * rz - particle_velocity_m_s_inout[p, 1])
            particle_velocity_m_s_inout[p, 2] += k_damping * (vc[2] + w[0] * ry - w[1] * rx - particle_velocity_m_s_inout[p, 2])


@nb.njit(cache=True, fastmath=False)
def _solve3(A, b):
    """Solve the symmetric 3x3 system A x = b by Cramer's rule; x = 0 if A is (near) singular
    (all particles on one line: no rotation to keep)."""
    c00 = A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1]
    c01 = A[1, 2] * A[2, 0] - A[1, 0] * A[2, 2]
    c02 = A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]
    det = A[0, 0] * c00 + A[0, 1] * c01 + A[0, 2] * c02
    scale = abs(A[0, 0]) + abs(A[1, 1]) + abs(A[2, 2])
    x = np.zeros(3)
    if scale == 0.0 or abs(det) <= 1e-12 * scale * scale * scale:
        return x
    c10 = A[0, 2] * A[2, 1] - A[0, 1] * A[2, 2]
    c11 = A[0, 0] * A[2, 2] - A[0, 2] * A[2, 0]
    c12 = A[0, 1] * A[2, 0] - A[0, 0] * A[2, 1]
    c20 = A[0, 1] * A[1, 2] - A[0, 2] * A[1, 1]
    c21 = A[0, 2] * A[1, 0] - A[0, 0] * A[1, 2]
    c22 = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
    x[0] = (c00 * b[0] + c10 * b[1] + c20 * b[2]) / det
    x[1] = (c01 * b[0] + c11 * b[1] + c21 * b[2]) / det
    x[2] = (c02 * b[0] + c12 * b[1] + c22 * b[2]) / det
    return x


@nb.njit(cache=True, fastmath=False)
def pbd_damping_pieces(particles, unit_bounds, particle_position_m, particle_velocity_m_s_inout, particle_mass_kg,
                       particle_inv_mass, particle_piece, piece_count, k_damping):
    """The same damping applied to each piece of a torn cloth on its own (fraytool.sim.kernels.pieces):
    every piece keeps its own linear and angular momentum, so pieces moving apart rigidly keep their
    relative velocity. Particles with piece -1 (inactive) or inverse mass 0 (held) are left alone."""
    m_sum = np.zeros(piece_count)
    xc = np.zeros((piece_count, 3))
    vc = np.zeros((piece_count, 3))
    for i in range(particles.shape[0]):
        p = particles[i]
        k = particle_piece[p]
        if k < 0 or particle_inv_mass[p] == 0.0:
            continue
        m = particle_mass_kg[p]
        m_sum[k] += m
        for d in range(3):
            xc[k, d] += m * particle_position_m[p, d]
            vc[k, d] += m * particle_velocity_m_s_inout[p, d]
    for k in range(piece_count):
        if m_sum[k] > 0.0:
            for d in range(3):
                xc[k, d] /= m_sum[k]
                vc[k, d] /= m_sum[k]
    L = np.zeros((piece_count, 3))
    I = np.zeros((piece_count, 3, 3))
    for i in range(particles.shape[0]):
        p = particles[i]
        k = particle_piece[p]
        if k < 0 or particle_inv_mass[p] == 0.0:
            continue
        m = particle_mass_kg[p]
        rx = particle_position_m[p, 0] - xc[k, 0]
        ry = particle_position_m[p, 1] - xc[k, 1]
        rz = particle_position_m[p, 2] - xc[k, 2]
        vx, vy, vz = particle_velocity_m_s_inout[p, 0], particle_velocity_m_s_inout[p, 1], particle_velocity_m_s_inout[p, 2]
        L[k, 0] += m * (ry * vz - rz * vy)
        L[k, 1] += m * (rz * vx - rx * vz)
        L[k, 2] += m * (rx * vy - ry * vx)
        I[k, 0, 0] += m * (ry * ry + rz * rz)
        I[k, 1, 1] += m * (rx * rx + rz * rz)
        I[k, 2, 2] += m * (rx * rx + ry * ry)
        I[k, 0, 1] -= m * rx * ry
        I[k, 0, 2] -= m * rx * rz
        I[k, 1, 2] -= m * ry * rz
    w = np.zeros((piece_count, 3))
    for k in range(piece_count):
        I[k, 1, 0] = I[k, 0, 1]
        I[k, 2, 0] = I[k, 0, 2]
        I[k, 2, 1] = I[k, 1, 2]
        w[k] = _solve3(I[k], L[k])
    _damp_pieces_toward(particles, unit_bounds, particle_position_m, particle_velocity_m_s_inout, particle_inv_mass,
                        particle_piece, xc, vc, w, k_damping)


@nb.njit(cache=True, fastmath=False, parallel=True)
def _damp_pieces_toward(particles, unit_bounds, particle_position_m, particle_velocity_m_s_inout, particle_inv_mass,
                        particle_piece, xc, vc, w, k_damping):
    """The last pass of `pbd_damping_pieces`, particle by particle in parallel over the units."""
    for u in nb.prange(unit_bounds.shape[0] - 1):
        for i in range(unit_bounds[u], unit_bounds[u + 1]):
            p = particles[i]
            k = particle_piece[p]
            if k < 0 or particle_inv_mass[p] == 0.0:
                continue
            rx = particle_position_m[p, 0] - xc[k, 0]
            ry = particle_position_m[p, 1] - xc[k, 1]
            rz = particle_position_m[p, 2] - xc[k, 2]
            particle_velocity_m_s_inout[p, 0] += k_damping * (vc[k, 0] + w[k, 1] * rz - w[k, 2] * ry
                                                        - particle_velocity_m_s_inout[p, 0])
            particle_velocity_m_s_inout[p, 1] += k_damping * (vc[k, 1] + w[k, 2] * rx - w[k, 0] * rz
                                                        - particle_velocity_m_s_inout[p, 1])
            particle_velocity_m_s_inout[p, 2] += k_damping * (vc[k, 2] + w[k, 0] * ry - w[k, 1] * rx
                                                        - particle_velocity_m_s_inout[p, 2])
