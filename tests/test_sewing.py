"""Seams sewn over time ([[seams]] sew_s, docs/garments.md): two flat panels either side of a closed mesh
cylinder, 10 cm apart, sew into a tube round it; the stitches pull in, never push, never break while sewing."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from fraytool.kinds import STITCH, STRUCT_WARP, STRUCT_WEFT
from fraytool.scene import parse_scene
from fraytool.sim.model import sewing_progress
from fraytool.sim.simulation import Simulation

RADIUS_M, Y0, Y1 = 0.03, -0.03, 0.08
STITCH_M = 0.004


def cylinder_obj(path, segments: int = 40) -> None:
    """A closed cylinder of RADIUS_M about the y axis from Y0 to Y1, outward-facing, with capped ends."""
    v = [(RADIUS_M * np.cos(a), y, RADIUS_M * np.sin(a)) for y in (Y0, Y1)
         for a in 2 * np.pi * np.arange(segments) / segments] + [(0.0, Y0, 0.0), (0.0, Y1, 0.0)]
    f = []
    for k in range(segments):
        k1 = (k + 1) % segments
        f += [(k, k + segments, k1 + segments), (k, k1 + segments, k1)]  # the side, outward
        f += [(2 * segments, k, k1), (2 * segments + 1, k1 + segments, k + segments)]  # bottom and top caps
    path.write_text("".join(f"v {x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in v)
                    + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f))


def panel(name: str, z: float) -> str:
    return f"""
[[cloth]]
name = "{name}"
warp_yarns = 31
weft_yarns = 13
spacing_m = 0.004
thickness_m = 0.0006
mass_per_crossing_kg = 5e-6
origin_m = [-0.06, 0.0, {z}]
plane = "xy"
edge = "hemmed"
[cloth.springs]
structural_n_per_m = 40.0
bend_n_per_m = 1.0
shear_n_per_m = 5.0
damping = 0.02
"""


def scene(sew_s: float, frames: int = 120) -> str:
    """Front panel at z = +5 cm, back at -5 cm, both 12 cm wide along x and 4.8 cm tall; their left edges sewn
    together and their right edges (segment 3: left, 1: right), every 4 mm."""
    seams = "".join(f"""
[[seams]]
panel_a = "front"
segment_a = {k}
panel_b = "back"
segment_b = {k}
stitch_spacing_m = 0.004
stitch_length_m = {STITCH_M}
stiffness_n_per_m = 80.0
break_strain = 0.5
sew_s = {sew_s}
""" for k in (1, 3))
    return (f"""
[scene]
name = "sew"
seed = 3
[time]
step_s = 0.00020833333333333335
steps_per_frame = 20
frames = {frames}
[world]
gravity_m_s2 = [0.0, 0.0, 0.0]
""" + panel("front", 0.05) + """
[cloth.tearing]
enabled = true
break_strain = 0.3
break_strain_spread = 0.0
""" + panel("back", -0.05) + seams + """
[self_collision]
enabled = true
[[bodies]]
name = "post"
shape = "mesh"
file = "post.obj"
friction = 0.2
""")


def radial_m(x: np.ndarray) -> np.ndarray:
    return np.hypot(x[..., 0], x[..., 2])


def test_sewing_progress_is_smooth_from_0_to_1_over_sew_s():
    sew = np.array([0.5, 0.0])
    assert sewing_progress(0.0, sew).tolist() == [0.0, 1.0]
    assert sewing_progress(0.25, sew)[0] == pytest.approx(0.5)
    assert sewing_progress(0.5, sew)[0] == 1.0 and sewing_progress(9.0, sew)[0] == 1.0
    t = np.linspace(0.0, 0.5, 101)
    p = np.array([sewing_progress(x, sew)[0] for x in t])
    assert (np.diff(p) >= 0.0).all() and p[1] < 1e-3  # no jerk at the start


def test_two_flat_panels_10_cm_apart_sew_into_a_tube_round_a_closed_cylinder(tmp_path):
    cylinder_obj(tmp_path / "post.obj")
    (tmp_path / "s.toml").write_text(scene(sew_s=0.3))
    sim = Simulation(parse_scene((tmp_path / "s.toml").read_text(), str(tmp_path / "s.toml")))
    m = sim.model
    stitches = np.flatnonzero(m.spring_kind == STITCH)
    start = np.linalg.norm(m.crossing_rest_position_m[m.spring_crossing_b[stitches]]
                           - m.crossing_rest_position_m[m.spring_crossing_a[stitches]], axis=1)
    assert stitches.size >= 20 and start.min() > 20 * STITCH_M  # the panels start far apart
    segments = np.flatnonzero((m.spring_kind == STRUCT_WEFT) | (m.spring_kind == STRUCT_WARP))
    inside_worst = 0.0
    for _ in range(m.crossing_count and 120):
        sim.advance_frame()
        x = sim.state.particle_position_m
        assert np.isfinite(x).all()
        assert not sim.state.spring_broken[stitches].any()  # nothing breaks while sewing (nor after: no load)
        # no mass inside the cylinder, and no yarn segment through it (sampled along its length)
        a, b = x[sim.state.spring_particle_a[segments]], x[sim.state.spring_particle_b[segments]]
        pts = a[:, None, :] + np.linspace(0.0, 1.0, 5)[None, :, None] * (b - a)[:, None, :]
        within = (pts[..., 1] > Y0) & (pts[..., 1] < Y1)
        inside_worst = max(inside_worst, float((RADIUS_M - radial_m(pts))[within].max(initial=-1.0)))
    assert inside_worst <= 0.0, f"a yarn reached {inside_worst * 1e3:.3f} mm inside the cylinder"
    x = sim.state.particle_position_m
    length = np.linalg.norm(x[sim.state.spring_particle_b[stitches]] - x[sim.state.spring_particle_a[stitches]],
                            axis=1)
    assert length.max() <= 1.2 * STITCH_M, length.max()
    np.testing.assert_allclose(sim.state.spring_rest_length_m[stitches], STITCH_M)
    # a tube round the post: every crossing now wraps it, all round
    n = m.crossing_count
    angle = np.arctan2(x[:n, 2], x[:n, 0])
    assert np.histogram(angle, bins=12, range=(-np.pi, np.pi))[0].min() > 0
    assert radial_m(x[:n]).max() < 0.06


def test_the_same_seams_without_sew_s_start_torn_and_say_so(tmp_path):
    cylinder_obj(tmp_path / "post.obj")
    (tmp_path / "s.toml").write_text(scene(sew_s=0.0, frames=2))
    run = subprocess.run([sys.executable, "-m", "fraytool", "check", str(tmp_path / "s.toml")],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    warnings = [x for x in run.stderr.splitlines() if x.startswith("fraytool: warning:")]
    assert len(warnings) == 2 and all("stitches start past their break strain" in w for w in warnings), run.stderr


@pytest.mark.parametrize("sew, fragment", [("-0.1", "sew_s = -0.1"), ("2.0", "must end within the shot")])
def test_a_bad_sew_s_is_one_line_and_exit_2(tmp_path, sew, fragment):
    cylinder_obj(tmp_path / "post.obj")
    (tmp_path / "s.toml").write_text(scene(sew_s=0.3, frames=120).replace("sew_s = 0.3", f"sew_s = {sew}"))
    run = subprocess.run([sys.executable, "-m", "fraytool", "check", str(tmp_path / "s.toml")],
                         capture_output=True, text=True)
    errors = [x for x in run.stderr.splitlines() if x.strip()]
    assert run.returncode == 2 and fragment in run.stderr and "[seams." in run.stderr, run.stderr
    assert len(errors) == 2  # one line per seam


def test_a_sewing_seam_between_edges_of_unequal_length_is_refused(tmp_path):
    cylinder_obj(tmp_path / "post.obj")
    text = scene(sew_s=0.3).replace("warp_yarns = 31\nweft_yarns = 13\nspacing_m = 0.004\nthickness_m = 0.0006\n"
                                    "mass_per_crossing_kg = 5e-6\norigin_m = [-0.06, 0.0, -0.05]",
                                    "warp_yarns = 31\nweft_yarns = 20\nspacing_m = 0.004\nthickness_m = 0.0006\n"
                                    "mass_per_crossing_kg = 5e-6\norigin_m = [-0.06, 0.0, -0.05]")
    assert text != scene(sew_s=0.3)
    (tmp_path / "s.toml").write_text(text)
    run = subprocess.run([sys.executable, "-m", "fraytool", "check", str(tmp_path / "s.toml")],
                         capture_output=True, text=True)
    assert run.returncode == 2 and "within 25 % of each other's length" in run.stderr, run.stderr


def test_gravity_waits_for_gravity_start_s_then_pulls_as_free_fall():
    """[world] gravity_start_s: a free cloth (no body, no damping) stays where it is until then, and afterwards
    falls as symplectic Euler integrates g: after n steps, dt^2 g n (n + 1) / 2 below its rest."""
    from helpers import small_scene_text

    dt, start = 4e-4, 0.02
    text = small_scene_text(steps_per_frame=10, frames=20).replace("[world]\n", f"[world]\ngravity_start_s = {start}\n", 1)
    assert "gravity_start_s" in text
    sim = Simulation(parse_scene(text, "g.toml"))
    rest = sim.state.particle_position_m[:sim.model.crossing_count, 1].copy()
    waiting = round(start / dt)
    for _ in range(waiting):
        sim.step()
    np.testing.assert_array_equal(sim.state.particle_position_m[:sim.model.crossing_count, 1], rest)
    n = 30
    for _ in range(n):
        sim.step()
    drop = rest - sim.state.particle_position_m[:sim.model.crossing_count, 1]
    np.testing.assert_allclose(drop, dt * dt * 9.81 * n * (n + 1) / 2, rtol=1e-9)


def test_a_stitch_being_sewn_holds_past_its_break_strain_and_breaks_once_sewn():
    """Two strips held apart at their outer edges: the seam between them cannot close, so as sewing shortens its
    stitches' rest length they stretch far past their break strain (0.2). None breaks while sewing (0.02 s);
    once sewn they are ordinary stitches and break."""
    from fraytool.sim.builder import ModelBuilder
    from helpers import small_scene

    b = ModelBuilder(seed=1, gravity_m_s2=(0.0, 0.0, 0.0))
    strip = dict(spacing_m=0.004, thickness_m=0.0006, mass_per_crossing_kg=5e-6, structural_n_per_m=40.0,
                 warp_yarns=3, weft_yarns=6)
    b.add_cloth(name="a", **strip)
    b.add_panel("b", **strip, origin_m=(0.05, 0.0, 0.0))
    b.add_sphere("left", radius_m=0.001, collide=False)
    b.add_sphere("right", radius_m=0.001, position_m=(0.06, 0.0, 0.0), collide=False)
    b.add_attachment("left", panel="a", edge="left")
    b.add_attachment("right", panel="b", edge="right")
    b.add_seam(panel_a="a", segment_a=1, panel_b="b", segment_b=3, reverse=True, stitch_spacing_m=0.004,
               stitch_length_m=0.004, stiffness_n_per_m=20.0, break_strain=0.2, sew_s=0.02)
    model = b.finalize()
    stitches = np.flatnonzero(model.spring_kind == STITCH)
    sim = Simulation(small_scene(step_s=4e-4), model=model)
    stretched = 0.0
    while sim.state.time_s < 0.02 - 4e-4 - 1e-9:  # every step that ends before sewing does
        sim.step()
        x = sim.state.particle_position_m
        length = np.linalg.norm(x[sim.state.spring_particle_b[stitches]] - x[sim.state.spring_particle_a[stitches]],
                                axis=1)
        stretched = max(stretched, float((length / sim.state.spring_rest_length_m[stitches]).max()))
        assert not sim.state.spring_broken[stitches].any(), sim.state.time_s
    assert stretched > 2.0  # far past 1.2
    for _ in range(10):
        sim.step()
    assert sim.state.spring_broken[stitches].any()
