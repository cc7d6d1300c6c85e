"""Air drag and wind (docs/wind.md) against the drag law's own consequences: the terminal speed of a cloth falling
face-down, the angle a cloth hanging in a steady wind settles at, the yarn-end drag of the cylinder law, and the
gusts' strength and correlation lengths. Each figure moves well past its tolerance with the force off or doubled
(the tolerances are a few per cent; off or doubled changes each by tens of per cent)."""
import math

import numpy as np
import pytest

from fraytool.scene import parse_scene
from fraytool.sim import Simulation, build_model
from fraytool.sim.air import air_model, air_velocity_m_s, gust_modes
from fraytool.sim.kernels.air import accumulate_air_drag, crossing_centres
from helpers import small_scene_text

RHO = 1.2
MASS_KG = 2.0e-5  # helpers' mass_per_crossing_kg
SPACING_M = 0.005
G = 9.81


def _air_scene(drag_normal=1.2, drag_tangential=0.02, world="", extra="", **overrides) -> str:
    text = small_scene_text(**overrides)
    text = text.replace('weave = "plain"', f'weave = "plain"\ndrag_normal = {drag_normal}\n'
                                           f'drag_tangential = {drag_tangential}')
    return text.replace("gravity_m_s2 = [0.0, -9.81, 0.0]", "gravity_m_s2 = [0.0, -9.81, 0.0]\n" + world) + extra


def _run(sim: Simulation, seconds: float) -> None:
    for _ in range(int(round(seconds / sim.dt_s))):
        sim.solver.step(sim.state, sim.dt_s)


def test_flat_cloth_falls_face_down_at_the_terminal_speed_of_the_drag_law():
    """m g = 1/2 rho C_n A v^2 with A = spacing^2 per crossing: v_t = sqrt(2 m g / (rho C_n A)); on the way there
    v(t) = v_t tanh(g t / v_t) (quadratic drag from rest)."""
    cn = 1.2
    sim = Simulation(parse_scene(_air_scene(drag_normal=cn, nx=10, ny=10), "fall.toml"))
    v_t = math.sqrt(2.0 * MASS_KG * G / (RHO * cn * SPACING_M ** 2))
    _run(sim, 0.3)
    v = sim.state.particle_velocity_m_s[:sim.model.crossing_count, 1]
    expected = v_t * math.tanh(G * 0.3 / v_t)
    assert abs(-v.mean() - expected) < 0.02 * expected, (-v.mean(), expected)
    _run(sim, 1.2)  # 1.5 s: tanh(4.5) = 0.9998
    v = sim.state.particle_velocity_m_s[:sim.model.crossing_count, 1]
    assert abs(-v.mean() - v_t) < 0.02 * v_t, (-v.mean(), v_t)
    assert v.std() < 1e-6 * v_t  # face-down, every crossing alike


def _hanging_angle_deg(wind_m_s: float, cn: float) -> float:
    """phi with sigma g sin(phi) = 1/2 rho C_n W^2 cos^2(phi): a straight hanging sheet feels no net normal load
    (sigma = mass per area), by bisection."""
    sigma = MASS_KG / SPACING_M ** 2
    lo, hi = 0.0, math.pi / 2
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if sigma * G * math.sin(mid) < 0.5 * RHO * cn * wind_m_s ** 2 * math.cos(mid) ** 2:
            lo = mid
        else:
            hi = mid
    return math.degrees(lo)


HANGING = """
[[bodies]]
name = "bar"
shape = "box"
half_extents_m = [0.04, 0.002, 0.002]
position_m = [0.0, 0.2, 0.0]
collide = false

[[attachments]]
body = "bar"
edge = "top"
"""


def _hang(wind_m_s: float, cn: float, **kw) -> float:
    text = _air_scene(drag_normal=cn, drag_tangential=0.02, world=f"wind_m_s = [0.0, 0.0, {wind_m_s}]", extra=HANGING,
                      nx=8, ny=24, damping=0.02, **kw)
    text = text.replace('origin_m = [-0.03, 0.1, -0.03]', 'origin_m = [-0.0175, 0.085, 0.0]').replace(
        'plane = "xz"', 'plane = "xy"')
    sim = Simulation(parse_scene(text, "hang.toml"))
    _run(sim, 2.5)
    m = sim.model
    x = sim.state.particle_position_m[:m.crossing_count]
    top, bottom = x[m.crossing_grid_j == m.crossing_grid_j.max()], x[m.crossing_grid_j == 0]
    drop = top.mean(axis=0) - bottom.mean(axis=0)
    return math.degrees(math.atan2(-drop[2], drop[1]))


def test_cloth_hanging_in_a_steady_wind_settles_at_the_angle_that_balances_drag_and_gravity():
    wind, cn = 3.0, 1.2
    expected = _hanging_angle_deg(wind, cn)
    assert 25.0 < expected < 50.0  # a clear lean, far from hanging straight or flying flat
    measured = _hang(wind, cn)
    assert abs(measured - expected) < 0.05 * expected, (measured, expected)
    doubled = _hang(wind, 2.0 * cn)  # the check can fail: twice the drag leans the cloth far more
    assert abs(doubled - expected) > 0.2 * expected, (doubled, expected)


def _loose_yarn_forces(wind):
    """Drag on a 3 x 2 cloth with its warp springs cut: every mass is on a loose weft yarn (a cylinder)."""
    from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT

    model = build_model(parse_scene(_air_scene(drag_normal=1.1, drag_tangential=0.05, nx=3, ny=2), "yarn.toml"))
    state = model.state()
    assert state.spring_alive[model.spring_kind == STRUCT_WARP].all()  # the warp yarns are there at rest ...
    alive = state.spring_alive & (model.spring_kind == STRUCT_WEFT)  # ... and the call sees them cut
    centre = np.zeros((model.crossing_count, 3))
    crossing_centres(model.crossing_count, state.particle_position_m, state.particle_mass_kg, state.particle_active,
                     centre)
    air = np.tile(np.asarray(wind, float), (model.crossing_count, 1))
    force = np.zeros_like(state.particle_position_m)
    accumulate_air_drag(air_model(model), state.particle_position_m, state.particle_velocity_m_s,
                        state.particle_mass_kg, state.particle_active, alive, state.spring_particle_a,
                        state.spring_particle_b, centre, air, 1e-4, force)
    return model, force


def test_a_loose_yarn_feels_the_cylinder_law_across_and_along_it():
    """A mass on a loose yarn is spacing / 2 of cylinder per live segment, of diameter thickness: across the flow
    1/2 rho C_n d l W^2, along it 1/2 rho C_t d l W^2 (the weft runs along x in the plane xz)."""
    d, s = 0.0008, SPACING_M
    model, across = _loose_yarn_forces((0.0, 0.0, 2.0))
    middle = model.crossing_grid_i == 1
    expected = 0.5 * RHO * 1.1 * d * s * 2.0 ** 2  # two segments of s / 2
    assert np.allclose(across[:model.crossing_count][middle, 2], expected, rtol=1e-12)
    assert np.allclose(across[:model.crossing_count][~middle, 2], expected / 2, rtol=1e-12)  # the yarn's ends
    assert np.allclose(across[:, :2], 0.0)
    _, along = _loose_yarn_forces((2.0, 0.0, 0.0))
    assert np.allclose(along[:model.crossing_count][middle, 0], 0.5 * RHO * 0.05 * d * s * 2.0 ** 2, rtol=1e-12)


def test_one_step_of_drag_never_more_than_stops_a_mass_against_the_air():
    """A gale on a light cloth with a long step: the capped impulse leaves the mass at most at the air's speed."""
    text = _air_scene(drag_normal=50.0, world="wind_m_s = [0.0, 200.0, 0.0]", step_s=4e-4)
    sim = Simulation(parse_scene(text, "gale.toml"))
    sim.solver.step(sim.state, sim.dt_s)
    v = sim.state.particle_velocity_m_s[:sim.model.crossing_count, 1]
    assert np.isfinite(v).all() and v.max() <= 200.0 + 1e-9 and v.min() > 0.0


def test_drag_across_and_along_the_cloth_is_capped_part_by_part():
    """A gale at 45 degrees to a flat cloth, drag_normal far above drag_tangential: the normal part of the drag is
    capped on its own, so the velocity across the cloth reaches the air's and never overshoots it, step by step."""
    text = _air_scene(drag_normal=50.0, drag_tangential=0.001, world="wind_m_s = [200.0, 200.0, 0.0]")
    sim = Simulation(parse_scene(text, "gale.toml"))
    n = sim.model.crossing_count
    for _ in range(5):
        sim.solver.step(sim.state, sim.dt_s)
        v = sim.state.particle_velocity_m_s[:n]
        assert np.isfinite(v).all() and v[:, 1].max() <= 200.0 + 1e-9 and v[:, 1].min() > 0.0
        assert v[:, 0].max() < 20.0  # along the cloth, the small coefficient barely moves it


GUST_L, GUST_T, GUST_SIGMA = 0.3, 0.5, 2.0


def _gust_statistics(strength=GUST_SIGMA, length=GUST_L, time=GUST_T, seeds=16):
    """Per component RMS over space, and the correlations u(x) u(x + L e) / <u^2> (random directions e) and
    u(x, t) u(x, t + T) / <u^2>, averaged over seeds."""
    rms, across, later = [], [], []
    for seed in range(seeds):
        g = gust_modes(seed, strength, length, time)
        rng = np.random.default_rng(100 + seed)
        x = rng.uniform(-20 * GUST_L, 20 * GUST_L, (8000, 3))
        u = air_velocity_m_s((0.0, 0.0, 0.0), g, x, 1.0)
        e = rng.normal(size=x.shape)
        e /= np.linalg.norm(e, axis=1)[:, None]
        var = (u * u).mean()
        rms.append(np.sqrt((u * u).mean(axis=0)))
        across.append((u * air_velocity_m_s((0.0, 0.0, 0.0), g, x + GUST_L * e, 1.0)).mean() / var)
        later.append((u * air_velocity_m_s((0.0, 0.0, 0.0), g, x, 1.0 + GUST_T)).mean() / var)
    return np.mean(rms, axis=0), float(np.mean(across)), float(np.mean(later))


def test_gusts_have_the_asked_strength_and_length_and_time_scales():
    """exp(-r^2 / 2 L^2) at r = L and exp(-tau^2 / 2 T^2) at tau = T are both exp(-1/2) (docs/wind.md)."""
    rms, across, later = _gust_statistics()
    assert np.allclose(rms, GUST_SIGMA, rtol=0.03), rms
    assert abs(across - math.exp(-0.5)) < 0.05, across
    assert abs(later - math.exp(-0.5)) < 0.05, later


@pytest.mark.parametrize("scale", [0.5, 2.0])
def test_gust_statistics_fail_when_a_scale_is_off(scale):
    """The checks above can fail: a field made with a scale halved or doubled misses them."""
    rms, across, later = _gust_statistics(strength=GUST_SIGMA * scale, length=GUST_L * scale, time=GUST_T * scale,
                                          seeds=4)
    assert not np.allclose(rms, GUST_SIGMA, rtol=0.03)
    assert abs(across - math.exp(-0.5)) > 0.05 and abs(later - math.exp(-0.5)) > 0.05


def test_mean_wind_carries_the_gusts():
    """Frozen turbulence: with gust_time_s long, the field at x + W tau, tau later, is the field at x now."""
    g = gust_modes(3, 1.5, 0.2, 1e4)
    x = np.random.default_rng(0).uniform(-1, 1, (50, 3))
    w = np.array([4.0, 0.0, 1.0])
    now = air_velocity_m_s(w, g, x, 0.5) - w
    later = air_velocity_m_s(w, g, x + 0.25 * w, 0.75) - w
    assert np.allclose(now, later, atol=1e-4 * 1.5)
    assert not np.allclose(now, air_velocity_m_s(w, g, x, 0.75) - w, atol=0.05)


GUSTY = "wind_m_s = [0.0, 0.0, 2.0]\ngust_strength_m_s = 1.0\ngust_length_m = 0.05\ngust_time_s = 0.2"


def test_gusty_frames_are_the_same_for_the_same_seed_and_differ_for_another():
    def frames(seed):
        sim = Simulation(parse_scene(_air_scene(world=GUSTY, seed=seed, frames=4), "gust.toml"))
        _run(sim, 0.03)
        return sim.state.particle_position_m.copy()

    a, b = frames(1), frames(1)
    assert a.tobytes() == b.tobytes()
    assert not np.array_equal(a, frames(2))


def test_a_scene_without_drag_builds_no_air_stage_and_warns_when_wind_moves_nothing():
    still = build_model(parse_scene(small_scene_text(), "still.toml"))
    assert still.panel_drag_normal.size == 0
    assert not any(s.__class__.__name__ == "AirDrag" for s in Simulation(parse_scene(small_scene_text(), "s.toml"))
                   .solver.stages)
    windy = small_scene_text().replace("gravity_m_s2 = [0.0, -9.81, 0.0]",
                                       "gravity_m_s2 = [0.0, -9.81, 0.0]\nwind_m_s = [3.0, 0.0, 0.0]")
    model = build_model(parse_scene(windy, "windy.toml"))
    assert model.panel_drag_normal.size == 0
    assert any("the wind moves nothing" in w for w in model.build_warnings)
    assert model.digest() != still.digest()  # the wind is part of the Model all the same
    assert not any("wind" in w for w in build_model(parse_scene(_air_scene(world="wind_m_s = [3.0, 0.0, 0.0]"),
                                                                "a.toml")).build_warnings)
