"""The multi-resolution base model ([cloth.multires], fraytool.sim.multires, docs/multires.md).

Checked against things the code does not compute itself: an affine deformation (which bilinear
interpolation must reproduce exactly), the fine model's own mass and centre of mass, momentum before
and after a refinement, the yarn-resolution model run side by side (a fully refined coarse model must
be it, bit for bit), and a tearing run (no split or cut may touch a slaved crossing)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fraytool.errors import SceneError
from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from fraytool.scene import load_scene
from fraytool.scene.load import parse_scene
from fraytool.sim import multires
from fraytool.sim.builder import ModelBuilder, build_model
from fraytool.sim.solver import SolverExplicitPBD

ROOT = Path(__file__).resolve().parent.parent


def _cloth(nx=13, ny=11, factor=4, tearing=False, band=1):
    b = ModelBuilder(seed=3)
    b.add_cloth(warp_yarns=nx, weft_yarns=ny, spacing_m=0.004, thickness_m=0.0006, mass_per_crossing_kg=1e-5,
                structural_n_per_m=20.0, bend_n_per_m=0.5, shear_n_per_m=2.0)
    if tearing:
        b.set_tearing()
    b.set_multires(factor=factor, band_cells=band)
    return b.finalize()


def test_lines_cover_the_grid_with_the_last_yarn():
    assert multires.coarse_lines(13, 4).tolist() == [0, 4, 8, 12]
    assert multires.coarse_lines(11, 4).tolist() == [0, 4, 8, 10]
    assert multires.coarse_lines(2, 8).tolist() == [0, 1]


def test_interpolation_reproduces_an_affine_deformation_exactly():
    model = _cloth()
    lay = multires.coarse_layout(model)
    rng = np.random.default_rng(0)
    a, t = rng.normal(size=(3, 3)), rng.normal(size=3)
    x = model.crossing_rest_position_m @ a.T + t  # any affine map of the flat grid
    free = lay.crossing_is_node.copy()
    y = x.copy()
    y[~free] = 1e9  # forgotten: interpolation must bring them back
    multires.interpolate_slaved(lay, free, y)
    assert np.allclose(y, x, atol=1e-12)
    assert np.allclose(lay.crossing_weight.sum(axis=1), 1.0)


def test_hanging_nodes_lie_on_their_edge():
    """A crossing on a coarse line between two nodes interpolates those two nodes only (so it agrees
    with both cells beside it: no seam at a refined border)."""
    model = _cloth()
    lay = multires.coarse_layout(model)
    nx = model.warp_yarns
    for c in range(model.crossing_count):
        i, j = c % nx, c // nx
        used = lay.crossing_node[c][lay.crossing_weight[c] != 0.0]
        ui, uj = used % nx, used // nx
        if i in lay.lines_i:
            assert (ui == i).all()
        if j in lay.lines_j:
            assert (uj == j).all()


def test_lumped_masses_keep_total_mass_and_centre_of_mass():
    model = _cloth()
    state = model.state()
    n = model.crossing_count
    mass = state.particle_mass_kg[:n]
    assert mass.sum() == pytest.approx(model.crossing_mass_kg.sum(), rel=1e-13)
    x = model.crossing_rest_position_m
    centre_fine = (model.crossing_mass_kg[:, None] * x).sum(0) / model.crossing_mass_kg.sum()
    centre_lumped = (mass[:, None] * x).sum(0) / mass.sum()
    assert np.allclose(centre_lumped, centre_fine, atol=1e-15)
    lay = multires.coarse_layout(model)
    assert (mass[~lay.crossing_is_node] == 0).all() and (state.particle_inv_mass[:n][~lay.crossing_is_node] == 0).all()


def test_refinement_keeps_mass_and_momentum():
    from fraytool.sim.stages.multires import CoarseWork

    model = _cloth()
    state = model.state()
    rt = CoarseWork(model)
    rt.ensure(state)
    rng = np.random.default_rng(1)
    lay = rt.layout
    state.particle_velocity_m_s[:] = rng.normal(size=state.particle_velocity_m_s.shape)
    state.particle_position_m[: model.crossing_count] += 1e-3 * rng.normal(size=(model.crossing_count, 3))
    free = multires.free_crossings(lay, state.coarse_cell_refined)
    multires.interpolate_slaved(lay, free, state.particle_velocity_m_s)
    multires.interpolate_slaved(lay, free, state.particle_position_m)

    def moments():
        m = state.particle_mass_kg
        return m.sum(), (m[:, None] * state.particle_velocity_m_s).sum(0)

    mass0, p0 = moments()
    new = np.zeros(lay.cell_count, bool)
    new[[0, 4]] = True
    rt.refine(state, new)
    mass1, p1 = moments()
    assert mass1 == pytest.approx(mass0, rel=1e-13)
    assert np.allclose(p1, p0, rtol=1e-12, atol=1e-18)
    now_free = multires.free_crossings(lay, state.coarse_cell_refined)
    assert now_free.sum() > free.sum()
    born = now_free & ~free
    assert (state.particle_mass_kg[: model.crossing_count][born] == model.crossing_mass_kg[born]).all()


def test_fully_refined_is_the_yarn_resolution_model_bit_for_bit():
    """Every cell refined: no slaved crossing, no coarse spring at work; the steps must be those of
    factor 1 exactly (same springs in the same order, same strain-limit lists)."""
    spec = load_scene(ROOT / "scenes" / "drape.toml")
    fine = build_model(spec)
    coarse = build_model(load_scene(ROOT / "scenes" / "drape.toml", [("cloth.multires.factor", 4)]))
    a, b = fine.state(), coarse.state()
    b.coarse_cell_refined[:] = True
    multires.set_masses(coarse, multires.coarse_layout(coarse), b.coarse_cell_refined, b)
    assert np.array_equal(a.particle_mass_kg, b.particle_mass_kg)
    sa, sb = SolverExplicitPBD(fine), SolverExplicitPBD(coarse)
    for _ in range(150):
        sa.step(a, spec.time.step_s)
        sb.step(b, spec.time.step_s)
    assert np.array_equal(a.particle_position_m, b.particle_position_m)
    assert np.abs(a.particle_position_m - fine.state().particle_position_m).max() > 1e-3  # it moved


def test_coarse_drape_rests_on_the_ball_near_the_fine_one():
    spec = load_scene(ROOT / "scenes" / "drape.toml", [("time.frames", 12)])
    out = {}
    for k in (1, 4):
        model = build_model(load_scene(ROOT / "scenes" / "drape.toml", [("cloth.multires.factor", k)]))
        state, solver = model.state(), SolverExplicitPBD(model)
        for _ in range(12 * spec.time.steps_per_frame):
            solver.step(state, spec.time.step_s)
        solver.complete(state, spec.time.step_s)  # slaved crossings on their interpolation
        out[k] = state.particle_position_m[: model.crossing_count].copy()
        centre = model.body_initial_position_m[0]
        r = np.linalg.norm(out[k] - centre, axis=1)
        # every crossing, slaved ones too, outside the ball (margin: half the thickness)
        assert r.min() >= model.body_params[0, 0] + 0.49 * model.thickness_m  # (a sphere: its radius)
    gap = np.linalg.norm(out[4] - out[1], axis=1)
    assert gap.mean() < 0.01  # within 2 yarn spacings on average of the fine drape


@pytest.mark.parametrize("scene,factor", [("fig6_thrown_ball_plain", 4), ("fig6_thrown_ball_twill", 2)])
def test_a_tear_never_touches_a_slaved_crossing(scene, factor):
    """fig6 (a thrown ball tears a plain / twill weave): the cells refine ahead of the tear, so every
    split crossing and every cut spring is in refined cells, and the cloth still tears. Twill at factor
    2 needs the band raised to hold a split's walk along its floats (split_walk_band)."""
    spec = load_scene(ROOT / "scenes" / f"{scene}.toml", [("cloth.multires.factor", factor)])
    model = build_model(spec)
    state, solver = model.state(), SolverExplicitPBD(model)
    lay = multires.coarse_layout(model)
    frames = spec.time.frames
    for _ in range(frames * spec.time.steps_per_frame):
        solver.step(state, spec.time.step_s)
        free = multires.free_crossings(lay, state.coarse_cell_refined)
        assert free[state.crossing_yarn_level].all()
    refined = state.coarse_cell_refined
    assert 0 < refined.sum() < refined.size  # refined where it tore, coarse elsewhere
    broken = np.flatnonzero(state.spring_broken)
    assert broken.size > 0
    assert (multires.share(lay.spring_cells[broken], refined, at_fine=True) == 1.0).all()
    n = model.crossing_count
    assert state.particle_mass_kg.sum() == pytest.approx(model.crossing_mass_kg.sum(), rel=1e-12)
    assert np.isfinite(state.particle_position_m[:n]).all()


def test_resume_from_a_checkpoint_matches_an_unbroken_run():
    """A run resumed from a frame's checkpoint (written after the frame's end, with a fresh solver whose
    start-of-step positions are zero) gives the same state, every array, as the unbroken run; also
    when the saved state is taken mid-frame and stepped by a bare solver."""
    from fraytool.sim.simulation import Simulation
    from fraytool.sim.state import State

    spec = load_scene(ROOT / "scenes" / "fig6_thrown_ball_plain.toml", [("cloth.multires.factor", 4)])
    sim = Simulation(spec)
    for _ in range(6):
        sim.advance_frame()
    checkpoint = {k: v.copy() for k, v in sim.checkpoint_arrays().items()}
    for _ in range(6):
        sim.advance_frame()
    resumed = Simulation(spec, model=sim.model, state=State.from_arrays(checkpoint), frame=6)
    for _ in range(6):
        resumed.advance_frame()
    assert sim.state.spring_broken.any() and 0 < sim.state.coarse_cell_refined.sum()
    for name, value in sim.state.arrays().items():
        assert np.array_equal(value, resumed.state.arrays()[name]), name

    model = sim.model
    state, solver = model.state(), SolverExplicitPBD(model)
    steps = 6 * spec.time.steps_per_frame + 7  # mid-frame
    for _ in range(steps):
        solver.step(state, spec.time.step_s)
    saved = State.from_arrays(state.arrays())
    for _ in range(steps):
        solver.step(state, spec.time.step_s)
    again, solver2 = saved, SolverExplicitPBD(model)
    for _ in range(steps):
        solver2.step(again, spec.time.step_s)
    solver.complete(state, spec.time.step_s)
    solver2.complete(again, spec.time.step_s)
    for name, value in state.arrays().items():
        assert np.array_equal(value, again.arrays()[name]), name


def test_factor_must_be_a_power_of_two_up_to_8():
    text = (ROOT / "scenes" / "drape.toml").read_text() + "\n"
    with pytest.raises(SceneError, match=r"\[cloth.multires\] factor = 3: must be 1, 2, 4 or 8"):
        parse_scene(text.replace("[cloth.springs]", "[cloth.multires]\nfactor = 3\n\n[cloth.springs]"), "x.toml")


def test_structural_springs_of_refined_cells_are_strain_limited_only():
    model = _cloth(tearing=True)
    solver = SolverExplicitPBD(model)
    state = model.state()
    solver.step(state, 1e-4)
    strain = next(s for s in solver.stages if type(s).__name__ == "StrainLimiting")
    assert strain.limited_springs.size == 0  # nothing refined, nothing held: the coarse model only
    state.coarse_cell_refined[0] = True
    state.bump_topology()  # an edit by hand says so
    solver.step(state, 1e-4)
    lay = multires.coarse_layout(model)
    limited = strain.limited_springs
    kinds = model.spring_kind[limited]
    assert limited.size > 0 and np.isin(kinds, (STRUCT_WEFT, STRUCT_WARP)).all()
    assert (multires.share(lay.spring_cells[limited], state.coarse_cell_refined, at_fine=True) > 0).all()


def test_study_multires_writes_the_comparison(tmp_path, capsys):
    """`fraytool study --multires`: one row per factor; k = 1 is the reference (its own distance 0, its
    tear figures those of a plain run of the scene); the others' relative differences follow from the
    rows; the report and plot are written."""
    import csv

    from fraytool.commands.main import main
    from fraytool.sim.simulation import Simulation

    scene = ROOT / "scenes" / "fig6_thrown_ball_plain.toml"
    assert main(["study", str(scene), "--multires", "--factors", "2,1", "--duration", "0.125", "-o",
                 str(tmp_path)]) == 0
    folder = tmp_path / "study" / "multires"
    rows = list(csv.DictReader(open(folder / "runs.csv")))
    assert [r["factor"] for r in rows] == ["1", "2"]
    ref, k2 = rows
    assert float(ref["shape_mean_m"]) == 0.0 and float(ref["speedup"]) == 1.0
    sim = Simulation(load_scene(scene))
    for _ in range(30 * sim.steps_per_frame):
        sim.step()
    assert int(ref["broken_springs"]) == int(sim.state.spring_broken.sum())
    assert int(ref["yarn_level_crossings"]) == int(sim.state.crossing_yarn_level.sum())
    b1, b2 = int(ref["broken_springs"]), int(k2["broken_springs"])
    assert float(k2["broken_springs_rel"]) == pytest.approx((b2 - b1) / b1, abs=1e-6)
    assert 0.0 < float(k2["refined_fraction"]) <= 1.0
    assert "| 2 |" in (folder / "report.md").read_text()


def test_study_factors_flag_is_checked(tmp_path, capsys):
    from fraytool.commands.main import main

    scene = str(ROOT / "scenes" / "drape.toml")
    assert main(["study", scene, "--multires", "--factors", "1,3", "-o", str(tmp_path)]) == 2
    assert "--factors '1,3': '3' is not a factor; each is 1, 2, 4 or 8" in capsys.readouterr().err
    assert main(["study", scene, "--factors", "1,2", "-o", str(tmp_path)]) == 2
    assert "--factors goes with --multires" in capsys.readouterr().err


def test_check_reports_the_coarse_grid(capsys):
    import json

    from fraytool.commands.main import main

    assert main(["check", str(ROOT / "scenes" / "tablecloth_tear.toml"), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    # 512 yarns at factor 4: lines at 0, 4, ..., 508 and 511 -> 129 per axis, 128 x 128 cells
    assert info["coarse_factor"] == 4 and info["coarse_nodes"] == 129 * 129 and info["coarse_cells"] == 128 * 128
    # the clip and the bar hold the left and right edges, whole edges between held nodes: nothing refines
    # for them (test_a_held_edge_stays_coarse_and_on_its_body), and the ball is not near yet
    assert info["cells_refined_at_start"] == 0
    assert info["refine_strain"] == pytest.approx(0.7 * 0.12)


def test_coarse_yarn_springs_add_up_to_the_fine_yarns_across_uneven_cells():
    """Pulling the cloth along a yarn direction, the fine model's stiffness is (number of yarns) x (k /
    chain length); the coarse structural springs across any section of cells (a last cell one spacing
    wide included) must add up to the same."""
    model = _cloth(nx=10, ny=9, factor=4)
    lay = multires.coarse_layout(model)
    k = 20.0
    for kind, lines, along, yarns in ((STRUCT_WARP, lay.lines_i, lay.lines_j, model.warp_yarns),
                                      (STRUCT_WEFT, lay.lines_j, lay.lines_i, model.weft_yarns)):
        span = along[1] - along[0]  # the first row (column) of cells
        sel = lay.coarse_kind == kind
        a, b = lay.coarse_a[sel], lay.coarse_b[sel]
        nx = model.warp_yarns
        first = ((a // nx) == along[0]) & ((b // nx) == along[1]) if kind == STRUCT_WARP else \
            ((a % nx) == along[0]) & ((b % nx) == along[1])
        total = lay.coarse_stiffness_n_per_m[sel][first].sum()
        assert first.sum() == lines.shape[0]
        assert total == pytest.approx(yarns * k / span)


def test_the_band_holds_a_splits_walk_along_the_longest_float():
    from fraytool.sim.builder import longest_float, split_walk_band

    plain = np.array([[(i + j) % 2 == 0 for i in range(8)] for j in range(8)])
    twill22 = np.array([[(i + j) % 4 < 2 for i in range(8)] for j in range(8)])
    satin5 = np.array([[(i - 2 * j) % 5 == 0 for i in range(10)] for j in range(10)])
    assert [longest_float(w) for w in (plain, twill22, satin5)] == [1, 2, 4]
    # a walk runs float + 1 crossings past the spring: ceil((float + 1) / factor) cells, plus one
    assert [split_walk_band(twill22, k) for k in (2, 4, 8)] == [3, 2, 2]
    assert split_walk_band(satin5, 2) == 4
    b = ModelBuilder(seed=1)
    b.add_cloth(warp_yarns=20, weft_yarns=20, spacing_m=0.004, thickness_m=0.0006, mass_per_crossing_kg=1e-5,
                structural_n_per_m=20.0, weave="satin")
    b.set_multires(factor=2, band_cells=1)
    assert b.finalize().refine_band_cells == 4


def test_a_grid_without_crossings_between_nodes_starts_refined():
    model = _cloth(nx=2, ny=2, factor=2, tearing=True)
    assert model.state().coarse_cell_refined.all()


def test_a_frame_ends_with_every_slaved_crossing_on_its_interpolation():
    """The steps keep only the hanging nodes on their interpolation (the other slaved crossings are read
    by nothing in a step); a frame's end (Simulation.advance_frame -> solver.complete) puts every
    slaved crossing on it, position exactly, velocity as the nodes' interpolated velocity."""
    from fraytool.sim.simulation import Simulation

    spec = load_scene(ROOT / "scenes" / "fig6_thrown_ball_plain.toml", [("cloth.multires.factor", 4)])
    sim = Simulation(spec)
    lay = multires.coarse_layout(sim.model)
    for _ in range(3):
        sim.advance_frame()
    free = multires.free_crossings(lay, sim.state.coarse_cell_refined)
    assert 0 < free.sum() < free.size
    x, v = sim.state.particle_position_m, sim.state.particle_velocity_m_s
    n = sim.model.crossing_count
    want_x, want_v = x[:n].copy(), v[:n].copy()
    multires.interpolate_slaved(lay, free, want_x)
    multires.interpolate_slaved(lay, free, want_v)
    assert np.array_equal(x[:n][~free], want_x[~free])
    scale = np.abs(v[:n][free]).max()
    assert scale > 0.01  # the cloth is moving
    # (x - x_prev) / dt of interpolated positions against the interpolated velocities: equal up to rounding
    assert np.abs(v[:n][~free] - want_v[~free]).max() < 1e-8 * scale


def test_slaved_crossings_are_on_their_interpolation_whenever_a_split_may_read_them():
    """A split reads its neighbours (the couple's normal) and its settle the yarn segments it could
    carry through; the steps keep most slaved crossings stale, so on every step with a hot cell (a
    spring past the refine strain, which every split needs) the slaved crossings within band + 1 cells
    of each hot cell are synced before a stage that declares it reads them. Checked by a pass that
    declares that read, just before the tearing stage of every such step of fig6 at factor 4
    (self-collision off: it would sync them all anyway), through to its tear."""
    from fraytool.sim.simulation import Simulation
    from fraytool.sim.stages.base import POSITIONS, SLAVED_NEAR_HOT, HookStage

    spec = load_scene(ROOT / "scenes" / "fig6_thrown_ball_plain.toml",
                      [("cloth.multires.factor", 4), ("self_collision.enabled", False)])
    sim = Simulation(spec)
    runtime = sim.solver.context.coarse
    lay = runtime.layout
    reach = sim.model.refine_band_cells + 1
    n = sim.model.crossing_count
    seen = {"hot": 0, "stale elsewhere": 0}

    def check(state, prev, dt):
        free = multires.free_crossings(lay, state.coarse_cell_refined)
        want = state.particle_position_m[:n].copy()
        multires.interpolate_slaved(lay, free, want)
        off = np.flatnonzero(~free & (state.particle_position_m[:n] != want).any(axis=1))
        if not runtime.hot.any():
            return
        seen["hot"] += 1
        cell = lay.crossing_weight_cell[off]
        ci, cj = cell % lay.cells_x, cell // lay.cells_x
        hot = np.flatnonzero(runtime.hot)
        hi, hj = hot % lay.cells_x, hot // lay.cells_x
        near = ((np.abs(ci[:, None] - hi[None, :]) <= reach) & (np.abs(cj[:, None] - hj[None, :]) <= reach)).any(1)
        assert not near.any(), f"step {state.step_index}: slaved crossings {off[near][:5]} near a hot cell are stale"
        seen["stale elsewhere"] += bool(off.size)

    sim.solver.insert_stage(HookStage("refinement", check, reads=frozenset({POSITIONS, SLAVED_NEAR_HOT}),
                                      writes=frozenset()))
    assert [type(s).__name__ for s in sim.solver.stages][-4:] == ["CoarseSync", "HookStage", "TearingStage",
                                                                   "VelocityPostProcess"]
    for _ in range(40):
        sim.advance_frame()
    assert sim.state.spring_broken.any() and seen["hot"] > 0 and seen["stale elsewhere"] > 0


def test_a_held_edge_stays_coarse_and_on_its_body():
    """An edge held by one body between held nodes needs no refinement: each slaved crossing on it is
    the interpolation of two held nodes, which a rigid map carries onto the crossing's own attachment
    point. Checked against the body's map of each held crossing's offset while the bar swings the
    edge down (tablecloth_tear resized); and a grip on a few crossings inside a cell (its nodes free)
    refines that cell and the band around it from the start."""
    from fraytool.sim.simulation import Simulation

    scene = ROOT / "scenes" / "tablecloth_tear.toml"
    small = [("cloth.warp_yarns", 33), ("cloth.weft_yarns", 33), ("cloth.spacing_m", 0.03),
             ("cloth.mass_per_crossing_kg", 2.8e-4), ("cloth.tearing.enabled", False),
             ("cloth.multires.refine_near_bodies", False)]
    sim = Simulation(load_scene(scene, small))
    m = sim.model
    lay = multires.coarse_layout(m)
    assert not sim.state.coarse_cell_refined.any()
    held = m.attachment_particle
    assert (~multires.free_crossings(lay, sim.state.coarse_cell_refined)[held]).sum() >= 2 * 32 * 3 // 4
    start = sim.state.particle_position_m[held].copy()
    for _ in range(4):
        sim.advance_frame()
    st = sim.state
    b = m.attachment_body
    want = st.body_position_m[b] + np.einsum("kij,kj->ki", m.body_rotation[b], m.attachment_offset_m)
    x = st.particle_position_m[held]
    assert np.abs(x - start).max() > 0.01  # the bar has moved its edge
    assert np.abs(x - want).max() < 1e-12

    b2 = ModelBuilder(seed=3)
    b2.add_cloth(warp_yarns=29, weft_yarns=29, spacing_m=0.004, thickness_m=0.0006, mass_per_crossing_kg=1e-5,
                 structural_n_per_m=20.0, bend_n_per_m=0.5, shear_n_per_m=2.0)
    b2.add_sphere("grip", radius_m=0.001, position_m=[0.006, 0.0, 0.006], collide=False)
    b2.add_attachment("grip", warp_range=[1, 2], weft_range=[1, 2])  # inside the first cell (nodes at 0 and 4)
    b2.set_multires(factor=4, band_cells=1)
    gripped = b2.finalize()
    glay = multires.coarse_layout(gripped)
    assert not multires.followed_by_interpolation(gripped, glay).any()
    refined = multires.initial_refined(gripped, glay).reshape(glay.cells_y, glay.cells_x)
    reach = 1 + int(gripped.refine_band_cells)  # the cell and its band (the band the weave needs)
    assert refined[:reach, :reach].all() and not refined[reach:, :].any() and not refined[:, reach:].any()


def test_slaved_forces_reach_the_nodes_whole():
    """gather_slaved_forces hands each slaved crossing's force to its nodes with its weights (the
    transpose of the interpolation): the total force is kept, and so is the torque about the origin
    when the slaved crossings sit on their interpolation (both linear in the weights, which sum to 1).
    Catches the forces handed on short (at 90 %)."""
    from fraytool.sim.kernels.multires import gather_slaved_forces

    model = _cloth()
    lay = multires.coarse_layout(model)
    n = model.crossing_count
    free = multires.free_crossings(lay, np.zeros(lay.cell_count, bool))
    x = model.crossing_rest_position_m.copy()
    x += np.random.default_rng(5).normal(0.0, 1e-3, x.shape)
    multires.interpolate_slaved(lay, free, x)
    f = np.random.default_rng(6).normal(size=(2 * n, 3))
    total, torque = f[:n].sum(axis=0), np.cross(x, f[:n]).sum(axis=0)
    slaved = np.flatnonzero(~free).astype(np.int32)
    gather_slaved_forces(slaved, lay.crossing_node, lay.crossing_weight, f)
    assert (f[slaved] == 0.0).all()
    np.testing.assert_allclose(f[:n].sum(axis=0), total, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.cross(x, f[:n]).sum(axis=0), torque, rtol=0, atol=1e-13)


def test_a_slaved_crossing_in_a_body_ends_exactly_on_its_surface():
    """collide_slaved moves a slaved crossing's nodes by the smallest mass-weighted move that puts its
    interpolated point on the surface (frictionless plane): the point ends at the contact margin exactly,
    the nodes move along the normal only. Catches the nodes moved short (90 % of the way)."""
    from fraytool.kinds import SHAPE_PLANE
    from fraytool.sim.kernels.bodies import BodiesIn
    from fraytool.sim.kernels.multires import collide_slaved

    model = _cloth()
    lay = multires.coarse_layout(model)
    state = model.state()
    free = multires.free_crossings(lay, state.coarse_cell_refined)
    s = int(np.flatnonzero(~free & (lay.crossing_weight > 0).all(axis=1))[0])  # inside a cell: four nodes
    cell = int(lay.crossing_weight_cell[s])
    cell_nodes = lay.cell_nodes
    cell_start = np.zeros(lay.cell_count + 1, np.int64)
    cell_start[cell + 1:] = 1
    cells = (cell_start, np.array([s], np.int32), cell_nodes, np.unique(cell_nodes[cell]).astype(np.int32),
             lay.crossing_node, lay.crossing_weight)
    x = state.particle_position_m
    normal = np.array([0.0, 0.0, 1.0]) if np.ptp(x[:model.crossing_count, 2]) == 0 else np.array([0.0, 1.0, 0.0])
    margin = 0.5 * model.thickness_m
    point = lay.crossing_weight[s] @ x[lay.crossing_node[s]]
    plane_at = point + (margin + 2e-4) * normal  # the point 0.2 mm inside (margin included)
    bodies = BodiesIn(np.array([SHAPE_PLANE], np.int8), normal[None, :].copy(), np.eye(3)[None], np.zeros(1),
                      np.ones(1, bool), np.zeros(1, bool), plane_at[None, :], np.zeros((1, 3)), np.zeros((1, 3)))
    before = x.copy()
    hits = collide_slaved(cells, bodies, margin, 1e-4, state.particle_inv_mass, before.copy(), x, np.zeros(3),
                          np.zeros(model.crossing_count, np.uint8))
    assert hits == 1
    after = lay.crossing_weight[s] @ x[lay.crossing_node[s]]
    assert abs((after - plane_at) @ normal - margin) < 1e-15
    moved = x - before
    assert np.abs(moved - np.outer(moved @ normal, normal)).max() < 1e-18  # along the normal only


def test_strain_limiting_reads_the_hanging_nodes_on_their_interpolation():
    """Whenever strain limiting runs in a multi-resolution step, every hanging node (a slaved crossing a
    working fine spring pulls) sits on its nodes' interpolation: it is an anchor of the fine springs the
    limit projects. Catches the sync of the hanging nodes dropped before it (a stale anchor)."""
    from fraytool.sim.simulation import Simulation
    from fraytool.sim.stages import core

    spec = load_scene(ROOT / "scenes" / "fig6_thrown_ball_plain.toml",
                      [("cloth.multires.factor", 4), ("self_collision.enabled", False)])
    sim = Simulation(spec)
    coarse = sim.solver.context.coarse
    lay = coarse.layout
    seen = {"checks": 0, "hanging": 0}
    original = core.StrainLimiting.run

    def checked(stage, state, ctx, dt_s):
        coarse.ensure(state)
        hanging = coarse.loaded_slaved
        if hanging.shape[0]:
            want = np.einsum("kq,kqd->kd", lay.crossing_weight[hanging],
                             state.particle_position_m[lay.crossing_node[hanging]])
            assert np.array_equal(state.particle_position_m[hanging], want), state.step_index
            seen["hanging"] += 1
        seen["checks"] += 1
        original(stage, state, ctx, dt_s)

    core.StrainLimiting.run = checked
    try:
        for _ in range(8):
            sim.advance_frame()
    finally:
        core.StrainLimiting.run = original
    assert seen["hanging"] > 0 and seen["checks"] == 8 * spec.time.steps_per_frame


def test_a_hot_cell_refines_exactly_its_band():
    """cells_to_refine: a coarse spring strained past the refine strain makes its cells hot, and the cells
    within band_cells of a hot cell (Chebyshev distance on the cell grid, numpy's `multires.dilate` as
    the oracle) refine, no more and no fewer. Catches a band one cell narrower (or wider)."""
    from fraytool.sim.stages.base import StepContext
    from fraytool.sim.stages.multires import CoarseWork, Refinement

    model = _cloth(nx=33, ny=33, factor=4, tearing=True, band=2)
    state = model.state()
    assert not state.coarse_cell_refined.any()
    ctx = StepContext.for_model(model)
    ctx.coarse = CoarseWork(model)
    lay = ctx.coarse.layout
    node = int(lay.cell_nodes[lay.cell_count // 2 + lay.cells_x // 2, 0])
    state.particle_position_m[node, 0] += 0.3 * 4 * model.spacing_m  # its coarse springs 30 % longer
    Refinement(model).run(state, ctx, 1e-4)
    hot = ctx.coarse.hot
    assert hot.any()
    want = multires.dilate(hot, lay.cells_x, lay.cells_y, model.refine_band_cells)
    assert model.refine_band_cells >= 2
    assert np.array_equal(state.coarse_cell_refined, want)


def test_the_parallel_sync_gives_the_serial_sync_bit_for_bit():
    """sync_slaved_parallel (CoarseWork.sync_all on a garment's tens of thousands of slaved crossings) against
    the serial sync_slaved: the same interpolation of every slaved crossing, bit for bit, the nodes untouched."""
    from fraytool.sim.kernels.multires import sync_slaved, sync_slaved_parallel

    model = _cloth(nx=41, ny=37, factor=4)
    lay = multires.coarse_layout(model)
    slaved = np.flatnonzero(~multires.free_crossings(lay, np.zeros(lay.cell_count, bool))).astype(np.int32)
    assert slaved.size > 1000
    values = np.random.default_rng(2).normal(size=(model.crossing_count, 3))
    serial, parallel = values.copy(), values.copy()
    sync_slaved(slaved, lay.crossing_node, lay.crossing_weight, serial)
    sync_slaved_parallel(slaved, lay.crossing_node, lay.crossing_weight, parallel)
    assert np.array_equal(serial, parallel)
    assert not np.array_equal(serial[slaved], values[slaved])  # it did interpolate
    nodes = np.setdiff1d(np.arange(model.crossing_count), slaved)
    assert np.array_equal(parallel[nodes], values[nodes])
