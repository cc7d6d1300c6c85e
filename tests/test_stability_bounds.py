"""Estimates of ω_max (fraytool.sim.stability) against a dense eigenvalue oracle, and their order:
power iteration <= exact <= Gershgorin; the report `fraytool check` can print; determinism."""
import dataclasses as dc
import math

import numpy as np
import pytest

from fraytool.scene import load_scene, parse_scene
from fraytool.sim import build_model
from fraytool.kinds import SHEAR_TWIN
from fraytool.sim.stability import (
    gershgorin_omega_max,
    power_iteration,
    power_iteration_omega_max,
    stability_report,
    stable_step_bound_s,
    stiffness_operator,
)

CLOTH = """
[scene]
name = "grid"
seed = 2

[time]
step_s = 2e-4
steps_per_frame = 5
frames = 3

[cloth]
warp_yarns = {nx}
weft_yarns = {ny}
spacing_m = 0.005
thickness_m = 0.0008
mass_per_crossing_kg = 2.0e-5
plane = "xy"

[cloth.springs]
structural_n_per_m = 30.0
bend_n_per_m = 1.5
shear_n_per_m = 4.0
damping = 0.01
"""

HOLD = """
[[bodies]]
name = "rail"
shape = "sphere"
radius_m = 0.001
collide = false

[[attachments]]
body = "rail"
corner = "top_left"
corner_size = 2
"""


def grid(nx=6, ny=5, held=True):
    return build_model(parse_scene(CLOTH.format(nx=nx, ny=ny) + (HOLD if held else ""), "grid.toml"))


def dense_omega_max(model) -> float:
    """Oracle: M^-1 K assembled entry by entry from the springs (held crossings removed)."""
    n = model.crossing_count
    kmat = np.zeros((n, n))
    for s in range(model.spring_count):
        if model.spring_kind[s] == SHEAR_TWIN:
            continue
        a, b, k = model.spring_crossing_a[s], model.spring_crossing_b[s], model.spring_base_stiffness_n_per_m[s]
        kmat[a, a] += k
        kmat[b, b] += k
        kmat[a, b] -= k
        kmat[b, a] -= k
    free = np.ones(n, bool)
    free[model.attachment_particle] = False
    mk = kmat[np.ix_(free, free)] / model.crossing_mass_kg[free][:, None]
    return math.sqrt(max(np.linalg.eigvals(mk).real))


@pytest.mark.parametrize("held", [True, False], ids=["held corner", "free"])
def test_power_iteration_matches_dense_oracle_and_is_bracketed(held):
    model = grid(held=held)
    exact = dense_omega_max(model)
    p = power_iteration(model)
    assert p.converged
    assert p.omega_max == pytest.approx(exact, rel=1e-4)
    assert p.omega_max <= exact * (1 + 1e-12)  # a Rayleigh quotient never exceeds λ_max
    assert gershgorin_omega_max(model) >= exact * (1 - 1e-12)


def test_operator_is_the_symmetric_mass_scaled_stiffness():
    model = grid(4, 3)
    a = stiffness_operator(model).dense()
    np.testing.assert_allclose(a, a.T, atol=1e-6 * np.abs(a).max())
    held = model.attachment_particle
    assert not a[held].any() and not a[:, held].any()


def test_unequal_masses_are_weighted():
    model = grid(5, 4)
    rng = np.random.default_rng(3)
    model = dc.replace(model, crossing_mass_kg=model.crossing_mass_kg * rng.uniform(0.2, 5.0, model.crossing_count))
    assert power_iteration_omega_max(model) == pytest.approx(dense_omega_max(model), rel=1e-4)


def test_gershgorin_is_safe_but_not_sharp_for_a_grid():
    model = grid(8, 8, held=False)
    g, p = gershgorin_omega_max(model), power_iteration_omega_max(model)
    assert 1.0 < g / p < 1.5  # Gershgorin is safe but not sharp for a finite grid


def test_report_for_check():
    spec = load_scene("scenes/drape.toml")
    model = build_model(spec)
    r = stability_report(model, spec.time.step_s)
    assert r["stability_bound_gershgorin_s"] == pytest.approx(stable_step_bound_s(model))
    assert r["stability_bound_gershgorin_s"] <= r["stability_bound_power_s"]
    assert r["step_over_bound_power"] == pytest.approx(spec.time.step_s / r["stability_bound_power_s"])
    assert r["step_over_bound_power"] < 1.0 and r["power_converged"]
    assert r["stiffest_spring_n_per_m"] == spec.cloth.springs.structural_n_per_m
    assert r["lightest_mass_kg"] == spec.cloth.mass_per_crossing_kg
    assert stability_report(model, spec.time.step_s) == r  # seeded: the same numbers every time


def test_no_free_mass_or_no_spring_gives_no_bound():
    model = grid(3, 3, held=False)
    model = dc.replace(model, spring_base_stiffness_n_per_m=np.zeros(model.spring_count))
    assert power_iteration_omega_max(model) == 0.0
    assert stable_step_bound_s(model) == math.inf
