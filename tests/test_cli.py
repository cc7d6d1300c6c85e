"""The CLI contract other issues rely on: simulate --json, check, bench --json, --version, python -m."""
import re
import json
import subprocess
import sys

import pytest

from fraytool import __version__
from fraytool.commands.main import main
from helpers import small_scene_text


def test_version(capsys):
    try:
        main(["--version"])
    except SystemExit as exc:
        assert exc.code == 0
    assert __version__ in capsys.readouterr().out


def test_simulate_json_summary(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text(small_scene_text(frames=4))
    assert main(["simulate", str(scene), "-o", str(tmp_path / "out"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("frames", "masses", "springs", "broken_springs", "yarn_level_masses", "max_strain", "all_finite"):
        assert key in out
    assert out["frames"] == 4 and out["masses"] == 144 and out["all_finite"] is True
    assert len(list((tmp_path / "out" / "frames").glob("frame_*.npz"))) == 4


def test_bench_json(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text(small_scene_text(frames=4))
    assert main(["bench", str(scene), "--frames", "3", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) >= {"scene", "masses", "springs", "frames", "ms_per_frame", "stages_ms_per_frame",
                        "export_ms_per_frame", "compile_s"}
    assert out["frames"] == 3 and out["ms_per_frame"] > 0
    assert {"forces", "integration", "strain_limiting"} <= set(out["stages_ms_per_frame"])
    assert out["export_ms_per_frame"] > 0 and "export" not in out["stages_ms_per_frame"]
    assert out["kernels_compiled_in_timed_frames"] >= 0


def test_bench_times_again_when_kernels_compiled_during_the_timed_frames(tmp_path, monkeypatch):
    """A kernel compiled during the timed frames (a cold numba cache) would be in the stage means and
    the memory peak: the bench then times the frames again and reports that second run."""
    import itertools

    from fraytool.commands import bench
    from fraytool.scene import load_scene

    scene = tmp_path / "s.toml"
    scene.write_text(small_scene_text(frames=4))
    runs = []
    real = bench._timed_run

    def counted(*args, **kwargs):
        runs.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(bench, "_timed_run", counted)
    counter = itertools.count(10, 3)                      # every call sees 3 more compilations
    monkeypatch.setattr(bench, "kernels_compiled", lambda: next(counter))
    out = bench.bench_simulation(load_scene(scene), frames=2)
    assert len(runs) == 2 and out["timed_runs"] == 2 and out["kernels_compiled_in_timed_frames"] == 3
    runs.clear()
    monkeypatch.setattr(bench, "kernels_compiled", lambda: 10)  # nothing compiled: timed once
    out = bench.bench_simulation(load_scene(scene), frames=2)
    assert len(runs) == 1 and out["timed_runs"] == 1 and out["kernels_compiled_in_timed_frames"] == 0


def test_bench_counts_kernels_compiled_in_this_process(monkeypatch):
    """`bench` says when numba compiled a fraytool kernel during the timed frames (its stage means then
    include the compilation): the counter follows the cache misses of fraytool's dispatchers."""
    import types

    import numba

    from fraytool.commands.bench import kernels_compiled

    module = types.ModuleType("fraytool._bench_probe")

    @numba.njit(cache=False)
    def probe(x):
        return x + 1

    module.probe = probe
    monkeypatch.setitem(sys.modules, module.__name__, module)
    before = kernels_compiled()
    assert probe(1) == 2          # compiled now (no cache: a miss)
    assert kernels_compiled() == before + 1
    assert probe(2) == 3          # the same signature: no compilation
    assert kernels_compiled() == before + 1


def test_python_dash_m_and_default_out_dir(tmp_path):
    scene = tmp_path / "tiny.toml"
    scene.write_text(small_scene_text(name="tiny", frames=2))
    r = subprocess.run([sys.executable, "-m", "fraytool", "simulate", str(scene)], cwd=tmp_path,
                       capture_output=True, text=True, stdin=subprocess.DEVNULL)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "outputs" / "tiny" / "frames" / "frame_000001.npz").is_file()
    assert r.stderr.count("\r") == 0  # no progress bar when not on a terminal


def test_check_json_figures(capsys):
    assert main(["check", "scenes/fig7_square_grab.toml", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["masses"] == 4096
    assert out["springs_by_kind"]["structural_weft"] == 64 * 63
    # the shear twins are slots reserved for splits, not springs: the kinds add up to the springs
    assert out["springs_by_kind"]["shear_twin"] == 0 and sum(out["springs_by_kind"].values()) == out["springs"]
    assert out["spring_slots"] == out["springs"] + out["shear_twin_slots"] and out["shear_twin_slots"] > 0
    assert 0 < out["stability_bound_s"] < 1


@pytest.mark.parametrize("mode", ["log", "bar", "none"])
def test_progress_modes(mode, tmp_path, capsys, monkeypatch):
    import fraytool.progress

    monkeypatch.setattr(fraytool.progress, "LOG_EVERY_S", 0.0)  # a line at every frame
    scene = tmp_path / "s.toml"
    scene.write_text(small_scene_text(frames=5))
    assert main(["simulate", str(scene), "-o", str(tmp_path / "out"), "--progress", mode]) == 0
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.startswith("fraytool progress: ")]
    if mode == "log":
        assert "\r" not in err and len(lines) >= 4
        assert re.fullmatch(r"fraytool progress: simulate small: 3/5 frames \(60%\), [0-9.]+ frames/s, ETA [0-9.]+ s",
                            lines[1]), lines
        assert lines[-1].startswith("fraytool progress: simulate small: 5/5 frames (100%)") and len(lines) == 4
    elif mode == "bar":
        assert "\r" in err and not lines
    else:
        assert "\r" not in err and not lines and "simulate small" not in err


def test_progress_auto_is_log_off_a_terminal(monkeypatch):
    import io

    import fraytool.progress

    monkeypatch.setattr(fraytool.progress, "_default_mode", "auto")
    from fraytool.progress import Progress

    class Tty(io.StringIO):
        def isatty(self):
            return True

    assert Progress(3, "x", stream=io.StringIO()).mode == "log"
    assert Progress(3, "x", stream=Tty()).mode == "bar"


def test_unknown_scene_name_suggests_the_closest_shipped_ones(capsys):
    assert main(["check", "fig7_sqare_grab"]) == 2
    err = capsys.readouterr().err
    assert "did you mean fig7_square_grab" in err
    assert main(["check", "stress/very_stif_small_step"]) == 2
    assert "did you mean stress/very_stiff_small_step" in capsys.readouterr().err
    assert main(["check", "fig6"]) == 2  # a scene's start
    assert "did you mean fig6_thrown_ball_plain or fig6_thrown_ball_twill?" in capsys.readouterr().err


def test_a_negative_camera_position_needs_no_equals_sign(tmp_path):
    from fraytool.commands.main import _join_negative_vectors, build_parser

    argv = _join_negative_vectors(["render", "drape", "--camera-position", "-0.02,0.26,0.16",
                                   "--camera-target", "-1,-2,-3", "--fov", "40"])
    args = build_parser().parse_args(argv)
    assert args.camera_position == "-0.02,0.26,0.16" and args.camera_target == "-1,-2,-3" and args.fov == 40.0


def test_a_cold_kernel_cache_is_announced_once(tmp_path, monkeypatch):
    """The first simulation after an install or update compiles its kernels (about a minute): one line
    says so before it starts; the next simulation in the same process says nothing."""
    import io

    import fraytool._numba_cache as cache
    from fraytool.sim.run import simulate_to_disk
    from helpers import small_scene

    monkeypatch.setattr(cache, "COLD", True)
    first, second = io.StringIO(), io.StringIO()
    simulate_to_disk(small_scene(), tmp_path / "a", frames=2, progress=False, stream=first)
    simulate_to_disk(small_scene(), tmp_path / "b", frames=2, progress=False, stream=second)
    assert first.getvalue().count("compiling the simulation kernels") == 1
    assert "compiling" not in second.getvalue()


def test_a_kernel_compiled_mid_run_is_announced_once():
    """A cache that holds some kernels but not those a scene's features need (fig7's tearing after a drape)
    compiles them mid-run: one line says so, the first time a fraytool kernel compiles; a kernel loaded
    or compiled before, or one of another package, says nothing."""
    import numba

    from fraytool._numba_cache import FIRST_USE_NOTE, first_compile_notice

    def kernel(module: str):
        space = {"__name__": module}
        exec("def f(x):\n    return x + 1\n", space)
        return numba.njit(space["f"])

    said = []
    ours, other = kernel("fraytool.sim.kernels.probe"), kernel("elsewhere.probe")
    with first_compile_notice(said.append):
        other(1)
        assert said == []
        ours(1)
        ours(2)
        kernel("fraytool.render.probe")(1)
    assert said == [FIRST_USE_NOTE]
    with first_compile_notice(said.append):
        ours(3)                                   # compiled already: nothing to say
    assert said == [FIRST_USE_NOTE]


def test_a_misspelled_flag_gets_one_line_and_a_suggestion(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["render", "fig6_thrown_ball_plain", "--frmaes", "0:2"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "unrecognized arguments: --frmaes" in err and "did you mean --frames?" in err
    assert len(err.strip().splitlines()) == 1 and "usage:" not in err


def test_simulate_resume_says_where_it_resumed(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text(small_scene_text(frames=5))
    out = tmp_path / "out"
    assert main(["simulate", str(scene), "-o", str(out), "--frames", "3", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["resumed_at_frame"] is None      # a fresh run
    assert main(["simulate", str(scene), "-o", str(out), "--resume"]) == 0
    assert "(resumed at frame 3: frames 0-2 verified and kept)" in capsys.readouterr().err


def test_a_frame_range_past_the_scene_says_how_to_make_it_longer(capsys):
    """`render --frames 0:500` on a 36-frame scene: the message says --set time.frames=500."""
    from fraytool.commands.main import main as _main

    assert _main(["render", "drape", "--frames", "0:500", "--png", "--no-mp4", "-o", "/nonexistent/x"]) == 2
    assert "--set time.frames=500" in capsys.readouterr().err


def test_model_builder_error_is_importable_where_the_readme_says():
    from fraytool.sim import ModelBuilder, ModelBuilderError

    with pytest.raises(ModelBuilderError):
        ModelBuilder().add_cloth(warp_yarns=1, weft_yarns=3, spacing_m=0.01, thickness_m=0.001,
                                 mass_per_crossing_kg=1e-5, structural_n_per_m=1.0)


def test_more_msaa_samples_than_the_driver_draws_is_said(tmp_path, capsys):
    """[render] samples above the context's GL_MAX_SAMPLES (4 on llvmpipe) draws with the maximum and says
    so, naming the key, the value asked and the count drawn, rather than dropping to it silently."""
    from fraytool.render.context import create_context

    ctx = create_context()
    most = int(ctx.max_samples)
    ctx.release()
    scene = tmp_path / "s.toml"
    scene.write_text(small_scene_text(frames=2))
    assert main(["render", str(scene), "-o", str(tmp_path / "out"), "--frames", "0:1", "--resolution", "64x48",
                 "--set", f"render.samples={2 * most}", "--png", "--no-mp4"]) == 0
    err = capsys.readouterr().err
    assert f"warning: [render] samples = {2 * most}:" in err and f"drawing with {most}" in err
    assert main(["render", str(scene), "-o", str(tmp_path / "out2"), "--frames", "0:1", "--resolution", "64x48",
                 "--set", f"render.samples={most}", "--png", "--no-mp4"]) == 0
    assert "samples =" not in capsys.readouterr().err
