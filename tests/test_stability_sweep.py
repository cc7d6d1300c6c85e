"""`fraytool study --stability`: stiff and extreme variants classified as stable, strain over the
limit, oscillating or unstable (guard); and every scene in scenes/stress/ meets the expectation it
states in its `#! expect = {...}` line."""
import csv

import pytest

from fraytool.commands.main import main
from fraytool.scene import parse_scene
from fraytool.study import plot
from fraytool.study.runner import RunResult
from fraytool.study.stability_sweep import OUTCOMES, STRAIN_SLACK, classify, run_stability_sweep
from fraytool.study.stress import check_expectation, read_expectation, stress_scenes

SMALL = """
[scene]
name = "small_sweep"
seed = 2

[time]
step_s = 4e-4
steps_per_frame = 10
frames = 13

[cloth]
warp_yarns = 6
weft_yarns = 6
spacing_m = 0.005
thickness_m = 0.0008
mass_per_crossing_kg = 2.0e-5
origin_m = [-0.0125, 0.0, 0.0]
plane = "xy"

[cloth.springs]
structural_n_per_m = 20.0
bend_n_per_m = 0.5
shear_n_per_m = 2.0
damping = 0.01

[[bodies]]
name = "rail"
shape = "sphere"
radius_m = 0.001
position_m = [0.0, 0.025, 0.0]
collide = false

[[attachments]]
body = "rail"
edge = "top"
"""

STRESS = stress_scenes()


def test_classify_order_of_outcomes():
    spec = parse_scene(SMALL, "s.toml")
    ok = RunResult(spec=spec, frames=1, max_strain=0.1, max_jitter=1e-4)
    assert classify(ok, 0.1) == "stable"
    assert classify(RunResult(spec=spec, frames=1, max_strain=0.1 * (1 + 2 * STRAIN_SLACK)), 0.1) == "strain_over_limit"
    assert classify(RunResult(spec=spec, frames=1, max_strain=0.5, max_jitter=0.5), 0.1) == "oscillating"
    assert classify(RunResult(spec=spec, frames=1, status="unstable", max_jitter=0.5), 0.1) == "unstable"


def test_quick_sweep_classifies_the_stiff_and_extreme_cases(tmp_path, capsys):
    scene = tmp_path / "small_sweep.toml"
    scene.write_text(SMALL)
    rc = main(["study", "--stability", "--quick", str(scene), "-o", str(tmp_path)])
    assert rc == 0
    err = capsys.readouterr().err
    assert "stability sweep of small_sweep" in err
    rows = {r["case"]: r for r in csv.DictReader((tmp_path / "study" / "stability.csv").open())}
    assert {r["outcome"] for r in rows.values()} <= set(OUTCOMES)
    assert {r["group"] for r in rows.values()} == {"base", "stiffness", "step", "pull", "impact", "mass", "thin"}
    assert rows["scene as given"]["outcome"] == "stable"
    assert rows["stiffness x0.1"]["outcome"] == "stable"
    assert rows["step 0.9 x bound"]["outcome"] == "stable"
    # far past the bound the explicit step cannot be stable, whatever holds it bounded
    for case in ("stiffness x1000", "mass x0.001", "step 2 x bound"):
        assert rows[case]["outcome"] in ("oscillating", "unstable"), rows[case]
        assert float(rows[case]["step_over_bound_power"]) > 1.5
    report = (tmp_path / "study" / "stability.md").read_text()
    assert "| stiffness x1000 |" in report and "Outcomes:" in report
    if plot.have_matplotlib():
        assert (tmp_path / "study" / "stability.png").stat().st_size > 1000


def test_guard_stopped_cases_carry_the_stage():
    spec = parse_scene(SMALL.replace("[cloth.springs]", "[cloth.strain]\nmax_iterations = 0\n\n[cloth.springs]"),
                       "unlimited.toml")
    sweep = run_stability_sweep(spec, quick=True, stream=None)
    unstable = [c for c in sweep.cases if c.outcome == "unstable"]
    assert unstable, [(c.name, c.outcome) for c in sweep.cases]
    for c in unstable:
        row = c.row()
        assert row["guard_stage"] and row["guard_particle"] is not None and row["guard_step"] > 0


def test_every_stress_scene_states_its_expectation():
    assert len(STRESS) >= 6
    outcomes = set()
    for path in STRESS:
        text = path.read_text()
        assert text.startswith("#") and "# Expect: " in text, f"{path.name}: no top comment with 'Expect:'"
        expect = read_expectation(path)
        assert expect is not None and expect["outcome"] in OUTCOMES
        outcomes.add(expect["outcome"])
    assert outcomes == set(OUTCOMES)  # each outcome has at least one stress scene


@pytest.mark.parametrize("path", STRESS, ids=lambda p: p.stem)
def test_stress_scene_meets_its_expectation(path):
    result = check_expectation(path)
    assert result["passed"], f"{path.name}: {result['problems']}"
