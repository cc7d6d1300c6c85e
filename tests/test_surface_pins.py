"""Cloth pinned to a mesh body's surface (docs/garments.md "Pinning"; fraytool.sim.surface_pins): a held
crossing follows its place on an animated, moving triangle, to 1e-6 m; it lets go above release_force_n."""
from __future__ import annotations

import numpy as np
import pytest

from fraytool.sim.builder import ModelBuilder, ModelBuilderError
from fraytool.sim.simulation import Simulation
from helpers import small_scene

A0, C0, B0 = np.array([-0.05, 0.0, -0.05]), np.array([0.0, 0.0, 0.05]), np.array([0.05, 0.0, -0.05])
A1, C1, B1 = np.array([-0.06, 0.01, -0.05]), np.array([0.0, 0.02, 0.06]), np.array([0.05, 0.0, -0.04])
KEY_S = 0.02
PATH = [[0.0, 0.0, 0.0, 0.0], [KEY_S, 0.01, 0.0, 0.005]]


def builder(release_force_n: float = 0.0, region_center=(0.0, 0.002, 0.0)) -> ModelBuilder:
    """A 3 x 3 cloth 2 mm above a triangle (A, C, B: normal +y) whose vertices move to A1, C1, B1 over KEY_S
    while its body translates along PATH; the middle crossing, above the triangle's point 0.25 A + 0.5 C +
    0.25 B (the origin at rest), pinned to it."""
    b = ModelBuilder(seed=1, gravity_m_s2=(0.0, -9.81, 0.0))
    b.add_cloth(warp_yarns=3, weft_yarns=3, spacing_m=0.01, thickness_m=0.001, mass_per_crossing_kg=1e-5,
                structural_n_per_m=20.0, origin_m=(-0.01, 0.002, -0.01))
    b.add_mesh("tri", vertices_m=np.stack([np.stack([A0, C0, B0]), np.stack([A1, C1, B1])]),
               triangles=np.array([[0, 1, 2]]), key_times_s=[0.0, KEY_S], motion="kinematic", path=PATH,
               collide=False)
    b.add_attachment("tri", region_center_m=region_center, region_radius_m=0.001, release_force_n=release_force_n)
    return b


def expected_m(t: float) -> np.ndarray:
    """The pinned crossing's place at time t, from the keys and the path alone."""
    w = min(t / KEY_S, 1.0)
    a, c, b = (1 - w) * A0 + w * A1, (1 - w) * C0 + w * C1, (1 - w) * B0 + w * B1
    n = np.cross(c - a, b - a)
    n /= np.linalg.norm(n)
    body = (1 - w) * np.array(PATH[0][1:]) + w * np.array(PATH[1][1:])
    return body + 0.25 * a + 0.5 * c + 0.25 * b + 0.002 * n


def test_a_pinned_crossing_stays_on_its_place_on_a_moving_deforming_triangle():
    model = builder().finalize()
    assert model.attachment_triangle.tolist() == [0]
    np.testing.assert_allclose(model.attachment_barycentric[0], [0.25, 0.5, 0.25], atol=1e-12)
    np.testing.assert_allclose(model.attachment_normal_offset_m, [0.002], atol=1e-12)
    sim = Simulation(small_scene(), model=model)
    p = int(model.attachment_particle[0])
    worst = 0.0
    for _ in range(70):  # past the last key: held there
        sim.step()
        worst = max(worst, float(np.linalg.norm(sim.state.particle_position_m[p] - expected_m(sim.state.time_s))))
    assert worst <= 1e-6, worst
    assert np.linalg.norm(expected_m(KEY_S) - expected_m(0.0)) > 0.01  # it did move


def test_a_pinned_crossing_lets_go_above_its_release_force_and_never_below():
    """The crossing's weight alone is 1e-5 kg x 9.81 = 98 uN: released at 50 uN (then it falls away from the
    triangle, its place), held at 1 N."""
    for force, let_go in ((5e-5, True), (1.0, False)):
        model = builder(release_force_n=force).finalize()
        sim = Simulation(small_scene(), model=model)
        p = int(model.attachment_particle[0])
        for _ in range(70):
            sim.step()
        off = float(np.linalg.norm(sim.state.particle_position_m[p] - expected_m(sim.state.time_s)))
        assert (sim.state.particle_inv_mass[p] > 0.0) == let_go
        assert (off > 1e-3) == let_go, off


def test_a_surface_pin_with_no_triangle_within_reach_is_refused():
    with pytest.raises(ModelBuilderError, match=r"0\.1 m from the mesh's surface, beyond the reach of a surface pin"):
        b = ModelBuilder()
        b.add_cloth(warp_yarns=3, weft_yarns=3, spacing_m=0.01, thickness_m=0.001, mass_per_crossing_kg=1e-5,
                    structural_n_per_m=20.0, origin_m=(-0.01, 0.1, -0.01))
        b.add_mesh("tri", vertices_m=np.stack([A0, C0, B0]), triangles=np.array([[0, 1, 2]]))
        b.add_attachment("tri", region_center_m=(0.0, 0.1, 0.0), region_radius_m=0.001)


def test_a_hook_catches_its_crossings_at_catch_s_and_holds_them_where_they_were_then():
    """Before catch_s the selected crossing falls with the cloth (it is free); from then on it keeps the offset
    it had from the moving body at that moment, to 1e-12 m, while the body moves on."""
    b = ModelBuilder(seed=1, gravity_m_s2=(0.0, -9.81, 0.0))
    b.add_cloth(warp_yarns=3, weft_yarns=3, spacing_m=0.01, thickness_m=0.001, mass_per_crossing_kg=1e-5,
                structural_n_per_m=20.0, origin_m=(-0.01, 0.0, -0.01))
    b.add_box("hook", half_extents_m=(0.001, 0.001, 0.01), motion="kinematic", collide=False,
              path=[[0.0, 0.0, 0.01, 0.0], [0.1, 0.05, 0.01, 0.0]])
    b.add_attachment("hook", region_center_m=(0.0, 0.0, 0.0), region_radius_m=0.001, catch_s=0.01)
    model = b.finalize()
    sim = Simulation(small_scene(), model=model)
    p = int(model.attachment_particle[0])
    rest = sim.state.particle_position_m[p].copy()
    caught_at = None
    for _ in range(60):
        before = sim.state.time_s
        sim.step()
        x, c = sim.state.particle_position_m[p], sim.state.body_position_m[0]
        if before < 0.01 - 1e-12 and sim.state.time_s <= 0.01:
            assert sim.state.particle_inv_mass[p] > 0.0
        if sim.state.particle_inv_mass[p] == 0.0:
            if caught_at is None:
                caught_at = (sim.state.time_s, x - c)
            np.testing.assert_allclose(x - c, caught_at[1], atol=1e-12)
    assert caught_at is not None and abs(caught_at[0] - 0.0104) < 1e-9  # the step whose start passed 0.01 s
    assert caught_at[1][1] < -0.01 - 1e-4  # it had fallen below the hook's height minus its rest gap when caught
    assert rest[1] == 0.0


def test_a_held_mass_lets_go_under_its_own_weight_alone():
    """A 2 x 2 cloth held whole by a still body: its springs are at rest (no pull), so what the pin bears is the
    weight, 1e-5 kg x 9.81 = 98 uN each: released at 50 uN, held at 150 uN."""
    for force, let_go in ((5e-5, True), (1.5e-4, False)):
        b = ModelBuilder(seed=1, gravity_m_s2=(0.0, -9.81, 0.0))
        b.add_cloth(warp_yarns=2, weft_yarns=2, spacing_m=0.01, thickness_m=0.001, mass_per_crossing_kg=1e-5,
                    structural_n_per_m=20.0)
        b.add_sphere("rest", radius_m=0.001, collide=False)
        b.add_attachment("rest", region_center_m=(0.005, 0.0, 0.005), region_radius_m=0.02, release_force_n=force)
        model = b.finalize()
        assert model.attachment_count == 4
        sim = Simulation(small_scene(), model=model)
        sim.step()
        sim.step()
        assert ((sim.state.particle_inv_mass[model.attachment_particle] > 0.0).all()) == let_go
