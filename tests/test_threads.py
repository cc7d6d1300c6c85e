"""The parallel kernels give the same frames on one thread and on two (fraytool/threads.py), and
--threads is checked."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fraytool.commands.main import main
from fraytool.threads import thread_limit
from helpers import pulled_strip_text

ROOT = Path(__file__).resolve().parents[1]


def _simulate(scene: Path, out: Path, threads: int) -> dict:
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads), PYTHONPATH=str(ROOT))
    r = subprocess.run([sys.executable, "-m", "fraytool", "simulate", str(scene), "-o", str(out), "--json",
                        "--progress", "none"], capture_output=True, text=True, env=env, cwd=ROOT, timeout=600)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


PARALLEL_STRIP = """[cloth.strain]
limit = 0.10
stiffness_n_per_m = {stiffness}
damping_ratio = {damping}
[self_collision]
enabled = true
"""
"""The pulled strip with self-collision and the hard strain limit (colour groups in parallel,
stiffness 0) or the figure scenes' compliant one (yarn lines in parallel)."""


@pytest.mark.parametrize("stiffness,factor", [(0.0, 1), (400.0, 1), (400.0, 2)],
                         ids=["hard limit", "compliant limit", "compliant limit, multires factor 2"])
def test_a_tearing_run_is_bit_identical_on_one_and_two_threads(tmp_path, stiffness, factor):
    """The yarn-level pulled strip with self-collision tears (splits, cuts, couples): every frame and
    the checkpoint are the same bytes whether numba may use one thread or two; also as a coarse base
    model that refines ahead of the tear ([cloth.multires], docs/multires.md)."""
    scene = tmp_path / "strip.toml"
    extra = PARALLEL_STRIP.format(stiffness=stiffness, damping=1.0 if stiffness else 0.0)
    if factor > 1:
        extra += f"[cloth.multires]\nfactor = {factor}\n"
    scene.write_text(pulled_strip_text("strip", yarn_level=True, extra=extra))
    one = _simulate(scene, tmp_path / "one", 1)
    two = _simulate(scene, tmp_path / "two", 2)
    if factor > 1:  # it starts (partly) coarse and refines during the run: both kinds of cell ran
        from fraytool.scene import load_scene
        from fraytool.sim.builder import build_model

        start = build_model(load_scene(scene)).state().coarse_cell_refined
        with np.load(tmp_path / "one" / "frames" / "checkpoint.npz") as c:
            end = c["coarse_cell_refined"]
        assert start.sum() < start.size and end.sum() > start.sum()
    assert one["broken_springs"] > 0 and one["yarn_level_crossings"] > 0  # it tore at the yarn level
    assert {k: v for k, v in one.items() if "wall" not in k and "_s" != k[-2:]} == \
        {k: v for k, v in two.items() if "wall" not in k and "_s" != k[-2:]}
    frames = sorted((tmp_path / "one" / "frames").glob("*.npz"))
    assert len(frames) > 3
    for path in frames:
        with np.load(path) as a, np.load(tmp_path / "two" / "frames" / path.name) as b:
            assert sorted(a.files) == sorted(b.files)
            for key in a.files:
                assert a[key].tobytes() == b[key].tobytes(), (path.name, key)


@pytest.mark.parametrize("scene,frames", [("mannequin_snag", 40), ("flag_tear", 24)])
def test_mesh_contact_and_air_drag_are_bit_identical_on_one_and_two_threads(tmp_path, scene, frames):
    """mannequin_snag's cloth against its mesh (masses and yarn segments, both in parallel: the segments'
    first sweep tested beforehand, fraytool.sim.kernels.mesh_contact.segments_touching) as it catches and
    tears, and flag_tear's air drag and gusts (parallel over crossings): the same bytes on one thread and on
    two."""
    def run(threads: int) -> Path:
        out = tmp_path / str(threads)
        env = dict(os.environ, NUMBA_NUM_THREADS=str(threads), PYTHONPATH=str(ROOT))
        r = subprocess.run([sys.executable, "-m", "fraytool", "simulate", scene, "-o", str(out),
                            "--frames", str(frames), "--progress", "none"], capture_output=True, text=True, env=env,
                           cwd=ROOT, timeout=600)
        assert r.returncode == 0, r.stderr
        return out / "frames"

    one, two = run(1), run(2)
    frames_written = sorted(one.glob("*.npz"))
    assert len(frames_written) > frames
    with np.load(one / f"frame_{frames - 1:06d}.npz") as last, np.load(one / "frame_000000.npz") as first:
        assert not np.array_equal(last["particle_position_m"], first["particle_position_m"])
    for path in frames_written:
        with np.load(path) as a, np.load(two / path.name) as b:
            for key in a.files:
                assert a[key].tobytes() == b[key].tobytes(), (path.name, key)


def test_threads_flag_is_checked(tmp_path, capsys):
    scene = tmp_path / "strip.toml"
    scene.write_text(pulled_strip_text("strip"))
    too_many = thread_limit() + 1
    assert main(["simulate", str(scene), "-o", str(tmp_path / "o"), "--threads", str(too_many)]) == 2
    err = capsys.readouterr().err
    assert f"--threads {too_many}: allowed 1 to {thread_limit()}" in err
    assert main(["simulate", str(scene), "-o", str(tmp_path / "o"), "--threads", "0"]) == 2
    assert not (tmp_path / "o").exists()  # refused before anything was written


@pytest.mark.skipif(thread_limit() < 2, reason="needs two cores: numba allows one thread here")
def test_threads_flag_and_the_default_set_numba(tmp_path, monkeypatch):
    """--threads N sets numba's threads; without it a command runs one thread, unless the environment
    sets NUMBA_NUM_THREADS (fraytool.threads.DEFAULT_THREADS). More than one thread asks OpenMP for
    spinning waits, unless the environment chose a wait policy (fraytool.threads.WAIT_POLICY)."""
    import numba

    from fraytool.threads import WAIT_POLICY

    monkeypatch.delenv("OMP_WAIT_POLICY", raising=False)  # set by the run below: undone after the test
    scene = tmp_path / "strip.toml"
    scene.write_text(pulled_strip_text("strip"))
    before = numba.get_num_threads()

    def run(*extra):
        assert main(["simulate", str(scene), "-o", str(tmp_path / "o"), "--frames", "1", "--progress", "none",
                     *extra]) == 0
        return numba.get_num_threads()

    try:
        assert run("--threads", "2") == 2
        assert os.environ["OMP_WAIT_POLICY"] == WAIT_POLICY
        monkeypatch.setenv("OMP_WAIT_POLICY", "PASSIVE")
        assert run("--threads", "2") == 2 and os.environ["OMP_WAIT_POLICY"] == "PASSIVE"  # the user's stands
        monkeypatch.delenv("NUMBA_NUM_THREADS", raising=False)
        assert run() == 1  # the default
        numba.set_num_threads(2)
        monkeypatch.setenv("NUMBA_NUM_THREADS", "2")
        assert run() == 2  # the environment's choice stands
        assert run("--threads", "1") == 1
    finally:
        numba.set_num_threads(before)
