"""After strain limiting every structural spring is within the limit, or the cap was reported."""
import math

import numpy as np
import pytest

from fraytool.sim import build_model
from fraytool.sim.kernels.strain_limit import limit_strain
from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from helpers import small_scene


def _structural_strain(model, state, x):
    sel = (model.spring_kind == STRUCT_WEFT) | (model.spring_kind == STRUCT_WARP)
    d = x[state.spring_particle_b[sel]] - x[state.spring_particle_a[sel]]
    return np.linalg.norm(d, axis=1) / model.spring_rest_length_m[sel] - 1.0


def _run(model, state, x, max_iterations, inv_mass=None):
    limited = np.nonzero(model.spring_kind <= STRUCT_WARP)[0].astype(np.int32)
    return limit_strain(limited, model.spring_rest_length_m, 0.10, 1e-6, max_iterations,
                        state.particle_inv_mass if inv_mass is None else inv_mass,
                        state.spring_particle_a, state.spring_particle_b, state.spring_alive, x)


def test_within_limit_when_converged():
    model = build_model(small_scene(nx=10, ny=10))
    state = model.state()
    rng = np.random.default_rng(5)
    x = state.particle_position_m.copy()
    x[: model.crossing_count] *= rng.uniform(1.0, 1.6, size=(model.crossing_count, 1))  # stretch the cloth
    x[: model.crossing_count] += rng.normal(scale=0.002, size=(model.crossing_count, 3))
    assert _structural_strain(model, state, x).max() > 0.3
    iterations, converged = _run(model, state, x, 500)
    assert converged and 1 < iterations < 500
    assert _structural_strain(model, state, x).max() <= 0.10 + 2e-6


def test_cap_is_reported_when_limit_cannot_be_met():
    model = build_model(small_scene(nx=6, ny=2))
    state = model.state()
    x = state.particle_position_m.copy()
    inv = state.particle_inv_mass.copy()
    # hold both ends of the cloth far apart: the limit is infeasible
    left = np.arange(0, 12, 6)
    right = left + 5
    x[right, 0] += 0.02
    inv[left] = 0.0
    inv[right] = 0.0
    iterations, converged = _run(model, state, x, 25, inv)
    assert iterations == 25 and not converged
    assert _structural_strain(model, state, x).max() > 0.10


def _chain(n_springs, rest_m, stretch):
    """A straight chain of n_springs springs along x, ends held (inverse mass 0), every spring
    stretched to `stretch` x rest."""
    x = np.zeros((n_springs + 1, 3))
    x[:, 0] = np.arange(n_springs + 1) * rest_m * stretch
    w = np.ones(n_springs + 1)
    w[0] = w[-1] = 0.0
    a = np.arange(n_springs, dtype=np.int32)
    return x, w, a, a + 1


def test_compliant_limit_converges_to_the_implicit_step_of_a_stiff_yarn():
    """Held ends 15 % apart and a 10 % limit: the limit cannot be met. As a compliant constraint
    (XPBD, k_limit past the limit) the sweeps converge to the minimiser of
        sum_i m / (2 h^2) (x_i - x0_i)^2 + sum_s k_limit / 2 (x_{s+1} - x_s - (1 + limit) L)^2,
    one implicit Euler step of a yarn that stiffens past the limit (every spring stays past it here,
    so the minimiser solves a tridiagonal linear system: the independent reference). The hard
    projection instead stops at its cap with an uneven residual."""
    from strain_reference import limit_strain_compliant

    n, rest, limit, k_limit, h, mass = 12, 0.004, 0.10, 400.0, 2e-4, 5e-6
    x, w, a, b = _chain(n, rest, 1.15)
    w[1:-1] = 1.0 / mass
    x[1:-1, 0] += np.random.default_rng(3).uniform(-0.1, 0.1, n - 1) * rest  # uneven to start
    x0 = x.copy()
    rest_lengths = np.full(n, rest)
    alive = np.ones(n, bool)
    springs = np.arange(n, dtype=np.int32)
    hard = x.copy()
    _, hard_converged = limit_strain(springs, rest_lengths, limit, 1e-12, 200, w, a, b, alive, hard)
    assert not hard_converged  # the hard limit cannot be met: it stops at its cap
    it, converged = limit_strain_compliant(springs, rest_lengths, limit, 1e-13, 100000, 1.0 / (k_limit * h * h),
                                           w, a, b, alive, np.zeros(n), x)
    assert converged
    # reference: (m/h^2 + 2k) x_i - k x_{i-1} - k x_{i+1} = m/h^2 x0_i (interior; the l_max terms cancel)
    m_h2 = mass / h ** 2
    A = np.zeros((n - 1, n - 1))
    rhs = m_h2 * x0[1:-1, 0]
    for r in range(n - 1):
        A[r, r] = m_h2 + 2 * k_limit
        if r > 0:
            A[r, r - 1] = -k_limit
        if r < n - 2:
            A[r, r + 1] = -k_limit
    rhs[0] += k_limit * x0[0, 0]
    rhs[-1] += k_limit * x0[-1, 0]
    reference = np.linalg.solve(A, rhs)
    assert (np.diff(np.concatenate([[x0[0, 0]], reference, [x0[-1, 0]]])) > (1 + limit) * rest).all()
    np.testing.assert_allclose(x[1:-1, 0], reference, atol=1e-10)
    assert np.ptp(np.diff(x[:, 0])) < np.ptp(np.diff(x0[:, 0]))  # tension evens the yarn out


def test_compliant_limit_with_infinite_stiffness_is_the_hard_projection():
    from fraytool.sim.kernels.strain_limit import limit_strain
    from strain_reference import limit_strain_compliant

    n, rest = 8, 0.004
    x, w, a, b = _chain(n, rest, 1.3)
    w[-1] = 1.0  # one free end: feasible
    springs = np.arange(n, dtype=np.int32)
    rest_lengths = np.full(n, rest)
    alive = np.ones(n, bool)
    hard = x.copy()
    limit_strain(springs, rest_lengths, 0.1, 1e-12, 5000, w, a, b, alive, hard)
    soft = x.copy()
    limit_strain_compliant(springs, rest_lengths, 0.1, 1e-12, 5000, 0.0, w, a, b, alive, np.zeros(n), soft)
    np.testing.assert_allclose(soft, hard, atol=1e-12)


def _stretch_history(c_n_s_per_m, k_limit=400.0, mass=5e-6, rest=0.004, limit=0.10, v0=0.5, dt=2e-7, t_end=6e-4):
    """Two free masses joined by one spring, starting exactly at the limit and moving apart at v0:
    each step x += v dt, then the dashpot past the limit, then the compliant limit (as the solver's
    strain-limiting stage does), v = (x - x_prev) / dt. Returns times and stretch past the limit."""
    from fraytool.sim.kernels.strain_limit import damp_overstretched
    from strain_reference import limit_strain_compliant

    x = np.array([[0.0, 0.0, 0.0], [(1 + limit) * rest, 0.0, 0.0]])
    v = np.array([[-v0 / 2, 0.0, 0.0], [v0 / 2, 0.0, 0.0]])
    w = np.full(2, 1.0 / mass)
    a, b = np.array([0], np.int32), np.array([1], np.int32)
    springs, rest_lengths, alive = np.array([0], np.int32), np.array([rest]), np.array([True])
    times, stretch = [], []
    for step in range(int(round(t_end / dt))):
        prev = x.copy()
        x += v * dt
        damp_overstretched(springs, rest_lengths, limit, c_n_s_per_m, dt, w, a, b, alive, prev, x)
        limit_strain_compliant(springs, rest_lengths, limit, 1e-14, 1000, 1.0 / (k_limit * dt * dt), w, a, b, alive,
                               np.zeros(1), x)
        v = (x - prev) / dt
        times.append((step + 1) * dt)
        stretch.append(x[1, 0] - x[0, 0] - (1 + limit) * rest)
    return np.array(times), np.array(stretch)


@pytest.mark.parametrize("zeta", [0.0, 0.5, 1.0])
def test_dashpot_past_the_limit_follows_the_damped_oscillator(zeta):
    """While a spring is past its limit and lengthening, the compliant limit (k_limit) and the
    dashpot (c) make it a damped oscillator in the stretch u: mu u'' = -k u - c u', mu = m/2 the
    reduced mass, u(0) = 0, u'(0) = v0. The largest stretch and when it comes, against the
    analytic solution (the dashpot acts only while lengthening, which is exactly up to that peak)."""
    k, mass, v0 = 400.0, 5e-6, 0.5
    mu = mass / 2
    omega = math.sqrt(k / mu)
    c = 2 * zeta * math.sqrt(k * mu)
    t, u = _stretch_history(c, k_limit=k, mass=mass, v0=v0)
    if zeta < 1.0:
        wd = omega * math.sqrt(1 - zeta ** 2)
        t_peak = math.atan2(wd, zeta * omega) / wd
        u_peak = v0 / wd * math.exp(-zeta * omega * t_peak) * math.sin(wd * t_peak)
    else:
        t_peak = 1 / omega
        u_peak = v0 * t_peak * math.exp(-1)
    i = int(np.argmax(u))
    assert abs(u[i] - u_peak) <= 0.01 * u_peak
    assert abs(t[i] - t_peak) <= 0.01 * t_peak


def test_dashpot_keeps_momentum_and_leaves_slack_springs_alone():
    from fraytool.sim.kernels.strain_limit import damp_overstretched

    rng = np.random.default_rng(4)
    n, rest, limit = 8, 0.004, 0.1
    x, w, a, b = _chain(n, rest, 1.0)
    w[:] = rng.uniform(1e5, 3e5, n + 1)
    prev = x + rng.normal(0.0, 1e-4, x.shape)
    x[4:, 0] += 0.2 * rest  # spring 3 stretched 20 %: past the limit; the others at rest length
    prev[4:, 0] += 0.19 * rest - 1e-4  # ... and lengthening in this step
    springs, rest_lengths, alive = np.arange(n, dtype=np.int32), np.full(n, rest), np.ones(n, bool)
    before = x.copy()
    damp_overstretched(springs, rest_lengths, limit, 0.1, 2e-4, w, a, b, alive, prev, x)
    moved = np.flatnonzero(np.abs(x - before).max(axis=1) > 0)
    assert set(moved) == {3, 4}  # only the ends of the stretched spring
    m = 1.0 / w
    np.testing.assert_allclose((m[:, None] * (x - before)).sum(axis=0), 0.0, atol=1e-18)
    assert x[4, 0] - x[3, 0] < before[4, 0] - before[3, 0]  # its stretching is slowed


def _grid_pulled_apart(nx=24, ny=8, stretch=1.18, seed=4):
    """A cloth model whose left and right columns are held (inverse mass 0) and pulled apart so
    that the limit cannot be met, its free crossings jittered: (model, state, x, inverse masses)."""
    model = build_model(small_scene(nx=nx, ny=ny))
    state = model.state()
    x = state.particle_position_m.copy()
    n = model.crossing_count
    x0 = x[:n, 0].min()
    x[:n, 0] = x0 + (x[:n, 0] - x0) * stretch
    x[:n] += np.random.default_rng(seed).normal(scale=2e-4, size=(n, 3))
    inv = state.particle_inv_mass.copy()
    held = np.isclose(state.particle_position_m[:n, 0], state.particle_position_m[:n, 0].min()) | np.isclose(
        state.particle_position_m[:n, 0], state.particle_position_m[:n, 0].max())
    inv[:n][held] = 0.0
    return model, state, x, inv


def test_yarn_line_solve_reaches_the_point_solve_fixed_point_in_far_fewer_sweeps():
    """`limit_strain_lines` (a tridiagonal solve per yarn, block Gauss-Seidel) and
    `limit_strain_compliant` (point Gauss-Seidel, the slow reference) solve the same XPBD
    system: converged tightly, they give the same positions. On a cloth pulled apart by its held
    edges the line solve gets there in a small fraction of the point solve's sweeps."""
    from fraytool.sim.kernels.strain_limit import limit_strain_lines
    from strain_reference import limit_strain_compliant
    from fraytool.sim.stages.core import colour_ordered_structural_springs, yarn_line_springs

    model, state, x, inv = _grid_pulled_apart()
    alpha = 1.0 / (400.0 * 2e-4 ** 2)
    assert _structural_strain(model, state, x).max() > 0.15
    point = x.copy()
    springs = colour_ordered_structural_springs(model)
    it_point, ok_point = limit_strain_compliant(springs, model.spring_rest_length_m, 0.10, 1e-11, 200000, alpha, inv,
                                               state.spring_particle_a, state.spring_particle_b, state.spring_alive,
                                               np.zeros(springs.shape[0]), point)
    lines = x.copy()
    ls, starts, groups = yarn_line_springs(model)
    n = ls.shape[0]
    it_lines, ok_lines = limit_strain_lines(
        ls, starts, groups, (0.10, 1e-11, 200000), alpha,
        (model.spring_rest_length_m, inv, state.spring_particle_a, state.spring_particle_b, state.spring_alive),
        (np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros((n, 3)), np.zeros(starts.shape[0] - 1),
         np.zeros(starts.shape[0] - 1, np.int64), np.zeros(len(lines), np.int64)), lines)
    assert ok_point and ok_lines
    assert _structural_strain(model, state, lines).max() > 0.11  # infeasible: the yarns stretch past the limit
    # XPBD on nonlinear constraints accumulates each correction along the direction it had when made,
    # so the two orders of update end at slightly different points of the solution set: within a
    # 500th of a spacing, the strains (up to 23 %) within 0.003
    assert np.abs(lines - point).max() < 2e-3 * model.spacing_m
    np.testing.assert_allclose(_structural_strain(model, state, lines), _structural_strain(model, state, point),
                               atol=3e-3)
    assert it_lines * 5 < it_point, (it_lines, it_point)


def test_yarn_line_solve_matches_the_implicit_chain_step():
    """One straight yarn held at both ends 15 % apart (directions fixed, so the implicit step is
    the exact fixed point): the line solve converges to it, as the point solve does (tested against
    the tridiagonal reference above), in a few sweeps."""
    from fraytool.sim.kernels.strain_limit import limit_strain_lines
    from strain_reference import limit_strain_compliant

    n, rest, limit, k_limit, h, mass = 12, 0.004, 0.10, 400.0, 2e-4, 5e-6
    x, w, a, b = _chain(n, rest, 1.15)
    w[1:-1] = 1.0 / mass
    x[1:-1, 0] += np.random.default_rng(3).uniform(-0.1, 0.1, n - 1) * rest
    springs = np.arange(n, dtype=np.int32)
    rest_lengths = np.full(n, rest)
    alive = np.ones(n, bool)
    alpha = 1.0 / (k_limit * h * h)
    point = x.copy()
    limit_strain_compliant(springs, rest_lengths, limit, 1e-13, 100000, alpha, w, a, b, alive, np.zeros(n), point)
    z = np.zeros(n)
    it, converged = limit_strain_lines(springs, np.array([0, n], np.int64), np.array([0, 1], np.int64),
                                       (limit, 1e-13, 1000), alpha, (rest_lengths, w, a, b, alive),
                                       (z.copy(), z.copy(), z.copy(), z.copy(), np.zeros((n, 3)), np.zeros(1),
                                        np.zeros(1, np.int64), np.zeros(len(x), np.int64)), x)
    assert converged and it < 20
    np.testing.assert_allclose(x, point, atol=1e-10)


def test_dashpot_past_the_limit_decays_as_the_exact_exponential_at_any_step():
    """Two free masses on a line past the limit, moving apart at v0: under the dashpot alone the
    stretch rate obeys dv/dt = -c (w_a + w_b) v, so after T it is v0 exp(-c (w_a + w_b) T), whatever
    the step (one step of g = 3.6, about half the figure scenes' g, included). Momentum is kept."""
    from fraytool.sim.kernels.strain_limit import damp_overstretched

    mass, rest, limit, c, v0, T = 5e-6, 0.004, 0.10, 0.0894, 0.3, 1e-4
    w = np.full(2, 1.0 / mass)
    a, b = np.array([0], np.int32), np.array([1], np.int32)
    for steps in (1, 4, 32):
        dt = T / steps
        x = np.array([[0.0, 0.0, 0.0], [1.3 * rest, 0.0, 0.0]])
        v = np.array([[-v0 / 2, 0.0, 0.0], [v0 / 2, 0.0, 0.0]])
        for _ in range(steps):
            prev = x.copy()
            x = x + v * dt
            damp_overstretched(np.array([0], np.int32), np.array([rest]), limit, c, dt, w, a, b, np.array([True]),
                               prev, x)
            v = (x - prev) / dt
        np.testing.assert_allclose(v[1, 0] - v[0, 0], v0 * math.exp(-c * 2.0 / mass * T), rtol=1e-8)
        assert abs(v[0, 0] + v[1, 0]) < 1e-12  # momentum


def _serial_and_grouped(model, state, springs, starts, x0, w, tolerance, sweeps):
    """(positions, result) of `limit_strain` and of `limit_strain_groups` from x0, limit 5 %."""
    from fraytool.sim.kernels.strain_limit import limit_strain, limit_strain_groups

    serial, grouped = x0.copy(), x0.copy()
    a, b, alive = state.spring_particle_a, state.spring_particle_b, state.spring_alive
    got_serial = limit_strain(springs, model.spring_rest_length_m, 0.05, tolerance, sweeps, w, a, b, alive, serial)
    got_grouped = limit_strain_groups(springs, starts, (0.05, tolerance, sweeps),
                                      (model.spring_rest_length_m, w, a, b, alive),
                                      np.zeros(springs.shape[0], np.int64), np.zeros(len(grouped), np.int64), grouped)
    return (serial, got_serial), (grouped, got_grouped)


def test_colour_groups_in_parallel_match_the_serial_sweeps_bit_for_bit():
    """limit_strain_groups (each colour group in parallel) moves every particle exactly as limit_strain
    over the same list does, and reports the same sweeps."""
    from fraytool.sim.stages.core import colour_groups

    model = build_model(small_scene(nx=9, ny=7))
    state = model.state()
    springs, starts = colour_groups(model)
    rng = np.random.default_rng(11)
    x0 = state.particle_position_m + rng.normal(scale=0.0012, size=state.particle_position_m.shape)
    w = state.particle_inv_mass.copy()
    w[0] = 0.0  # a held corner
    (serial, got_serial), (grouped, got_grouped) = _serial_and_grouped(model, state, springs, starts, x0, w, 1e-9, 7)
    assert not np.array_equal(serial, x0)  # it projected something
    assert got_serial == got_grouped
    assert serial.tobytes() == grouped.tobytes()


def test_grouped_sweeps_that_skip_untouched_springs_match_the_serial_sweeps_on_a_pulled_corner():
    """Only a corner pulled out: most springs are within the limit and untouched after the first
    sweep, so `limit_strain_groups` skips them (its docstring); over 40 sweeps it still ends on the
    same bits as the serial `limit_strain`, which projects every spring every sweep."""
    from fraytool.sim.stages.core import colour_groups

    model = build_model(small_scene(nx=24, ny=20))
    state = model.state()
    springs, starts = colour_groups(model)
    x0 = state.particle_position_m.copy()
    corner = np.argmax(x0[:, 0] + x0[:, 2])
    x0[corner] += np.array([0.02, 0.01, 0.02])          # five spacings out
    w = state.particle_inv_mass.copy()
    w[corner] = 0.0                                      # held there
    (serial, got_serial), (grouped, got_grouped) = _serial_and_grouped(model, state, springs, starts, x0, w, 1e-12,
                                                                       40)
    moved = np.linalg.norm(serial - x0, axis=1) > 0
    assert 0 < moved.sum() < 0.5 * len(moved)          # a part of the cloth follows the corner
    assert got_serial == got_grouped and got_serial[0] > 5
    assert serial.tobytes() == grouped.tobytes()
