"""Slow reference of the compliant strain limit (tests only): point Gauss-Seidel over the springs,
one spring at a time, with the same multipliers and fixed point as the production kernel
`fraytool.sim.kernels.strain_limit.limit_strain_lines` (which solves a yarn at a time).
It was the production kernel until it was replaced for converging too slowly on long yarns."""
from __future__ import annotations

import math

import numba as nb


@nb.njit(cache=True, fastmath=False)
def limit_strain_compliant(
    # model
    limited_springs, spring_rest_length_m, strain_limit, tolerance, max_iterations, compliance_s2_per_kg,
    # state in
    particle_inv_mass, spring_particle_a, spring_particle_b, spring_alive,
    # scratch (zeroed here)
    tension_scratch,
    # state in/out
    particle_position_m,
):
    """Strain limiting as a compliant inequality constraint (XPBD, Macklin, Müller & Chentanez 2016):
    C = l - (1 + limit) L >= 0 is resisted with compliance alpha = 1 / k_limit [m/N], i.e. a
    yarn stiffness k_limit = 1 / alpha above the limit, through the multiplier mu >= 0 (tension
    impulse / h^2) accumulated over the step's sweeps:

        d_mu = (C - alpha~ mu) / (w_a + w_b + alpha~),   alpha~ = alpha / h^2 (passed in),
        mu' = max(0, mu + d_mu),  x_a += w_a (mu' - mu) u,  x_b -= w_b (mu' - mu) u.

    With alpha = 0 this is the hard projection of `limit_strain`. With alpha > 0 a pull the limit cannot
    meet (two grips apart, a ball pressing on) stretches the yarn by a definite amount instead of
    leaving whatever an iteration cap leaves: the sweeps converge and the strain past the limit,
    hence where and when yarns break, no longer depends on the step. Returns (sweeps, converged)."""
    n = limited_springs.shape[0]
    stretch = 1.0 + strain_limit
    for k in range(n):
        tension_scratch[k] = 0.0
    for it in range(max_iterations):
        worst = 0.0
        for k in range(n):
            kk = k if it % 2 == 0 else n - 1 - k
            s = limited_springs[kk]
            if not spring_alive[s]:
                continue
            a = spring_particle_a[s]
            b = spring_particle_b[s]
            rest = spring_rest_length_m[s]
            max_length = stretch * rest
            dx = particle_position_m[b, 0] - particle_position_m[a, 0]
            dy = particle_position_m[b, 1] - particle_position_m[a, 1]
            dz = particle_position_m[b, 2] - particle_position_m[a, 2]
            d2 = dx * dx + dy * dy + dz * dz
            mu = tension_scratch[kk]
            if mu == 0.0 and d2 <= max_length * max_length:
                continue  # slack and not pulling: nothing to do
            w_a = particle_inv_mass[a]
            w_b = particle_inv_mass[b]
            alpha = compliance_s2_per_kg
            w = w_a + w_b + alpha
            if w == 0.0:
                continue
            length = math.sqrt(d2)
            c = length - max_length
            residual = c - alpha * mu
            new_mu = mu + residual / w
            if new_mu < 0.0:
                new_mu = 0.0
            dmu = new_mu - mu
            tension_scratch[kk] = new_mu
            if residual / rest > worst and new_mu > 0.0:
                worst = residual / rest
            if dmu == 0.0 or length == 0.0:
                continue
            f = dmu / length
            particle_position_m[a, 0] += w_a * f * dx
            particle_position_m[a, 1] += w_a * f * dy
            particle_position_m[a, 2] += w_a * f * dz
            particle_position_m[b, 0] -= w_b * f * dx
            particle_position_m[b, 1] -= w_b * f * dy
            particle_position_m[b, 2] -= w_b * f * dz
        if worst <= tolerance:
            return it + 1, True
    return max_iterations, max_iterations == 0
