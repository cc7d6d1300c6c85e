"""Tearing in whole simulations: the shipped Fig. 6 scene tears and frays, reproducibly."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from helpers import pulled_strip_text

from fraytool.io.frame_record import FrameRecord
from fraytool.scene import load_scene
from fraytool.sim import Simulation
from fraytool.sim.tearing import topology_problems

FRAMES = 30  # the ball has gone through the cloth by then


def scene(seed=None, yarn_level=True):
    spec = load_scene("scenes/fig6_thrown_ball_plain.toml")
    tear = dataclasses.replace(spec.cloth.tearing, yarn_level=yarn_level)
    spec = dataclasses.replace(spec, cloth=dataclasses.replace(spec.cloth, tearing=tear))
    if seed is not None:
        spec = dataclasses.replace(spec, scene=dataclasses.replace(spec.scene, seed=seed))
    return spec


def run(spec, frames=FRAMES) -> Simulation:
    sim = Simulation(spec)
    while sim.frame + 1 < frames:
        sim.advance_frame()
    return sim


@pytest.fixture(scope="module")
def torn():
    return run(scene())


@pytest.fixture(scope="module")
def torn_base_only():
    return run(scene(yarn_level=False))


def test_yarn_level_tear_frays_and_base_only_tear_is_clean(torn, torn_base_only):
    spacing = torn.model.spacing_m
    yarn = torn.summary()
    base = torn_base_only.summary()
    assert yarn["broken_springs"] >= 20 and base["broken_springs"] >= 20  # both tear
    # frayed: loose yarn ends stick out past the torn edge by more than one yarn spacing
    assert yarn["fray_free_end_count"] >= 20
    assert yarn["fray_mean_free_end_m"] > spacing
    assert yarn["fray_max_free_end_m"] > 3 * spacing
    # clean: every cut yarn ends exactly at the edge of the weave
    assert base["fray_free_end_count"] == 0 and base["fray_max_free_end_m"] == 0.0
    assert base["yarn_level_masses"] == 0 and base["connected_couples"] == 0


def test_summary_reports_the_tear(torn):
    s = torn.summary()
    for key in ("broken_springs", "yarn_level_masses", "connected_couples", "disconnected_couples",
                "fray_free_end_count", "fray_mean_free_end_m", "fray_max_free_end_m"):
        assert key in s, key
    state = torn.state
    assert s["broken_springs"] == int(state.spring_broken.sum())
    assert s["yarn_level_masses"] == 2 * int(state.crossing_yarn_level.sum())
    assert s["connected_couples"] + s["disconnected_couples"] == int(state.crossing_yarn_level.sum())
    assert s["all_finite"]


def test_yarn_level_region_stays_where_the_cloth_tears(torn):
    state, model = torn.state, torn.model
    level = state.crossing_yarn_level
    assert 0 < level.sum() < 0.25 * model.crossing_count
    record = torn.record()
    assert (record.crossing_yarn_level == level).all()  # the frame record says it per crossing
    assert topology_problems(model, state) == []
    # before the ball arrives the whole cloth is base level
    early = run(scene(), frames=3)
    assert not early.state.crossing_yarn_level.any() and not early.state.spring_broken.any()


def test_same_seed_same_tear_other_seed_other_tear(torn):
    again = run(scene())
    for name, value in torn.state.arrays().items():
        assert np.array_equal(value, again.state.arrays()[name]), name  # bit-identical
    other = run(scene(seed=torn.spec.scene.seed + 1))
    assert other.state.spring_broken.any()
    assert not np.array_equal(other.state.spring_broken, torn.state.spring_broken)


def test_resuming_from_a_saved_state_continues_the_same_tear(torn, tmp_path):
    spec = scene()
    first = run(spec, frames=15)
    saved = tmp_path / "state.npz"
    np.savez(saved, **first.state.arrays())
    from fraytool.sim.state import State

    with np.load(saved) as data:
        resumed = Simulation(spec, model=first.model, state=State.from_arrays(data), frame=first.frame)
    while resumed.frame + 1 < FRAMES:
        resumed.advance_frame()
    for name, value in torn.state.arrays().items():
        assert np.array_equal(value, resumed.state.arrays()[name]), name
    assert isinstance(resumed.record(), FrameRecord)




@pytest.mark.parametrize("spread, straight", [(0.0, True), (0.03, False)])
def test_random_break_limits_make_the_cut_ragged(spread, straight):
    # A strip pulled apart by its edges: with equal limits every weft yarn breaks in the same column
    # (a knife cut; the strip is symmetric, so it may cut at both grips: at most two straight
    # cuts); with the scene's spread they break in many columns.
    from fraytool.scene import parse_scene
    from fraytool.kinds import STRUCT_WEFT

    sim = run(parse_scene(pulled_strip_text(spread=spread), "strip.toml"), frames=40)
    m, s = sim.model, sim.state
    broken = np.nonzero(s.spring_broken & (m.spring_kind == STRUCT_WEFT))[0]
    assert len(broken) >= m.weft_yarns  # torn through
    columns = set((m.spring_crossing_a[broken] % m.warp_yarns).tolist())
    assert (len(columns) <= 2) == straight, sorted(columns)
    if not straight:
        assert len(columns) >= 4
