"""Golden-image tests of your own scenes from a pytest suite (docs/golden.md "In a test suite").

In conftest.py:

    pytest_plugins = ["fraytool.testing"]

and a test is one line:

    def test_my_shot(golden):
        golden("scenes/my_shot.toml", "tests/goldens")

`pytest --update-goldens` (the option this plugin adds) rewrites the goldens instead of checking them.
Without pytest, call `assert_matches_golden(scene, golden_dir, update=...)` directly. A check that fails
raises AssertionError naming each failing frame and figure, and writes report.html beside the golden
(<golden_dir>/<scene>-report/) for a look.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Optional, Sequence

import pytest

UPDATE_ENV = "FRAYTOOL_UPDATE_GOLDENS"
"""Set to 1 to update goldens where no pytest option says (assert_matches_golden called directly)."""


def assert_matches_golden(scene: str | os.PathLike, golden_dir: str | os.PathLike, *, frames: Optional[Sequence[int]] = None,
                          sets: Sequence[str] = (), update: Optional[bool] = None,
                          work_dir: Optional[str | os.PathLike] = None) -> list:
    """Check (or with `update`, rewrite) the golden of `scene` in golden_dir: fraytool golden check /
    update as a function. `sets` are --set overrides ("scene.seed=3"); `update` None reads FRAYTOOL_UPDATE_GOLDENS.
    Returns the frame verdicts (fraytool.golden.compare.FrameVerdict); raises AssertionError on a regression."""
    from fraytool.golden.compare import FAIL
    from fraytool.golden.report import Report
    from fraytool.golden.run import (check_scene, load_for_check, load_for_golden, parse_frames, update_command_line,
                                     update_scene)

    scene, golden_dir = str(scene), Path(golden_dir)
    if update is None:
        update = os.environ.get(UPDATE_ENV, "") not in ("", "0")
    work = Path(work_dir) if work_dir else None
    if update:
        spec = load_for_golden(scene, list(sets))
        chosen = list(frames) if frames else parse_frames(None, spec)
        update_scene(spec, golden_dir, chosen, list(sets), work)
        return []
    spec, checked_sets = load_for_check(scene, golden_dir, list(sets))
    result = check_scene(spec, golden_dir, list(frames) if frames else None,
                         update_command_line(scene, golden_dir, checked_sets) + "  (or pytest --update-goldens)",
                         checked_sets, work)
    failed = [v for v in result.verdicts if v.status == FAIL]
    if failed:
        report = Report(golden_dir / f"{spec.name}-report")
        report.add(spec.name, result.golden_dir, result.verdicts, result.images, result.differences, spec.golden.fail)
        report.write()
        lines = [r for v in failed for r in v.reasons if ": fail: " in r]
        raise AssertionError(f"golden check of {spec.name} failed (report: {report.out / 'report.html'}):\n"
                             + "\n".join(lines))
    return result.verdicts


def assert_image_matches_golden(name: str, image, golden_dir: str | os.PathLike, *, tolerance=None,
                                update: bool = False, results_dir: Optional[str | os.PathLike] = None):
    """Compare an image you rendered yourself (uint8 or uint16, (H, W, 3)) with golden_dir/<name>.png (8 or
    16 bits, as the image), or rewrite it with `update`. `tolerance`: a fraytool.golden.compare.ImageTolerance
    (default: its defaults, the [golden] table's). On a regression: AssertionError with the failing figures
    and report.html, the reference, the new image and the difference in results_dir/<name>/ (default:
    golden_dir/results/<name>/). Returns the verdict. A missing golden fails; it is never made silently."""
    import numpy as np
    from PIL import Image

    from fraytool.golden.compare import FAIL, FrameVerdict, ImageTolerance, judge_image
    from fraytool.golden.report import Report
    from fraytool.render.png16 import read_png16, write_png16

    image = np.ascontiguousarray(image)
    path = Path(golden_dir) / f"{name}.png"
    sixteen = image.dtype == np.uint16
    if update:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_png16(path, image) if sixteen else Image.fromarray(image).save(path)
        return FrameVerdict(0)
    results = Path(results_dir) if results_dir else Path(golden_dir) / "results"
    as16 = (lambda a: a.astype(np.uint16) * 257) if not sixteen else (lambda a: a)
    if not path.is_file():
        Image.fromarray(image if not sixteen else (image // 257).astype(np.uint8)).save(
            _mkdir(results / name) / "new.png")
        raise AssertionError(f"golden image {path} is missing (it is never made silently); the current image is "
                             f"{results / name / 'new.png'}: run pytest --update-goldens to make it, then look at it")
    golden = read_png16(path)[..., :3] if sixteen else np.asarray(Image.open(path).convert("RGB"))
    verdict = FrameVerdict(0)
    tol = tolerance or ImageTolerance()
    judge_image(verdict, as16(golden), as16(image[..., :3]), tol)
    if verdict.status == FAIL:
        report = Report(results)
        report.add(name, path, [verdict], {0: (as16(golden), as16(image[..., :3]))}, [], tol.fail)
        report.write()
        raise AssertionError(f"{name}: differs from {path}: " + "; ".join(verdict.reasons)
                             + f" (report: {results / 'report.html'})")
    return verdict


def _mkdir(p: Path) -> Path:
    p.mkdir(parents=True, exist_ok=True)
    return p


def pytest_addoption(parser) -> None:
    parser.addoption("--update-goldens", action="store_true", default=False,
                     help="rewrite golden images (fraytool.testing, tests/golden) instead of comparing with them")


@pytest.fixture
def update_goldens(request) -> bool:
    """True under `pytest --update-goldens`."""
    return bool(request.config.getoption("--update-goldens"))


@pytest.fixture
def golden(update_goldens, tmp_path_factory):
    """golden(scene, golden_dir, frames=None, sets=()): assert_matches_golden with --update-goldens honoured
    (frames simulated in a temporary folder)."""
    work = tmp_path_factory.mktemp("fraytool-golden")

    def check(scene, golden_dir, frames=None, sets=()):
        return assert_matches_golden(scene, golden_dir, frames=frames, sets=sets, update=update_goldens,
                                     work_dir=work)

    return check
