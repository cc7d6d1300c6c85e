"""Panels cut from the weave grid: outline polygons, image masks, grain, hemmed and raw borders
(docs/panels.md). Checked against geometry computed here from the shape itself (lattice points in
a circle, a mask's pixels), not against the builder's own arrays."""
from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from fraytool.render.yarns import yarn_pieces
from fraytool.scene import parse_scene
from fraytool.sim.builder import ModelBuilder, ModelBuilderError, build_model
from fraytool.sim.tearing import YarnTearing, topology_problems
from fraytool.kinds import STRUCT_WEFT

SPACING = 0.004

SCENE = """
[scene]
name = "panel"
seed = 3
[time]
step_s = 2e-4
steps_per_frame = 1
frames = 2
[cloth]
spacing_m = 0.004
thickness_m = 0.0006
mass_per_crossing_kg = 5e-6
plane = "xz"
{shape}
[cloth.springs]
structural_n_per_m = 40.0
bend_n_per_m = 1.0
shear_n_per_m = 5.0
[cloth.tearing]
enabled = true
transition_strain = 0.12
break_strain = 0.2
break_strain_spread = 0.0
"""


def circle(radius_m: float, corners: int = 720, centre=(0.0, 0.0)) -> list[list[float]]:
    return [[centre[0] + radius_m * math.cos(2 * math.pi * k / corners),
             centre[1] + radius_m * math.sin(2 * math.pi * k / corners)] for k in range(corners)]


def toml_points(points) -> str:
    return "[" + ", ".join(f"[{u!r}, {v!r}]" for u, v in points) + "]"


def panel(shape: str, **kw):
    return build_model(parse_scene(SCENE.format(shape=shape), "panel.toml", **kw))


def uv(model):
    """Rest positions in the xz plane as (u, v) [m]."""
    return model.crossing_rest_position_m[:, [0, 2]]


def test_a_round_outline_holds_exactly_the_lattice_points_inside_the_circle():
    r = 0.1013
    model = panel(f"outline_m = {toml_points(circle(r))}")
    p = uv(model)
    # every crossing inside the circle, on the lattice spacing_m apart
    assert (np.hypot(p[:, 0], p[:, 1]) < r).all()
    assert np.allclose(p / SPACING, np.round(p / SPACING), atol=1e-9)
    # and every lattice point well inside the circle is a crossing (the 720-gon hugs the circle to 1 um)
    k = np.arange(-30, 31)
    lattice = np.stack(np.meshgrid(k, k), -1).reshape(-1, 2) * SPACING
    d = np.hypot(lattice[:, 0], lattice[:, 1])
    assert (np.abs(d - r) > 1e-5).all()  # no lattice point on the rim, where a 720-gon and a circle differ
    inside = lattice[d < r]
    assert model.crossing_count == len(inside)


def test_memory_and_work_follow_the_panels_area_not_its_bounding_box():
    """A disc of radius r against the square of side 2r around it: crossings, springs and every array of
    the model scale with the area ratio pi/4 (the grid's per-place tables are a few bytes each)."""
    r = 0.12
    disc = panel(f"outline_m = {toml_points(circle(r))}")
    square = panel(f"outline_m = {toml_points([[-r, -r], [r, -r], [r, r], [-r, r]])}")
    ratio = math.pi / 4
    assert disc.crossing_count / square.crossing_count == pytest.approx(ratio, rel=0.04)
    assert disc.spring_count / square.spring_count == pytest.approx(ratio, rel=0.05)
    size = lambda m: sum(v.nbytes for v in m.arrays().values())
    assert size(disc) / size(square) == pytest.approx(ratio, rel=0.05)
    # the state a step works on, too
    assert disc.state().particle_position_m.nbytes / square.state().particle_position_m.nbytes == \
        pytest.approx(ratio, rel=0.04)


def test_a_rectangle_given_as_an_outline_is_the_rectangle():
    rect = build_model(parse_scene(SCENE.format(shape="warp_yarns = 9\nweft_yarns = 5"), "r.toml"))
    w, h = 8 * SPACING, 4 * SPACING
    shaped = panel(f"outline_m = {toml_points([[-1e-6, -1e-6], [w + 1e-6, -1e-6], [w + 1e-6, h + 1e-6], [-1e-6, h + 1e-6]])}")
    assert shaped.crossing_count == rect.crossing_count == 45
    np.testing.assert_array_equal(shaped.crossing_rest_position_m, rect.crossing_rest_position_m)
    np.testing.assert_array_equal(shaped.spring_crossing_a, rect.spring_crossing_a)
    np.testing.assert_array_equal(shaped.spring_kind, rect.spring_kind)


def test_grain_turns_the_weave_inside_the_outline():
    model = panel(f"outline_m = {toml_points(circle(0.05))}\ngrain_deg = 30.0")
    weft = model.spring_kind == STRUCT_WEFT
    d = uv(model)[model.spring_crossing_b[weft]] - uv(model)[model.spring_crossing_a[weft]]
    assert np.allclose(np.hypot(d[:, 0], d[:, 1]), SPACING)
    assert np.allclose(np.degrees(np.arctan2(d[:, 1], d[:, 0])), 30.0)


def test_a_mask_image_keeps_the_crossings_over_white(tmp_path):
    """An L-shaped mask of 40 x 40 pixels over 0.16 m: a crossing exists where its pixel is white."""
    img = np.zeros((40, 40), np.uint8)
    img[:, :10] = 255       # the left quarter, full height
    img[30:, :] = 255       # the bottom quarter (image rows 30.. are v < 0.04 m)
    Image.fromarray(img).save(tmp_path / "L.png")
    scene = tmp_path / "s.toml"
    scene.write_text(SCENE.format(shape='mask = "L.png"\nmask_size_m = [0.16, 0.16]'))
    from fraytool.scene import load_scene

    model = build_model(load_scene(scene))
    p = uv(model)
    px = np.floor(p[:, 0] / 0.16 * 40).astype(int)
    py = np.floor((1 - p[:, 1] / 0.16) * 40).astype(int)
    assert (img[py, px] == 255).all()
    # count the white lattice points independently
    k = np.arange(0, 41) * SPACING
    uu, vv = np.meshgrid(k, k)
    x, y = np.floor(uu / 0.16 * 40).astype(int), np.floor((1 - vv / 0.16) * 40).astype(int)
    ok = (x >= 0) & (x < 40) & (y >= 0) & (y < 40)
    assert model.crossing_count == int((img[y[ok], x[ok]] == 255).sum())


def test_hemmed_border_crossings_never_split_raw_ones_do():
    """Stretch a disc 15 % (past the 12 % transition, below the 20 % break): on a raw disc border
    crossings split into couples like any other; on a hemmed one the border stays base level."""
    shape = f"outline_m = {toml_points(circle(0.04, 90))}"
    for edge in ("raw", "hemmed"):
        model = panel(shape + f'\nedge = "{edge}"')
        state = model.state()
        x = state.particle_position_m
        x[:model.crossing_count] *= 1.15
        YarnTearing(model)(state, x.copy(), 2e-4)
        assert topology_problems(model, state) == []
        border = np.zeros(model.crossing_count, bool)
        border |= (model.crossing_weft_springs < 0).any(axis=1) | (model.crossing_warp_springs < 0).any(axis=1)
        split = state.crossing_yarn_level
        assert split[~border].sum() > 20
        if edge == "raw":
            assert split[border].sum() > 10
        else:
            assert not split[border].any()
            assert model.crossing_hemmed.sum() == border.sum()


def test_a_hem_doubles_the_break_strain_of_the_yarn_segments_along_it_only():
    """The same disc, raw and hemmed, draws the same break strains; the hem doubles those of the structural
    springs with both ends on the border (the folded-over yarn), not those from the border inwards."""
    from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT

    shape = f"outline_m = {toml_points(circle(0.04, 90))}"
    raw, hemmed = panel(shape + '\nedge = "raw"'), panel(shape + '\nedge = "hemmed"')
    border = (raw.crossing_weft_springs < 0).any(axis=1) | (raw.crossing_warp_springs < 0).any(axis=1)
    a, b = raw.spring_crossing_a, raw.spring_crossing_b
    structural = (raw.spring_kind == STRUCT_WEFT) | (raw.spring_kind == STRUCT_WARP)
    along, inward = structural & border[a] & border[b], structural & (border[a] != border[b])
    assert along.sum() > 20 and inward.sum() > 20
    ratio = hemmed.spring_break_strain / raw.spring_break_strain
    np.testing.assert_allclose(ratio[along], 2.0)
    np.testing.assert_allclose(ratio[~along], 1.0)


def test_yarn_pieces_of_a_round_panel_run_inside_it():
    """Untorn, every weft row and warp column of a disc is one piece from border to border, with clean
    (not frayed) ends."""
    model = panel(f"outline_m = {toml_points(circle(0.05))}")
    state = model.state()
    topo = model.arrays()
    pieces = yarn_pieces(topo, state.particle_position_m, state.crossing_yarn_level, state.spring_alive)
    rows = np.unique(model.crossing_grid_j).size
    cols = np.unique(model.crossing_grid_i).size
    assert (pieces.kind == 0).sum() == rows and (pieces.kind == 1).sum() == cols
    assert not pieces.broken_start.any() and not pieces.broken_end.any()
    assert pieces.points.shape[0] == 2 * model.crossing_count
    assert (np.hypot(pieces.points[:, 0], pieces.points[:, 2]) < 0.05).all()


def test_a_round_panel_simulates_and_tears_with_a_valid_topology():
    """Pulled at two opposite rim points until it tears: finite, the tear's topology consistent."""
    from fraytool.sim import Simulation

    text = SCENE.format(shape=f"outline_m = {toml_points(circle(0.03, 90))}") + """
[[bodies]]
name = "a"
shape = "sphere"
radius_m = 0.002
position_m = [-0.03, 0.0, 0.0]
motion = "kinematic"
velocity_m_s = [-1.0, 0.0, 0.0]
collide = false
[[bodies]]
name = "b"
shape = "sphere"
radius_m = 0.002
position_m = [0.03, 0.0, 0.0]
motion = "kinematic"
velocity_m_s = [1.0, 0.0, 0.0]
collide = false
[[attachments]]
body = "a"
edge = "left"
[[attachments]]
body = "b"
edge = "right"
"""
    spec = parse_scene(text.replace("frames = 2", "frames = 40").replace("steps_per_frame = 1", "steps_per_frame = 10"), "p.toml")
    sim = Simulation(spec)
    for _ in range(39):
        sim.advance_frame()
    s = sim.summary()
    assert s["all_finite"] and s["broken_springs"] > 0
    assert topology_problems(sim.model, sim.state) == []


BAD_SHAPES = {
    "a strip one yarn wide": ("outline_m = [[-0.001, -0.001], [0.041, -0.001], [0.041, 0.001], [-0.001, 0.001]]",
                              "holds 11 crossings at spacing_m = 0.004 but no 2 x 2 cell"),
    "self-intersecting": ("outline_m = [[0.0, 0.0], [0.1, 0.1], [0.1, 0.0], [0.0, 0.1]]", "cross: a panel's outline must not cross itself"),
    "too small": ("outline_m = [[0.0, 0.0], [0.005, 0.0], [0.0, 0.005]]", "a panel needs at least 4"),
    "two points": ("outline_m = [[0.0, 0.0], [0.1, 0.0]]", "needs at least 3 points"),
    "both shapes": ('outline_m = [[0.0, 0.0], [0.1, 0.0], [0.0, 0.1]]\nmask = "m.png"\nmask_size_m = [0.1, 0.1]',
                    "give outline_m or mask, not both"),
    "mask not an image": ('mask = "notes.png"\nmask_size_m = [0.1, 0.1]', "not an image"),
    "mask missing": ('mask = "nowhere.png"\nmask_size_m = [0.1, 0.1]', "no such file"),
    "mask without size": ('mask = "notes.png"', "mask_size_m"),
    "yarns with an outline": ("warp_yarns = 10\noutline_m = [[0.0, 0.0], [0.1, 0.0], [0.0, 0.1]]", "the shape sets the grid"),
    "no shape no yarns": ("weft_yarns = 10", "`warp_yarns` is missing or 0"),
}


@pytest.mark.parametrize("case", sorted(BAD_SHAPES))
def test_a_bad_shape_is_one_clear_line_and_exit_2(case, tmp_path):
    shape, fragment = BAD_SHAPES[case]
    (tmp_path / "notes.png").write_text("these are notes, not pixels")
    scene = tmp_path / "bad.toml"
    scene.write_text(SCENE.format(shape=shape))
    run = subprocess.run([sys.executable, "-m", "fraytool", "check", str(scene)], capture_output=True, text=True)
    assert run.returncode == 2, run.stderr
    lines = [line for line in run.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and fragment in lines[0] and "bad.toml: [cloth]" in lines[0], run.stderr
    assert "Traceback" not in run.stderr


def test_the_builder_refuses_a_bad_outline_in_one_line():
    b = ModelBuilder()
    with pytest.raises(ModelBuilderError, match="must not cross itself"):
        b.add_cloth(spacing_m=0.004, thickness_m=0.0006, mass_per_crossing_kg=5e-6, structural_n_per_m=40.0,
                    outline_m=[[0, 0], [0.1, 0.1], [0.1, 0], [0, 0.1]])
    b.add_cloth(spacing_m=0.004, thickness_m=0.0006, mass_per_crossing_kg=5e-6, structural_n_per_m=40.0,
                outline_m=circle(0.02, 60), edge="hemmed")
    model = b.finalize()
    assert model.crossing_hemmed.any() and not model.full_grid
