"""`fraytool batch` on Dask distributed: shots, wedges and job files expand as documented; a real local
cluster of two worker processes, one killed in the middle of the job, finishes with outputs
byte-identical to single-process `fraytool render` runs; a bad shot is reported and the others finish;
a re-run of a finished job does nothing and a half-finished one continues."""
import json
import os
import re
import signal
import threading
import time
from pathlib import Path

import pytest

from fraytool.commands.main import main
from fraytool.errors import InputError
from fraytool.farm.shots import RenderOptions, expand, load_job, parse_wedge
from helpers import small_scene_text


@pytest.fixture
def scene(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(small_scene_text(frames=24))
    return path


@pytest.mark.parametrize("text,key,values", [
    ("scene.seed=1,2,3", "scene.seed", [1, 2, 3]),
    ("scene.seed=1..4", "scene.seed", [1, 2, 3, 4]),
    ("cloth.tearing.break_strain=0.1..0.3:0.1", "cloth.tearing.break_strain", [0.1, 0.2, 0.3]),
    ("cloth.weave=plain,twill", "cloth.weave", ["plain", "twill"]),
    ("world.gravity_m_s2=[0.0, -9.81, 0.0],[0.0, -1.0, 0.0]", "world.gravity_m_s2", [[0.0, -9.81, 0.0], [0.0, -1.0, 0.0]]),
])
def test_wedge_values(text, key, values):
    assert parse_wedge(text) == (key, values)


@pytest.mark.parametrize("text", ["scene.seed", "scene.seed=4..1", "scene.seed=1.5..3", "scene.seed=0..100000"])
def test_bad_wedges_are_input_errors(text):
    with pytest.raises(InputError):
        parse_wedge(text)


def test_wedge_expands_to_named_shots_with_their_values(scene):
    shots = expand(str(scene), [("cloth.tearing.enabled", True)], [parse_wedge("scene.seed=1,2"),
                                                                    parse_wedge("cloth.weave=plain,twill")], RenderOptions())
    assert [s.name for s in shots] == ["small_seed-1_weave-plain", "small_seed-1_weave-twill",
                                       "small_seed-2_weave-plain", "small_seed-2_weave-twill"]
    assert shots[3].label == "seed=2, weave=twill" and shots[3].group == "small" and not shots[3].error
    assert ("cloth.tearing.enabled", True) in shots[0].sets and ("scene.name", shots[0].name) in shots[0].sets


def test_job_file(tmp_path, scene):
    job = tmp_path / "job.toml"
    job.write_text(f"""
[job]
name = "night"
chunk_frames = 5
[render]
resolution = [64, 48]
[[shots]]
scene = "{scene.name}"
wedge = {{ "scene.seed" = [1, 2] }}
render = {{ frames = "0:10" }}
[[shots]]
scene = "{scene.name}"
name = "heavy"
set = {{ "cloth.springs.bend_n_per_m" = 1.0 }}
[[shots]]
scene = "missing_scene_name"
""")
    j = load_job(job)
    assert j.name == "night" and j.chunk_frames == 5
    assert [s.name for s in j.shots] == ["small_seed-1", "small_seed-2", "heavy", "missing_scene_name"]
    assert j.shots[0].render == RenderOptions((64, 48), None, None, "0:10")
    assert j.shots[2].render.frames is None and j.shots[2].render.resolution == (64, 48)
    assert j.shots[3].error and "missing_scene_name" in j.shots[3].error
    job.write_text(job.read_text().replace("chunk_frames = 5", "chunk_frames = 5\nspeed = 2"))
    with pytest.raises(InputError, match=r"\[job\] speed: unknown key; allowed keys: chunk_frames, name"):
        load_job(job)


def _tree(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name not in ("job.json", ".fraytool.lock")}


def test_killed_worker_is_retried_and_outputs_match_single_process_renders(scene, tmp_path):
    from distributed import Client, LocalCluster

    from fraytool.farm.runner import run_job
    from fraytool.farm.shots import Job

    shots = expand(str(scene), [], [parse_wedge("scene.seed=1,2")], RenderOptions(resolution=(64, 48)))
    job = Job("kill", shots, chunk_frames=4)
    out = tmp_path / "farm"
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster, \
            Client(cluster) as client:
        pids = client.run(os.getpid)
        result = {}
        runner = threading.Thread(target=lambda: result.update(run_job(job, out, client, progress="none")))
        runner.start()
        deadline = time.monotonic() + 120
        while not list(out.glob("*/png/*.png")) and time.monotonic() < deadline:
            time.sleep(0.02)
        victim = sorted(pids.values())[0]
        os.kill(victim, signal.SIGKILL)  # a worker dies in the middle of the job
        runner.join(timeout=300)
        assert not runner.is_alive()
        assert victim not in client.run(os.getpid).values()  # the nanny started a new worker
    assert result["status"] == "done", json.dumps(result, indent=1)[:3000]
    for shot, seed in zip(shots, (1, 2)):
        single = tmp_path / "single" / shot.name
        assert main(["render", str(scene), "-o", str(single), "--png", "--resolution", "64x48",
                     "--set", f"scene.seed={seed}", "--set", f"scene.name={shot.name}", "--progress", "none"]) == 0
        farm, alone = _tree(out / shot.name), _tree(single)
        assert sorted(farm) == sorted(alone)
        different = [name for name in farm if farm[name] != alone[name]]
        assert not different, different
    assert (out / "small_contact_sheet.mp4").is_file()
    stills = sorted(p.name for p in out.glob("small_contact_sheet_*.png"))  # first, middle and last frame
    frames = sorted(int(p.stem.rsplit("_", 1)[1]) for p in out.glob("small_contact_sheet_*.png"))
    assert len(stills) == 3 and frames[0] == 0 and frames[-1] == len(list((out / shots[0].name / "png").glob("*.png"))) - 1


def test_bad_shot_is_reported_others_finish_rerun_does_nothing(scene, tmp_path, capsys, monkeypatch):
    bad = tmp_path / "bad.toml"
    bad.write_text(small_scene_text().replace("spacing_m = 0.005", "spacing_m = -1"))
    short = tmp_path / "short.toml"
    short.write_text(small_scene_text(frames=4, name="short"))
    out = tmp_path / "job"
    monkeypatch.chdir(tmp_path)  # relative scene paths reach the workers as absolute ones
    argv = ["batch", scene.name, bad.name, short.name, "-o", str(out), "--workers", "1", "--resolution", "64x48",
            "--frames", "0:6", "--progress", "none"]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.count("bad: invalid") == 1 and "spacing_m = -1" in err and "1 of 3 shot(s) done" in err
    assert "short: invalid" in err and "END <= 4" in err and "dashboard" in err
    data = json.loads((out / "job.json").read_text())
    assert data["status"] == "failed"
    assert data["shots"]["bad"]["status"] == "invalid" and "spacing_m = -1" in data["shots"]["bad"]["error"]
    assert data["shots"]["small"]["scene"] == str(scene)
    good = data["shots"]["small"]
    assert good["status"] == "done" and set(good["tasks"]) == {"simulate", "render 0-6", "join"}
    assert Path(good["outputs"]["video"]).name == "small_000000-000006.mp4"
    stamps = {p: p.stat().st_mtime_ns for p in (out / "small").rglob("*") if p.is_file()}
    assert main(argv) == 1
    assert "small: already done" in capsys.readouterr().err
    assert {p: p.stat().st_mtime_ns for p in (out / "small").rglob("*") if p.is_file()} == stamps
    Path(good["outputs"]["video"]).unlink()  # half-finished: the join runs again, nothing else is redone
    assert main(argv) == 1
    assert Path(good["outputs"]["video"]).is_file()
    again = json.loads((out / "job.json").read_text())["shots"]["small"]["tasks"]
    assert again["render 0-6"]["rendered"] == 0 and again["render 0-6"]["reused"] == 6
    (out / "small" / "png" / "frame_000003.png").unlink()  # a missing PNG: the shot is not done
    assert main(argv) == 1
    assert "small: already done" not in capsys.readouterr().err
    assert json.loads((out / "job.json").read_text())["shots"]["small"]["tasks"]["render 0-6"]["rendered"] == 1
    frame = out / "small" / "frames" / "frame_000005.npz"
    before = frame.read_bytes()
    assert main(argv + ["--set", "cloth.springs.bend_n_per_m=2.0"]) == 1  # other settings: done again
    assert "small: already done" not in capsys.readouterr().err
    assert frame.read_bytes() != before  # simulated afresh with the new settings
    tasks = json.loads((out / "job.json").read_text())["shots"]["small"]["tasks"]
    assert tasks["render 0-6"]["rendered"] == 6 and tasks["join"]["status"] == "done"


@pytest.mark.parametrize("argv,needle", [
    (["batch", "drape", "--scheduler", "bogus://x"], "expected an address like tcp://HOST:8786"),
    (["batch", "drape", "--scheduler", "tcp://127.0.0.1:notaport"], "expected an address like tcp://HOST:8786"),
    (["batch", "drape", "--scheduler", "tcp://127.0.0.1:8786", "--workers", "2"], "--workers starts a local cluster"),
])
def test_bad_batch_flags_exit_2_before_any_cluster(argv, needle, capsys):
    assert main(argv) == 2
    assert needle in capsys.readouterr().err


@pytest.mark.parametrize("text,needle", [
    ("[job]\nname = 7\n[[shots]]\nscene = \"drape\"\n", "[job] name = '7'"),
    ("[job]\nname = \"../../escaped\"\n[[shots]]\nscene = \"drape\"\n", "never a path"),
    ("[[shot]]\nscene = \"drape\"\n", "[[shots]] tables"),
    ("[[shots]]\nscene = \"drape\"\nframes = \"0:4\"\n", "unknown key 'frames'"),
    ("[[shots\nscene = 1", "not valid TOML"),
])
def test_bad_job_files_exit_2(text, needle, tmp_path, capsys):
    job = tmp_path / "job.toml"
    job.write_text(text)
    assert main(["batch", str(job), "-o", str(tmp_path / "out")]) == 2
    assert needle in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_batch_log_reports_frames_per_stage(scene, tmp_path, capsys, monkeypatch):
    import fraytool.progress

    monkeypatch.setattr(fraytool.progress, "LOG_EVERY_S", 0.0)
    argv = ["batch", str(scene), "-o", str(tmp_path / "o"), "--workers", "1", "--resolution", "64x48",
            "--frames", "0:6", "--chunk-frames", "3", "--progress", "log"]
    assert main(argv) == 0
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("fraytool progress: batch")]
    assert len(lines) >= 4
    assert re.search(r"simulate 6/6 frames \([0-9.]+/s\); render 6/6 frames \([0-9.]+/s\); join 1/1 shots", lines[-1])
    assert any(re.search(r"render 3/6 frames \([0-9.]+/s, ETA [0-9]+ s\)", ln) for ln in lines), lines


@pytest.mark.parametrize("flags,needle", [
    (["--set", "cloth.nope=1"], "[cloth] nope = 1: unknown key"),
    (["--frames", "0:1000"], "--frames '0:1000': expected START:END"),
    (["--wedge", "scene.sed=1,2"], "[scene] sed = 1: unknown key"),
])
def test_a_batch_where_no_shot_can_run_exits_2_before_starting_a_cluster(tmp_path, capsys, monkeypatch, flags, needle):
    """Bad input that spoils every shot is bad input (exit 2, each reason named), found before any
    cluster starts and before anything is written."""
    import fraytool.farm.runner as runner

    def no_cluster(*a, **k):
        raise AssertionError("a cluster was started")

    monkeypatch.setattr(runner, "local_client", no_cluster)
    out = tmp_path / "job"
    assert main(["batch", "fig6_thrown_ball_plain", "-o", str(out), *flags]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err
    if "--wedge" in flags:   # two shots: a line each, then the summary
        assert err.count("\n") == 3 and "none of the 2 shot(s) can run" in err
    else:                    # one shot: its reason alone, on one line, the shot named once
        assert err.count("\n") == 1 and err.count("fig6_thrown_ball_plain") == 1
    assert not out.exists()


def test_farm_tasks_write_16bit_alpha_pngs_and_exrs_when_asked(scene, tmp_path):
    """The batch's tasks (run here in-process, as a worker runs them) honour --alpha, --depth 16 and
    --exr: RGBA 16-bit PNGs and EXRs with R, G, B, A, Z for every frame of the range, then the MP4."""
    import subprocess

    import imageio_ffmpeg
    import numpy as np

    from fraytool.farm import tasks
    from fraytool.farm.runner import _outputs_complete
    from fraytool.render.exr import read_exr

    (shot,) = expand(str(scene), [], [], RenderOptions(resolution=(64, 48), frames="0:3", alpha=True, depth=16,
                                                        exr=True))
    out = tmp_path / "shot"
    frames = tasks.shot_frames(shot, out)
    tasks.simulate_task(shot, str(out), frames.end)
    tasks.render_chunk_task(shot, str(out), 0, 3, 1)
    result = tasks.join_task(shot, str(out))
    assert _outputs_complete({"outputs": {"video": result["video"], "png": result["png_dir"], "exr": result["exr_dir"]}},
                             frames)
    for k in range(3):
        png = out / "png" / f"frame_{k:06d}.png"
        raw = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-i", str(png), "-f", "rawvideo",
                              "-pix_fmt", "rgba64le", "-"], capture_output=True, check=True).stdout
        rgba = np.frombuffer(raw, "<u2").reshape(48, 64, 4)
        # transparent background; the cloth covers (at 64 x 48 it is far-field surface but for the border
        # yarns, and the surface's alpha is the weave's coverage, about 0.6 here: the gaps show through)
        assert rgba[..., 3].min() == 0 and rgba[..., 3].max() > 30000
        assert np.any(rgba[..., :3] % 257 != 0)                           # real 16-bit values, not 8-bit ones
        channels = read_exr(out / "exr" / f"frame_{k:06d}.exr")
        assert set(channels) == {"R", "G", "B", "A", "Z"}
    (out / "exr" / "frame_000001.exr").unlink()
    assert not _outputs_complete({"outputs": {"video": result["video"], "png": result["png_dir"],
                                              "exr": result["exr_dir"]}}, frames)


def test_job_file_render_flags(tmp_path, scene):
    job = tmp_path / "job.toml"
    job.write_text(f'[render]\nalpha = true\ndepth = 16\nexr = true\n[[shots]]\nscene = "{scene}"\n')
    (shot,) = load_job(job).shots
    assert (shot.render.alpha, shot.render.depth, shot.render.exr) == (True, 16, True)
    job.write_text(f'[render]\ndepth = 12\n[[shots]]\nscene = "{scene}"\n')
    with pytest.raises(InputError, match=r"depth = 12: 8 or 16"):
        load_job(job)


def test_farm_tasks_prores_and_fit_match_fraytool_render(scene, tmp_path):
    """--codec prores and --fit in a batch (its tasks run here in-process, as a worker runs them): the
    whole shot is simulated before any chunk renders, every chunk gets the camera fitted over the whole
    shot, the PNGs are 16-bit RGBA and byte for byte those of `fraytool render --png --codec prores
    --depth 16 --fit`, and the join writes a ProRes 4444 .mov with alpha."""
    import subprocess

    import imageio_ffmpeg

    from fraytool.farm import tasks
    from fraytool.farm.runner import _outputs_complete

    (shot,) = expand(str(scene), [], [], RenderOptions(resolution=(64, 48), frames="0:4", codec="prores", fit=True))
    out = tmp_path / "shot"
    assert tasks.frames_to_simulate(shot, out) == 24      # the fit covers the whole shot, not frames 0-3
    tasks.simulate_task(shot, str(out), tasks.frames_to_simulate(shot, out))
    tasks.render_chunk_task(shot, str(out), 0, 2, 1)       # two chunks: each fits the camera itself
    tasks.render_chunk_task(shot, str(out), 2, 4, 1)
    stale = Path(tasks.render_job_for(shot, out, tasks.shot_frames(shot, out))[0].video_path).with_suffix(".mp4")
    stale.write_bytes(b"an H.264 run of this shot before")
    result = tasks.join_task(shot, str(out))
    assert result["video"].endswith(".mov")
    assert not stale.exists()                              # the other codec's old video went with it
    assert _outputs_complete({"outputs": {"video": result["video"], "png": result["png_dir"]}}, tasks.shot_frames(shot, out))
    probe = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-i", result["video"]],
                           capture_output=True, text=True).stderr
    assert "prores" in probe and "yuva444p" in probe, probe

    ref = tmp_path / "ref"
    assert main(["render", str(scene), "-o", str(ref), "--png", "--codec", "prores", "--depth", "16",
                 "--fit", "--frames", "0:4", "--resolution", "64x48", "--progress", "none"]) == 0
    for k in range(4):
        name = f"frame_{k:06d}.png"
        assert (out / "png" / name).read_bytes() == (ref / "png" / name).read_bytes(), name


def test_job_file_codec_and_fit(tmp_path, scene):
    job = tmp_path / "job.toml"
    job.write_text(f'[render]\ncodec = "prores"\nfit = true\n[[shots]]\nscene = "{scene}"\n')
    (shot,) = load_job(job).shots
    assert (shot.render.codec, shot.render.fit) == ("prores", True)
    job.write_text(f'[render]\ncodec = "prores"\ndepth = 8\n[[shots]]\nscene = "{scene}"\n')
    with pytest.raises(InputError, match=r'codec = "prores" with depth = 8'):
        load_job(job)
    job.write_text(f'[render]\ncodec = "vp9"\n[[shots]]\nscene = "{scene}"\n')
    with pytest.raises(InputError, match=r'codec = \'vp9\': "h264" or "prores"'):
        load_job(job)


def test_batch_refuses_prores_with_8bit_pngs(capsys):
    assert main(["batch", "drape", "--codec", "prores", "--depth", "8"]) == 2
    assert "--codec prores with --depth 8" in capsys.readouterr().err


def test_a_job_json_of_the_version_before_codec_and_fit_still_finds_its_finished_shots(scene, tmp_path):
    """Shots that set neither codec nor fit keep the settings digest the version before those options
    wrote into job.json (its rule, spelled out here: the scene, the overrides and the seven render
    options it had), and an entry that names its video 'mp4' still counts as complete."""
    import hashlib

    from fraytool.farm.runner import _outputs_complete, settings_digest
    from fraytool.render.options import FrameRange

    (shot,) = expand(str(scene), [("scene.seed", 3)], [], RenderOptions(resolution=(64, 48), frames="0:2", depth=16))
    old_fields = {"resolution": (64, 48), "samples": None, "wireframe": None, "frames": "0:2", "alpha": None,
                  "depth": 16, "exr": None}
    h = hashlib.sha256(json.dumps([shot.scene, shot.sets, old_fields], default=str).encode())
    h.update(scene.read_bytes())
    assert settings_digest(shot) == h.hexdigest()[:16]
    (prores,) = expand(str(scene), [("scene.seed", 3)], [], RenderOptions(resolution=(64, 48), frames="0:2",
                                                                          depth=16, codec="prores"))
    assert settings_digest(prores) != settings_digest(shot)
    png = tmp_path / "png"
    png.mkdir()
    for k in range(2):
        (png / f"frame_{k:06d}.png").write_bytes(b"x")
    video = tmp_path / "small.mp4"
    video.write_bytes(b"x")
    assert _outputs_complete({"outputs": {"mp4": str(video), "png": str(png)}}, FrameRange(0, 2))
    video.unlink()
    assert not _outputs_complete({"outputs": {"mp4": str(video), "png": str(png)}}, FrameRange(0, 2))


def test_the_join_rounds_16bit_pngs_to_8_bits_for_h264(tmp_path):
    """An H.264 join from 16-bit PNGs rounds each value to the nearest 8-bit step (v / 257), as the
    8-bit render does from the same colour, instead of dropping the low byte."""
    import numpy as np

    from fraytool.farm.tasks import _read_png16_as_8bit
    from fraytool.render.png16 import write_png16

    values = np.array([0, 128, 129, 200, 257, 32896, 33024, 33025, 65535], np.uint16)
    image = np.repeat(values[None, :, None], 3, axis=2)
    write_png16(tmp_path / "f.png", image)
    got = _read_png16_as_8bit(tmp_path / "f.png")[0, :, 0]
    assert got.tolist() == [0, 0, 1, 1, 1, 128, 128, 129, 255]
    assert got.tolist() != (values >> 8).tolist()   # what dropping the low byte gives


def test_a_retried_simulate_task_continues_the_frames_already_written(scene, tmp_path, monkeypatch):
    """A task retried after its worker died (or a job re-run for more frames) resumes: frames already on
    disk are kept as they are and only the missing ones are stepped. Catches the task starting from
    scratch (a fresh run gives the same frames, so only the work done and the files tell)."""
    from fraytool.farm import tasks
    from fraytool.sim.solver import SolverExplicitPBD

    (shot,) = expand(str(scene), [], [], RenderOptions(resolution=(64, 48), frames="0:6"))
    out = tmp_path / "shot"
    tasks.simulate_task(shot, str(out), 3)
    kept = {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in (out / "frames").glob("frame_*.npz")}
    assert sorted(kept) == [f"frame_{k:06d}.npz" for k in range(3)]
    steps = []
    original = SolverExplicitPBD.step
    monkeypatch.setattr(SolverExplicitPBD, "step",
                        lambda self, state, dt: (steps.append(state.step_index), original(self, state, dt))[1])
    tasks.simulate_task(shot, str(out), 6)
    spf = tasks.load_shot(shot).time.steps_per_frame
    assert len(steps) == 3 * spf and steps[0] == 2 * spf  # frames 3-5, from frame 2's checkpoint
    for name, stamp in kept.items():
        p = out / "frames" / name
        assert (p.stat().st_ino, p.stat().st_mtime_ns) == stamp, name


def test_a_dashed_wedge_range_points_at_the_dotted_one():
    """`--wedge scene.seed=1-3` is a range written the wrong way: the error shows `1..3`."""
    with pytest.raises(InputError, match=r"scene\.seed=1\.\.3"):
        parse_wedge("scene.seed=1-3")
    assert parse_wedge("scene.name=1-3") == ("scene.name", ["1-3"])


def test_a_contact_sheet_has_readable_labels_and_no_empty_tile():
    """Three shots on a 2 x 2 grid: the third is centred in the last row on the grey ground (no black tile
    where a fourth would be), and each label is at least 5 % of the tile high."""
    import numpy as np
    from PIL import ImageDraw, Image

    from fraytool.farm.contact_sheet import SHEET_BACKGROUND, compose, label_font, tile_grid

    tw, th = 320, 180
    images = [np.full((th, tw, 3), v, np.uint8) for v in (200, 150, 100)]
    grid = tile_grid(3)
    assert grid == (2, 2)
    sheet = compose(images, ["seed=1", "seed=2", "seed=3"], (tw, th), grid)
    assert sheet.shape == (2 * th, 2 * tw, 3)
    last = sheet[th + th // 2]  # a line through the last row, below the label
    assert (last[tw // 2 + 10: tw + tw // 2 - 10] == 100).all()        # the third shot, centred
    assert (last[: tw // 2 - 1] == SHEET_BACKGROUND).all() and (last[-(tw // 2 - 1):] == SHEET_BACKGROUND).all()
    assert not (sheet == 0).all(axis=-1)[th:, :].all(axis=0).any()    # no black column in the last row
    box = ImageDraw.Draw(Image.new("RGB", (10, 10))).textbbox((0, 0), "seed=3", font=label_font(th))
    assert box[3] - box[1] >= 0.05 * th


def test_job_file_and_command_line_supersample(tmp_path, scene):
    """`supersample` in a job file's [render] table (or a shot's) and --supersample reach each shot's render job
    (the command line winning), and a value outside 1-4 is refused naming the table."""
    from fraytool.farm.shots import RenderOptions
    from fraytool.farm.tasks import render_job_for
    from fraytool.render.options import FrameRange

    job = tmp_path / "job.toml"
    job.write_text(f'[render]\nsupersample = 2\n[[shots]]\nscene = "{scene}"\n[[shots]]\nscene = "{scene}"\n'
                   f'name = "finer"\nrender = {{ supersample = 3 }}\n')
    shots = load_job(job).shots
    assert [s.render.supersample for s in shots] == [2, 3]
    rendered = render_job_for(shots[0], tmp_path / "out", FrameRange(0, 2, 1))[0]
    assert rendered.spec.render.supersample == 2
    (cli,) = load_job(job, render=RenderOptions(supersample=1)).shots[:1]
    assert cli.render.supersample == 1
    job.write_text(f'[render]\nsupersample = 5\n[[shots]]\nscene = "{scene}"\n')
    with pytest.raises(InputError, match=r"\[render\] supersample = 5: expected an integer from 1 to 4"):
        load_job(job)


@pytest.mark.parametrize("line, needle", [
    ("resolution = [64, 47]", "[render] resolution = [64, 47]: the MP4 (H.264, yuv420p) needs an even width and height"),
    ("resolution = [1, 48]", "[render] resolution = [1, 48]: expected WIDTHxHEIGHT with whole numbers from 2 to 8192"),
    ("samples = 99", "[render] samples = 99: expected 0 to 64"),
    ("samples = 2.5", "[render] samples = 2.5: a whole number"),
])
def test_a_job_files_render_values_are_checked_by_the_render_commands_own_checks(tmp_path, line, needle):
    """The job file's [render] ranges are `fraytool render`'s (fraytool.render.options, checked_key): the same
    rule, worded with the file and the key; an odd size is refused up front, as `fraytool render` refuses it for
    an MP4."""
    job = tmp_path / "job.toml"
    job.write_text(f'[render]\n{line}\n[[shots]]\nscene = "drape"\n')
    with pytest.raises(InputError) as caught:
        load_job(job)
    assert needle in str(caught.value) and str(job) in str(caught.value), str(caught.value)
