"""Same scene and seed give bit-identical frames; --resume after an interruption gives the same
frames as an uninterrupted run; a killed write never leaves a corrupt frame."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from fraytool.io.frame_store import FrameStore, save_verified
from fraytool.sim.run import simulate_to_disk
from fraytool.scene import parse_scene
from helpers import BALL, assert_arrays_equal, pulled_strip_text, small_scene, small_scene_text



def _frames(out: Path) -> list[dict]:
    store = FrameStore(out)
    result = []
    for k in range(store.frames_complete()):
        with np.load(store.frame_path(k)) as d:
            result.append({name: d[name] for name in d.files})
    return result


def _assert_same_frames(a: list[dict], b: list[dict]) -> None:
    assert len(a) == len(b) > 0
    for fa, fb in zip(a, b):
        assert_arrays_equal(fa, fb)


def test_same_seed_same_frames(tmp_path):
    spec = small_scene(BALL, frames=8)
    simulate_to_disk(spec, tmp_path / "a", progress=False)
    simulate_to_disk(spec, tmp_path / "b", progress=False)
    fa, fb = _frames(tmp_path / "a"), _frames(tmp_path / "b")
    _assert_same_frames(fa, fb)
    assert not np.array_equal(fa[0]["particle_position_m"], fa[-1]["particle_position_m"])  # it moved


def test_resume_equals_uninterrupted(tmp_path, monkeypatch):
    spec = small_scene(BALL, frames=10)
    simulate_to_disk(spec, tmp_path / "full", progress=False)

    # Interrupt: the write of frame 6 dies after the record is on disk, before checkpoint + manifest.
    original = FrameStore.write_frame

    def dying_write(self, record, state, write_record=True):
        if record.frame == 6:
            save_verified(self.frame_path(record.frame), record.arrays(), self.scene_hash())
            raise KeyboardInterrupt
        original(self, record, state, write_record)

    monkeypatch.setattr(FrameStore, "write_frame", dying_write)
    with pytest.raises(KeyboardInterrupt):
        simulate_to_disk(spec, tmp_path / "cut", progress=False)
    monkeypatch.setattr(FrameStore, "write_frame", original)
    assert FrameStore(tmp_path / "cut").frames_complete() == 6
    simulate_to_disk(spec, tmp_path / "cut", resume=True, progress=False)
    _assert_same_frames(_frames(tmp_path / "full"), _frames(tmp_path / "cut"))


def _checkpoint(out: Path) -> dict:
    with np.load(out / "frames" / "checkpoint.npz") as d:
        return {name: d[name] for name in d.files}


def test_resume_with_self_collision_and_tearing(tmp_path):
    """A strip torn at yarn level with self-collision on, stopped after 17 frames (its yarns have been
    meeting for two frames, and meet again in the next) and resumed to 22: every frame and the checkpoint are the same, array
    by array and bit for bit, as an unbroken run's. The unbroken run keeps its broad-phase candidates
    across the whole run; the resumed one builds them afresh (fraytool.sim.stages.self_collision,
    "Results independent of the kept candidates")."""
    spec = parse_scene(pulled_strip_text("torn_strip_sc", yarn_level=True, extra="[self_collision]\nenabled = true\n"),
                       "torn_strip_sc.toml")
    stop, total = 17, 22
    simulate_to_disk(spec, tmp_path / "full", frames=total, progress=False)
    first = simulate_to_disk(spec, tmp_path / "cut", frames=stop, progress=False)
    assert FrameStore(tmp_path / "cut").frames_complete() == stop
    assert first["yarn_level_masses"] > 0 and first["self_collision_pairs"] > 0  # torn, yarns met before the stop
    resumed = simulate_to_disk(spec, tmp_path / "cut", frames=total, resume=True, progress=False)
    assert resumed["self_collision_pairs"] > 0  # ... and after it (the counters restart at a resume)
    full, cut = _frames(tmp_path / "full"), _frames(tmp_path / "cut")
    assert len(full) == len(cut) == total
    _assert_same_frames(full, cut)
    a, b = _checkpoint(tmp_path / "full"), _checkpoint(tmp_path / "cut")
    assert sorted(a) == sorted(b)
    assert_arrays_equal(a, b)


def test_killed_process_resumes_to_identical_frames(tmp_path):
    """A real SIGKILL in the middle of a run: every frame on disk loads, and --resume completes it."""
    scene = tmp_path / "scene.toml"
    scene.write_text(small_scene_text(frames=400, steps_per_frame=20, nx=20, ny=20) + BALL)
    env = {**os.environ, "PYTHONHASHSEED": "0"}
    cmd = [sys.executable, "-m", "fraytool", "simulate", str(scene), "-o", str(tmp_path / "cut")]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    store = FrameStore(tmp_path / "cut")
    deadline = time.time() + 120
    while store.frames_complete() < 20 and time.time() < deadline and proc.poll() is None:
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    done = store.frames_complete()
    assert 20 <= done < 400, "the run was not interrupted in the middle"
    for k in range(done):
        np.load(store.frame_path(k))["particle_position_m"]  # every counted frame is complete
    r = subprocess.run(cmd + ["--resume", "--frames", "60"], env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    r = subprocess.run(cmd[:-1] + [str(tmp_path / "full"), "--frames", "60"], env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    _assert_same_frames(_frames(tmp_path / "full")[:60], _frames(tmp_path / "cut")[:60])


def test_manifest_records_scene_hash_seed_version(tmp_path):
    spec = small_scene(frames=3)
    simulate_to_disk(spec, tmp_path, progress=False)
    m = json.loads((tmp_path / "frames" / "manifest.json").read_text())
    assert m["frames_complete"] == 3 and m["seed"] == 1 and m["fraytool_version"]
    assert len(m["scene_hash"]) == 16
