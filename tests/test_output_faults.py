"""Outputs that survive faults: damaged frame stores are found (`check --outputs`) and repaired by
re-simulating (`--resume`, `render`); I/O failures exit 1 with one line naming the path, the cause and
what to do; one writer per output folder (a lock by pid and host); temp files of dead writers are
swept. Full disk and read-only folders use a small tmpfs where the test may mount one, and a fault
injected at the writer everywhere."""
import contextlib
import errno
import json
import os
import socket
import subprocess
import sys
import threading
import time
import uuid

import numpy as np
import pytest

from fraytool.commands.main import main
from fraytool.io import frame_record
from fraytool.io.frame_record import STALE_TEMP_S, _writer_tag
from fraytool.io.frame_store import FrameStore
from fraytool.io.lock import LOCK_NAME, STALE_AFTER_S
from helpers import assert_arrays_equal, small_scene_text

FRAMES = 6


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """A scene file and an intact, uninterrupted run of it."""
    root = tmp_path_factory.mktemp("reference")
    scene = root / "scene.toml"
    scene.write_text(small_scene_text(frames=FRAMES))
    assert main(["simulate", str(scene), "-o", str(root / "out")]) == 0
    return scene, root / "out"


def _copy(src, dst):
    import shutil

    shutil.copytree(src, dst)
    return dst


def _arrays(path):
    with np.load(path) as d:
        return {k: d[k] for k in d.files}


def _assert_same_store(a, b):
    for k in range(FRAMES):
        assert_arrays_equal(_arrays(FrameStore(a).frame_path(k)), _arrays(FrameStore(b).frame_path(k)))
    assert FrameStore(b).frames_complete() == FRAMES


def _truncate(path):
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def _flip_byte(path):
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))


def _foreign(path, tmp_path):
    other = tmp_path / "other.toml"
    other.write_text(small_scene_text(frames=FRAMES, seed=2, bend=0.7))
    assert main(["simulate", str(other), "-o", str(tmp_path / "other")]) == 0
    path.write_bytes((tmp_path / "other" / "frames" / path.name).read_bytes())


DAMAGE = {
    "truncated frame": (lambda out, tmp: _truncate(out / "frames" / "frame_000003.npz"), "frame_000003.npz: truncated"),
    "missing frame": (lambda out, tmp: (out / "frames" / "frame_000003.npz").unlink(), "frame_000003.npz: missing"),
    "corrupted frame": (lambda out, tmp: _flip_byte(out / "frames" / "frame_000002.npz"), "frame_000002.npz"),
    "foreign frame": (lambda out, tmp: _foreign(out / "frames" / "frame_000004.npz", tmp),
                      "frame_000004.npz: from another scene"),
    "garbage manifest": (lambda out, tmp: (out / "frames" / "manifest.json").write_text("{garbage"),
                         "manifest.json: unreadable"),
    "edited manifest": (lambda out, tmp: (out / "frames" / "manifest.json").write_text(
        (out / "frames" / "manifest.json").read_text().replace('"frames_complete": 6', '"frames_complete": 60')),
                        "manifest.json: checksum mismatch"),
    "corrupted checkpoint": (lambda out, tmp: _flip_byte(out / "frames" / "checkpoint.npz"), "checkpoint.npz"),
    "truncated topology": (lambda out, tmp: _truncate(out / "frames" / "topology.npz"), "topology.npz: truncated"),
}


@pytest.mark.parametrize("case", sorted(DAMAGE))
def test_damage_is_named_then_repaired_by_resume(case, reference, tmp_path, capsys):
    scene, good = reference
    out = _copy(good, tmp_path / "out")
    damage, named = DAMAGE[case]
    damage(out, tmp_path)
    capsys.readouterr()
    assert main(["check", "--outputs", str(out), str(scene)]) == 1
    err = capsys.readouterr().err
    assert named in err, err
    assert main(["simulate", str(scene), "-o", str(out), "--resume"]) == 0
    err = capsys.readouterr().err
    assert named in err, err  # the repair says what it found
    assert "Traceback" not in err
    _assert_same_store(good, out)
    assert main(["check", "--outputs", str(out), str(scene)]) == 0


def test_check_outputs_names_every_missing_frame_and_refuses_a_folder_with_no_shot(reference, tmp_path, capsys):
    """Frames 1 and 3-4 deleted: the first gap is named by its file, the rest by their numbers (a count and a
    range said nothing of which). A folder with no frames, images or video is not a shot: exit 2, not a
    "damaged" topology."""
    scene, good = reference
    out = _copy(good, tmp_path / "out")
    for k in (1, 3, 4):
        (out / "frames" / f"frame_{k:06d}.npz").unlink()
    capsys.readouterr()
    assert main(["check", "--outputs", str(out), str(scene)]) == 1
    err = capsys.readouterr().err
    assert "frame_000001.npz: missing" in err and f"2 more frame file(s) between 2 and {FRAMES - 1} missing: 3-4" in err
    (tmp_path / "empty" / "notes").mkdir(parents=True)
    assert main(["check", "--outputs", str(tmp_path / "empty")]) == 2
    err = capsys.readouterr().err
    assert "not a shot's output folder" in err and "damaged" not in err, err


def test_intact_outputs_check_clean_and_json(reference, capsys):
    scene, good = reference
    capsys.readouterr()
    assert main(["check", "--outputs", str(good), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["intact"] and report["frames_verified"] == FRAMES and report["checkpoint_frame"] == FRAMES - 1


def test_resume_with_a_garbage_manifest_keeps_every_frame(reference, tmp_path, capsys):
    """The old behaviour deleted every frame; now the frames that verify are kept, untouched."""
    scene, good = reference
    out = _copy(good, tmp_path / "out")
    (out / "frames" / "manifest.json").write_text("not json at all")
    stamps = {k: os.stat(FrameStore(out).frame_path(k)).st_mtime_ns for k in range(FRAMES)}
    assert main(["simulate", str(scene), "-o", str(out), "--resume"]) == 0
    assert {k: os.stat(FrameStore(out).frame_path(k)).st_mtime_ns for k in range(FRAMES)} == stamps
    _assert_same_store(good, out)


def test_render_over_a_damaged_store_repairs_it(reference, tmp_path):
    scene, good = reference
    out = _copy(good, tmp_path / "out")
    _truncate(out / "frames" / "frame_000004.npz")
    r = subprocess.run([sys.executable, "-m", "fraytool", "render", str(scene), "-o", str(out), "--png", "--no-mp4",
                        "--resolution", "64x48", "--frames", "3:6"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "frame_000004.npz: truncated" in r.stderr and "Traceback" not in r.stderr
    _assert_same_store(good, out)
    assert len(list((out / "png").glob("*.png"))) == 3


def test_stale_temp_files_are_swept(reference, tmp_path, capsys):
    """Temp files of dead writers go (this host: the pid is gone; another host: an hour old); a live
    writer's, and another host's fresh one, stay."""
    scene, good = reference
    out = _copy(good, tmp_path / "out")
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    host = _writer_tag().rpartition("-")[0]
    stale = out / "frames" / f".frame_000003.npz.{host}-{dead.pid}.k2j3h4.tmp"
    live = out / "frames" / f".frame_000004.npz.{host}-{os.getppid()}.a8d7f6.tmp"
    remote_fresh = out / "frames" / ".frame_000005.npz.othernode-12.b8c7e6.tmp"
    remote_old = out / "frames" / ".checkpoint.npz.othernode-13.c8c7e6.tmp"
    for p in (stale, live, remote_fresh, remote_old):
        p.write_bytes(b"half a frame")
    old = time.time() - STALE_TEMP_S - 5
    os.utime(remote_old, (old, old))
    capsys.readouterr()
    assert main(["check", "--outputs", str(out)]) == 1
    assert "temp file of a killed write" in capsys.readouterr().err
    assert main(["simulate", str(scene), "-o", str(out), "--resume"]) == 0
    assert not stale.exists() and not remote_old.exists()
    assert live.exists() and remote_fresh.exists()


# -- one writer per folder -------------------------------------------------------------------------

def _write_lock(out, **holder):
    out.mkdir(parents=True, exist_ok=True)
    (out / LOCK_NAME).write_text(json.dumps({"command": "simulate", "started": "then", **holder}))


def test_a_second_writer_is_refused_while_the_first_lives(reference, tmp_path, capsys):
    scene, _ = reference
    out = tmp_path / "out"
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        _write_lock(out, pid=sleeper.pid, host=socket.gethostname())
        assert main(["simulate", str(scene), "-o", str(out)]) == 1
        err = capsys.readouterr().err
        assert "in use by another fraytool run" in err and f"pid {sleeper.pid}" in err and str(out) in err
        assert not (out / "frames").exists()
    finally:
        sleeper.kill()
        sleeper.wait()
    # the holder is dead now: its lock is stale and taken over
    assert main(["simulate", str(scene), "-o", str(out)]) == 0
    assert FrameStore(out).frames_complete() == FRAMES and not (out / LOCK_NAME).exists()


def test_a_second_render_waits_for_the_first(reference, tmp_path):
    """Farm shards on one folder: the second render waits while the first simulates, then reuses
    its frames."""
    scene, good = reference
    out = tmp_path / "out"
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(2)"])
    reaper = threading.Thread(target=sleeper.wait)  # a zombie would count as alive
    reaper.start()
    _write_lock(out, pid=sleeper.pid, host=socket.gethostname())
    r = subprocess.run([sys.executable, "-m", "fraytool", "render", str(scene), "-o", str(out), "--png", "--no-mp4",
                        "--resolution", "64x48", "--frames", "0:2"], capture_output=True, text=True, timeout=120)
    reaper.join()
    assert r.returncode == 0, r.stderr
    assert f"waiting for {out}" in r.stderr and f"pid {sleeper.pid}" in r.stderr
    assert len(list((out / "png").glob("*.png"))) == 2


def test_a_lock_from_another_host_counts_while_it_is_fresh(reference, tmp_path, capsys):
    scene, _ = reference
    out = tmp_path / "out"
    _write_lock(out, pid=1, host="farm-node-that-is-not-here")
    assert main(["simulate", str(scene), "-o", str(out)]) == 1
    assert "farm-node-that-is-not-here" in capsys.readouterr().err
    old = time.time() - STALE_AFTER_S - 5
    os.utime(out / LOCK_NAME, (old, old))
    assert main(["simulate", str(scene), "-o", str(out)]) == 0


def test_two_runs_started_together_never_mix_frames(reference, tmp_path):
    """Two processes into one fresh folder: one simulates, the other exits 1 naming the holder (or
    runs after it), and the folder ends intact."""
    scene, good = reference
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "fraytool", "simulate", str(scene), "-o", str(out)]
    procs = [subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    results = [(p.wait(), p.stderr.read()) for p in procs]
    codes = sorted(c for c, _ in results)
    assert codes in ([0, 0], [0, 1]), results
    for code, err in results:
        assert "Traceback" not in err
        if code == 1:
            assert "in use by another fraytool run" in err
    _assert_same_store(good, out)


# -- I/O failures ----------------------------------------------------------------------------------

def _fail_writes_after(monkeypatch, n_ok: int, err: int):
    real = frame_record.atomic_write_bytes
    count = {"n": 0}

    def failing(path, writer):
        count["n"] += 1
        if count["n"] > n_ok:
            raise OSError(err, os.strerror(err), str(path))
        real(path, writer)

    monkeypatch.setattr(frame_record, "atomic_write_bytes", failing)


def _one_failure_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.startswith("fraytool:")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.mark.parametrize("code,cause,advice", [(errno.ENOSPC, "No space left on device", "--resume"),
                                               (errno.EROFS, "Read-only file system", "another output folder"),
                                               (errno.EACCES, "Permission denied", "writable")])
def test_injected_write_failure_exits_1_and_keeps_what_was_written(code, cause, advice, reference, tmp_path,
                                                                   monkeypatch, capsys):
    scene, good = reference
    out = tmp_path / "out"
    _fail_writes_after(monkeypatch, 5, code)  # .npz writes: topology, then record + checkpoint of frames 0, 1
    assert main(["simulate", str(scene), "-o", str(out)]) == 1
    line = _one_failure_line(capsys.readouterr().err)
    assert line.startswith("fraytool: run failed: ") and str(out / "frames") in line and cause in line and advice in line
    monkeypatch.undo()
    survey = FrameStore(out).survey()
    assert survey.clean and survey.good_frames == 2  # the frames counted are intact
    assert main(["simulate", str(scene), "-o", str(out), "--resume"]) == 0
    _assert_same_store(good, out)


def test_output_folder_that_is_a_file(reference, tmp_path, capsys):
    scene, _ = reference
    target = tmp_path / "a_file"
    target.write_text("keep me")
    assert main(["simulate", str(scene), "-o", str(target)]) == 1
    line = _one_failure_line(capsys.readouterr().err)
    assert str(target) in line and "in the way" in line
    assert target.read_text() == "keep me"


@contextlib.contextmanager
def _tmpfs(path, size: str, read_only: bool = False):
    """Mount a small tmpfs at `path`; yields False where mounting is not allowed (not root, no
    CAP_SYS_ADMIN), and the tests then rely on the injected faults above."""
    path.mkdir(parents=True, exist_ok=True)
    opts = f"size={size}" + (",ro" if read_only else "")
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", opts, f"fraytool-test-{uuid.uuid4().hex[:8]}", str(path)],
                       capture_output=True)
    if r.returncode != 0:
        yield False
        return
    try:
        yield True
    finally:
        subprocess.run(["umount", "-l", str(path)], capture_output=True)


def test_full_disk_on_a_real_small_tmpfs(reference, tmp_path, capsys):
    scene, good = reference
    mnt = tmp_path / "small"
    with _tmpfs(mnt, "160k") as mounted:
        if not mounted:
            pytest.skip("cannot mount a tmpfs here; test_injected_write_failure_exits_1... covers ENOSPC")
        out = mnt / "out"
        assert main(["simulate", str(scene), "-o", str(out)]) == 1
        line = _one_failure_line(capsys.readouterr().err)
        assert "No space left on device" in line and "--resume" in line
        survey = FrameStore(out).survey()
        assert survey.clean, survey.problems  # what the manifest counts is intact
        assert not [p for p in (out / "frames").iterdir() if p.name.endswith(".tmp")]


def test_read_only_folder_on_a_real_read_only_mount(reference, tmp_path, capsys):
    scene, _ = reference
    mnt = tmp_path / "ro"
    with _tmpfs(mnt, "1m", read_only=True) as mounted:
        if not mounted:
            pytest.skip("cannot mount a tmpfs here; test_injected_write_failure_exits_1... covers EROFS")
        assert main(["simulate", str(scene), "-o", str(mnt / "out")]) == 1
        line = _one_failure_line(capsys.readouterr().err)
        assert str(mnt / "out") in line and "Read-only file system" in line


def test_full_disk_while_rendering_pngs_exits_1_naming_the_png(reference, tmp_path, monkeypatch, capsys):
    """Fault injected at the PNG writer (tmpfs or not): exit 1, the PNG's path in the line, the PNGs
    written before it kept and verified, no temp file left; running again finishes the job."""
    from fraytool.render import encode

    scene, good = reference
    out = _copy(good, tmp_path / "out")
    real = encode.atomic_write_bytes
    written = []

    def failing(path, writer):
        if len(written) == 3:
            def short_write(f):  # the disk fills up in the middle of the PNG
                f.write(b"\x89PNG")
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            return real(path, short_write)
        written.append(path)
        return real(path, writer)

    monkeypatch.setattr(encode, "atomic_write_bytes", failing)
    argv = ["render", str(scene), "-o", str(out), "--png", "--resolution", "64x48"]
    assert main(argv) == 1
    line = _one_failure_line(capsys.readouterr().err)
    assert str(out / "png" / "frame_000003.png") in line and "No space left on device" in line and "again" in line
    assert sorted(p.name for p in (out / "png").iterdir()) == [f"frame_00000{k}.png" for k in range(3)]
    assert not list(out.glob(".*partial*")) and not (out / "small.mp4").exists()
    monkeypatch.undo()
    assert main(argv) == 0
    assert "3 rendered, 3 kept" in capsys.readouterr().err


def _recomputed_manifest(out, **fields):
    """A hostile edit: the manifest's fields changed and its checksum recomputed."""
    from fraytool.io.frame_store import _manifest_checksum

    path = out / "frames" / "manifest.json"
    data = json.loads(path.read_text())
    data.update(fields)
    data["checksum"] = _manifest_checksum(data)
    path.write_text(json.dumps(data))


@pytest.mark.parametrize("fields", [{"frames_complete": "abc"}, {"frames_complete": None}, {"frames_complete": -3},
                                    {"frames_complete": 10**9}, {"scene_hash": 7}])
def test_a_manifest_with_nonsense_fields_is_damaged_not_a_traceback(fields, reference, tmp_path, capsys):
    scene, good = reference
    out = _copy(good, tmp_path / "out")
    _recomputed_manifest(out, **fields)
    capsys.readouterr()
    assert main(["check", "--outputs", str(out)]) == 1
    assert "manifest.json: fields out of range" in capsys.readouterr().err
    assert main(["simulate", str(scene), "-o", str(out), "--resume"]) == 0
    _assert_same_store(good, out)


def test_a_stray_far_frame_does_not_make_a_million_frames(reference, tmp_path, capsys):
    scene, good = reference
    out = _copy(good, tmp_path / "out")
    (out / "frames" / "manifest.json").unlink()
    (out / "frames" / "frame_999999.npz").write_bytes(b"stray")
    t = time.monotonic()
    assert main(["check", "--outputs", str(out)]) == 1
    err = capsys.readouterr().err
    assert time.monotonic() - t < 10 and len(err.splitlines()) < 10, err[:2000]


def test_a_frames_folder_that_lost_its_manifest_is_still_ours(reference, tmp_path, capsys):
    """After a full disk took the manifest: a fresh run may clear fraytool's own checksummed files."""
    scene, good = reference
    out = _copy(good, tmp_path / "out")
    (out / "frames" / "manifest.json").unlink()
    assert main(["simulate", str(scene), "-o", str(out)]) == 0
    _assert_same_store(good, out)


def test_someone_elses_manifest_does_not_make_a_folder_ours(reference, tmp_path, capsys):
    scene, _ = reference
    out = tmp_path / "out"
    (out / "frames").mkdir(parents=True)
    (out / "frames" / "manifest.json").write_text('{"my": "data"}')
    (out / "frames" / "checkpoint.npz").write_text("precious")
    (out / "frames" / ".user-notes.tmp").write_text("mine")
    assert main(["simulate", str(scene), "-o", str(out)]) == 1
    assert "did not write" in capsys.readouterr().err
    assert (out / "frames" / "manifest.json").read_text() == '{"my": "data"}'
    assert (out / "frames" / "checkpoint.npz").read_text() == "precious"
    assert (out / "frames" / ".user-notes.tmp").read_text() == "mine"


def test_json_outputs_are_strict_json(tmp_path, capsys):
    def strict(text):
        return json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} in JSON output"))

    scene = tmp_path / "held.toml"
    scene.write_text(small_scene_text() + '\n[[bodies]]\nname = "hook"\nshape = "sphere"\nradius_m = 0.001\n'
                     'position_m = [0.0, 2.0, 0.0]\n\n[[attachments]]\nbody = "hook"\nregion_center_m = [0.0, 0.1, 0.0]\n'
                     "region_radius_m = 1.0\n")
    assert main(["check", str(scene), "--json"]) == 0
    info = strict(capsys.readouterr().out)
    assert info["stability_bound_s"] == "inf"  # every mass is held: nothing can oscillate
    assert main(["simulate", str(scene), "-o", str(tmp_path / "o"), "--json"]) == 0
    strict(capsys.readouterr().out)


def test_a_huge_flag_value_is_not_echoed_whole(reference, tmp_path, capsys):
    scene, _ = reference
    for argv in (["render", str(scene), "--camera-position", "1," * 3000], ["simulate", str(scene), "--frames", "9" * 5000],
                 ["render", str(scene), "--frames", "0:" + "9" * 5000],
                 ["render", str(scene), "--resolution", "9" * 5000 + "x2"]):
        with contextlib.suppress(SystemExit):
            assert main(argv) == 2
        err = capsys.readouterr().err
        assert err and max(len(line) for line in err.splitlines()) < 1100, argv[2]


def test_a_failed_atomic_write_names_the_file_not_its_temp(reference, tmp_path, capsys):
    scene, _ = reference
    out = tmp_path / "out"
    assert main(["simulate", str(scene), "-o", str(out), "--frames", "3"]) == 0
    (out / "frames" / "frame_000003.npz").mkdir()  # a folder where the next frame goes
    (out / "frames" / "frame_000003.npz" / "x").write_text("keep")
    assert main(["simulate", str(scene), "-o", str(out), "--resume"]) == 1
    line = _one_failure_line(capsys.readouterr().err)
    assert f"{out / 'frames' / 'frame_000003.npz'}:" in line and ".tmp" not in line, line
    assert (out / "frames" / "frame_000003.npz" / "x").read_text() == "keep"


def test_check_outputs_names_a_partial_mp4_of_a_killed_render(reference, tmp_path, capsys):
    _, good = reference
    out = _copy(good, tmp_path / "out")
    (out / ".small.partial-otherhost-99.mp4").write_bytes(b"half")
    assert main(["check", "--outputs", str(out)]) == 1
    assert "partial MP4 of a killed render" in capsys.readouterr().err


def test_a_fresh_run_that_fills_the_disk_gives_the_previous_frames_back(reference, tmp_path, monkeypatch, capsys):
    """Scene A's frames are in the folder; scene B's fresh run fails on a full disk: A's frames are
    back in place, intact, and nothing of B's is left."""
    scene, good = reference
    out = _copy(good, tmp_path / "out")
    other = tmp_path / "other.toml"
    other.write_text(small_scene_text(frames=FRAMES, seed=5))
    _fail_writes_after(monkeypatch, 3, errno.ENOSPC)
    assert main(["simulate", str(other), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert "the previous frames are back in place" in err and "No space left on device" in err
    monkeypatch.undo()
    assert not (out / "frames.previous").exists()
    assert main(["check", "--outputs", str(out), str(scene)]) == 0
    _assert_same_store(good, out)
    # and a fresh run that completes leaves no frames.previous behind
    assert main(["simulate", str(other), "-o", str(out)]) == 0
    assert not (out / "frames.previous").exists() and FrameStore(out).frames_complete() == FRAMES


def test_resume_over_another_scenes_frames_exits_1_saying_why(reference, tmp_path, capsys):
    scene, good = reference
    out = _copy(good, tmp_path / "out")
    other = tmp_path / "other.toml"
    other.write_text(small_scene_text(frames=FRAMES, seed=9))
    assert main(["simulate", str(other), "-o", str(out), "--resume"]) == 1
    line = _one_failure_line(capsys.readouterr().err)
    assert "different scene" in line and "cannot be continued" in line and "without --resume" in line
    _assert_same_store(good, out)  # nothing was touched


def test_check_outputs_names_damaged_passes_exrs_and_videos(reference, tmp_path, capsys):
    """Every pass folder (png/, png_beside/ ...), the EXRs and the finished videos are checked, not
    only png/: a truncated beside-PNG, EXR or MOV is named (exit 1); intact ones pass (exit 0)."""
    scene, good = reference
    out = _copy(good, tmp_path / "out")
    assert main(["render", str(scene), "-o", str(out), "--frames", "4:6", "--resolution", "64x48", "--png",
                 "--exr", "--codec", "prores", "--wireframe", "beside", "--progress", "none"]) == 0
    capsys.readouterr()
    assert main(["check", "--outputs", str(out), str(scene)]) == 0
    assert "2 PNGs, 2 EXRs, 1 videos checked: intact" in capsys.readouterr().out
    movie = next(out.glob("*.mov"))
    for path in (out / "png_beside" / "frame_000004.png", out / "exr_beside" / "frame_000005.exr", movie):
        _truncate(path)
    assert main(["check", "--outputs", str(out), str(scene)]) == 1
    err = capsys.readouterr().err
    assert "png_beside/frame_000004.png: damaged PNG" in err
    assert "exr_beside/frame_000005.exr: damaged EXR" in err
    assert f"{movie.name}: damaged video (truncated" in err


def test_check_outputs_on_a_batch_job_folder_checks_it_shot_by_shot(reference, tmp_path, capsys):
    """A batch job folder holds job.json and one folder per shot: `check --outputs` on it checks every
    shot's folder on its own and names the ones with problems (exit 1), or says the job is intact."""
    scene, good = reference
    job = tmp_path / "job"
    job.mkdir()
    (job / "job.json").write_text("{}")
    _copy(good, job / "shot_a")
    _copy(good, job / "shot_b")
    capsys.readouterr()
    assert main(["check", "--outputs", str(job)]) == 0
    assert "2 shot(s) checked: intact" in capsys.readouterr().out
    (job / "shot_b" / "frames" / "frame_000002.npz").write_bytes(b"garbage")
    assert main(["check", "--outputs", str(job), "--json"]) == 1
    report = json.loads(capsys.readouterr().out)
    assert not report["intact"] and [r["intact"] for r in report["shots"]] == [True, False]
    assert any("frame_000002.npz" in line for line in report["shots"][1]["problems"])
    empty = tmp_path / "empty_job"
    (empty / "shot_a").mkdir(parents=True)
    (empty / "job.json").write_text("{}")
    assert main(["check", "--outputs", str(empty)]) == 2
    assert "no shot has frames yet" in capsys.readouterr().err


def test_check_outputs_names_the_frames_a_killed_run_did_not_write(reference, tmp_path, capsys, monkeypatch):
    """A run killed part way (here: at frame 3 of FRAMES) leaves a folder whose every file verifies; it is
    still incomplete: exit 1, naming the missing frames. With the scene, a run of fewer frames than the
    scene asks for (--frames) is incomplete too; without it, that run is what was asked for."""
    from fraytool.io.frame_store import FrameStore
    from fraytool.scene import load_scene
    from fraytool.sim.run import simulate_to_disk

    scene, _ = reference
    out = tmp_path / "killed"
    original = FrameStore.write_frame

    def dying(self, record, state, write_record=True):
        if record.frame == 3:
            raise KeyboardInterrupt
        original(self, record, state, write_record)

    monkeypatch.setattr(FrameStore, "write_frame", dying)
    with pytest.raises(KeyboardInterrupt):
        simulate_to_disk(load_scene(scene), out, progress=False)
    monkeypatch.setattr(FrameStore, "write_frame", original)
    capsys.readouterr()
    assert main(["check", "--outputs", str(out), "--json"]) == 1
    report = json.loads(capsys.readouterr().out)
    assert report["frames_verified"] == 3 and report["frames_planned"] == FRAMES
    assert any(f"frames 3-{FRAMES - 1} of {FRAMES} are missing" in line for line in report["problems"])
    short = tmp_path / "short"
    assert main(["simulate", str(scene), "-o", str(short), "--frames", "3"]) == 0
    assert main(["check", "--outputs", str(short)]) == 0
    assert main(["check", "--outputs", str(short), str(scene)]) == 1
    assert f"frames 3-{FRAMES - 1} of {FRAMES} are missing" in capsys.readouterr().err


def test_check_outputs_names_png_sets_of_two_renders_mixed(reference, tmp_path, capsys):
    """A png/ folder holding 8-bit RGB frames of one render beside 16-bit RGBA frames of another (or
    another size): every file is a good PNG, but the set is not one render's. Exit 1, naming both kinds."""
    import numpy as np
    from PIL import Image

    from fraytool.render.png16 import write_png16

    _, good = reference
    out = _copy(good, tmp_path / "out")
    (out / "png").mkdir()
    for k in range(3):
        Image.fromarray(np.zeros((12, 16, 3), np.uint8)).save(out / "png" / f"frame_{k:06d}.png")
    capsys.readouterr()
    assert main(["check", "--outputs", str(out)]) == 0
    for k in range(3, 5):
        write_png16(out / "png" / f"frame_{k:06d}.png", np.zeros((12, 16, 4), np.uint16))
    assert main(["check", "--outputs", str(out)]) == 1
    err = capsys.readouterr().err
    assert "mixed" in err and "3 of 16x12 8-bit RGB" in err and "2 of 16x12 16-bit RGBA" in err
    assert "render every frame at one setting" in err                   # and what makes it one set again


def test_a_render_that_leaves_two_sets_in_png_says_so(reference, tmp_path, capsys):
    """Rendering a frame range at another size into a folder rendered before leaves PNGs of both sizes: the
    render warns (it wrote only its frames), and rendering every frame at one size makes one set again."""
    scene, good = reference
    out = _copy(good, tmp_path / "out")
    common = [str(scene), "-o", str(out), "--png", "--no-mp4"]
    assert main(["render", *common, "--resolution", "32x24"]) == 0
    capsys.readouterr()
    assert main(["render", *common, "--resolution", "48x32", "--frames", "0:2"]) == 0
    err = capsys.readouterr().err
    assert "warning:" in err and "2 different renders mixed" in err and "2 of 48x32" in err, err
    assert main(["render", *common, "--resolution", "48x32"]) == 0
    assert "mixed" not in capsys.readouterr().err
    assert main(["check", "--outputs", str(out)]) == 0


def test_a_lock_from_another_host_is_stale_only_after_two_minutes_untouched(tmp_path):
    """Another host's run touches its lock every 20 s (LOCK_TOUCH): a lock untouched for 60 s still holds
    (a slow shared file system), one untouched for 130 s is stale (STALE_AFTER_S = 120 s). Catches the
    stale age cut short (a live run on another machine losing its folder)."""
    import json as _json

    from fraytool.io.lock import LOCK_NAME, held_by_live_process

    lock = tmp_path / LOCK_NAME
    lock.write_text(_json.dumps({"pid": 12345, "host": "another-host.example", "command": "simulate",
                                 "started": "2026-12-04T00:00:00"}))
    now = time.time()
    os.utime(lock, (now - 60, now - 60))
    assert held_by_live_process(tmp_path)
    os.utime(lock, (now - 130, now - 130))
    assert not held_by_live_process(tmp_path)
