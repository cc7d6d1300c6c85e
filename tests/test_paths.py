"""Keyframed paths that turn (issue 35, item 5): orientation keys, linear or Catmull-Rom interpolation.

Every expected value is analytic: a rotation at a known rate, circles about the axis, quadratic motions
that a time-parameterised Catmull-Rom spline reproduces exactly (fraytool.sim.paths)."""
import json
import math

import numpy as np
import pytest

from fraytool.scene import parse_scene
from fraytool.sim import Simulation
from fraytool.sim.builder import ModelBuilder
from fraytool.sim.kernels.bodies import bodies_in
from fraytool.sim.kernels.rigid_contact import surface_distances
from fraytool.sim.record import frame_record
from fraytool.sim.rigid import kinematic_orientation, kinematic_position
from fraytool.geometry.rotations import quat_to_matrix
from helpers import small_scene_text

STEP_S = 4e-4
SPIN_DEG_PER_S = 720.0
"""The spun bar's rate: 90 degrees per key interval of 0.125 s."""
KEY_DT_S = 0.125
BAR_CENTRE_M = (-0.03, 0.1, -0.0025)
"""On the cloth's left edge (x = -0.03), halfway along it: the edge turns about its middle."""


def _rot_y(angle_rad: float) -> np.ndarray:
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _spun_bar(interpolation: str, keys: int = 5) -> str:
    """A kinematic bar holding the cloth's left edge, spun about y at SPIN_DEG_PER_S by orientation keys
    every 90 degrees (a full turn with keys=5)."""
    rows = ", ".join(f"[{k * KEY_DT_S}, 0.0, {k * SPIN_DEG_PER_S * KEY_DT_S}, 0.0]" for k in range(keys))
    return f"""
[[bodies]]
name = "bar"
shape = "box"
half_extents_m = [0.003, 0.003, 0.04]
position_m = {list(BAR_CENTRE_M)}
motion = "kinematic"
collide = false
path_rotation_deg = [{rows}]
interpolation = "{interpolation}"

[[attachments]]
body = "bar"
edge = "left"
"""


def _sim(extra: str, **overrides) -> Simulation:
    return Simulation(parse_scene(small_scene_text(**overrides) + extra, "paths.toml"))


def _steps(sim: Simulation, n: int) -> None:
    for _ in range(n):
        sim.step()


@pytest.mark.parametrize("interpolation", ["linear", "catmull_rom"])
def test_spun_body_turns_at_its_rate_and_carries_the_cloth_on_circles(interpolation):
    """Keys every 90 degrees about y at a constant rate: the orientation is R_y(omega t) with either
    interpolation (Catmull-Rom reproduces a linear angle), held masses run on circles about the bar's
    centre, c + R_y(omega t) (x0 - c), at the chord speed 2 r sin(omega dt / 2) / dt, and the body's
    angular velocity is omega about y."""
    sim = _sim(_spun_bar(interpolation), gravity="[0.0, 0.0, 0.0]")
    m = sim.model
    held = m.attachment_particle
    centre = np.array(BAR_CENTRE_M)
    start = sim.state.particle_position_m[held].copy()
    omega = math.radians(SPIN_DEG_PER_S)
    steps = 700  # 0.28 s: past the second key, 201.6 degrees
    _steps(sim, steps - 1)
    before = sim.state.particle_position_m[held].copy()
    sim.step()
    t = steps * STEP_S
    assert sim.state.time_s == pytest.approx(t, abs=1e-12)
    turn = _rot_y(omega * t)
    np.testing.assert_allclose(sim.state.body_rotation[0], turn, atol=1e-12)
    np.testing.assert_allclose(sim.state.body_angular_velocity_rad_s[0], [0.0, omega, 0.0], atol=1e-7)
    np.testing.assert_allclose(sim.state.body_position_m[0], centre, atol=0)
    after = sim.state.particle_position_m[held]
    np.testing.assert_allclose(after, centre + (start - centre) @ turn.T, atol=1e-12)
    radius = np.linalg.norm((start - centre)[:, [0, 2]], axis=1)
    assert radius.max() > 0.02  # the edge's ends are far from the axis
    speed = np.linalg.norm(after - before, axis=1) / STEP_S
    np.testing.assert_allclose(speed, 2 * radius * math.sin(omega * STEP_S / 2) / STEP_S, rtol=1e-7, atol=1e-9)
    assert speed.max() == pytest.approx(omega * radius.max(), rel=1e-5)


def test_turning_body_is_held_after_its_last_key_and_recorded_turned():
    """After the last key the body stays at the last orientation (and stops turning); the frame record,
    which the renderer draws from, carries the turned orientation, not the one at rest."""
    sim = _sim(_spun_bar("linear", keys=2), gravity="[0.0, 0.0, 0.0]")
    _steps(sim, int(round(1.5 * KEY_DT_S / STEP_S)))
    last = _rot_y(math.radians(SPIN_DEG_PER_S * KEY_DT_S))
    np.testing.assert_allclose(sim.state.body_rotation[0], last, atol=1e-12)
    np.testing.assert_array_equal(sim.state.body_angular_velocity_rad_s[0], np.zeros(3))
    record = frame_record(sim.model, sim.state, 1)
    np.testing.assert_allclose(record.body_rotation[0], last, atol=1e-7)
    np.testing.assert_allclose(sim.model.body_rotation[0], np.eye(3), atol=0)  # at rest: the first key


def test_turned_box_collides_in_its_turned_pose():
    """A long box turned 90 degrees about y (its long axis from z to x): a point 3 cm along z is now outside
    (3 cm - the 3 mm half width), a point 3 cm along x inside (3 mm from the nearest face); at rest it is
    the other way round."""
    sim = _sim(_spun_bar("linear", keys=2).replace("collide = false", "collide = true").split("[[attachments]]")[0],
               gravity="[0.0, 0.0, 0.0]")
    _steps(sim, int(KEY_DT_S / STEP_S) + 20)  # past the last key: held turned
    c = np.array(BAR_CENTRE_M)
    points = c + np.array([[0.0, 0.0, 0.03], [0.03, 0.0, 0.0]])
    distance = np.empty(2)
    surface_distances(0, bodies_in(sim.model, sim.state), points, distance)
    np.testing.assert_allclose(distance, [0.03 - 0.003, -0.003], atol=1e-12)


TURNTABLE = """
[[bodies]]
name = "table"
shape = "box"
half_extents_m = [0.05, 0.005, 0.05]
position_m = [0.0, 0.0946, 0.0]
motion = "kinematic"
friction = 1.0
path_rotation_deg = [[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 90.0, 0.0]]
"""
"""A turntable under the cloth (its top at y = 0.0996, the cloth's half thickness below the cloth), turning
90 degrees about y in 0.5 s."""


def test_friction_of_a_turning_body_carries_the_cloth_round():
    """Cloth lying on a turntable turns with it: friction acts on the move relative to the turning surface,
    dt (v + omega x r). After 0.25 s (45 degrees) the cloth has turned within 4 degrees of the table (the
    few steps of kinetic friction at the start); without omega x r it would stay put."""
    sim = _sim(TURNTABLE)
    n = sim.model.crossing_count
    x0 = sim.state.particle_position_m[:n].copy()
    _steps(sim, int(round(0.25 / STEP_S)))
    x1 = sim.state.particle_position_m[:n]
    far = np.hypot(x0[:, 0], x0[:, 2]) > 0.01  # angles of masses near the axis are ill-defined
    turned = np.arctan2(x0[far, 0], x0[far, 2]) - np.arctan2(x1[far, 0], x1[far, 2])
    turned = (turned + math.pi) % (2 * math.pi) - math.pi  # R_y turns z towards x: angle(x, z) grows
    turned = -turned
    assert np.median(np.degrees(turned)) == pytest.approx(45.0, abs=4.0)


def _path_body(rows, interpolation: str, key: str = "path") -> str:
    return f"""
[[bodies]]
name = "mover"
shape = "sphere"
radius_m = 0.005
position_m = [0.0, 0.3, 0.0]
motion = "kinematic"
collide = false
{key} = {json.dumps([[float(v) for v in r] for r in rows])}
interpolation = "{interpolation}"
"""


KEY_TIMES_S = (0.0, 0.05, 0.07, 0.16, 0.2)
"""Uneven key spacing: the time-parameterised spline still reproduces a quadratic."""


def _quadratic_m(t: float) -> np.ndarray:
    """A thrown body's path: x = x0 + v t + a t^2 / 2 per axis."""
    return np.array([0.01 + 0.3 * t, 0.3 + 1.2 * t - 4.905 * t * t, -0.02 + 0.5 * t * t])


def _quadratic_model(interpolation: str):
    rows = [(t, *_quadratic_m(t)) for t in KEY_TIMES_S]
    return _sim(_path_body(rows, interpolation)).model


def test_catmull_rom_path_reproduces_a_quadratic_motion_through_its_keys():
    """Keys sampled from a quadratic motion at uneven times: the Catmull-Rom path is that motion at every
    time between the first and last keys, passes through each key, and is held outside them."""
    m = _quadratic_model("catmull_rom")
    for t in np.linspace(0.0, KEY_TIMES_S[-1], 97):
        np.testing.assert_allclose(kinematic_position(m, 0, t), _quadratic_m(t), atol=1e-14)
    for t in KEY_TIMES_S:
        np.testing.assert_allclose(kinematic_position(m, 0, t), _quadratic_m(t), atol=1e-15)
    np.testing.assert_allclose(kinematic_position(m, 0, 0.3), _quadratic_m(KEY_TIMES_S[-1]), atol=0)


def _velocity_jump_m_s(m, t: float, h: float = 1e-6) -> float:
    """|right - left| difference quotient of the body's position at time t."""
    left = (kinematic_position(m, 0, t) - kinematic_position(m, 0, t - h)) / h
    right = (kinematic_position(m, 0, t + h) - kinematic_position(m, 0, t)) / h
    return float(np.linalg.norm(right - left))


def test_catmull_rom_velocity_is_continuous_at_keys_where_linear_jumps():
    """At each interior key the left and right difference quotients agree to O(h) for Catmull-Rom (and
    give the quadratic's velocity v + a t), while the linear path's velocity jumps there."""
    smooth, corners = _quadratic_model("catmull_rom"), _quadratic_model("linear")
    h = 1e-6
    for t in KEY_TIMES_S[1:-1]:
        assert _velocity_jump_m_s(smooth, t, h) < 1e-4
        assert _velocity_jump_m_s(corners, t, h) > 0.1
        central = (kinematic_position(smooth, 0, t + h) - kinematic_position(smooth, 0, t - h)) / (2 * h)
        np.testing.assert_allclose(central, [0.3, 1.2 - 9.81 * t, 1.0 * t], atol=1e-7)


def _wobble_deg(t: float) -> tuple[float, float, float]:
    """Euler angles of a grip that turns about changing axes."""
    return 40.0 * math.sin(7.0 * t), 25.0 * t, 60.0 * math.cos(5.0 * t)


def _angular_jump_rad_s(m, t: float, h: float = 1e-6) -> float:
    """|right - left| angular velocity at time t, from R(t +- h) R(t)^T."""
    def omega(a, b):
        turn = quat_to_matrix(kinematic_orientation(m, 0, b)) @ quat_to_matrix(kinematic_orientation(m, 0, a)).T
        return np.array([turn[2, 1] - turn[1, 2], turn[0, 2] - turn[2, 0], turn[1, 0] - turn[0, 1]]) / (2 * (b - a))
    return float(np.linalg.norm(omega(t, t + h) - omega(t - h, t)))


def test_catmull_rom_orientation_passes_through_keys_with_continuous_angular_velocity():
    """Orientation keys about changing axes: both interpolations pass through every key (R of the Euler
    angles, R = Rz Ry Rx); Catmull-Rom's angular velocity is continuous at the interior keys, slerp's
    jumps."""
    rows = [(t, *_wobble_deg(t)) for t in KEY_TIMES_S]
    smooth = _sim(_path_body(rows, "catmull_rom", "path_rotation_deg")).model
    corners = _sim(_path_body(rows, "linear", "path_rotation_deg")).model
    for t in KEY_TIMES_S:
        ax, ay, az = (math.radians(a) for a in _wobble_deg(t))
        rx = np.array([[1, 0, 0], [0, math.cos(ax), -math.sin(ax)], [0, math.sin(ax), math.cos(ax)]])
        rz = np.array([[math.cos(az), -math.sin(az), 0], [math.sin(az), math.cos(az), 0], [0, 0, 1]])
        want = rz @ _rot_y(ay) @ rx
        for m in (smooth, corners):
            np.testing.assert_allclose(quat_to_matrix(kinematic_orientation(m, 0, t)), want, atol=1e-12)
    for t in KEY_TIMES_S[1:-1]:
        assert _angular_jump_rad_s(smooth, t) < 1e-3
        assert _angular_jump_rad_s(corners, t) > 0.5


def test_builder_takes_quaternion_keys_as_the_file_takes_euler_keys():
    """ModelBuilder.add_box(path_quaternion=...) with the quaternions of a turn about y (cos a/2, 0,
    sin a/2, 0), any length, gives the keys a file's path_rotation_deg gives."""
    from_file = _sim(_spun_bar("catmull_rom")).model
    b = ModelBuilder()
    b.add_cloth(spacing_m=0.005, thickness_m=0.0008, mass_per_crossing_kg=2e-5, warp_yarns=12, weft_yarns=12,
                structural_n_per_m=20.0)
    half = [math.radians(k * SPIN_DEG_PER_S * KEY_DT_S) / 2 for k in range(5)]
    b.add_box("bar", half_extents_m=(0.003, 0.003, 0.04), position_m=BAR_CENTRE_M, motion="kinematic",
              collide=False, interpolation="catmull_rom",
              path_quaternion=[(k * KEY_DT_S, 3 * math.cos(a), 0.0, 3 * math.sin(a), 0.0) for k, a in enumerate(half)])
    built = b.finalize()
    np.testing.assert_allclose(built.body_orientation_path[0], from_file.body_orientation_path[0], atol=1e-15)
    assert built.body_interpolation == ("catmull_rom",)


def test_a_turning_mesh_carries_the_cloth_round_and_keeps_it_out():
    """A rigid mesh turntable (a closed disk, not animated) turned by orientation keys at 180 degrees/s:
    friction on the move relative to its turning surface, c1 - c0 + (R - R0) l, carries the cloth round
    within 15 % of the disk's turn, and the continuous test in the turning frame keeps every mass on top."""
    import trimesh
    from fraytool.sim.solver import SolverExplicitPBD

    disk = trimesh.creation.cylinder(radius=0.06, height=0.01, sections=48)
    b = ModelBuilder(seed=1)
    b.add_cloth(warp_yarns=12, weft_yarns=12, spacing_m=0.004, thickness_m=0.0008, mass_per_crossing_kg=2e-5,
                structural_n_per_m=20.0, origin_m=(-0.022, 0.0055, -0.022))
    b.add_mesh("disk", vertices_m=np.asarray(disk.vertices)[:, [0, 2, 1]], triangles=np.asarray(disk.faces)[:, [0, 2, 1]],
               motion="kinematic", friction=1.0, path_rotation_deg=[(0.0, 0.0, 0.0, 0.0), (0.5, 0.0, 90.0, 0.0)])
    model = b.finalize()
    state, solver, dt_s, steps = model.state(), SolverExplicitPBD(model), 2e-4, 1000
    for _ in range(steps):
        solver.step(state, dt_s)
    rest, x = model.crossing_rest_position_m, state.particle_position_m[:model.crossing_count]
    far = np.hypot(rest[:, 0], rest[:, 2]) > 0.01
    turned = np.degrees(np.angle(np.exp(1j * (np.arctan2(x[:, 0], x[:, 2]) - np.arctan2(rest[:, 0], rest[:, 2])))[far].mean()))
    disk_turn = 180.0 * steps * dt_s
    assert abs(turned - disk_turn) < 0.15 * disk_turn
    assert x[:, 1].min() > 0.005  # on the disk, not in it


def test_a_checkpoint_from_before_turning_bodies_loads_with_the_rest_orientation():
    """A checkpoint without body_rotation (written before bodies could turn) gets the model's orientation at
    rest and no angular velocity; without the model's orientation it is refused, never guessed."""
    from fraytool.sim.state import State

    sim = _sim(BALL_ROTATED)
    arrays = {k: v for k, v in sim.state.arrays().items()
              if k not in ("body_rotation", "body_angular_velocity_rad_s")}
    loaded = State.from_arrays(arrays, sim.model.body_rotation)
    np.testing.assert_allclose(loaded.body_rotation[0], _rot_y(math.radians(30.0)), atol=1e-15)
    np.testing.assert_array_equal(loaded.body_angular_velocity_rad_s, np.zeros((1, 3)))
    with pytest.raises(KeyError):
        State.from_arrays(arrays)


BALL_ROTATED = """
[[bodies]]
name = "ball"
shape = "sphere"
radius_m = 0.01
position_m = [0.0, 0.3, 0.0]
rotation_deg = [0.0, 30.0, 0.0]
"""
