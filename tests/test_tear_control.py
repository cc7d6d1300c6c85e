"""Tear control (docs/panels.md "Tear control"): weak lines, tear maps and scissors, checked against
what the keys say, computed here from the geometry (not read back from the builder's own tables)."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from fraytool.render.yarns import yarn_pieces
from fraytool.scene import load_scene, parse_scene
from fraytool.sim import Simulation
from fraytool.sim.builder import ModelBuilder, ModelBuilderError, build_model
from fraytool.sim.pieces import tear_distance_to_weak_lines

S = 0.004
SCENE = """
[scene]
name = "tc"
seed = {seed}
[time]
step_s = 0.00020833333333333335
steps_per_frame = 20
frames = {frames}
[cloth]
warp_yarns = {n}
weft_yarns = {n}
spacing_m = 0.004
thickness_m = 0.0006
mass_per_crossing_kg = 5e-6
origin_m = [0.0, 0.0, 0.0]
plane = "xz"
{cloth}
[cloth.springs]
structural_n_per_m = 40.0
bend_n_per_m = 1.0
shear_n_per_m = 5.0
damping = 0.02
[cloth.strain]
limit = 0.10
stiffness_n_per_m = 400.0
damping_ratio = 1.0
[cloth.tearing]
enabled = true
transition_strain = 0.12
break_strain = 0.24
break_strain_spread = {spread}
"""


def scene(extra: str = "", cloth: str = "", n: int = 16, spread: float = 0.02, seed: int = 1, frames: int = 2) -> str:
    return SCENE.format(cloth=cloth, n=n, spread=spread, seed=seed, frames=frames) + extra


def mids(model):
    uv = model.crossing_plane_uv_m
    return 0.5 * (uv[model.spring_crossing_a] + uv[model.spring_crossing_b])


@pytest.mark.parametrize("width_m", [0.004, 0.0054])
def test_a_weak_line_scales_the_break_strain_of_the_springs_in_its_band_only(width_m):
    """The band is width_m wide about the line: 0.0054 puts a row of spring middles (0.00283 m off the diagonal)
    just outside it, so a band 5 % wider would take them in."""
    plain = build_model(parse_scene(scene(), "a.toml"))
    line = f"[[weak_lines]]\npoints_m = [[0.0, 0.0], [0.06, 0.06]]\nwidth_m = {width_m}\nfactor = 0.6\n"
    weak = build_model(parse_scene(scene(line), "b.toml"))
    m = mids(plain)
    # distance to the diagonal u = v, computed here
    dist = np.abs(m[:, 0] - m[:, 1]) / np.sqrt(2.0)
    inside = (dist <= 0.5 * width_m) & (m[:, 0] <= 0.06) & (m[:, 1] <= 0.06)
    if width_m == 0.0054:
        assert ((dist > 0.5 * width_m) & (dist <= 0.55 * width_m)).sum() > 20
    floor = 0.12 * 1.01
    expect = np.where(inside, np.maximum(plain.spring_break_strain * 0.6, floor), plain.spring_break_strain)
    np.testing.assert_allclose(weak.spring_break_strain, expect, rtol=1e-12)
    assert inside.sum() > 20


def test_a_tear_map_sets_each_springs_mean_break_strain(tmp_path):
    """Left half black, right half white, spread 0: 0.15 under black, 0.30 under white; one pixel per
    crossing (a 16 x 16 map over 16 x 16 crossings)."""
    img = np.zeros((16, 16), np.uint8)
    img[:, 8:] = 255
    Image.fromarray(img).save(tmp_path / "map.png")
    (tmp_path / "s.toml").write_text(scene(cloth='tear_map = "map.png"\ntear_map_strain = [0.15, 0.30]', spread=0.0))
    model = build_model(load_scene(tmp_path / "s.toml"))
    m = mids(model)
    structural = (model.spring_kind == STRUCT_WEFT) | (model.spring_kind == STRUCT_WARP)
    left, right = structural & (m[:, 0] < 7.4 * S), structural & (m[:, 0] > 7.6 * S)
    np.testing.assert_allclose(model.spring_break_strain[left], 0.15)
    np.testing.assert_allclose(model.spring_break_strain[right], 0.30)


def test_a_tear_map_is_read_with_its_top_row_at_the_top_of_the_panel(tmp_path):
    """An asymmetric map (top half white, bottom half black): the springs in the upper half of the cloth (large
    v, the panel's top as the image shows it) get the white strain, those in the lower half the black one."""
    img = np.zeros((16, 16), np.uint8)
    img[:8, :] = 255
    Image.fromarray(img).save(tmp_path / "map.png")
    (tmp_path / "s.toml").write_text(scene(cloth='tear_map = "map.png"\ntear_map_strain = [0.15, 0.30]', spread=0.0))
    model = build_model(load_scene(tmp_path / "s.toml"))
    m = mids(model)
    structural = (model.spring_kind == STRUCT_WEFT) | (model.spring_kind == STRUCT_WARP)
    top, bottom = structural & (m[:, 1] > 7.6 * S), structural & (m[:, 1] < 7.4 * S)
    assert top.sum() > 100 and bottom.sum() > 100
    np.testing.assert_allclose(model.spring_break_strain[top], 0.30)
    np.testing.assert_allclose(model.spring_break_strain[bottom], 0.15)


@pytest.mark.parametrize("case,image,fragment", [
    ("wrong shape", (40, 10), "give an image of that shape"),
    ("not an image", None, "not an image"),
])
def test_a_bad_tear_map_is_one_clear_line_and_exit_2(tmp_path, case, image, fragment):
    if image is None:
        (tmp_path / "map.png").write_text("no pixels here")
    else:
        Image.fromarray(np.zeros(image[::-1], np.uint8)).save(tmp_path / "map.png")
    (tmp_path / "s.toml").write_text(scene(cloth='tear_map = "map.png"\ntear_map_strain = [0.15, 0.30]'))
    run = subprocess.run([sys.executable, "-m", "fraytool", "check", str(tmp_path / "s.toml")],
                         capture_output=True, text=True)
    lines = [x for x in run.stderr.splitlines() if x.strip()]
    assert run.returncode == 2 and len(lines) == 1 and fragment in lines[0] and "tear_map" in lines[0], run.stderr


def test_scissors_cut_along_their_path_at_a_constant_speed_and_leave_clean_ends():
    """A straight cut between warps 5 and 6 (u = 5.5 spacings) from v = -0.5 to 15.5 spacings over
    0.04 s: weft yarn j (at v = j spacings) is reached at fraction (j + 0.5) / 16 of the path, at
    t = 0.04 (j + 0.5) / 16, and cut by the end of the step that passes that time."""
    extra = "[[cuts]]\npath_m = [[0.022, -0.002], [0.022, 0.062]]\nstart_s = 0.0\nend_s = 0.04\n"
    spec = parse_scene(scene(extra, frames=12), "c.toml")
    sim = Simulation(spec)
    model = sim.model
    weft = model.weft_structural_spring[:, 5]  # between warps 5 and 6 of every weft yarn
    frame_s = spec.time.step_s * spec.time.steps_per_frame
    for frame in range(1, 12):
        sim.advance_frame()
        t = frame * frame_s
        reached = 0.04 * (np.arange(16) + 0.5) / 16 <= t + 1e-12
        np.testing.assert_array_equal(~sim.state.spring_alive[weft], reached, err_msg=f"frame {frame}")
    assert not sim.state.spring_broken.any()  # scissors are not breaks
    pieces = yarn_pieces(model.arrays(), sim.state.particle_position_m, sim.state.crossing_yarn_level,
                         sim.state.spring_alive)
    assert not pieces.broken_start.any() and not pieces.broken_end.any()
    assert (pieces.kind == 0).sum() == 32  # every weft yarn in two pieces


def test_scissors_cut_each_spring_in_the_step_that_reaches_it():
    """Step by step: after the step ending at time T, the springs the scissors reach by T are cut and no
    others (a cut one step late, or early, shows at some step)."""
    extra = "[[cuts]]\npath_m = [[0.022, -0.002], [0.022, 0.062]]\nstart_s = 0.0\nend_s = 0.0039\n"
    spec = parse_scene(scene(extra, frames=2), "c.toml")
    sim = Simulation(spec)
    weft = sim.model.weft_structural_spring[:, 5]
    reach = 0.0039 * (np.arange(16) + 0.5) / 16  # none within 7e-6 s of a step's end: no rounding tie
    dt = spec.time.step_s
    steps = int(np.ceil(0.0039 / dt)) + 2
    assert steps >= 18  # the cut crosses the yarns within a few steps each: a one-step slip shows
    for k in range(1, steps + 1):
        sim.step()
        np.testing.assert_array_equal(~sim.state.spring_alive[weft], reach <= k * dt + 1e-12, err_msg=f"step {k}")


def test_scissors_need_tearing_on():
    text = scene("[[cuts]]\npath_m = [[0.022, -0.002], [0.022, 0.062]]\nend_s = 0.04\n").replace(
        "enabled = true", "enabled = false")
    with pytest.raises(Exception, match="scissors"):
        parse_scene(text, "c.toml")
    b = ModelBuilder()
    b.add_cloth(warp_yarns=8, weft_yarns=8, spacing_m=S, thickness_m=0.0006, mass_per_crossing_kg=5e-6,
                structural_n_per_m=40.0)
    b.add_cut(path_m=[[0.01, -0.002], [0.01, 0.03]], end_s=0.01)
    with pytest.raises(ModelBuilderError, match="set_tearing"):
        b.finalize()


def test_a_tear_follows_a_diagonal_weak_line_within_3_spacings():
    """Two bars along the left and right edges pull a 24 x 24 cloth apart; a weak line runs across it at
    a slant. Every broken spring lies within 3 yarn spacings of the line (seeds 1 and 2; seeds 1-8 of
    the shipped perforated_tear: benchmarks/weak_line.py, docs/panels.md)."""
    extra = """
[[weak_lines]]
points_m = [[0.036, -0.002], [0.058, 0.094]]
width_m = 0.006
factor = 0.5
[[bodies]]
name = "l"
shape = "box"
half_extents_m = [0.002, 0.002, 0.05]
position_m = [0.0, 0.0, 0.046]
motion = "kinematic"
path = [[0.0, 0.0, 0.0, 0.046], [0.01, 0.0, 0.0, 0.046], [0.30, -0.06, 0.0, 0.046]]
collide = false
[[bodies]]
name = "r"
shape = "box"
half_extents_m = [0.002, 0.002, 0.05]
position_m = [0.092, 0.0, 0.046]
motion = "kinematic"
path = [[0.0, 0.092, 0.0, 0.046], [0.01, 0.092, 0.0, 0.046], [0.30, 0.152, 0.0, 0.046]]
collide = false
[[attachments]]
body = "l"
edge = "left"
[[attachments]]
body = "r"
edge = "right"
"""
    for seed in (1, 2):
        spec = parse_scene(scene(extra, n=24, seed=seed, frames=60), "w.toml")
        sim = Simulation(spec)
        for _ in range(59):
            sim.advance_frame()
        d = tear_distance_to_weak_lines(sim.model, sim.state, spec.weak_lines) / S
        s = sim.summary()
        assert d.size >= 20 and s["pieces"] >= 2, (seed, d.size, s["pieces"])
        assert d.max() <= 3.0, (seed, d.max())
    # and without the weak line the same pull tears elsewhere: the line is what guides it
    no_line = "[[bodies]]" + extra.split("[[bodies]]", 1)[1]
    sim = Simulation(parse_scene(scene(no_line, n=24, seed=1, frames=60), "w.toml"))
    for _ in range(59):
        sim.advance_frame()
    d = tear_distance_to_weak_lines(sim.model, sim.state, spec.weak_lines) / S
    assert d.size == 0 or d.max() > 3.0
