"""The multi-resolution base model on shaped panels and on several sewn panels (docs/multires.md,
"Shaped panels and garments").

Checked against things the layout does not compute itself: the yarn-resolution model's elastic energy
under a uniform stretch (the coarse springs and the fine springs at the borders must carry exactly the
fine yarns' stiffness, outlines and the grid between panels included), the fine model's mass and centre
of mass, an affine deformation (which bilinear interpolation reproduces exactly), and the same scene run
at yarn resolution (the tear figures of `fraytool study --multires`)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from fraytool.kinds import STITCH, STRUCT_WARP, STRUCT_WEFT
from fraytool.sim import multires
from fraytool.sim.builder import ModelBuilder
from fraytool.sim.stages.multires import CoarseWork

ROOT = Path(__file__).resolve().parent.parent
SPACING_M = 0.004


def _circle(radius_m: float, corners: int, centre=(0.0, 0.0)) -> list[list[float]]:
    return [[centre[0] + radius_m * math.cos(2 * math.pi * k / corners),
             centre[1] + radius_m * math.sin(2 * math.pi * k / corners)] for k in range(corners)]


def _garment(factor: int = 4, seam: bool = True):
    """A disc (outline), a rectangle and a taller rectangle sewn to it along an edge: three panels, so
    three blocks of the grid and the places between them."""
    b = ModelBuilder(seed=2)
    common = dict(spacing_m=SPACING_M, thickness_m=0.0006, mass_per_crossing_kg=1e-5, structural_n_per_m=20.0,
                  bend_n_per_m=0.5, shear_n_per_m=2.0)
    b.add_cloth(name="disc", **common, outline_m=_circle(0.05, 48), grain_deg=0.0)
    b.add_panel("a", **common, warp_yarns=14, weft_yarns=11, origin_m=(0.08, 0.0, 0.0))
    b.add_panel("b", **common, warp_yarns=9, weft_yarns=11, origin_m=(0.14, 0.0, 0.0))
    if seam:
        b.add_seam(panel_a="a", segment_a=1, panel_b="b", segment_b=3, reverse=True, stitch_spacing_m=SPACING_M,
                   stiffness_n_per_m=20.0, break_strain=0.2)
    b.set_multires(factor=factor, band_cells=1)
    return b.finalize()


def _structural_energy(model, x: np.ndarray) -> tuple[float, float]:
    """(the elastic energy of the structural springs at work in the coarse model with its initial cells,
    the same of every structural spring at yarn resolution) at positions x [J]."""
    state = model.state()
    work = CoarseWork(model)
    work.ensure(state)
    lay = work.layout

    def energy(listed, share, kind, a, b, rest, k):
        mine = (kind[listed] == STRUCT_WEFT) | (kind[listed] == STRUCT_WARP)
        s = listed[mine]
        stretch = np.linalg.norm(x[b[s]] - x[a[s]], axis=1) - rest[s]
        return float((share[mine] * 0.5 * k[s] * stretch ** 2).sum())

    coarse = energy(work.fine_listed, work.fine_share, model.spring_kind, model.spring_crossing_a,
                    model.spring_crossing_b, model.spring_rest_length_m, model.spring_base_stiffness_n_per_m) \
        + energy(work.coarse_listed, work.coarse_share, lay.coarse_kind, lay.coarse_a, lay.coarse_b,
                 lay.coarse_rest_length_m, lay.coarse_stiffness_n_per_m)
    every = np.arange(model.spring_count)
    fine = energy(every, np.ones(model.spring_count), model.spring_kind, model.spring_crossing_a,
                  model.spring_crossing_b, model.spring_rest_length_m, model.spring_base_stiffness_n_per_m)
    return coarse, fine


@pytest.mark.parametrize("axis", [0, 2], ids=["along the weft (x)", "along the warp (z)"])
def test_coarse_and_border_springs_carry_the_fine_yarns_stiffness_exactly(axis):
    """A uniform stretch of every panel along one yarn direction: the coarse model's structural energy
    (coarse springs of whole cells, fine springs of refined cells, each with its share) equals the
    yarn-resolution model's, with cells cut by an outline and the places between panels refined."""
    model = _garment(seam=False)
    lay = multires.coarse_layout(model)
    refined = model.state().coarse_cell_refined
    assert lay.cell_whole.sum() > 8 and (~refined[lay.cell_whole]).sum() > 8  # coarse cells in all panels
    assert refined[~lay.cell_whole].all()
    x = model.crossing_rest_position_m.copy()
    x[:, axis] *= 1.03
    coarse, fine = _structural_energy(model, x)
    assert fine > 0.0
    assert coarse == pytest.approx(fine, rel=1e-12)


def test_a_shaped_and_sewn_cloth_keeps_its_mass_centre_and_affine_maps():
    model = _garment()
    lay = multires.coarse_layout(model)
    state = model.state()
    n = model.crossing_count
    mass = state.particle_mass_kg[:n]
    assert mass.sum() == pytest.approx(model.crossing_mass_kg.sum(), rel=1e-13)
    x = model.crossing_rest_position_m
    centre = (model.crossing_mass_kg[:, None] * x).sum(0) / model.crossing_mass_kg.sum()
    assert np.allclose((mass[:, None] * x).sum(0) / mass.sum(), centre, atol=1e-15)
    free = multires.free_crossings(lay, state.coarse_cell_refined)
    assert 0 < (~free).sum() < n
    # every crossing interpolates crossings of its own panel, and an affine map comes back exactly
    used = lay.crossing_weight != 0.0
    panel = model.crossing_panel
    assert (panel[lay.crossing_node][used] == np.repeat(panel[:, None], 4, axis=1)[used]).all()
    rng = np.random.default_rng(4)
    affine = x @ rng.normal(size=(3, 3)).T + rng.normal(size=3)
    y = affine.copy()
    y[~free] = 1e9
    multires.interpolate_slaved(lay, free, y)
    assert np.allclose(y, affine, atol=1e-12)
    # the seam's crossings start free, and so does every crossing of a cell an outline cuts
    stitch = model.spring_kind == STITCH
    assert stitch.any()
    assert free[model.spring_crossing_a[stitch]].all() and free[model.spring_crossing_b[stitch]].all()
    in_cut_cells = np.isin(lay.crossing_cells, np.flatnonzero(~lay.cell_whole)).any(axis=1)
    only_cut = in_cut_cells & ~np.isin(lay.crossing_cells, np.flatnonzero(lay.cell_whole)).any(axis=1)
    assert only_cut.any() and free[only_cut].all()
    # a coarse spring joins two crossings of one panel, and a whole cell's nodes are all there
    assert (panel[lay.coarse_a] == panel[lay.coarse_b]).all()
    assert (lay.cell_nodes[lay.cell_whole] >= 0).all() and (lay.cell_nodes[~lay.cell_whole] == -1).all()


def test_the_band_reads_a_shaped_weave_only_where_it_has_crossings():
    """A float ends at a panel's edge: places without a crossing do not join two panels' runs."""
    from fraytool.sim.builder import longest_float

    plain = np.array([[(i + j) % 2 == 0 for i in range(6)] for j in range(4)])
    run_across = np.zeros((4, 6), bool)  # one weft on top all along, but the middle place is absent
    present = np.ones((4, 6), bool)
    present[:, 3] = False
    assert longest_float(run_across, present) == 4  # the columns: four rows each
    assert longest_float(run_across.T, present.T) == 4
    assert longest_float(plain, present) == 1
    only_rows = np.ones((1, 7), bool)
    gap = np.ones((1, 7), bool)
    gap[0, 4] = False
    assert longest_float(only_rows) == 7 and longest_float(only_rows, gap) == 4


def test_a_round_cloth_at_factor_4_tears_like_its_yarn_resolution_run():
    """round_tablecloth (an outline panel) at factor 4 against factor 1: the tear figures and the tear's
    centroid of `fraytool study --multires` within its tolerances, and cells left coarse at the end."""
    from fraytool.scene import load_scene
    from fraytool.study.multires_study import run_multires_study

    spec = load_scene(ROOT / "scenes" / "round_tablecloth.toml")
    study = run_multires_study(spec, factors=(1, 4), frames=36)
    k1, k4 = study.runs
    assert k1.tear["broken_springs"] > 0 and k1.centroid_m is not None
    assert k4.within(), (k4.relative, k4.centroid_distance_spacings)
    assert 0.0 < k4.refined_fraction < 1.0


@pytest.mark.parametrize("how", ["catch_s", "release_force_n"])
def test_a_refinement_keeps_whether_a_changing_attachment_holds(how):
    """An attachment caught later is free until then, and one that let go is free after: a refinement
    (which sets every slot's masses afresh) must not hold them again; nor let go of one still held."""
    from fraytool.sim.stages.multires import CoarseWork

    b = ModelBuilder(seed=1)
    b.add_cloth(warp_yarns=33, weft_yarns=33, spacing_m=SPACING_M, thickness_m=0.0006, mass_per_crossing_kg=1e-5,
                structural_n_per_m=20.0)
    b.add_sphere("grip", radius_m=0.002, position_m=(0.064, 0.0, 0.064), collide=False)
    b.add_attachment("grip", warp_range=[15, 17], weft_range=[15, 17], **{how: 0.5})
    b.set_multires(factor=4, band_cells=1)
    model = b.finalize()
    state = model.state()
    work = CoarseWork(model)
    work.ensure(state)
    held = model.attachment_particle
    free = multires.free_crossings(work.layout, state.coarse_cell_refined)
    assert free[held].all()  # each changes on its own: its cells are refined from the start
    before = state.particle_inv_mass[held] == 0.0
    assert before.all() == (how == "release_force_n") and before.any() == before.all()
    state.particle_inv_mass[held[0]] = 0.0 if how == "catch_s" else 1.0 / state.particle_mass_kg[held[0]]  # one changed
    new = np.zeros(work.layout.cell_count, bool)
    new[0] = True
    assert not state.coarse_cell_refined[0]
    work.refine(state, new)
    after = state.particle_inv_mass[held] == 0.0
    assert after[0] == (how == "catch_s") and (after[1:] == before[1:]).all()


def test_no_coarse_spring_bridges_a_slit_of_a_shaped_panel():
    """A panel with a slot one spacing wide cut into it: the yarn model has no yarn or bend spring across the
    slot, so no coarse spring may run across a place without a crossing (a coarse bend spring spans two cells)."""
    from fraytool.kinds import BEND_WARP, BEND_WEFT

    h = 0.0005
    slot = [[-h, -h], [0.034 + h, -h], [0.034 + h, 0.026], [0.038 - h, 0.026], [0.038 - h, -h], [0.048 + h, -h],
            [0.048 + h, 0.048 + h], [-h, 0.048 + h]]
    b = ModelBuilder(seed=1)
    b.add_cloth(spacing_m=SPACING_M, thickness_m=0.0006, mass_per_crossing_kg=1e-5, structural_n_per_m=20.0,
                bend_n_per_m=5.0, shear_n_per_m=2.0, outline_m=slot, grain_deg=0.0)
    b.set_multires(factor=2, band_cells=1)
    model = b.finalize()
    grid = model.crossing_grid()
    assert (grid < 0).sum() > 5  # the slot is there
    lay = multires.coarse_layout(model)
    gi, gj = model.crossing_grid_i, model.crossing_grid_j
    checked = 0
    for s in range(lay.coarse_kind.size):
        a, b_ = lay.coarse_a[s], lay.coarse_b[s]
        if lay.coarse_kind[s] in (BEND_WEFT, STRUCT_WEFT):
            places = grid[gj[a], gi[a]:gi[b_] + 1]
        elif lay.coarse_kind[s] in (BEND_WARP, STRUCT_WARP):
            places = grid[gj[a]:gj[b_] + 1, gi[a]]
        else:
            continue
        checked += 1
        assert (places >= 0).all(), (lay.coarse_kind[s], gi[a], gj[a], gi[b_], gj[b_])
    assert checked > 20 and (lay.coarse_kind == BEND_WEFT).any()


def test_a_panel_with_no_whole_cell_starts_refined_with_a_moving_body():
    b = ModelBuilder(seed=1)
    b.add_cloth(spacing_m=SPACING_M, thickness_m=0.0006, mass_per_crossing_kg=1e-5, structural_n_per_m=20.0,
                outline_m=_circle(0.0105, 32, centre=(0.0125, 0.0125)), grain_deg=0.0)
    b.add_sphere("ball", radius_m=0.01, position_m=(0.0, 0.05, 0.0), motion="kinematic", velocity_m_s=(0, -1, 0))
    b.set_multires(factor=4)
    model = b.finalize()
    assert not multires.coarse_layout(model).cell_whole.any()
    assert model.state().coarse_cell_refined.all()


def test_a_scene_with_air_drag_and_a_coarse_model_is_refused_with_its_keys():
    from fraytool.errors import SceneError
    from fraytool.scene import load_scene

    with pytest.raises(SceneError) as caught:
        load_scene(ROOT / "scenes" / "flag_tear.toml", [("cloth.multires.factor", 2)])
    text = str(caught.value)
    assert "[cloth] drag_normal = 1.2" in text and "factor = 1" in text and "flag_tear.toml" in text
