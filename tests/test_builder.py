"""ModelBuilder in code: the same Model as the scene file, the grid's known counts and lengths, and one
clear error per bad argument."""
import dataclasses
import inspect
import math
from pathlib import Path

import numpy as np
import pytest

from fraytool.errors import SceneError
from fraytool.kinds import BEND_WARP, BEND_WEFT, SHEAR, SHEAR_TWIN, STRUCT_WARP, STRUCT_WEFT
from fraytool.scene import load_scene, parse_scene, schema
from fraytool.sim import ModelBuilder, build_model
from fraytool.sim.builder import ModelBuilderError, PanelConfig
from helpers import assert_arrays_equal

pytestmark = pytest.mark.fast  # `pytest -m fast` (docs/testing.md)

ROOT = Path(__file__).resolve().parent.parent

SCENE = """
[scene]
name = "built"
seed = 7
[time]
step_s = 2e-4
steps_per_frame = 10
frames = 3
[world]
gravity_m_s2 = [0.0, -9.0, 0.5]
[cloth]
warp_yarns = 14
weft_yarns = 9
spacing_m = 0.004
thickness_m = 0.0006
mass_per_crossing_kg = 5e-6
origin_m = [-0.02, 0.05, 0.01]
plane = "xy"
weave = "twill"
twill = "3/1"
[cloth.springs]
structural_n_per_m = 40.0
bend_n_per_m = 1.0
shear_n_per_m = 5.0
damping = 0.02
[cloth.strain]
limit = 0.08
max_iterations = 12
tolerance = 1e-5
[cloth.tearing]
enabled = true
transition_strain = 0.1
break_strain = 0.16
break_strain_spread = 0.02
disconnect_factor = 2.5
[self_collision]
enabled = true
iterations = 3
friction = 0.1
[[bodies]]
name = "bar"
shape = "box"
half_extents_m = [0.002, 0.03, 0.002]
position_m = [-0.02, 0.066, 0.01]
rotation_deg = [0.0, 0.0, 10.0]
collide = false
[[bodies]]
name = "grip"
shape = "sphere"
radius_m = 0.003
motion = "kinematic"
path = [[0.0, 0.032, 0.082, 0.01], [0.1, 0.05, 0.09, 0.01]]
rotation_deg = [0.0, 30.0, 0.0]
gravity = false
[[bodies]]
name = "ball"
shape = "sphere"
radius_m = 0.01
motion = "dynamic"
mass_kg = 0.02
position_m = [0.01, 0.06, 0.03]
velocity_m_s = [0.0, 0.0, -2.0]
friction = 0.25
start_s = 0.01
[[bodies]]
name = "floor"
shape = "plane"
normal = [0.0, 2.0, 0.0]
position_m = [0.0, -0.1, 0.0]
motion = "kinematic"
velocity_m_s = [0.0, 0.1, 0.0]
[[attachments]]
body = "bar"
edge = "left"
[[attachments]]
body = "grip"
corner = "top_right"
corner_size = 2
[[attachments]]
body = "ball"
warp_range = [5, 6]
weft_range = [0, 8]
[[attachments]]
body = "bar"
region_center_m = [0.0, 0.06, 0.01]
region_radius_m = 0.005
"""


def built_in_code() -> ModelBuilder:
    """SCENE, written as ModelBuilder calls."""
    b = ModelBuilder(seed=7, gravity_m_s2=(0.0, -9.0, 0.5))
    b.add_cloth(warp_yarns=14, weft_yarns=9, spacing_m=0.004, thickness_m=0.0006, mass_per_crossing_kg=5e-6,
                origin_m=(-0.02, 0.05, 0.01), plane="xy", weave="twill", twill="3/1",
                structural_n_per_m=40.0, bend_n_per_m=1.0, shear_n_per_m=5.0, damping=0.02)
    b.set_strain_limit(limit=0.08, max_iterations=12, tolerance=1e-5)
    b.set_tearing(transition_strain=0.1, break_strain=0.16, break_strain_spread=0.02, disconnect_factor=2.5)
    b.set_self_collision(iterations=3, friction=0.1)
    b.add_box("bar", half_extents_m=(0.002, 0.03, 0.002), position_m=(-0.02, 0.066, 0.01),
              rotation_deg=(0.0, 0.0, 10.0), collide=False)
    b.add_sphere("grip", radius_m=0.003, motion="kinematic", rotation_deg=(0.0, 30.0, 0.0), gravity=False,
                 path=[(0.0, 0.032, 0.082, 0.01), (0.1, 0.05, 0.09, 0.01)])
    ball = b.add_sphere("ball", radius_m=0.01, motion="dynamic", mass_kg=0.02, position_m=(0.01, 0.06, 0.03),
                        velocity_m_s=(0.0, 0.0, -2.0), friction=0.25, start_s=0.01)
    b.add_plane("floor", normal=(0.0, 2.0, 0.0), position_m=(0.0, -0.1, 0.0), motion="kinematic",
                velocity_m_s=(0.0, 0.1, 0.0))
    b.add_attachment("bar", edge="left")
    b.add_attachment("grip", corner="top_right", corner_size=2)
    b.add_attachment(ball, warp_range=(5, 6), weft_range=(0, 8))  # a body index works as well as its name
    b.add_attachment("bar", region_center_m=(0.0, 0.06, 0.01), region_radius_m=0.005)
    return b


def assert_models_equal(expected, actual) -> None:
    """Every field bit for bit, naming the first that differs."""
    assert_arrays_equal(expected.arrays(), actual.arrays())
    assert expected.arrays().keys() == actual.arrays().keys()
    assert expected.body_names == actual.body_names
    assert_arrays_equal(dict(enumerate(expected.body_path)), dict(enumerate(actual.body_path)))
    for f in dataclasses.fields(expected):
        a, b = getattr(expected, f.name), getattr(actual, f.name)
        if not isinstance(a, (np.ndarray, tuple)):
            assert type(a) is type(b) and a == b, f.name


# --- the same Model from code as from the file ------------------------------------------------------

def test_scene_built_in_code_equals_the_scene_file():
    assert_models_equal(build_model(parse_scene(SCENE, "built.toml")), built_in_code().finalize())


def test_readme_example_is_the_drape_scene():
    b = ModelBuilder(seed=1)
    b.add_cloth(warp_yarns=30, weft_yarns=30, spacing_m=0.005, thickness_m=0.0008, mass_per_crossing_kg=2.0e-5,
                origin_m=(-0.0725, 0.12, -0.0725), structural_n_per_m=20.0, bend_n_per_m=0.5, shear_n_per_m=2.0)
    b.set_strain_limit(limit=0.10, max_iterations=30)
    b.add_sphere("ball", radius_m=0.05, position_m=(0.0, 0.05, 0.0), friction=0.4)
    b.add_plane("floor", friction=0.6)
    assert_models_equal(build_model(load_scene(ROOT / "scenes" / "drape.toml")), b.finalize())


def test_numpy_arguments_give_the_same_model():
    def build(seed, nx, origin):
        b = ModelBuilder(seed=seed)
        b.add_cloth(warp_yarns=nx, weft_yarns=5, spacing_m=0.01, thickness_m=0.001, mass_per_crossing_kg=1e-5,
                    structural_n_per_m=10.0, origin_m=origin)
        return b.finalize()
    assert_models_equal(build(3, 6, (0.0, 0.1, 0.0)), build(np.int64(3), np.int32(6), np.array([0.0, 0.1, 0.0])))


def test_finalize_leaves_the_builder_usable():
    b = built_in_code()
    first = b.finalize()
    assert_models_equal(first, b.finalize())
    b.add_sphere("late", radius_m=0.01)
    assert b.finalize().body_count == first.body_count + 1


# --- facts known without the builder ------------------------------------------------------------------

def grid(nx=11, ny=7, spacing=0.004, bend=1.0, shear=5.0, **cloth):
    b = ModelBuilder()
    b.add_cloth(warp_yarns=nx, weft_yarns=ny, spacing_m=spacing, thickness_m=spacing / 8,
                mass_per_crossing_kg=cloth.pop("mass", 5e-6), structural_n_per_m=40.0, bend_n_per_m=bend,
                shear_n_per_m=shear, **cloth)
    return b


def test_total_mass_from_areal_density():
    density_kg_m2, s, nx, ny = 0.15, 0.005, 20, 13
    model = grid(nx, ny, s, mass=density_kg_m2 * s * s).finalize()  # each crossing stands for an s x s patch
    assert math.isclose(model.crossing_mass_kg.sum(), density_kg_m2 * (nx * s) * (ny * s), rel_tol=1e-12)


@pytest.mark.parametrize("nx,ny", [(2, 2), (11, 7), (3, 20)])
def test_spring_counts_and_rest_lengths_follow_the_grid(nx, ny):
    s = 0.004
    model = grid(nx, ny, s).finalize()
    count = {k: int((model.spring_kind == k).sum()) for k in range(6)}
    assert count[STRUCT_WEFT] == ny * (nx - 1) and count[STRUCT_WARP] == nx * (ny - 1)
    assert count[BEND_WEFT] == ny * (nx - 2) and count[BEND_WARP] == nx * (ny - 2)
    assert count[SHEAR] == count[SHEAR_TWIN] == 2 * (nx - 1) * (ny - 1)
    expected = {STRUCT_WEFT: s, STRUCT_WARP: s, BEND_WEFT: 2 * s, BEND_WARP: 2 * s,
                SHEAR: math.sqrt(2) * s, SHEAR_TWIN: math.sqrt(2) * s}
    for kind, length in expected.items():
        np.testing.assert_allclose(model.spring_rest_length_m[model.spring_kind == kind], length, rtol=1e-12)
    assert model.weft_structural_spring.shape == (ny, nx - 1) and model.warp_structural_spring.shape == (nx, ny - 1)


def test_no_bend_or_shear_springs_at_zero_stiffness():
    model = grid(bend=0.0, shear=0.0).finalize()
    assert set(np.unique(model.spring_kind)) == {STRUCT_WEFT, STRUCT_WARP}
    assert (model.spring_twin == -1).all()


def test_grid_lies_in_its_plane_from_the_origin():
    s, nx, ny = 0.004, 11, 7
    model = grid(nx, ny, s, plane="xy", origin_m=(0.1, 0.2, 0.3)).finalize()
    x = model.crossing_rest_position_m
    np.testing.assert_allclose(x[:, 2], 0.3)
    np.testing.assert_allclose(x[nx * ny - 1], (0.1 + (nx - 1) * s, 0.2 + (ny - 1) * s, 0.3), rtol=1e-12)


def test_plain_weave_alternates_at_every_crossing():
    model = grid(nx=6, ny=5).finalize()
    ii, jj = np.meshgrid(np.arange(6), np.arange(5))
    assert (model.crossing_weft_on_top == ((ii + jj) % 2 == 0).ravel()).all()


def test_attachments_select_edges_and_corners_and_keep_the_first_holder():
    nx, ny = 11, 7
    b = grid(nx, ny)
    b.add_box("bar", half_extents_m=(0.001, 0.02, 0.001))
    b.add_sphere("grip", radius_m=0.002)
    b.add_attachment("bar", edge="left")
    b.add_attachment("grip", corner="bottom_left", corner_size=3)
    model = b.finalize()
    left = [j * nx for j in range(ny)]
    corner_only = [j * nx + i for j in range(3) for i in range(1, 3)]
    assert model.attachment_particle.tolist() == left + corner_only
    assert model.attachment_body.tolist() == [0] * ny + [1] * len(corner_only)


def test_break_strains_come_from_the_seed_and_stay_above_the_transition():
    def strains(seed):
        b = ModelBuilder(seed=seed)
        b.add_cloth(warp_yarns=8, weft_yarns=8, spacing_m=0.004, thickness_m=0.0005, mass_per_crossing_kg=5e-6,
                    structural_n_per_m=40.0)
        b.set_tearing(transition_strain=0.15, break_strain=0.16, break_strain_spread=0.05)
        return b.finalize().spring_break_strain
    assert (strains(4) == strains(4)).all() and not (strains(4) == strains(5)).all()
    assert strains(4).min() >= 0.15 * 1.01


def test_solver_settings_reach_the_model():
    m = built_in_code().finalize()
    assert (m.strain_limit, m.strain_max_iterations, m.strain_tolerance) == (0.08, 12, 1e-5)
    assert m.tearing and m.yarn_level and m.transition_strain == 0.1
    assert math.isclose(m.disconnect_distance_m, 2.5 * 0.0006)
    assert m.self_collision and m.self_collision_iterations == 3
    plain = grid().finalize()
    assert not plain.tearing and not plain.self_collision and plain.strain_limit == 0.10


# --- clear errors for bad arguments ---------------------------------------------------------------------

def cloth(**change):
    args = dict(warp_yarns=10, weft_yarns=8, spacing_m=0.005, thickness_m=0.0008, mass_per_crossing_kg=2e-5,
                structural_n_per_m=20.0)
    args.update(change)
    return lambda b: b.add_cloth(**args)


def with_cloth(call):
    def run(b):
        cloth()(b)
        b.add_sphere("ball", radius_m=0.01)
        call(b)
    return run


BAD = {
    "negative spacing": (cloth(spacing_m=-0.01), ["ModelBuilder.add_cloth: spacing_m = -0.01", "a number >= 1e-06"]),
    "spacing as text": (cloth(spacing_m="5mm"), ['spacing_m = "5mm"', "a number"]),
    "too few yarns": (cloth(warp_yarns=1), ["warp_yarns = 1", "an integer >= 2"]),
    "fractional yarns": (cloth(weft_yarns=2.5), ["weft_yarns = 2.5", "an integer"]),
    "unknown weave": (cloth(weave="knit"), ['weave = "knit"', '"plain"', '"twill"']),
    "bad twill": (cloth(weave="twill", twill="2-2"), ['twill = "2-2"', '"a/b"']),
    "table weave without table": (cloth(weave="table"), ['weave = "table"', "needs a `table` key"]),
    "thick cloth": (cloth(thickness_m=0.006), ["thickness_m = 0.006", "must be below spacing_m = 0.005"]),
    "short origin": (cloth(origin_m=(0.0, 0.1)), ["origin_m = [0.0, 0.1]", "3 numbers"]),
    "damping above 1": (cloth(damping=1.5), ["damping = 1.5", "<= 1"]),
    "second cloth": (lambda b: (cloth()(b), cloth()(b)), ["add_cloth", "add_panel adds more"]),
    "seed below 0": (lambda b: ModelBuilder(seed=-1), ["ModelBuilder: seed = -1", ">= 0"]),
    "zero strain limit": (lambda b: b.set_strain_limit(limit=0.0), ["set_strain_limit: limit = 0.0", "> 0"]),
    "damper on a hard limit": (lambda b: b.set_strain_limit(damping_ratio=1.0),
                               ["set_strain_limit: damping_ratio = 1.0", "needs stiffness_n_per_m > 0"]),
    "transition above break": (lambda b: b.set_tearing(transition_strain=0.3, break_strain=0.2),
                               ["set_tearing: transition_strain = 0.3", "must be below break_strain = 0.2"]),
    "no self-collision passes": (lambda b: b.set_self_collision(iterations=0), ["iterations = 0", ">= 1"]),
    "zero radius": (lambda b: b.add_sphere("s", radius_m=0.0), ["add_sphere: radius_m = 0.0", "> 0"]),
    "flat box": (lambda b: b.add_box("b", half_extents_m=(0.1, 0.0, 0.1)), ["add_box", "half_extents_m", "> 0"]),
    "dynamic plane": (lambda b: b.add_plane("p", motion="dynamic"), ['add_plane: motion = "dynamic"', '"static"']),
    "zero normal": (lambda b: b.add_plane("p", normal=(0, 0, 0)), ["normal = [0.0, 0.0, 0.0]", "non-zero"]),
    "unknown motion": (lambda b: b.add_sphere("s", radius_m=0.1, motion="flying"),
                       ['motion = "flying"', '"kinematic"']),
    "path without kinematic": (lambda b: b.add_sphere("s", radius_m=0.1, path=[(0, 0, 0, 0)]),
                               ["path", 'needs motion = "kinematic"']),
    "path back in time": (lambda b: b.add_sphere("s", radius_m=0.1, motion="kinematic",
                                                 path=[(1, 0, 0, 0), (0.5, 0, 0, 0)]), ["path = ", "[t, x, y, z]"]),
    "same name twice": (lambda b: (b.add_sphere("s", radius_m=0.1), b.add_box("s", half_extents_m=(1, 1, 1))),
                        ['add_box: name = "s"', "unique"]),
    "attachment before cloth": (lambda b: b.add_attachment("ball", edge="left"),
                                ["add_attachment", "add_cloth first"]),
    "unknown body": (with_cloth(lambda b: b.add_attachment("ghost", edge="left")),
                     ['add_attachment: body = "ghost"', "must name one of", "ball"]),
    "body index out of range": (with_cloth(lambda b: b.add_attachment(3, edge="left")), ["body = 3", "1 added"]),
    "two selections": (with_cloth(lambda b: b.add_attachment("ball", edge="left", corner="top_left")),
                       ["exactly one selection", "edge", "corner"]),
    "no selection": (with_cloth(lambda b: b.add_attachment("ball")), ["exactly one selection", "none"]),
    "range outside the grid": (with_cloth(lambda b: b.add_attachment("ball", warp_range=(0, 10), weft_range=(0, 1))),
                               ["warp_range = [0, 10]", "<= 9"]),
    "lone weft range": (with_cloth(lambda b: b.add_attachment("ball", weft_range=(0, 1))), ["go together"]),
    "region without radius": (with_cloth(lambda b: b.add_attachment("ball", region_center_m=(0, 0, 0))),
                              ["region_radius_m = 0.0", "must be > 0"]),
    "finalize without cloth": (lambda b: b.finalize(), ["ModelBuilder.finalize", "add_cloth"]),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_argument_gives_one_clear_error(case):
    call, fragments = BAD[case]
    with pytest.raises(ModelBuilderError) as info:
        call(ModelBuilder())
    message = str(info.value)
    for fragment in fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"
    assert isinstance(info.value, ValueError) and isinstance(info.value, SceneError)  # Python and CLI both


def test_every_bad_argument_of_a_call_is_reported_at_once():
    with pytest.raises(ModelBuilderError) as info:
        cloth(spacing_m=0.0, mass_per_crossing_kg=-1.0, plane="xx")(ModelBuilder())
    assert len(info.value.messages) == 3


def test_unknown_argument_is_a_type_error():
    with pytest.raises(TypeError, match="spacing"):
        cloth(spacing=0.005)(ModelBuilder())


def test_a_failed_call_adds_nothing():
    b = ModelBuilder()
    with pytest.raises(ModelBuilderError):
        b.add_sphere("s", radius_m=-1.0)
    with pytest.raises(ModelBuilderError):
        cloth(thickness_m=1.0)(b)
    assert b.bodies == [] and b.cloth is None


# --- one declaration per key: the builder's arguments are the scene keys -------------------------------

T = schema.TOP
METHOD_KEYS = {
    "__init__": {"seed": T["scene"]["seed"], **T["world"]},
    "PanelConfig": {**T["cloth"], **T["cloth.springs"]},
    "set_strain_limit": T["cloth.strain"],
    "set_tearing": T["cloth.tearing"],
    "set_self_collision": T["self_collision"],
    "add_attachment": T["attachments"],
}


@pytest.mark.parametrize("method", sorted(METHOD_KEYS))
def test_builder_arguments_are_the_scene_keys_with_their_defaults(method):
    keys = METHOD_KEYS[method]
    target = PanelConfig if method == "PanelConfig" else getattr(ModelBuilder, method)
    params = {n: p for n, p in inspect.signature(target).parameters.items() if n != "self"}
    assert set(params) == set(keys)
    for name, p in params.items():
        if name == "enabled":
            assert p.default is True  # calling set_tearing / set_self_collision turns it on
        elif keys[name].default is schema.REQUIRED:
            assert p.default is inspect.Parameter.empty, name
        else:
            assert p.default == keys[name].default, name


def test_a_panel_config_is_one_record_for_add_cloth_and_add_panel_and_keywords_replace_its_values():
    """The same PanelConfig makes two panels; a keyword given beside it wins; the Model is the one the
    keywords alone make; a setting that is not a key, or a required one left out, is a TypeError."""
    from fraytool.sim.builder import PanelConfig

    shirt = PanelConfig(spacing_m=0.005, thickness_m=0.001, mass_per_crossing_kg=2e-5, structural_n_per_m=20.0,
                        warp_yarns=6, weft_yarns=5, shear_n_per_m=3.0)
    by_config = ModelBuilder(seed=2)
    by_config.add_cloth(shirt)
    assert by_config.add_panel("back", shirt, origin_m=(0.1, 0.0, 0.0), warp_yarns=4) == 1
    by_keys = ModelBuilder(seed=2)
    by_keys.add_cloth(spacing_m=0.005, thickness_m=0.001, mass_per_crossing_kg=2e-5, structural_n_per_m=20.0,
                      warp_yarns=6, weft_yarns=5, shear_n_per_m=3.0)
    by_keys.add_panel("back", spacing_m=0.005, thickness_m=0.001, mass_per_crossing_kg=2e-5,
                      structural_n_per_m=20.0, warp_yarns=4, weft_yarns=5, shear_n_per_m=3.0, origin_m=(0.1, 0.0, 0.0))
    a, b = by_config.finalize(), by_keys.finalize()
    assert a.crossing_count == 6 * 5 + 4 * 5 and a.digest() == b.digest()
    with pytest.raises(TypeError, match="'spacing'"):
        ModelBuilder().add_cloth(shirt, spacing=0.004)
    with pytest.raises(TypeError, match="'structural_n_per_m'"):
        ModelBuilder().add_cloth(spacing_m=0.005, thickness_m=0.001, mass_per_crossing_kg=2e-5, warp_yarns=3,
                                 weft_yarns=3)


def test_body_methods_cover_every_body_key():
    taken = set()
    arrays = {"vertices_m", "triangles", "key_times_s"}  # add_mesh: a mesh given in code, not a scene key
    for method in ("add_sphere", "add_box", "add_plane", "add_mesh"):
        params = {n: p for n, p in inspect.signature(getattr(ModelBuilder, method)).parameters.items()
                  if n not in arrays}
        for name, p in params.items():
            if name == "file":
                assert p.default is None  # file or arrays: neither given is an error
            elif name != "self" and p.default is not inspect.Parameter.empty:
                assert p.default == schema.TOP["bodies"][name].default, (method, name)
        taken |= set(params) - {"self"}
    assert taken == set(schema.TOP["bodies"]) - {"shape"}


@pytest.mark.parametrize("normal, unit", [((1e200, 1e200, 0.0), (2 ** -0.5, 2 ** -0.5, 0.0)),
                                          ((0.0, 1e-200, 0.0), (0.0, 1.0, 0.0))])
def test_plane_normal_keeps_its_direction_at_any_scale(normal, unit):
    # |n|^2 overflows to inf for the first (n / |n| was 0: a plane facing nowhere) and underflows to
    # 0 for the second (it was refused as a zero vector).
    b = ModelBuilder()
    b.add_plane("floor", normal=normal)
    b.add_cloth(warp_yarns=3, weft_yarns=3, spacing_m=0.01, thickness_m=0.001, mass_per_crossing_kg=1e-5,
                structural_n_per_m=10.0)
    np.testing.assert_allclose(b.finalize().body_params[0], unit, rtol=1e-12)  # a plane: its unit normal


@pytest.mark.parametrize("centre, holds", [("[0.0, 0.1, 0.5]", False), ("[0.0, 0.1, 0.0]", True)])
def test_an_attachment_that_holds_no_crossing_is_a_warning(centre, holds, tmp_path, capsys):
    """The 12 x 12 cloth lies at y = 0.1 m over x, z from -0.03 to 0.025 m: a 1 cm region around z = 0.5 m
    holds none of it (the nearest crossing, at x = 0, z = 0.025, is 0.475 m away), and check says so and
    that the ball holds nothing; around the origin it holds some, and nothing is said."""
    from fraytool.commands.main import main
    from helpers import BALL, small_scene_text

    path = tmp_path / "s.toml"
    path.write_text(small_scene_text() + BALL + f'\n[[attachments]]\nbody = "ball"\nregion_center_m = {centre}\n'
                    "region_radius_m = 0.01\n")
    assert main(["check", str(path)]) == 0
    warnings = [x for x in capsys.readouterr().err.splitlines() if x.startswith("fraytool: warning:")]
    if holds:
        assert warnings == []
        return
    assert warnings == [f"fraytool: warning: {path}: [attachments.0] body 'ball': region_radius_m = 0.01 around "
                        "region_center_m = [0, 0.1, 0.5] holds no crossing of panel 'cloth' (the nearest is 0.475 m "
                        "from the centre); the body holds nothing"]


def test_a_model_built_in_python_carries_the_warnings_of_its_entries():
    """The builder warns where the facts are at hand, so a Model built in code (no scene file) says too that
    its attachment holds nothing: a 1 cm region 0.4 m off a 5 x 5 cloth at the origin."""
    b = ModelBuilder()
    b.add_cloth(spacing_m=0.01, thickness_m=0.001, mass_per_crossing_kg=1e-5, structural_n_per_m=10.0,
                warp_yarns=5, weft_yarns=5)
    b.add_sphere("ball", radius_m=0.01)
    b.add_attachment("ball", region_center_m=(0.4, 0.0, 0.0), region_radius_m=0.01)
    b.add_attachment("ball", corner="top_left")
    model = b.finalize()
    assert list(model.build_warnings) == b.warnings
    assert len(model.build_warnings) == 1
    line = model.build_warnings[0]
    assert line.startswith("ModelBuilder: [attachments.0] body 'ball':") and "(the nearest is 0.36 m" in line
    assert model.attachment_entry_crossings.tolist() == [0, 1]


def test_a_hemmed_panel_doubles_its_border_yarns_break_strain_whichever_panel_it_is():
    """The hem doubles the break strain of structural springs along the border of a hemmed panel, the second
    panel's as well as the first's (it once did only where the first panel was hemmed)."""
    def build(first_edge: str, second_edge: str):
        b = ModelBuilder(seed=5)
        args = dict(spacing_m=0.01, thickness_m=0.001, mass_per_crossing_kg=1e-5, structural_n_per_m=10.0,
                    warp_yarns=4, weft_yarns=4)
        b.add_cloth(**args, edge=first_edge)
        b.add_panel("b", **args, edge=second_edge, origin_m=(0.1, 0.0, 0.0))
        b.set_tearing(break_strain=0.2, break_strain_spread=0.0)
        return b.finalize()

    from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT

    m = build("raw", "hemmed")
    structural = (m.spring_kind == STRUCT_WEFT) | (m.spring_kind == STRUCT_WARP)
    on_border = m.crossing_hemmed[m.spring_crossing_a] & m.crossing_hemmed[m.spring_crossing_b]
    second = m.crossing_panel[m.spring_crossing_a] == 1
    assert (structural & on_border & second).sum() == 12  # 3 springs along each of the 4 sides
    np.testing.assert_array_equal(m.spring_break_strain[structural & on_border], 0.4)
    np.testing.assert_array_equal(m.spring_break_strain[structural & ~on_border], 0.2)
    assert not (on_border & ~second).any()
