"""[[cuts]]: snips made in the cloth before the shot (docs/scene-format.md, docs/tearing.md "Snips")."""
from __future__ import annotations

import numpy as np
import pytest

from fraytool.errors import SceneError
from fraytool.kinds import BEND_WEFT, SHEAR, SHEAR_TWIN, STRUCT_WARP, STRUCT_WEFT
from fraytool.render.yarns import WEFT, yarn_pieces
from fraytool.scene import parse_scene
from fraytool.sim.builder import ModelBuilder, ModelBuilderError, build_model
from fraytool.sim.pieces import piece_figures

NX, NY = 8, 6

SCENE = """
[scene]
name = "cuts"
[time]
step_s = 2e-4
steps_per_frame = 1
frames = 2
[cloth]
warp_yarns = 8
weft_yarns = 6
spacing_m = 0.004
thickness_m = 0.0006
mass_per_crossing_kg = 5e-6
plane = "xy"
[cloth.springs]
structural_n_per_m = 40.0
bend_n_per_m = 1.0
shear_n_per_m = 5.0
"""


def _grid(model, s):
    a, b = int(model.spring_crossing_a[s]), int(model.spring_crossing_b[s])
    return (a % NX, a // NX), (b % NX, b // NX)


def _expected_between_columns(model, column: int, rows: range) -> set[int]:
    """Springs crossing the line i = column + 1/2 at a height inside [rows.start - 1/2, rows.stop - 1/2],
    listed by hand from the grid rules: weft structural and weft bend springs on those rows, and the
    two diagonals of each quad whose centre lies on the line."""
    out = set()
    for s in range(model.spring_count):
        (ia, ja), (ib, jb) = _grid(model, s)
        kind = model.spring_kind[s]
        lo, hi = min(ia, ib), max(ia, ib)
        if not lo <= column < hi:
            continue  # does not reach across the line
        if kind in (STRUCT_WEFT, BEND_WEFT) and ja in rows:
            out.add(s)
        elif kind == SHEAR and min(ja, jb) + 0.5 >= rows.start - 0.5 and min(ja, jb) + 0.5 <= rows.stop - 0.5:
            out.add(s)
    return out


def test_a_snip_between_two_warp_yarns_cuts_exactly_the_springs_across_it():
    scene = parse_scene(SCENE + "[[cuts]]\nstart = [3.5, 6.0]\nend = [3.5, 2.5]\n", "cuts.toml")
    model = build_model(scene)
    cut = set(np.nonzero(model.spring_precut)[0].tolist())
    assert cut == _expected_between_columns(model, 3, range(3, 6))
    assert not any(model.spring_kind[s] in (STRUCT_WARP, SHEAR_TWIN) for s in cut)
    state = model.state()
    assert not state.spring_alive[model.spring_precut].any()
    assert not state.spring_broken.any()  # a snip is not a break
    assert state.spring_alive[~model.spring_precut & (model.spring_kind != SHEAR_TWIN)].all()


def test_a_cut_right_across_the_cloth_leaves_two_pieces_from_the_start():
    b = ModelBuilder(seed=1)
    b.add_cloth(warp_yarns=NX, weft_yarns=NY, spacing_m=0.004, thickness_m=0.0006, mass_per_crossing_kg=5e-6,
                structural_n_per_m=40.0, bend_n_per_m=1.0, shear_n_per_m=5.0)
    b.add_cut(start=(2.5, -1.0), end=(2.5, NY))
    model = b.finalize()
    figures = piece_figures(model, model.state())
    assert figures["pieces"] == 2
    assert figures["largest_piece_fractions"] == pytest.approx([5 / 8, 3 / 8])


def test_a_line_along_a_yarn_cuts_only_the_springs_that_end_on_it():
    b = ModelBuilder()
    b.add_cloth(warp_yarns=NX, weft_yarns=NY, spacing_m=0.004, thickness_m=0.0006, mass_per_crossing_kg=5e-6,
                structural_n_per_m=40.0)
    b.add_cut(start=(0.0, 2.5), end=(7.0, 2.5))  # between weft yarns 2 and 3: parallel to every weft spring
    model = b.finalize()
    cut = np.nonzero(model.spring_precut)[0]
    assert len(cut) == NX  # the warp structural spring from row 2 to row 3 of every warp yarn, nothing else
    assert all(model.spring_kind[s] == STRUCT_WARP and {_grid(model, s)[0][1], _grid(model, s)[1][1]} == {2, 3}
               for s in cut)


def test_snipped_yarn_ends_are_drawn_clean_and_broken_ones_fade():
    model = build_model(parse_scene(SCENE + "[[cuts]]\nstart = [3.5, -1.0]\nend = [3.5, 6.0]\n", "cuts.toml"))
    state = model.state()
    weft = model.weft_structural_spring
    state.spring_alive[weft[1, 5]] = False  # a break on weft yarn 1, between crossings 5 and 6
    pieces = yarn_pieces(model.arrays(), state.particle_position_m, state.crossing_yarn_level, state.spring_alive)
    rows = [(int(p), bool(pieces.broken_start[p]), bool(pieces.broken_end[p]))
            for p in range(len(pieces.kind)) if pieces.kind[p] == WEFT and pieces.yarn[p] == 1]
    # weft 1: [0..3] clean | snip | [4..5] clean start, broken end | break | [6..7] broken start
    assert [(b0, b1) for _, b0, b1 in rows] == [(False, False), (False, True), (True, False)]


def test_bad_cuts_are_refused_with_the_key_and_the_range():
    with pytest.raises(SceneError) as err:
        parse_scene(SCENE + "[[cuts]]\nstart = [3.5, 60.0]\nend = [3.5, 2.5]\n", "cuts.toml")
    assert "[cuts.0] start = [3.5, 60.0]" in str(err.value) and "-1 <= j <= 6" in str(err.value)
    with pytest.raises(SceneError) as err:
        parse_scene(SCENE + "[[cuts]]\nstart = [1, 1]\nend = [1, 1]\n", "cuts.toml")
    assert "must differ from start" in str(err.value)
    with pytest.raises(SceneError) as err:
        parse_scene(SCENE + "[[cuts]]\nstart = [1, \"a\"]\nend = [1, 2]\n", "cuts.toml")
    assert "an array of 2 numbers" in str(err.value)
    with pytest.raises(ModelBuilderError, match="add_cut: call add_cloth first"):
        ModelBuilder().add_cut(start=(0.5, 0.0), end=(0.5, 3.0))


def test_a_cut_changes_the_scene_digest_so_resume_refuses_old_frames():
    from fraytool.scene.load import scene_hash
    plain = parse_scene(SCENE, "cuts.toml")
    snipped = parse_scene(SCENE + "[[cuts]]\nstart = [3.5, 6.0]\nend = [3.5, 2.5]\n", "cuts.toml")
    assert scene_hash(plain) != scene_hash(snipped)
