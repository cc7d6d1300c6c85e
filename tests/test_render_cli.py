"""`fraytool render` end to end: simulate, render, write MP4 and PNGs, resume, clear errors."""
from __future__ import annotations

import json

import os
import subprocess
import sys
from pathlib import Path

import pytest

from fraytool.commands.main import main
from test_render_encode import probe

SCENE = Path(__file__).resolve().parent / "scenes" / "golden_small.toml"   # 4 frames at 24 fps


def fraytool(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "fraytool", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, stdin=subprocess.DEVNULL, timeout=300)


def test_render_writes_mp4_and_pngs_then_resumes(tmp_path):
    out = tmp_path / "out"
    r = fraytool("render", SCENE, "-o", out, "--png", "--resolution", "64x48", "-v")
    assert r.returncode == 0, r.stderr
    assert "GL_RENDERER" in r.stderr and "GL_VERSION" in r.stderr
    assert "\r" not in r.stderr                                  # no progress bar off a terminal
    mp4 = out / "golden_small.mp4"
    assert probe(mp4) == {"codec": "h264", "pix_fmt": "yuv420p", "size": (64, 48), "fps": 24.0, "frames": 4}
    pngs = sorted((out / "png").glob("frame_*.png"))
    assert [p.name for p in pngs] == [f"frame_{k:06d}.png" for k in range(4)]
    assert (out / "frames" / "manifest.json").is_file()

    # Resume: frames are reused (no simulation), complete PNGs are kept, the MP4 is rebuilt.
    os.remove(pngs[2])
    before = {p.name: p.stat().st_mtime_ns for p in pngs if p.exists()}
    r = fraytool("render", SCENE, "-o", out, "--png", "--resolution", "64x48")
    assert r.returncode == 0, r.stderr
    assert "simulating" not in r.stderr
    assert "1 rendered, 3 kept" in r.stderr
    assert {p: (out / "png" / p).stat().st_mtime_ns for p in before} == before
    assert probe(mp4)["frames"] == 4

    # Other settings make other pixels: nothing is kept.
    r = fraytool("render", SCENE, "-o", out, "--png", "--resolution", "64x48", "--fov", "50")
    assert r.returncode == 0, r.stderr
    assert "4 rendered, 0 kept" in r.stderr


def test_frame_range_names_the_mp4_and_continues_a_shorter_simulation(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["render", str(SCENE), "-o", str(out), "--frames", "0:2", "--resolution", "32x24"]) == 0
    assert "simulating 2 frames" in capsys.readouterr().err
    assert probe(out / "golden_small_000000-000002.mp4")["frames"] == 2
    assert main(["render", str(SCENE), "-o", str(out), "--frames", "1:4:2", "--resolution", "32x24"]) == 0
    assert "continuing the simulation" in capsys.readouterr().err
    p = probe(out / "golden_small_000001-000004_step2.mp4")
    assert p["frames"] == 2 and p["size"] == (32, 24)
    assert main(["render", str(SCENE), "-o", str(out), "--no-mp4", "--png", "--wireframe", "only",
                 "--resolution", "33x25"]) == 0                  # odd sizes are fine without an MP4
    assert len(list((out / "png_wireframe").glob("*.png"))) == 4
    assert main(["render", str(SCENE), "-o", str(out), "--no-mp4", "--png", "--frames", "0:1",
                 "--set", "render.resolution=[33,25]"]) == 0   # and so is an odd size from the scene


def test_passes_never_overwrite_each_other(tmp_path):
    """The beauty pass, the wireframe and the wireframe beside, whole and ranged, into one folder:
    every file keeps its own name (docs/rendering.md lists them)."""
    out = tmp_path / "out"
    common = ["-o", str(out), "--png", "--resolution", "32x24"]
    for extra in ([], ["--wireframe", "only"], ["--wireframe", "beside"], ["--frames", "0:2"],
                  ["--wireframe", "beside", "--frames", "0:2"]):
        assert main(["render", str(SCENE), *common, *extra]) == 0
    names = sorted(p.name for p in out.iterdir() if p.suffix == ".mp4")
    assert names == ["golden_small.mp4", "golden_small_000000-000002.mp4", "golden_small_beside.mp4",
                     "golden_small_beside_000000-000002.mp4", "golden_small_wireframe.mp4"]
    beauty = {p.name: p.read_bytes() for p in (out / "png").iterdir()}
    assert len(beauty) == 4
    from PIL import Image

    assert Image.open(out / "png" / "frame_000000.png").size == (32, 24)
    assert Image.open(out / "png_beside" / "frame_000000.png").size == (64, 24)  # two panels of 32x24
    for d in ("png_wireframe", "png_beside"):
        assert sorted(p.name for p in (out / d).iterdir()) == sorted(beauty)
        assert all((out / d / n).read_bytes() != b for n, b in beauty.items())  # other pixels, other files


@pytest.mark.parametrize("flags,needle", [
    (["--resolution", "64x"], "--resolution '64x': expected WIDTHxHEIGHT"),
    (["--resolution", "65x48"], "even width and height"),
    (["--frames", "3:1"], "--frames '3:1': expected START:END[:STEP]"),
    (["--samples", "-2"], "--samples -2"),
    (["--camera-target", "a,b,c"], "--camera-target 'a,b,c'"),
    (["--no-mp4"], "nothing to write"),
    (["--set", "render.resolution=[33,25]"], "[render] resolution = [33, 25]: the MP4 (H.264, yuv420p) needs"),
    (["--codec", "prores", "--no-mp4"], "--codec prores chooses the video codec, but no video is written"),
    (["--exr", "--depth", "16"], "no PNGs are written: add --png\n"),
])
def test_bad_flags_exit_2_with_a_clear_message(tmp_path, capsys, flags, needle):
    assert main(["render", str(SCENE), "-o", str(tmp_path), *flags]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err
    assert not (tmp_path / "frames").exists()                    # nothing simulated


def test_bad_resolution_exits_2_from_the_command_line(tmp_path):
    r = fraytool("render", SCENE, "-o", tmp_path, "--resolution", "big")
    assert r.returncode == 2
    assert "--resolution 'big'" in r.stderr and "Traceback" not in r.stderr


def test_no_gl_context_exits_1_before_simulating(tmp_path, capsys, monkeypatch):
    from fraytool.render import context

    def fail(**kwargs):
        raise Exception("eglInitialize failed")

    monkeypatch.setattr(context.moderngl, "create_context", fail)
    assert main(["render", str(SCENE), "-o", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "libegl1" in err and "libgl1-mesa-dri" in err and "Traceback" not in err
    assert not (tmp_path / "frames").exists()


def test_bench_render_stage_timings(tmp_path):
    from fraytool.commands.render_bench import render_stage_timings
    from fraytool.scene import load_scene

    parts = {}
    t = render_stage_timings(load_scene(SCENE), tmp_path, frames=3, resolution=(64, 48), samples=4, parts=parts)
    assert set(t) == {"geometry", "draw", "readback", "encode"}
    assert all(v > 0 for v in t.values())
    assert (tmp_path / "frames" / "frame_000002.npz").is_file()     # simulated where asked
    assert {"yarns", "resolve", "other"} <= set(parts) and all(v > 0 for k, v in parts.items() if k != "other")


def test_bench_render_uses_the_scene_resolution(capsys):
    """`bench --render` draws at the scene's [render] resolution and samples, so --set changes them."""
    from fraytool.commands.main import main

    assert main(["bench", str(SCENE), "--frames", "2", "--render", "--json",
                 "--set", "render.resolution=[96,64]", "--set", "render.samples=2"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["render_resolution"] == [96, 64] and out["render_samples"] == 2
    assert "yarns" in out["render_draw_parts_ms_per_frame"]


def test_terminated_render_leaves_no_partial_mp4_and_resumes(tmp_path):
    import signal
    import time

    from fraytool.render.encode import png_settings

    scene = tmp_path / "long.toml"
    scene.write_text(SCENE.read_text().replace("frames = 4", "frames = 60"))
    out = tmp_path / "out"
    assert fraytool("simulate", scene, "-o", out).returncode == 0
    p = subprocess.Popen([sys.executable, "-m", "fraytool", "render", str(scene), "-o", str(out), "--png",
                          "--resolution", "320x240"], stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True)
    deadline = time.monotonic() + 120
    while len(list((out / "png").glob("frame_*.png"))) < 3 and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    p.send_signal(signal.SIGTERM)
    err = p.communicate(timeout=120)[1]
    assert p.returncode == 128 + signal.SIGTERM, err
    assert sorted(f.name for f in out.iterdir()) == ["frames", "png"]           # no MP4, no partial
    kept = sorted((out / "png").glob("*"))
    assert 3 <= len(kept) < 60 and all(png_settings(f) is not None for f in kept)   # only complete PNGs
    r = fraytool("render", scene, "-o", out, "--png", "--resolution", "320x240")
    assert r.returncode == 0, r.stderr
    assert f"{60 - len(kept)} rendered, {len(kept)} kept" in r.stderr
    assert probe(out / "golden_small.mp4")["frames"] == 60


def _processes_mentioning(text: str) -> list[int]:
    """Pids of live processes whose command line contains `text` (Linux /proc)."""
    found = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                if text.encode() in (d / "cmdline").read_bytes():
                    found.append(int(d.name))
            except OSError:
                pass
    return found


def test_killed_render_takes_its_ffmpeg_along_and_the_partial_is_swept(tmp_path):
    """kill -9 of fraytool while it encodes: its ffmpeg child dies with it (no orphan finishing a
    hidden partial MP4), and the next render sweeps the partial and writes the whole MP4."""
    import time

    scene = tmp_path / "long.toml"
    scene.write_text(SCENE.read_text().replace("frames = 4", "frames = 60"))
    out = tmp_path / "out"
    assert fraytool("simulate", scene, "-o", out).returncode == 0
    p = subprocess.Popen([sys.executable, "-m", "fraytool", "render", str(scene), "-o", str(out), "--png",
                          "--resolution", "320x240"], stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while len(list((out / "png").glob("frame_*.png"))) < 3 and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    partials = list(out.glob(".golden_small.partial-*.mp4"))
    assert partials and _processes_mentioning(str(partials[0])), "ffmpeg was not encoding"
    p.kill()
    p.wait()
    deadline = time.monotonic() + 10
    while _processes_mentioning(str(partials[0])) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _processes_mentioning(str(partials[0])), "ffmpeg outlived fraytool"
    # killed with fraytool, not left to finish: a partial that is there has no index (moov) at its front
    assert not partials[0].exists() or b"moov" not in partials[0].read_bytes()[: 1 << 16]
    r = fraytool("render", scene, "-o", out, "--png", "--resolution", "320x240")
    assert r.returncode == 0, r.stderr
    assert not list(out.glob(".*partial*")) and probe(out / "golden_small.mp4")["frames"] == 60


def _no_stepping(monkeypatch):
    """Any simulation step from here on fails the test: a render-only change must simulate nothing."""
    from fraytool.sim.simulation import Simulation

    def refuse(self):
        raise AssertionError("a simulation step ran for a change of the picture only")

    monkeypatch.setattr(Simulation, "step", refuse)


def test_look_dev_reuses_the_simulated_frames_for_a_shot_folder_and_a_scene(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["render", str(SCENE), "--no-mp4", "--png", "--resolution", "32x24"]) == 0  # outputs/golden_small
    shot = tmp_path / "outputs" / "golden_small"
    assert "simulating 4 frames" in capsys.readouterr().err
    _no_stepping(monkeypatch)
    # the shot's folder drawn elsewhere: its frames are read where they are, the new folder holds only pictures
    assert main(["render", str(shot), "-o", "lookdev_a", "--no-mp4", "--png", "--resolution", "48x32",
                 "--samples", "0", "--fov", "30", "--motion-blur", "0.5"]) == 0
    err = capsys.readouterr().err
    assert f"reusing the frames simulated in {Path('outputs/golden_small/frames')}" in err or "reusing" in err, err
    assert "simulating" not in err
    assert len(list((tmp_path / "lookdev_a" / "png").glob("frame_*.png"))) == 4
    assert not (tmp_path / "lookdev_a" / "frames").exists()
    # the scene file with settings that change only the picture, into another folder
    assert main(["render", str(SCENE), "-o", "lookdev_b", "--no-mp4", "--exr", "--camera-position", "0.3,0.4,0.5",
                 "--set", "render.background=[0.2, 0.2, 0.3]", "--set", "cloth.warp_color=[0.9, 0.1, 0.1]"]) == 0
    err = capsys.readouterr().err
    assert "reusing the frames simulated in" in err and "simulating" not in err, err
    assert len(list((tmp_path / "lookdev_b" / "exr").glob("*.exr"))) == 4


def test_a_change_of_the_simulation_simulates_again_and_names_the_key(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["render", str(SCENE), "--no-mp4", "--png", "--frames", "0:2", "--resolution", "32x24"]) == 0
    capsys.readouterr()
    assert main(["render", str(SCENE), "-o", "other", "--no-mp4", "--png", "--frames", "0:2", "--resolution", "32x24",
                 "--set", "world.gravity_m_s2=[0.0, -8.5, 0.0]"]) == 0
    err = capsys.readouterr().err
    assert "simulating 2 frames" in err
    assert "world.gravity_m_s2: [0.0, -9.81, 0.0] -> [0.0, -8.5, 0.0]" in err, err
    assert (tmp_path / "other" / "frames" / "manifest.json").is_file()


def test_a_scene_with_files_names_only_the_keys_that_changed(tmp_path, monkeypatch, capsys):
    """mannequin_snag names its mesh relative to its scene file: the frames' saved scene has no file of its own,
    and its mesh must still be read from the scene's folder, not named as a changed key."""
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "mannequin_snag", "--frames", "2", "--progress", "none"]) == 0
    capsys.readouterr()
    assert main(["render", "mannequin_snag", "-o", "other", "--frames", "0:2", "--png", "--no-mp4", "--resolution",
                 "64x36", "--set", "world.gravity_m_s2=[0.0, -8.0, 0.0]", "--progress", "none"]) == 0
    err = capsys.readouterr().err
    assert "world.gravity_m_s2: [0.0, -9.81, 0.0] -> [0.0, -8.0, 0.0]" in err and "bodies.0.file" not in err, err
