"""The step's contract (docs/architecture.md "The step's contract"): one step context, declared reads and
writes from which the coarse syncs follow, one topology change counter, one completion call."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fraytool.scene import load_scene
from fraytool.sim.builder import build_model
from fraytool.sim.simulation import Simulation
from fraytool.sim.solver import SolverExplicitPBD
from fraytool.sim.stages import plan_syncs
from fraytool.sim.stages.base import (COARSE_VIEWS, FORCES, HANGING, POSITIONS, SLAVED, SLAVED_NEAR_HOT,
                                      STALES_VIEWS, START_POSITIONS, StepContext)
from fraytool.sim.state import State
import pytest

pytestmark = pytest.mark.fast  # `pytest -m fast` (docs/testing.md)

ROOT = Path(__file__).resolve().parent.parent


@dataclass(eq=False)
class _Stage:
    name: str
    reads: frozenset
    writes: frozenset


def _names(stages) -> list:
    return [(type(s).__name__, getattr(s, "views", None) or s.name) for s in stages]


def test_syncs_follow_from_the_declarations():
    """A sync goes before a reader of a view only when a writer of positions or topology came since the
    last sync (or since the previous step's last writer); a sync of every slaved crossing covers the
    other views; no coarse model, no sync."""
    ctx = StepContext.for_model(build_model(load_scene(ROOT / "scenes" / "drape.toml")))
    forces = _Stage("forces", frozenset({HANGING}), frozenset({FORCES}))
    move = _Stage("integration", frozenset(), frozenset({POSITIONS, START_POSITIONS}))
    limit = _Stage("strain_limiting", frozenset({HANGING}), frozenset({POSITIONS}))
    pure = _Stage("collisions", frozenset({POSITIONS}), frozenset())
    collide = _Stage("self_collision", frozenset({SLAVED}), frozenset({POSITIONS}))
    hang_again = _Stage("refinement", frozenset({HANGING}), frozenset())
    tear = _Stage("tearing", frozenset({SLAVED_NEAR_HOT}), frozenset())
    stages = [forces, move, limit, pure, collide, hang_again, tear]
    assert plan_syncs(stages, ctx) == stages  # no coarse model
    ctx.coarse = object()  # a coarse model (plan_syncs only asks whether there is one)
    planned = plan_syncs(stages, ctx)
    syncs = [(type(p).__name__, p.views, p.name) for p in planned if p not in stages]
    assert syncs == [
        # none before forces: the step before ended with the hanging nodes synced (nothing wrote after
        # the refinement's sync)
        ("CoarseSync", (HANGING,), "strain_limiting"),  # after the position update
        ("CoarseSync", (SLAVED,), "self_collision"),  # the limit wrote positions since
        ("CoarseSync", (HANGING,), "refinement"),  # self-collision wrote positions since
        ("CoarseSync", (SLAVED_NEAR_HOT,), "tearing"),  # covered by nothing fresh: refinement's sync was hanging
    ]
    # a writer at the end of the step: the next step's first reader needs its sync
    stages.append(_Stage("tearing", frozenset(), frozenset({POSITIONS})))
    planned = plan_syncs(stages, ctx)
    assert type(planned[0]).__name__ == "CoarseSync" and planned[0].views == (HANGING,) and planned[1] is forces


def test_a_multires_tearing_scene_has_a_sync_before_each_reader_and_no_stage_holds_another():
    spec = load_scene(ROOT / "scenes" / "fig6_thrown_ball_plain.toml", [("cloth.multires.factor", 4)])
    solver = SolverExplicitPBD(build_model(spec))
    stages = solver.stages
    assert "SyncSlaved" not in [type(s).__name__ for s in stages]  # no hand-placed sync stage
    fresh = set(COARSE_VIEWS)  # a walk of two steps: what each reader sees
    for stage in stages + stages:
        if type(stage).__name__ == "CoarseSync":
            fresh |= set(COARSE_VIEWS) if SLAVED in stage.views else set(stage.views)
            continue
        for view in set(COARSE_VIEWS) & stage.reads:
            assert view in fresh, f"{type(stage).__name__} reads {view} out of date"
        if stage.writes & set(STALES_VIEWS):
            fresh = set()
    held = [(type(s).__name__, k) for s in stages for k, v in vars(s).items()
            if any(v is other for other in stages) or hasattr(v, "run") and hasattr(v, "writes")]
    assert held == []
    assert solver.tearing is solver.context.yarn_tearing and solver.context.coarse is not None


def test_the_topology_epoch_changes_with_the_topology_and_is_not_saved():
    sim = Simulation(load_scene(ROOT / "scenes" / "fig7_square_grab.toml"))
    state, tearing = sim.state, sim.solver.tearing
    seen = {state.topology_epoch}

    def changed() -> bool:
        new = state.topology_epoch not in seen
        seen.add(state.topology_epoch)
        return new

    c = 20 * sim.model.warp_yarns + 20
    assert tearing.split(state, [c]) == 1 and changed()
    tearing.disconnect(state, c)
    assert changed()
    spring = int(sim.model.weft_structural_spring[30, 30])
    assert tearing.cut(state, spring) > 0 and changed()
    copy = state.copy()
    assert copy.topology_epoch == state.topology_epoch  # the same topology: the caches are shared
    assert "topology_epoch" not in state.arrays()
    loaded = State.from_arrays(state.arrays())
    assert loaded.topology_epoch not in seen  # a loaded state: its own
    epoch = state.topology_epoch
    sim.step()
    assert state.topology_epoch == epoch  # a step that changes no topology keeps it


def test_a_step_that_cuts_changes_the_epoch():
    sim = Simulation(load_scene(ROOT / "scenes" / "fig7_square_grab.toml"))
    before = sim.state.topology_epoch
    for _ in range(40 * sim.steps_per_frame):
        sim.step()
        if sim.state.spring_broken.any():
            break
    assert sim.state.spring_broken.any() and sim.state.topology_epoch != before


def test_the_completion_call_is_documented_on_the_step():
    doc = SolverExplicitPBD.step.__doc__
    assert "complete(state, dt_s)" in doc and "advance_frame" in doc
    assert SolverExplicitPBD.complete.__doc__
    model = build_model(load_scene(ROOT / "scenes" / "drape.toml"))
    state, solver = model.state(), SolverExplicitPBD(model)
    solver.step(state, 1e-4)
    x = state.particle_position_m.copy()
    solver.complete(state, 1e-4)  # no coarse grid: nothing to do
    assert np.array_equal(x, state.particle_position_m)
