"""Analytic and conservation checks of the base-model step: free fall, attachments, contact."""
import numpy as np
from fraytool.sim.kernels.work_split import all_slots

from fraytool.scene import load_scene
from fraytool.sim import Simulation
from fraytool.sim.kernels.damping import pbd_damping
from helpers import small_scene

G = 9.81


def test_free_fall_matches_g_t2_over_2():
    sim = Simulation(small_scene(nx=4, ny=4, bend=0.0, shear=0.0))
    x0 = sim.state.particle_position_m[:16].copy()
    h = sim.dt_s
    n = 200
    for _ in range(n):
        sim.step()
    drop = x0[:, 1] - sim.state.particle_position_m[:16, 1]
    t = n * h
    # Symplectic Euler: y_n = y_0 - g h^2 n (n + 1) / 2 exactly, i.e. g t^2/2 + g t h/2.
    np.testing.assert_allclose(drop, G * h * h * n * (n + 1) / 2, rtol=1e-12)
    np.testing.assert_allclose(drop, G * t * t / 2, rtol=0, atol=G * t * h / 2 * 1.0001)
    np.testing.assert_allclose(sim.state.particle_position_m[:16, [0, 2]], x0[:, [0, 2]], atol=1e-15)


def test_attached_masses_follow_their_body_exactly():
    extra = """
[[bodies]]
name = "grip"
shape = "sphere"
radius_m = 0.004
motion = "kinematic"
path = [[0.0, -0.03, 0.1, -0.03], [0.01, -0.05, 0.12, -0.04], [0.02, -0.02, 0.08, -0.05]]
collide = false

[[attachments]]
body = "grip"
corner = "bottom_left"
corner_size = 2
"""
    sim = Simulation(small_scene(extra))
    held = sim.model.attachment_particle
    assert len(held) == 4
    offset = sim.state.particle_position_m[held] - sim.state.body_position_m[0]
    for _ in range(60):
        sim.step()
        t = sim.state.time_s
        path = sim.model.body_path[0]
        expected = np.array([np.interp(t, path[:, 0], path[:, 1 + d]) for d in range(3)])
        np.testing.assert_allclose(sim.state.body_position_m[0], expected, atol=1e-15)
        np.testing.assert_array_equal(sim.state.particle_position_m[held], sim.state.body_position_m[0] + offset)


def test_cloth_resting_on_sphere_does_not_sink():
    spec = load_scene("scenes/drape.toml")
    sim = Simulation(spec)
    ball = spec.bodies[0]
    surface = ball.radius_m + 0.5 * spec.cloth.thickness_m
    n = sim.model.crossing_count
    closest = np.inf
    for _ in sim.frames(24):
        d = np.linalg.norm(sim.state.particle_position_m[:n] - np.asarray(ball.position_m), axis=1)
        closest = min(closest, d.min())
    assert closest >= surface - 1e-9
    # and it really does rest on the ball (not hovering): some masses touch the surface
    assert closest <= surface + 1e-6


def _momenta(x, v, m):
    p = (m[:, None] * v).sum(axis=0)
    L = np.cross(x, m[:, None] * v).sum(axis=0)
    return p, L


def test_damping_preserves_linear_and_angular_momentum():
    rng = np.random.default_rng(11)
    n = 300
    x = rng.normal(size=(n, 3))
    v = rng.normal(size=(n, 3))
    m = rng.uniform(0.5, 2.0, n)
    w = 1.0 / m
    w[:10] = 0.0  # held particles are not part of the damped body
    free = w > 0
    p0, L0 = _momenta(x[free], v[free], m[free])
    v2 = v.copy()
    pbd_damping(*all_slots(len(x)), x, v2, m, w, 0.3)
    p1, L1 = _momenta(x[free], v2[free], m[free])
    np.testing.assert_allclose(p1, p0, rtol=1e-12, atol=1e-12 * np.abs(p0).max())
    np.testing.assert_allclose(L1, L0, rtol=1e-12, atol=1e-12 * np.abs(L0).max())
    np.testing.assert_array_equal(v2[~free], v[~free])
    # it does remove non-rigid motion: kinetic energy drops
    assert (m[free] * (v2[free] ** 2).sum(1)).sum() < (m[free] * (v[free] ** 2).sum(1)).sum()
    # and leaves a rigid motion alone
    omega = np.array([0.3, -1.0, 0.5])
    vr = np.array([1.0, 2.0, 3.0]) + np.cross(omega, x - (m[:, None] * x).sum(0) / m.sum())
    vr_all = vr.copy()
    pbd_damping(*all_slots(len(x)), x, vr_all, m, np.ones(n), 0.5)
    np.testing.assert_allclose(vr_all, vr, atol=1e-12)



def test_particle_lists_follow_splits_and_refinement():
    """The solver's lists (fraytool.sim.kernels.work_split.ParticleLists): free = inverse mass > 0,
    moving = active minus the slaved crossings, each cut into equal units covering the list; rebuilt
    when the state's topology epoch changes (a split, a refinement, another state), kept otherwise."""
    from fraytool.sim.builder import build_model
    from fraytool.sim.kernels.work_split import WORK_UNITS, ParticleLists

    model = build_model(small_scene(nx=6, ny=5))
    state = model.state()
    lists = ParticleLists()
    free, bounds = lists.free(state)
    assert free.tolist() == np.flatnonzero(state.particle_inv_mass > 0).tolist()
    assert bounds.shape == (WORK_UNITS + 1,) and bounds[0] == 0 and bounds[-1] == free.shape[0]
    assert (np.diff(bounds) >= 0).all() and np.ptp(np.diff(bounds)) <= 1
    slaved = np.array([3, 7], np.int32)
    lists.slaved_of = lambda _state: slaved  # as the solver sets it for a multi-resolution model
    moving, _ = lists.moving(state)
    expect = np.flatnonzero(state.particle_active)
    assert moving.tolist() == [p for p in expect.tolist() if p not in (3, 7)]
    assert lists.free(state)[0] is free  # nothing changed: the same list
    n = model.crossing_count
    state.particle_active[n + 5] = True  # a split activates a partner slot and gives it a mass
    state.particle_inv_mass[n + 5] = 1.0
    assert n + 5 not in lists.free(state)[0].tolist()  # edited by hand, no new epoch: the list is kept
    state.bump_topology()  # (the documented contract: a change of topology bumps the epoch)
    assert n + 5 in lists.free(state)[0].tolist() and n + 5 in lists.moving(state)[0].tolist()
    state.particle_inv_mass[2] = 0.0  # a refinement takes a crossing's mass away
    lists.slaved_of = lambda _state: np.array([2], np.int32)
    state.bump_topology()
    assert 2 not in lists.free(state)[0].tolist()
    assert lists.moving(state)[0].tolist().count(2) == 0
    other = model.state()
    assert lists.free(other)[0].tolist() == free.tolist()
