"""Every scene in scenes/ loads and runs a few frames with finite positions; and each passes its
own [checks] (scenes carry their own checks)."""
from pathlib import Path

import numpy as np
import pytest

from fraytool.resources import scenes_dir
from fraytool.scene import load_scene
from fraytool.sim.checks import run_scene_checks
from fraytool.sim import Simulation

ROOT = Path(__file__).resolve().parent.parent
SCENES = sorted((ROOT / "scenes").rglob("*.toml"))


def test_scenes_folder_is_the_shipped_one():
    assert SCENES, "no scenes found"
    assert scenes_dir().resolve() == (ROOT / "scenes").resolve()


@pytest.mark.parametrize("path", SCENES, ids=lambda p: str(p.relative_to(ROOT / "scenes")))
def test_scene_runs_a_few_frames(path):
    spec = load_scene(path)
    sim = Simulation(spec)
    for record in sim.frames(3):
        assert np.isfinite(record.particle_position_m).all()
    assert sim.frame == 2


def test_the_scenes_run_without_the_packages_fraytool_does_not_declare():
    """tests/conftest.py hides scipy (numba's BLAS for `@` in a kernel), so the runs above are a clean
    install's: a mesh scene whose kernel used `@` died there with "scipy 0.16+ is required"."""
    with pytest.raises(ImportError):
        import scipy  # noqa: F401
    assert "mannequin_snag.toml" in {p.name for p in SCENES}


MAIN_SCENES = sorted((ROOT / "scenes").glob("*.toml"))


@pytest.mark.parametrize("path", MAIN_SCENES, ids=lambda p: p.stem)
def test_scene_passes_its_own_checks(path):
    result = run_scene_checks(load_scene(path))
    failed = {k: v for k, v in result["results"].items() if not v["passed"]}
    assert result["passed"], f"{path.name}: failed checks {failed}"
    assert result["results"], "a scene must state at least one check"
