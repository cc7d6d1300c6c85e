"""`fraytool golden` and fraytool.testing (docs/golden.md): a golden made once passes when nothing that
changes pixels changed (another thread count, another llvmpipe thread count, a fresh numba cache: a
re-install), and fails, naming the frame and the figure, when something did (one yarn's colour, half a
pixel of camera, the seed of a tear, gravity on a drape). The report is loaded in a real browser."""
from __future__ import annotations

import json
import re
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest

TESTS = Path(__file__).resolve().parent
DRAPE = TESTS / "scenes" / "golden_drape.toml"
TEAR = TESTS / "scenes" / "golden_tear.toml"


def fraytool(*args, env=None, cwd=None) -> subprocess.CompletedProcess:
    full = {**os.environ, **(env or {})}
    return subprocess.run([sys.executable, "-m", "fraytool", *map(str, args)], capture_output=True, text=True,
                          env=full, cwd=cwd)


@pytest.fixture(scope="module")
def drape_golden(tmp_path_factory):
    """The drape's golden, made once on one thread."""
    root = tmp_path_factory.mktemp("golden")
    run = fraytool("golden", "update", DRAPE, "--dir", root / "g", "--work", root / "work", "--threads", "1")
    assert run.returncode == 0, run.stderr
    return root


def check(root, *args, scene=DRAPE, env=None, work="work"):
    return fraytool("golden", "check", scene, "--dir", root / "g", "--work", root / work, *args, env=env)


def test_update_stores_16_bit_pngs_yarns_and_metadata(drape_golden):
    folder = drape_golden / "g" / "golden_drape"
    meta = json.loads((folder / "golden.json").read_text())
    assert [f["frame"] for f in meta["frames"]] == [0, 3, 7]  # first, middle, last
    for key in ("fraytool_version", "scene_hash", "settings", "renderer", "cpu"):
        assert meta[key], key
    assert "llvmpipe" in meta["renderer"] or "Mesa" in meta["renderer"] or meta["renderer"]
    from fraytool.render.png16 import read_png16
    import numpy as np

    image = read_png16(folder / "frame_000007.png")
    assert image.dtype == np.uint16 and image.shape == (160, 240, 3)
    yarns = np.load(folder / "yarns_000007.npz")
    assert yarns["points_m"].dtype == np.float32 and len(yarns["offsets"]) == 33  # 16 weft + 16 warp yarns


@pytest.mark.parametrize("case", ["two threads", "llvmpipe one thread", "llvmpipe four threads", "fresh numba cache"])
def test_a_golden_passes_where_nothing_that_changes_pixels_changed(drape_golden, case, tmp_path):
    args, env, work = {
        "two threads": (["--threads", "2"], None, "work"),
        "llvmpipe one thread": ([], {"LP_NUM_THREADS": "1"}, "work"),
        "llvmpipe four threads": ([], {"LP_NUM_THREADS": "4"}, "work"),
        # a re-install: kernels compiled afresh and frames simulated again, from nothing
        "fresh numba cache": ([], {"NUMBA_CACHE_DIR": str(tmp_path / "numba")}, str(tmp_path / "work2")),
    }[case]
    run = check(drape_golden, *args, env=env, work=work)
    assert run.returncode == 0, run.stderr
    assert "golden check: pass" in run.stderr


def _failing_lines(run) -> list[str]:
    return [line for line in run.stderr.splitlines() if ": fail: " in line]


def test_half_a_pixel_of_camera_fails_naming_frame_and_figure(drape_golden):
    # half a pixel at the target: 0.216 m away, 40 degrees over 160 pixels -> 0.98 mm a pixel
    run = check(drape_golden, "--set", "camera.position_m=[0.000492, 0.2, 0.18]",
                "--set", "camera.target_m=[0.000492, 0.08, 0.0]")
    assert run.returncode == 1, run.stderr
    lines = _failing_lines(run)
    assert any(line.strip().startswith("fraytool:   frame 0: fail: image:") for line in lines), run.stderr
    assert "settings.camera" in run.stderr  # the report says what differs from the golden's metadata


def test_a_golden_made_with_a_set_is_checked_with_it(tmp_path):
    """docs/golden.md: `--set` is recorded, and the check applies it without being told again (a golden kept
    at a smaller size is checked at that size); a --set given to the check goes on top of it."""
    small = "render.resolution=[120,80]"
    run = fraytool("golden", "update", DRAPE, "--dir", tmp_path / "g", "--work", tmp_path / "work",
                   "--frames", "0,7", "--set", small)
    assert run.returncode == 0, run.stderr
    run = fraytool("golden", "check", DRAPE, "--dir", tmp_path / "g", "--work", tmp_path / "work")
    assert run.returncode == 0 and "golden check: pass" in run.stderr, run.stderr
    assert "differs from the golden's metadata" not in run.stderr, run.stderr
    # a frame the golden lacks: the command that makes it keeps the recorded --set
    run = fraytool("golden", "check", DRAPE, "--dir", tmp_path / "g", "--work", tmp_path / "work", "--frames", "3")
    assert run.returncode == 2 and "--set 'render.resolution=[120,80]' --frames 0,3,7" in run.stderr, run.stderr
    # a change given to the check still applies, and the metadata says which key moved, readably
    run = fraytool("golden", "check", DRAPE, "--dir", tmp_path / "g", "--work", tmp_path / "work",
                   "--set", "camera.fov_deg=41")
    assert run.returncode == 1, run.stderr
    assert "settings.camera.fov_deg: golden 40.0, now 41.0" in run.stderr, run.stderr


def test_a_check_puts_its_own_sets_after_the_recorded_ones():
    from fraytool.golden.run import sets_for_check

    assert sets_for_check(["render.resolution=[120,80]"], []) == ["render.resolution=[120,80]"]
    assert sets_for_check(["scene.seed=3"], ["scene.seed=3", "camera.fov_deg=41"]) == ["scene.seed=3",
                                                                                      "camera.fov_deg=41"]
    # the given value must win over the recorded list's last word on its key, even if recorded earlier
    assert sets_for_check(["scene.seed=4", "scene.seed=3"], ["scene.seed=4"])[-1] == "scene.seed=4"


def test_gravity_on_a_drape_fails_in_image_and_geometry(drape_golden):
    run = check(drape_golden, "--set", "world.gravity_m_s2=[0.0, -7.0, 0.0]")
    assert run.returncode == 1
    lines = _failing_lines(run)
    assert any("frame 7: fail: geometry: a yarn point moved" in line for line in lines), run.stderr
    assert not any("frame 0: fail" in line for line in lines)  # frame 0 is the rest pose either way


def test_one_yarns_colour_changed_fails(drape_golden, tmp_path):
    """The renderer draws one weft yarn in another colour (a palette entry it does not otherwise use)."""
    wrapper = tmp_path / "one_yarn.py"
    wrapper.write_text(textwrap.dedent(f"""
        import sys
        import numpy as np
        import fraytool.render.geometry as geometry
        from dataclasses import replace
        real = geometry.yarn_pieces
        def one_yarn_recoloured(*args, **kw):
            pieces = real(*args, **kw)
            color = pieces.color_index.copy()
            color[5] = 2.0  # weft yarn 5 in the third palette entry (the seams' dark thread)
            return replace(pieces, color=color)
        geometry.yarn_pieces = one_yarn_recoloured
        from fraytool.commands.main import main
        sys.exit(main(["golden", "check", {str(DRAPE)!r}, "--dir", {str(drape_golden / "g")!r},
                       "--work", {str(drape_golden / "work")!r}]))
    """))
    run = subprocess.run([sys.executable, str(wrapper)], capture_output=True, text=True)
    assert run.returncode == 1, run.stderr
    assert any("fail: image:" in line for line in _failing_lines(run)), run.stderr


def test_another_seed_of_a_tear_fails_on_the_tear(tmp_path):
    made = fraytool("golden", "update", TEAR, "--dir", tmp_path / "g", "--work", tmp_path / "work")
    assert made.returncode == 0, made.stderr
    same = fraytool("golden", "check", TEAR, "--dir", tmp_path / "g", "--work", tmp_path / "work")
    assert same.returncode == 0, same.stderr
    run = fraytool("golden", "check", TEAR, "--dir", tmp_path / "g", "--work", tmp_path / "work",
                   "--set", "scene.seed=2", "--junit", tmp_path / "junit.xml")
    assert run.returncode == 1
    lines = _failing_lines(run)
    assert any("frame 23: fail: geometry:" in line for line in lines), run.stderr
    suite = ET.parse(tmp_path / "junit.xml").getroot()
    assert suite.get("tests") == "3" and int(suite.get("failures")) >= 1
    failed = [c.get("name") for c in suite if c.find("failure") is not None]
    assert "frame_000023" in failed


def test_a_missing_golden_is_exit_2_naming_the_command_that_makes_it(tmp_path):
    run = fraytool("golden", "check", DRAPE, "--dir", tmp_path / "none", "--work", tmp_path / "work")
    assert run.returncode == 2
    assert "fraytool golden update" in run.stderr and str(tmp_path / "none") in run.stderr
    assert len([x for x in run.stderr.splitlines() if x.strip()]) == 1


def test_bad_frames_are_exit_2(drape_golden):
    run = check(drape_golden, "--frames", "0:5")
    assert run.returncode == 2 and "not a range" in run.stderr
    run = check(drape_golden, "--frames", "99")
    assert run.returncode == 2 and "0..7" in run.stderr


def test_the_report_loads_in_a_real_browser_with_every_image_and_a_working_swap(drape_golden, tmp_path):
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        pytest.fail("Debian's chromium is not installed (apt-get install chromium, README Set up): the report "
                    "must be loaded in a browser", pytrace=False)
    run = check(drape_golden, "--report", tmp_path / "report", "--set", "world.gravity_m_s2=[0.0, -7.0, 0.0]")
    assert run.returncode == 1
    summary = json.loads((tmp_path / "report" / "summary.json").read_text())
    assert summary["status"] == "fail"
    frames = summary["scenes"][0]["frames"]
    assert [f["status"] for f in frames][-1] == "fail" and "ssim" in frames[-1]["figures"]
    page = tmp_path / "report" / "report.html"
    dom = subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu", "--allow-file-access-from-files",
                          "--window-size=1400,1000", "--virtual-time-budget=5000", "--dump-dom", page.as_uri()],
                         capture_output=True, text=True, timeout=120).stdout
    body = dom[dom.index("<body"):dom.index(">", dom.index("<body"))]
    assert 'data-images-total="12"' in body and 'data-images-loaded="12"' in body, body
    assert 'data-swap-works="true"' in body, body
    assert 'data-status="fail"' in body
    # a reviewer's scan: the summary first, the failures at the top, the key that differs by key and value
    assert dom.index("id=\"summary\"") < dom.index("id=\"problems\"") < dom.index("<section"), dom[:2000]
    assert 'data-first-frame-status="fail"' in body, body
    assert "world.gravity_m_s2: [0.0, -9.81, 0.0] -&gt; [0.0, -7.0, 0.0]" in dom
    overview = summary["overview"][0]
    assert overview["status"] == "fail" and overview["frames"] == 3 and overview["counts"]["fail"] >= 1
    assert overview["worst"]["ssim"] == min(f["figures"]["ssim"] for f in frames)
    assert overview["worst"]["max_error"] == max(f["figures"]["max_error"] for f in frames)
    # images large enough to judge, each a link to itself at full size
    assert int(re.search(r'data-shown-width="(\d+)"', body).group(1)) >= 320, body
    for f in frames:
        for name in f["images"].values():
            assert f"<a href=\"{name}\" target=\"_blank\">" in dom, name
    # the ring where the yarns moved most sits on a changed part of the picture
    from PIL import Image

    moved = [f for f in frames if "moved_most_pixel" in f["figures"]]
    assert moved and int(re.search(r'data-rings="(\d+)"', body).group(1)) == 2 * len(moved)
    for f in moved:
        x, y = f["figures"]["moved_most_pixel"]
        diff = np.asarray(Image.open(tmp_path / "report" / f["images"]["diff"]))
        assert diff[max(0, y - 6):y + 7, max(0, x - 6):x + 7].max() > 0, (f["frame"], x, y)


def test_fraytool_testing_gives_a_studio_a_one_line_test(tmp_path):
    """A suite with `pytest_plugins = ["fraytool.testing"]` and `golden(scene, dir)`: --update-goldens makes
    the golden, a plain run passes, and the same test on a changed scene fails naming the frame."""
    scene = tmp_path / "shot.toml"
    scene.write_text(DRAPE.read_text())
    (tmp_path / "conftest.py").write_text('pytest_plugins = ["fraytool.testing"]\n')
    (tmp_path / "test_shot.py").write_text(
        f"def test_shot(golden):\n    golden({str(scene)!r}, {str(tmp_path / 'goldens')!r})\n")

    def pytest_run(*args):
        return subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *args],
                              capture_output=True, text=True, cwd=tmp_path)
    first = pytest_run()
    assert first.returncode == 1 and "fraytool golden update" in first.stdout  # no golden yet: it says how
    assert pytest_run("--update-goldens").returncode == 0
    assert (tmp_path / "goldens" / "golden_drape" / "golden.json").is_file()
    assert pytest_run().returncode == 0
    scene.write_text(DRAPE.read_text().replace("[scene]", "[world]\ngravity_m_s2 = [0.0, -7.0, 0.0]\n[scene]"))
    failed = pytest_run()
    assert failed.returncode == 1 and "frame 7: fail: geometry" in failed.stdout, failed.stdout[-2000:]


def test_the_farm_checks_many_shots_in_parallel_with_one_report(tmp_path):
    """fraytool batch --golden-update / --golden-check on a local Dask cluster: two wedge shots, their goldens
    made in parallel, then checked in parallel: unchanged they pass; with gravity changed both fail, in one
    report.html and one JUnit file."""
    common = [DRAPE, "--wedge", "scene.seed=1,2", "-o", tmp_path / "job", "--workers", "2"]
    made = fraytool("batch", *common, "--golden-update", tmp_path / "g")
    assert made.returncode == 0, made.stderr
    assert sorted(p.name for p in (tmp_path / "g").iterdir()) == ["golden_drape_seed-1", "golden_drape_seed-2"]
    same = fraytool("batch", *common, "--golden-check", tmp_path / "g")
    assert same.returncode == 0 and "golden check of 2 shot(s): pass" in same.stderr, same.stderr
    changed = fraytool("batch", *common, "--golden-check", tmp_path / "g", "--set", "world.gravity_m_s2=[0, -7, 0]",
                       "--junit", tmp_path / "junit.xml")
    assert changed.returncode == 1, changed.stderr
    summary = json.loads((tmp_path / "job" / "golden-report" / "summary.json").read_text())
    assert [s["scene"] for s in summary["scenes"]] == ["golden_drape_seed-1", "golden_drape_seed-2"]
    assert all(s["frames"][-1]["status"] == "fail" for s in summary["scenes"])
    assert (tmp_path / "job" / "golden-report" / "report.html").is_file()
    suite = ET.parse(tmp_path / "junit.xml").getroot()
    assert suite.get("tests") == "6" and int(suite.get("failures")) >= 2


def test_a_render_key_newer_than_the_golden_is_no_difference_at_its_default():
    """A golden recorded before fraytool had a [render] key lacks it: at its default the key changes no
    pixel and is not listed; set to anything else it is."""
    import dataclasses

    from fraytool.golden.capture import machine
    from fraytool.golden.store import settings_differences, settings_of
    from fraytool.scene import load_scene

    spec = load_scene(DRAPE)
    old = json.loads(json.dumps(settings_of(spec, []), default=list))
    del old["render"]["supersample"]
    meta = {"settings": old, "renderer": "r", "cpu": machine()}
    lines = [d for d in settings_differences(meta, spec, [], "r") if d.startswith("settings.")]
    assert lines == []
    finer = dataclasses.replace(spec, render=dataclasses.replace(spec.render, supersample=2))
    lines = [d for d in settings_differences(meta, finer, [], "r") if d.startswith("settings.")]
    assert lines == ["settings.render.supersample: golden null, now 2"]
