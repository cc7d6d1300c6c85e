"""Golden-image regression tests of the renderer.

Scene: tests/scenes/golden_small.toml (12 x 12 plain weave over a ball, 160 x 120, 4x MSAA), posed
analytically by tests/conftest.py at three frames: flat (0), draped (1), draped and torn with
yarn-level crossings and fading cut ends (2), plus frame 2 with the wireframe beside it, and frame 2
lit with key-light shadows, the ground plane and a fill light (LIT), and that frame with the yarns
drawn as ribbons; and the drape as the multi-resolution model draws it with one cell refined (f3). Regenerate one golden with
`pytest tests/test_render_golden.py -k NAME --update-goldens` (all with no -k) and review the image.

The comparison is fraytool.testing's (`assert_image_matches_golden`, docs/golden.md), the one a studio's
suite uses, with the tolerance OWN below: RMS over 8-bit values <= 1 level, at most 0.2 % of pixels with
a channel differing by more than 16 levels, and at most 0.5 % by more than one level (a second, finer
fail level: the share that catches a 10 % change of the Kajiya-Kay exponent, which the RMS cannot tell
from rounding; docs/testing.md). Repeated renders on one machine are bit-identical; the slack is for
other Mesa/LLVM versions moving a few edge pixels.

On failure, report.html with the reference, the new image and their difference is written to
tests/results/ and the path is printed. `pytest --update-goldens` rewrites the goldens (review the
images before committing them). A missing golden fails; it is never created silently.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from fraytool.golden.compare import FAIL, FrameVerdict, ImageTolerance, judge_image
from fraytool.render.geometry import GeometryBuilder, YarnStyle
from fraytool.render.renderer import Renderer
from fraytool.testing import assert_image_matches_golden

TESTS = Path(__file__).resolve().parent
GOLDEN_DIR = TESTS / "golden"
RESULTS_DIR = TESTS / "results"

OWN = ImageTolerance(fail=16.5 / 255, failpercent=0.2, hardfail=1.0, warn=1.5 / 255, warnpercent=0.5,
                     ssim_min=-1.0, rms_max=1.0 / 255, warn_fails=True)
"""The renderer goldens' tolerance (8-bit levels as fractions: more than 16 levels, more than one level)."""

CASES = {
    "golden_small_f0_flat": ("copy", "off"),
    "golden_small_f1_draped": ("draped", "off"),
    "golden_small_f2_torn": ("torn", "off"),
    "golden_small_f2_torn_beside": ("torn", "beside"),
    "golden_small_f2_torn_lit": ("torn", "off"),
    "golden_small_f2_torn_lit_ribbon": ("torn", "off"),
    "golden_small_f3_multires_border": ("multires_border", "off"),
}
LIT = {"golden_small_f2_torn_lit": dict(shadows=True, shadow_map_size=1024, fill_intensity=0.3,
                                        light_direction=(0.6, 1.0, 0.2)),
       "golden_small_f2_torn_lit_ribbon": dict(shadows=True, shadow_map_size=1024, fill_intensity=0.3,
                                               light_direction=(0.6, 1.0, 0.2), yarn_shape="ribbon")}
"""Render keys a case turns on over the scene's (which already has the ground plane): the torn frame
with key-light shadows, the ground and a fill light; and the same with the yarns drawn as ribbons
(fraytool.render.ribbon). The multi-resolution border (f3): the draped pose with only the centre cell
of a factor-4 coarse model refined, the rest on their cells' bilinear interpolation
(docs/multires.md): the yarns must run on across the border without a seam."""


def render_case(ctx, pc, name: str, render=None, camera=None) -> np.ndarray:
    pose, wireframe = CASES[name]
    render = render or dataclasses.replace(pc.spec.render, **LIT.get(name, {}))
    size = tuple(render.resolution)
    record = getattr(pc, pose)()
    renderer = Renderer(ctx, size, render.samples, render, camera or pc.spec.camera, pc.topology, wireframe)
    try:
        builder = GeometryBuilder(pc.topology, YarnStyle.from_spec(render, pc.topology), renderer.camera, size[1])
        return renderer.render(builder.build(record, yarns=wireframe != "only", lines=wireframe != "off")).copy()
    finally:
        renderer.release()


def check_golden(name: str, image: np.ndarray, update: bool, golden_dir: Path = GOLDEN_DIR,
                 results_dir: Path = RESULTS_DIR) -> None:
    """Compare with golden_dir/<name>.png (or rewrite it when `update`), as a studio's suite would."""
    assert_image_matches_golden(name, image, golden_dir, tolerance=OWN, update=update, results_dir=results_dir)


def compare(golden: np.ndarray, image: np.ndarray) -> FrameVerdict:
    """The verdict of two 8-bit images under OWN."""
    v = FrameVerdict(0)
    judge_image(v, golden.astype(np.uint16) * 257, image.astype(np.uint16) * 257, OWN)
    return v


@pytest.mark.parametrize("name", sorted(CASES))
def test_golden_images(name, gl_ctx, posed_cloth, update_goldens):
    check_golden(name, render_case(gl_ctx, posed_cloth, name), update_goldens)


def _golden(name: str) -> np.ndarray:
    path = GOLDEN_DIR / f"{name}.png"
    if not path.is_file():
        pytest.fail(f"golden image {path} is missing; run `pytest --update-goldens`")
    return np.asarray(Image.open(path).convert("RGB"))


def test_comparison_catches_a_slightly_moved_camera(gl_ctx, posed_cloth):
    name = "golden_small_f1_draped"
    cam = posed_cloth.spec.camera
    moved = dataclasses.replace(cam, position_m=(cam.position_m[0] + 0.001, *cam.position_m[1:]))  # 1 mm
    diff = compare(_golden(name), render_case(gl_ctx, posed_cloth, name, camera=moved))
    assert diff.status == FAIL, diff.figures


@pytest.mark.parametrize("field,value", [("specular", 0.5), ("light_intensity", 1.05)])
def test_comparison_catches_an_altered_shading_parameter(gl_ctx, posed_cloth, field, value):
    name = "golden_small_f2_torn"
    render = dataclasses.replace(posed_cloth.spec.render, **{field: value})
    diff = compare(_golden(name), render_case(gl_ctx, posed_cloth, name, render=render))
    assert diff.status == FAIL, diff.figures


def test_identical_renders_compare_equal(gl_ctx, posed_cloth):
    a = render_case(gl_ctx, posed_cloth, "golden_small_f2_torn")
    b = render_case(gl_ctx, posed_cloth, "golden_small_f2_torn")
    d = compare(a, b)
    assert d.status == "pass" and d.figures["rms_error"] == 0.0


def test_missing_golden_fails_and_is_not_created(tmp_path):
    image = np.zeros((8, 8, 3), np.uint8)
    with pytest.raises(AssertionError, match="missing"):
        check_golden("nothing_here", image, update=False, golden_dir=tmp_path / "golden",
                     results_dir=tmp_path / "results")
    assert not (tmp_path / "golden" / "nothing_here.png").exists()


def test_failure_writes_a_report_with_reference_new_and_diff(tmp_path):
    expected = np.zeros((10, 10, 3), np.uint8)
    golden = tmp_path / "golden"
    check_golden("case", expected, update=True, golden_dir=golden, results_dir=tmp_path / "results")
    actual = expected.copy()
    actual[2:6, 2:6] = 40
    with pytest.raises(AssertionError) as info:
        check_golden("case", actual, update=False, golden_dir=golden, results_dir=tmp_path / "results")
    assert str(tmp_path / "results" / "report.html") in str(info.value) and "16.000 % of pixels" in str(info.value)
    folder = tmp_path / "results" / "case"
    for f in ("reference_000000.png", "new_000000.png", "diff_000000.png"):
        assert (folder / f).is_file()
    diff = np.asarray(Image.open(folder / "diff_000000.png"))
    assert diff[3, 3] == 255 and diff[0, 0] == 0   # 40 levels: past the fail threshold, white


def test_comparison_catches_the_shadows_turned_off(gl_ctx, posed_cloth):
    name = "golden_small_f2_torn_lit"
    render = dataclasses.replace(posed_cloth.spec.render, **{**LIT[name], "shadows": False})
    diff = compare(_golden(name), render_case(gl_ctx, posed_cloth, name, render=render))
    assert diff.status == FAIL, diff.figures


@pytest.mark.parametrize("name", sorted(CASES))
def test_every_golden_catches_a_10_percent_change_of_the_specular_exponent(name, gl_ctx, posed_cloth):
    """The Kajiya-Kay exponent (render.shininess) 10 % higher: caught on every golden, by the share of
    pixels off by more than a level (the RMS alone let 20 % pass on four of five goldens)."""
    render = dataclasses.replace(posed_cloth.spec.render, **LIT.get(name, {}))
    render = dataclasses.replace(render, shininess=1.1 * render.shininess)
    diff = compare(_golden(name), render_case(gl_ctx, posed_cloth, name, render=render))
    assert diff.status == FAIL, diff.figures


@pytest.mark.parametrize("yarn", ["weft_color", "warp_color"])
@pytest.mark.parametrize("name", sorted(CASES))
def test_every_golden_catches_a_5_percent_change_of_a_yarn_colour(name, yarn, gl_ctx, posed_cloth):
    render = dataclasses.replace(posed_cloth.spec.render, **LIT.get(name, {}))
    render = dataclasses.replace(render, **{yarn: tuple(0.95 * c for c in getattr(render, yarn))})
    diff = compare(_golden(name), render_case(gl_ctx, posed_cloth, name, render=render))
    assert diff.status == FAIL, diff.figures


RENDER_IN_A_PROCESS = """
import sys
sys.path.insert(0, sys.argv[1])
import numpy as np
from PIL import Image
from fraytool.render.context import create_context
import conftest
from test_render_golden import CASES, render_case
ctx = create_context()
pc = conftest.PosedCloth(conftest.GOLDEN_SCENE)
for name in sorted(CASES):
    Image.fromarray(render_case(ctx, pc, name)).save(f"{sys.argv[2]}/{name}.png")
"""


@pytest.mark.parametrize("threads", ["1", "2"])
def test_the_goldens_pass_with_other_thread_counts(threads, tmp_path):
    """The same tolerance that catches the changes above lets every golden pass when llvmpipe draws on
    another number of threads (LP_NUM_THREADS) and numba's kernels run on another number (the
    geometry is built by them): the tolerance shown both ways."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "LP_NUM_THREADS": threads, "NUMBA_NUM_THREADS": threads}
    r = subprocess.run([sys.executable, "-c", RENDER_IN_A_PROCESS, str(TESTS), str(tmp_path)], env=env,
                       capture_output=True, text=True, cwd=TESTS.parent)
    assert r.returncode == 0, r.stderr[-3000:]
    for name in sorted(CASES):
        image = np.asarray(Image.open(tmp_path / f"{name}.png").convert("RGB"))
        diff = compare(_golden(name), image)
        assert diff.status == "pass", f"{name} on {threads} thread(s): {diff.reasons}"
