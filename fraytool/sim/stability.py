"""The explicit stability bound of the step (docs/method.md §4; issue "numerical stability").

Symplectic (semi-implicit) Euler, v += h M^-1 f(x); x += h v, applied to a linear spring network
is stable while h <= 2 / ω_max, with ω_max^2 the largest eigenvalue of M^-1 K: a mode of angular
frequency ω has the per-step amplification matrix [[1, -h ω^2], [h, 1 - h^2 ω^2]] (in (v, x)),
whose eigenvalues stay on the unit circle exactly while (h ω)^2 <= 4.

K is taken as the scalar stiffness Laplacian, each spring contributing k (e_a - e_b)(e_a - e_b)^T
in every direction. That is the Hessian along the spring; across it a spring stretched to length l
adds only k (1 - L / l) < k, so this K bounds the true Hessian of every stretched configuration
(and equals it for motion along a straight chain). Held masses (attachments) are fixed: their rows
and columns are removed. Every spring slot counts except the unborn shear twins; shear springs
count at full stiffness although they act only in compression. Springs of the yarn-level model
(docs/method.md §3.3) join half masses and are not part of this base-model bound.

Two estimates of ω_max bracket the true value:
- `gershgorin_omega_max`: Gershgorin's circle theorem, ω_max^2 <= max_i (2 / m_i) Σ_{s at i} k_s,
  an upper bound (so its step bound 2 / ω is safe); exact for an infinite chain.
- `power_iteration_omega_max`: power iteration on the symmetric M^-1/2 K M^-1/2 with the Rayleigh
  quotient, a lower bound that converges to ω_max (well within 1 % for the shipped scenes).
`stability_report` gives both and the step's ratio to each bound (for `fraytool check`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fraytool.sim.model import Model
from fraytool.kinds import SHEAR_TWIN

POWER_ITERATIONS = 2000
"""Default cap on power-iteration sweeps (at most about 0.3 s for the 4096-mass scene)."""
POWER_WORK_BUDGET = 50_000_000
"""`stability_report` (for `fraytool check`) stops power iteration after this many spring visits
(sweeps x springs): about a second on this machine, whatever the grid (2000 sweeps up to 25,000
springs, as in every shipped scene; 10 on a 1024 x 1024 grid). Unconverged, it is still a lower
bound of ω_max."""
POWER_TOLERANCE = 1e-4
"""Default stop: estimated relative error of ω_max^2, taken as (sweeps so far) x (relative change of the
Rayleigh quotient in the last sweep). When the top of the spectrum is crowded (large grids) the
quotient approaches λ_max like 1 / sweeps, so its error is about sweeps x its last change."""


@dataclass(frozen=True)
class StiffnessOperator:
    """The free part of M^-1/2 K M^-1/2 as arrays (base model, scalar per direction)."""

    spring_a: np.ndarray
    """First free-or-held end (crossing index) of each counted spring, shape (S,), int."""
    spring_b: np.ndarray
    """Second end, shape (S,), int."""
    spring_k: np.ndarray
    """Stiffness [N/m], shape (S,), float64."""
    inv_sqrt_mass: np.ndarray
    """1 / sqrt(m) [kg^-1/2] for free crossings, 0 for held ones, shape (crossing_count,)."""

    def apply(self, z: np.ndarray) -> np.ndarray:
        """y = M^-1/2 K M^-1/2 z (held entries of y are 0)."""
        n = self.inv_sqrt_mass.shape[0]
        u = z * self.inv_sqrt_mass
        f = self.spring_k * (u[self.spring_a] - u[self.spring_b])
        y = np.bincount(self.spring_a, f, minlength=n) - np.bincount(self.spring_b, f, minlength=n)
        return y * self.inv_sqrt_mass

    def dense(self) -> np.ndarray:
        """The full matrix (small models only: tests and oracles)."""
        n = self.inv_sqrt_mass.shape[0]
        return np.stack([self.apply(e) for e in np.eye(n)], axis=1)


def free_crossings(model: Model) -> np.ndarray:
    """True for crossings not held by a rigid body, shape (crossing_count,), bool."""
    n = model.crossing_count
    free = np.ones(n, bool)
    free[model.attachment_particle[model.attachment_particle < n]] = False
    return free


def stiffness_operator(model: Model) -> StiffnessOperator:
    counted = model.spring_kind != SHEAR_TWIN
    free = free_crossings(model)
    return StiffnessOperator(
        spring_a=model.spring_crossing_a[counted].astype(np.int64),
        spring_b=model.spring_crossing_b[counted].astype(np.int64),
        spring_k=model.spring_base_stiffness_n_per_m[counted].astype(float),
        inv_sqrt_mass=np.where(free, 1.0 / np.sqrt(model.crossing_mass_kg), 0.0),
    )


def gershgorin_omega_max(model: Model) -> float:
    """Upper bound of the highest angular frequency ω_max [rad/s] of the base-model cloth."""
    n = model.crossing_count
    alive = model.spring_kind != SHEAR_TWIN
    row = np.zeros(n)
    k = model.spring_base_stiffness_n_per_m[alive]
    np.add.at(row, model.spring_crossing_a[alive], k)
    np.add.at(row, model.spring_crossing_b[alive], k)
    free = free_crossings(model)
    if not free.any():
        return 0.0
    return float(math.sqrt(np.max(2.0 * row[free] / model.crossing_mass_kg[free])))


@dataclass(frozen=True)
class PowerIteration:
    omega_max: float
    """Estimate of ω_max [rad/s] (square root of the Rayleigh quotient; never above the true value)."""
    iterations: int
    converged: bool
    """True when the estimated relative error of ω_max^2 fell below the tolerance before the cap."""
    residual: float
    """|A z - λ z| / λ of the final unit vector z: some eigenvalue lies within residual * λ of λ."""


def power_iteration(model: Model, iterations: int = POWER_ITERATIONS, tolerance: float = POWER_TOLERANCE,
                    seed: int = 0) -> PowerIteration:
    """Power iteration for the largest eigenvalue of M^-1/2 K M^-1/2, from a seeded random start."""
    op = stiffness_operator(model)
    free = op.inv_sqrt_mass > 0.0
    if not free.any() or op.spring_k.size == 0:
        return PowerIteration(0.0, 0, True, 0.0)
    z = np.random.default_rng(seed).standard_normal(free.shape[0]) * free
    z /= np.linalg.norm(z)
    lam = 0.0
    y = op.apply(z)
    for it in range(1, iterations + 1):
        lam_new = float(z @ y)  # Rayleigh quotient of the unit vector z
        norm = float(np.linalg.norm(y))
        if norm == 0.0:
            return PowerIteration(0.0, it, True, 0.0)  # no spring touches a free mass
        converged = it > 1 and it * abs(lam_new - lam) <= tolerance * lam_new
        lam = lam_new
        z = y / norm
        y = op.apply(z)
        if converged:
            break
    lam_z = float(z @ y)
    residual = float(np.linalg.norm(y - lam_z * z)) / lam_z if lam_z > 0 else 0.0
    lam = max(lam, lam_z)
    return PowerIteration(math.sqrt(max(lam, 0.0)), it, converged, residual)


def power_iteration_omega_max(model: Model, iterations: int = POWER_ITERATIONS,
                              tolerance: float = POWER_TOLERANCE, seed: int = 0) -> float:
    """Estimate of ω_max [rad/s] by power iteration (a lower bound; Gershgorin gives an upper one)."""
    return power_iteration(model, iterations, tolerance, seed).omega_max


def stable_step_bound_s(model: Model) -> float:
    """Largest stable explicit step by Gershgorin, 2 / ω_max [s] (inf for a cloth without springs).
    Safe: the true bound is at least this."""
    w = gershgorin_omega_max(model)
    return math.inf if w == 0.0 else 2.0 / w


def stability_report(model: Model, step_s: float) -> dict:
    """Both estimates of ω_max, the step bounds 2 / ω_max they give, and the step's ratio to each.

    Power iteration stops at tolerance or after `power_sweep_cap` sweeps (POWER_WORK_BUDGET), so that
    `check` of a 1024 x 1024 grid takes seconds, not minutes.

    Keys: omega_max_gershgorin_rad_s, omega_max_power_rad_s, power_iterations, power_converged, power_sweep_cap,
    stability_bound_gershgorin_s (safe), stability_bound_power_s (sharp), step_s,
    step_over_bound_gershgorin, step_over_bound_power, stiffest_spring_n_per_m, lightest_mass_kg.
    """
    w_g = gershgorin_omega_max(model)
    counted = model.spring_kind != SHEAR_TWIN
    sweeps = int(min(POWER_ITERATIONS, max(10, POWER_WORK_BUDGET // max(int(counted.sum()), 1))))
    p = power_iteration(model, iterations=sweeps)
    free = free_crossings(model)

    def bound(w: float) -> float:
        return math.inf if w == 0.0 else 2.0 / w

    return {
        "omega_max_gershgorin_rad_s": w_g,
        "omega_max_power_rad_s": p.omega_max,
        "power_iterations": p.iterations,
        "power_converged": p.converged,
        "power_sweep_cap": sweeps,
        "stability_bound_gershgorin_s": bound(w_g),
        "stability_bound_power_s": bound(p.omega_max),
        "step_s": step_s,
        "step_over_bound_gershgorin": step_s * w_g / 2.0,
        "step_over_bound_power": step_s * p.omega_max / 2.0,
        "stiffest_spring_n_per_m": float(model.spring_base_stiffness_n_per_m[counted].max()) if counted.any() else 0.0,
        "lightest_mass_kg": float(model.crossing_mass_kg[free].min()) if free.any() else math.inf,
    }
