"""Rigid bodies: a thrown (dynamic) ball hits and pushes the cloth, and the cloth pushes back;
boxes and planes keep masses out."""
import numpy as np
from fraytool.sim.kernels.work_split import all_slots
import pytest

from fraytool.kinds import SHEAR, SHEAR_TWIN
from fraytool.sim import Simulation
from helpers import small_scene

BALL_MASS_KG = 0.002
BALL_RADIUS_M = 0.01
BALL_SPEED_M_S = 3.0
MASS_PER_CROSSING_KG = 2.0e-5
"""As in helpers.SMALL_SCENE; the 12 x 12 cloth below weighs 144 of these."""

BALL = f"""
[[bodies]]
name = "ball"
shape = "sphere"
radius_m = {BALL_RADIUS_M}
motion = "dynamic"
mass_kg = {BALL_MASS_KG}
position_m = [-0.0025, 0.13, -0.0025]
velocity_m_s = [0.0, {-BALL_SPEED_M_S}, 0.0]
gravity = {{gravity}}
"""

BARS = """
[[bodies]]
name = "left_bar"
shape = "box"
half_extents_m = [0.003, 0.003, 0.04]
position_m = [-0.03, 0.1, -0.005]
collide = false

[[bodies]]
name = "right_bar"
shape = "box"
half_extents_m = [0.003, 0.003, 0.04]
position_m = [0.025, 0.1, -0.005]
collide = false
"""

HELD = """
[[attachments]]
body = "left_bar"
edge = "left"

[[attachments]]
body = "right_bar"
edge = "right"
"""

THROWN = BARS + BALL.format(gravity="false") + HELD
"""The ball is thrown straight down at the middle of a cloth held at two edges by static bars."""


def _cloth_energy_j(sim) -> float:
    """Kinetic energy of the cloth plus the elastic energy of its springs, 1/2 k (l - L)^2 each
    (shear springs only in compression, docs/method.md §3.2). Both are >= 0."""
    s, m = sim.state, sim.model
    act = s.particle_active
    kinetic = 0.5 * float((s.particle_mass_kg[act] * (s.particle_velocity_m_s[act] ** 2).sum(axis=1)).sum())
    x = s.particle_position_m
    stretch = np.linalg.norm(x[s.spring_particle_b] - x[s.spring_particle_a], axis=1) - m.spring_rest_length_m
    slack_shear = np.isin(m.spring_kind, (SHEAR, SHEAR_TWIN)) & (stretch > 0.0)
    stretch = np.where(slack_shear, 0.0, stretch)
    elastic = 0.5 * float((s.spring_stiffness_n_per_m * stretch ** 2)[s.spring_alive].sum())
    return kinetic + elastic


def _ball_gap_m(sim, ball: int) -> float:
    """Smallest distance from a crossing to the ball's surface, less half the cloth thickness: 0 for a
    mass the contact pass has just pushed out (touching), negative inside."""
    n = sim.model.crossing_count
    d = np.linalg.norm(sim.state.particle_position_m[:n] - sim.state.body_position_m[ball], axis=1)
    return float(d.min()) - (BALL_RADIUS_M + 0.5 * sim.model.thickness_m)


TOUCHING_M = 1e-5
"""A mass this close to the ball (1/80 of the cloth thickness) touches it: contact leaves masses on
the surface, friction's tangential move lifts them off it by a hair."""


def test_held_cloth_stops_the_thrown_ball_and_throws_it_back():
    """A trampoline: with static supports and no gravity the cloth is passive, so it must stop the
    ball and send it back up, and cannot return more energy than the ball brought in: at the end,
    ball + cloth (kinetic and elastic) energy <= the ball's initial 1/2 M v0^2."""
    sim = Simulation(small_scene(THROWN, gravity="[0.0, 0.0, 0.0]", nx=12, ny=12, frames=40))
    n = sim.model.crossing_count
    ball = sim.model.body_names.index("ball")
    y0 = sim.state.particle_position_m[:n, 1].copy()
    energy_in = 0.5 * BALL_MASS_KG * BALL_SPEED_M_S ** 2
    lowest, clearance, contact_steps = 0.0, np.inf, 0
    for _ in range(39 * sim.steps_per_frame):
        sim.step()
        lowest = min(lowest, float((sim.state.particle_position_m[:n, 1] - y0).min()))
        gap = _ball_gap_m(sim, ball)
        clearance = min(clearance, gap)
        contact_steps += gap <= TOUCHING_M
    assert contact_steps > 0, "the ball never touched the cloth"
    assert lowest < -0.005, "the cloth was not pushed down by the ball"
    assert clearance >= -1e-9, f"a mass came {-clearance:.2e} m inside the ball (plus half the thickness)"
    assert _ball_gap_m(sim, ball) > 1e-3, "the ball is still on the cloth at the end"
    v = sim.state.body_velocity_m_s[ball]
    assert v[1] > 0.0, f"the held cloth did not stop the ball and send it back (v = {v})"
    energy_out = 0.5 * BALL_MASS_KG * float(v @ v) + _cloth_energy_j(sim)
    assert energy_out <= energy_in, f"a passive cloth returned {energy_out:.3e} J of the {energy_in:.3e} J it got"


UNBROKEN_TEARING = """
[cloth.tearing]
enabled = true
yarn_level = false
break_strain = 5.0
"""
"""Tearing on but nothing breaks: the solver then also runs rigid contact before strain limiting
(RigidContactBeforeLimit), a second exchange of momentum with the ball in every step."""


@pytest.mark.parametrize("tearing", [False, True], ids=["one_contact_pass", "two_contact_passes"])
@pytest.mark.parametrize("gravity", [False, True], ids=["no_gravity", "gravity"])
def test_momentum_the_ball_loses_is_the_momentum_the_free_cloth_gains(gravity, tearing):
    """A free cloth (no pins, no attachments) and the ball thrown at it: their only external force is
    gravity, so ball + cloth momentum changes by exactly (M + m_cloth) g t; with no gravity it is
    conserved. Springs, strain limiting and contact exchange momentum in equal and opposite pairs,
    so the balance holds at every step up to round-off: tolerance 1e-9 M v0 (6e-12 N s; it is met
    to ~1e-17 N s, while a reaction impulse or a ball mass off by one part in a million misses it
    by ~4e-9 N s). The ball's momentum uses its mass from the scene text, not the model's."""
    g = np.array([0.0, -9.81 if gravity else 0.0, 0.0])
    spec = small_scene(BALL.format(gravity="true" if gravity else "false") + (UNBROKEN_TEARING if tearing else ""),
                       gravity=f"[0.0, {g[1]}, 0.0]", nx=12, ny=12, frames=40)
    sim = Simulation(spec)
    names = [type(st).__name__ for st in sim.solver.stages]
    assert ("RigidContactBeforeLimit" in names) == tearing
    s = sim.state
    ball = sim.model.body_names.index("ball")
    act = s.particle_active
    assert sim.model.attachment_count == 0 and (s.particle_inv_mass[act] > 0.0).all(), "the cloth is not free"
    m = s.particle_mass_kg[act]
    cloth_mass = float(m.sum())
    assert cloth_mass == pytest.approx(144 * MASS_PER_CROSSING_KG, rel=1e-12)

    def momenta():
        return (m[:, None] * s.particle_velocity_m_s[act]).sum(axis=0), BALL_MASS_KG * s.body_velocity_m_s[ball].copy()

    sim.step()  # the throw: the ball gets its initial velocity (an external impulse), far from the cloth
    assert _ball_gap_m(sim, ball) > 0.01
    cloth0, ball0 = momenta()
    t0 = s.time_s
    np.testing.assert_allclose(ball0, BALL_MASS_KG * (np.array([0.0, -BALL_SPEED_M_S, 0.0]) + g * t0), rtol=1e-12)
    np.testing.assert_allclose(cloth0, cloth_mass * g * t0, rtol=1e-12, atol=1e-300)
    tolerance = 1e-9 * BALL_MASS_KG * BALL_SPEED_M_S
    worst, contact_steps = 0.0, 0
    for _ in range(39 * sim.steps_per_frame - 1):
        sim.step()
        contact_steps += _ball_gap_m(sim, ball) <= TOUCHING_M
        cloth, ball_p = momenta()
        external = (BALL_MASS_KG + cloth_mass) * g * (s.time_s - t0)
        worst = max(worst, float(np.abs((cloth - cloth0) + (ball_p - ball0) - external).max()))
    assert contact_steps > 0, "the ball never touched the cloth"
    assert not s.spring_broken.any()  # the same cloth in both cases: only the contact passes differ
    # the exchange is no trifle: the contact impulse on the cloth (its momentum change less gravity's)
    # took more than a third of the ball's momentum
    impulse = (cloth - cloth0) - cloth_mass * g * (s.time_s - t0)
    assert impulse[1] < -BALL_MASS_KG * BALL_SPEED_M_S / 3, f"the cloth received only {impulse} N s"
    assert worst <= tolerance, (f"ball + cloth momentum is off the external impulse by up to {worst:.3e} N s "
                                f"(tolerance {tolerance:.1e}): the ball lost a different momentum than the cloth got")


def test_box_and_plane_keep_masses_out():
    extra = """
[[bodies]]
name = "table"
shape = "box"
half_extents_m = [0.01, 0.02, 0.01]
position_m = [0.0, 0.05, 0.0]
rotation_deg = [0.0, 30.0, 0.0]

[[bodies]]
name = "floor"
shape = "plane"
position_m = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
"""
    sim = Simulation(small_scene(extra, frames=60, steps_per_frame=20))
    for _ in sim.frames(60):
        pass
    n = sim.model.crossing_count
    x = sim.state.particle_position_m[:n]
    half_t = 0.5 * sim.model.thickness_m
    assert x[:, 1].min() >= half_t - 1e-12
    R = sim.model.body_rotation[0]
    local = (x - np.array([0.0, 0.05, 0.0])) @ R
    half = np.array([0.01, 0.02, 0.01])
    outside = np.linalg.norm(np.maximum(np.abs(local) - half, 0.0), axis=1)  # distance to the box, 0 inside
    assert outside.min() >= half_t - 1e-9, "a mass is within half the thickness of the box"
    assert x[:, 1].max() > 0.05  # some of the cloth rests on the box top


def test_rigid_contact_kernel_allocates_nothing_and_matches_the_per_body_projection():
    """The per-step contact kernel allocates no memory (numba's runtime counts every allocation)
    for spheres, planes and turned boxes, and it moves each particle exactly as the one-body
    projection `project_out_of_body` (the reference, body by body in index order) does, friction off."""
    from numba.core.runtime import _nrt_python, rtsys

    from fraytool.kinds import SHAPE_BOX, SHAPE_PLANE, SHAPE_SPHERE
    from fraytool.sim.kernels.bodies import BodiesIn
    from fraytool.sim.kernels.rigid_contact import collide_rigid, project_out_of_body

    rng = np.random.default_rng(11)
    shape = np.array([SHAPE_SPHERE, SHAPE_PLANE, SHAPE_BOX], np.int32)
    angle = 0.4
    turn = np.array([[np.cos(angle), 0.0, np.sin(angle)], [0.0, 1.0, 0.0], [-np.sin(angle), 0.0, np.cos(angle)]])
    rotation = np.stack([np.eye(3), np.eye(3), turn])
    params = np.array([[0.05, 0.0, 0.0], [0.0, 1.0, 0.0], [0.04, 0.02, 0.03]])  # radius, normal, half extents
    position = np.array([[0.0, 0.0, 0.0], [0.0, -0.03, 0.0], [0.08, 0.0, 0.0]])
    friction = np.zeros(3)
    collide = np.ones(3, np.bool_)
    dynamic = np.zeros(3, np.bool_)
    x = rng.uniform(-0.1, 0.15, (4000, 3))
    prev = x.copy()
    inv = np.ones(4000)
    mass = np.ones(4000)
    impulse = np.zeros((3, 3))
    bodies = BodiesIn(shape, params, rotation, friction, collide, dynamic, position, np.zeros((3, 3)),
                      np.zeros((3, 3)))
    args = (bodies, 0.001, 1e-3, inv, mass, prev)
    collide_rigid(*all_slots(len(x)), *args, x.copy(), impulse)  # compile
    reference = x.copy()
    for p in range(reference.shape[0]):
        for k in range(3):
            project_out_of_body(k, bodies, 0.001, reference[p])
    def allocations(points):
        was_on = _nrt_python.memsys_stats_enabled()
        _nrt_python.memsys_enable_stats()
        try:
            before = rtsys.get_allocation_stats()
            hits = collide_rigid(*all_slots(len(points)), *args[:-3], inv[:len(points)], mass[:len(points)],
                                 prev[:len(points)], points, impulse)
            after = rtsys.get_allocation_stats()
        finally:
            if not was_on:
                _nrt_python.memsys_disable_stats()
        return after.alloc - before.alloc, after.mi_alloc - before.mi_alloc, hits

    got = x.copy()
    allocs, meminfos, contacts = allocations(got)
    # numba wraps each NumPy array passed in from Python once (a MemInfo per argument) and the
    # parallel loop over one body's particles schedules its threads (one allocation per body), and the
    # kernel keeps its contact counts per unit (one array); beyond those it allocates nothing: the same
    # count for 40 particles as for 4000
    arrays_passed = sum(isinstance(a, np.ndarray) for a in (*bodies, *args)) + 4
    assert arrays_passed + 1 <= allocs <= arrays_passed + 1 + len(shape)
    assert meminfos == allocs
    assert allocations(x[:40].copy())[:2] == (allocs, meminfos)
    assert contacts > 500  # every shape is hit
    assert np.array_equal(got, reference)
