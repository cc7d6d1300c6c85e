"""The stability guard: a non-finite or absurd value stops the run at once, with a diagnostic that
names the step, the stage, the mass and its springs; the last good state is saved; no frame record
with a NaN is ever written; the command exits 1 with one line and no traceback."""
import json
import math
from pathlib import Path

import numpy as np
import pytest

import fraytool.sim.simulation as simulation_module
from fraytool.commands.main import main
from fraytool.io.frame_store import FrameStore
from fraytool.sim.run import simulate_to_disk
from fraytool.scene import load_scene, parse_scene
from fraytool.sim import Simulation, SimulationUnstable
from fraytool.io.failure import LAST_GOOD_STATE, UNSTABLE_JSON
from fraytool.sim.guard import StageFailure, make_stage_check
from fraytool.sim.stages import HookStage
from fraytool.sim.state import State

SCENE = """
[scene]
name = "guarded"
seed = 4

[time]
step_s = 4e-4
steps_per_frame = 10
frames = 8

[cloth]
warp_yarns = 8
weft_yarns = 8
spacing_m = 0.005
thickness_m = 0.0008
mass_per_crossing_kg = 2.0e-5
origin_m = [-0.0175, 0.04, -0.0175]
plane = "xz"

[cloth.springs]
structural_n_per_m = 20.0
bend_n_per_m = 0.5
shear_n_per_m = 2.0
damping = 0.01

[[bodies]]
name = "ball"
shape = "sphere"
radius_m = 0.02
position_m = [0.0, 0.015, 0.0]
"""
INJECT_STEP = 37
"""The hook poisons the state during the step that brings step_index to INJECT_STEP + 1 (frame 3)."""
MASS = 13


def _poison_position(state, prev, dt):
    if state.step_index == INJECT_STEP:
        state.particle_position_m[MASS, 1] = np.nan


def _with_hook(monkeypatch, slot: str, hook):
    """Every solver the simulation makes runs `hook` as an extra stage at `slot`."""
    original = simulation_module.SolverExplicitPBD

    class Hooked(original):
        def __init__(self, model, *args, **kwargs):
            super().__init__(model, *args, **kwargs)
            self.insert_stage(HookStage(slot, hook))

    monkeypatch.setattr(simulation_module, "SolverExplicitPBD", Hooked)


def _strict_json(path: Path) -> dict:
    def no_nan(name):
        raise ValueError(f"{path} holds a bare {name}")

    return json.loads(path.read_text(), parse_constant=no_nan)


def _assert_no_nan_frame(out: Path) -> int:
    frames = sorted((out / "frames").glob("frame_*.npz"))
    for f in frames:
        with np.load(f) as d:
            for k in d.files:
                if d[k].dtype.kind == "f":
                    assert np.isfinite(d[k]).all(), f"{f.name}: {k} is not finite"
    with np.load(out / "frames" / "checkpoint.npz") as d:
        assert np.isfinite(d["particle_position_m"]).all()
    return len(frames)


def test_injected_nan_stops_the_run_and_no_nan_frame_is_written(tmp_path, monkeypatch, capsys):
    scene = tmp_path / "guarded.toml"
    scene.write_text(SCENE)
    _with_hook(monkeypatch, "tearing", _poison_position)
    out = tmp_path / "out"
    rc = main(["simulate", str(scene), "-o", str(out)])
    err = capsys.readouterr().err
    assert rc == 1
    assert "Traceback" not in err
    lines = [ln for ln in err.splitlines() if ln.startswith("fraytool:")]
    assert len(lines) == 1, err
    line = lines[0]
    assert line.startswith("fraytool: run failed: simulation became unstable at step 38")
    assert "in stage tearing (_poison_position)" in line and f"mass {MASS} " in line and "non-finite" in line
    assert str(out / "frames" / UNSTABLE_JSON) in line

    # frames 0..3 complete and finite; the failure was in frame 4
    assert _assert_no_nan_frame(out) == 4
    store = FrameStore(out)
    assert store.frames_complete() == 4
    diag = _strict_json(out / "frames" / UNSTABLE_JSON)
    assert diag["step"] == 38 and diag["stage"] == "tearing" and diag["stage_located"]
    assert diag["particle"] == MASS and diag["crossing"] == [MASS % 8, MASS // 8]
    assert diag["last_good_frame"] == 3
    spring_ends = {tuple(sorted((MASS, s["other_particle"]))) for s in diag["springs"]}
    assert (MASS, MASS + 1) in spring_ends and diag["spring"] in [s["spring"] for s in diag["springs"]]
    assert store.manifest()["unstable"]["stage"] == "tearing"
    # the state just before the failed step is saved, finite, and is the state at step 37
    with np.load(out / "frames" / LAST_GOOD_STATE) as d:
        last = State.from_arrays(d)
    assert last.step_index == INJECT_STEP and np.isfinite(last.particle_position_m).all()
    frame, arrays = store.load_checkpoint()
    state = State.from_arrays(arrays)
    sim = Simulation(parse_scene(SCENE, "guarded.toml"), state=state, frame=frame)
    for _ in range(INJECT_STEP - state.step_index):
        sim.step()
    np.testing.assert_array_equal(sim.state.particle_position_m, last.particle_position_m)


@pytest.mark.parametrize("slot", ["yarn_contact", "self_collision"])
def test_the_diagnostic_names_the_stage_that_produced_the_value(tmp_path, monkeypatch, slot):
    _with_hook(monkeypatch, slot, _poison_position)
    with pytest.raises(SimulationUnstable) as info:
        simulate_to_disk(parse_scene(SCENE, "guarded.toml"), tmp_path, progress=False)
    assert info.value.diagnostic["stage"] == slot
    assert _assert_no_nan_frame(tmp_path) == 4


def test_non_finite_body_in_a_frame_record_is_never_written(tmp_path, monkeypatch):
    """A static body's position is not checked every step; the record check keeps it off disk."""

    def poison_body(state, prev, dt):
        if state.step_index == 29:  # the last step of frame 3
            state.body_position_m[0] = np.nan

    _with_hook(monkeypatch, "tearing", poison_body)
    with pytest.raises(SimulationUnstable) as info:
        simulate_to_disk(parse_scene(SCENE, "guarded.toml"), tmp_path, progress=False)
    assert info.value.diagnostic["stage"] == "frame record"
    assert _assert_no_nan_frame(tmp_path) == 3
    assert _strict_json(tmp_path / "frames" / UNSTABLE_JSON)["stage"] == "frame record"


def test_a_real_instability_is_stopped_in_the_velocity_update(tmp_path):
    spec = load_scene("scenes/stress/stiff_past_bound_unlimited.toml")
    with pytest.raises(SimulationUnstable) as info:
        simulate_to_disk(spec, tmp_path, progress=False)
    d = info.value.diagnostic
    assert d["stage"] == "integration" and d["kernel"] == "integrate_velocities"
    assert d["step_over_bound"] > 1.5
    assert "x the stability bound" in str(info.value) and "use [time] step_s <=" in str(info.value)
    assert "\n" not in str(info.value)
    n = _assert_no_nan_frame(tmp_path)
    assert n == d["last_good_frame"] + 1 >= 3
    end = d["end_of_step"]  # what the end-of-step check saw: the speed over the limit
    assert not (math.sqrt(sum(v * v for v in end["velocity_m_s"])) <= d["speed_limit_m_s"])


def test_stage_check_flags_non_finite_forces():
    sim = Simulation(parse_scene(SCENE, "guarded.toml"))
    sim.step()
    solver, state = sim.solver, sim.state
    check = make_stage_check(solver, state, sim.dt_s)
    forces = solver.stages[0]  # declares it writes the forces, so they are checked from here on
    check(forces)  # all sane: nothing raised
    solver.context.force_n[5, 0] = np.inf
    with pytest.raises(StageFailure) as info:
        check(forces)
    assert info.value.diagnostic["particle"] == 5 and info.value.diagnostic["kernel"] == "accumulate_spring_forces"


def test_guard_is_off_in_normal_runs_and_the_replay_leaves_no_trace(monkeypatch, tmp_path):
    sim = Simulation(parse_scene(SCENE, "guarded.toml"))
    assert sim.solver.stage_check is None
    _with_hook(monkeypatch, "tearing", _poison_position)
    sim = Simulation(parse_scene(SCENE, "guarded.toml"))
    start = sim.state.copy()
    with pytest.raises(SimulationUnstable) as info:
        for _ in range(INJECT_STEP + 5):
            sim.step()
    from fraytool.sim.guard import explain_failure

    stages_before = dict(sim.solver.stage_s)
    diag, before = explain_failure(sim.solver, start, sim.dt_s, info.value.diagnostic)
    assert diag["stage"] == "tearing" and before.step_index == INJECT_STEP
    assert sim.solver.stage_check is None and sim.solver.stage_s == stages_before
