"""Golden-image regression tests of the renderer.

Scene: tests/scenes/golden_small.toml (12 x 12 plain weave over a ball, 160 x 120, 4x MSAA), posed
analytically by tests/conftest.py at three frames: flat (0), draped (1), draped and torn with
yarn-level crossings and fading cut ends (2), plus frame 2 with the wireframe beside it, and frame 2
lit with key-light shadows, the ground plane and a fill light (LIT), and that frame with the yarns
drawn as ribbons; and the drape as the multi-resolution model draws it with one cell refined (f3). Regenerate one golden with
`pytest tests/test_render_golden.py -k NAME --update-goldens` (all with no -k) and review the image.

Tolerance (fraytool.render.imagecompare): RMS over 8-bit values <= 1.0, and at most 0.2 % of pixels
with a channel differing by more than 16. Repeated renders on one machine are bit-identical; the
slack is for other Mesa/LLVM versions moving a few edge pixels.

On failure, expected.png, actual.png and diff.png (|difference| x 8) are written to
tests/results/<golden name>/ and the path is printed. `pytest --update-goldens` rewrites the goldens
(review the images before committing them). A missing golden fails; it is never created silently.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from fraytool.render.geometry import GeometryBuilder, YarnStyle
from imagecompare import compare_images, write_failure_images
from fraytool.render.renderer import Renderer

TESTS = Path(__file__).resolve().parent
GOLDEN_DIR = TESTS / "golden"
RESULTS_DIR = TESTS / "results"

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
    """Compare with golden_dir/<name>.png (or rewrite it when `update`); fail with a pointer to the
    expected / actual / diff images otherwise."""
    path = golden_dir / f"{name}.png"
    if update:
        golden_dir.mkdir(parents=True, exist_ok=True)
        Image.fromarray(image).save(path)
        return
    if not path.is_file():
        folder = write_failure_images(results_dir / name, None, image)
        pytest.fail(f"golden image {path} is missing (it is never created silently); the current render is "
                    f"{folder / 'actual.png'}; run `pytest --update-goldens` to create it, then review it")
    expected = np.asarray(Image.open(path).convert("RGB"))
    diff = compare_images(expected, image)
    if not diff.ok:
        folder = write_failure_images(results_dir / name, expected, image)
        pytest.fail(f"{name}: render differs from {path}: {diff.describe()}; expected, actual and diff "
                    f"(x8) images are in {folder}")


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
    diff = compare_images(_golden(name), render_case(gl_ctx, posed_cloth, name, camera=moved))
    assert not diff.ok, diff.describe()


@pytest.mark.parametrize("field,value", [("specular", 0.5), ("light_intensity", 1.05)])
def test_comparison_catches_an_altered_shading_parameter(gl_ctx, posed_cloth, field, value):
    name = "golden_small_f2_torn"
    render = dataclasses.replace(posed_cloth.spec.render, **{field: value})
    diff = compare_images(_golden(name), render_case(gl_ctx, posed_cloth, name, render=render))
    assert not diff.ok, diff.describe()


def test_identical_renders_compare_equal(gl_ctx, posed_cloth):
    a = render_case(gl_ctx, posed_cloth, "golden_small_f2_torn")
    b = render_case(gl_ctx, posed_cloth, "golden_small_f2_torn")
    d = compare_images(a, b)
    assert d.ok and d.rms == 0.0


def test_missing_golden_fails_and_is_not_created(tmp_path):
    image = np.zeros((8, 8, 3), np.uint8)
    with pytest.raises(pytest.fail.Exception, match="missing"):
        check_golden("nothing_here", image, update=False, golden_dir=tmp_path / "golden",
                     results_dir=tmp_path / "results")
    assert not (tmp_path / "golden" / "nothing_here.png").exists()


def test_failure_writes_expected_actual_and_diff(tmp_path):
    expected = np.zeros((10, 10, 3), np.uint8)
    golden = tmp_path / "golden"
    check_golden("case", expected, update=True, golden_dir=golden, results_dir=tmp_path / "results")
    actual = expected.copy()
    actual[2:6, 2:6] = 40
    with pytest.raises(pytest.fail.Exception) as info:
        check_golden("case", actual, update=False, golden_dir=golden, results_dir=tmp_path / "results")
    folder = tmp_path / "results" / "case"
    assert str(folder) in str(info.value)
    for f in ("expected.png", "actual.png", "diff.png"):
        assert (folder / f).is_file()
    diff = np.asarray(Image.open(folder / "diff.png"))
    assert diff[3, 3].tolist() == [255, 255, 255] and diff[0, 0].tolist() == [0, 0, 0]   # amplified x8


def test_comparison_catches_the_shadows_turned_off(gl_ctx, posed_cloth):
    name = "golden_small_f2_torn_lit"
    render = dataclasses.replace(posed_cloth.spec.render, **{**LIT[name], "shadows": False})
    diff = compare_images(_golden(name), render_case(gl_ctx, posed_cloth, name, render=render))
    assert not diff.ok, diff.describe()


@pytest.mark.parametrize("name", sorted(CASES))
def test_every_golden_catches_a_10_percent_change_of_the_specular_exponent(name, gl_ctx, posed_cloth):
    """The Kajiya-Kay exponent (render.shininess) 10 % higher: caught on every golden, by the share of
    pixels off by more than a level (the RMS alone let 20 % pass on four of five goldens)."""
    render = dataclasses.replace(posed_cloth.spec.render, **LIT.get(name, {}))
    render = dataclasses.replace(render, shininess=1.1 * render.shininess)
    diff = compare_images(_golden(name), render_case(gl_ctx, posed_cloth, name, render=render))
    assert not diff.ok, diff.describe()


@pytest.mark.parametrize("yarn", ["weft_color", "warp_color"])
@pytest.mark.parametrize("name", sorted(CASES))
def test_every_golden_catches_a_5_percent_change_of_a_yarn_colour(name, yarn, gl_ctx, posed_cloth):
    render = dataclasses.replace(posed_cloth.spec.render, **LIT.get(name, {}))
    render = dataclasses.replace(render, **{yarn: tuple(0.95 * c for c in getattr(render, yarn))})
    diff = compare_images(_golden(name), render_case(gl_ctx, posed_cloth, name, render=render))
    assert not diff.ok, diff.describe()


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
        diff = compare_images(_golden(name), image)
        assert diff.ok, f"{name} on {threads} thread(s): {diff.describe()}"
