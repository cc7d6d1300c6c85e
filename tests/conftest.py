"""Shared pytest set-up.

- `--update-goldens` (from the fraytool.testing plugin): rewrite the golden images in tests/golden/
  instead of comparing with them (tests/test_render_golden.py, tests/test_golden.py). A missing golden
  fails without it; it is never created silently.
- `gl_ctx`: the one OpenGL context of the test session, made by fraytool's own factory
  (fraytool.render.context.create_context). This is the only place tests create a context; every
  test that uses it is checked for a clean GL error state afterwards.
- Synthetic frames for the renderer: the model of a small scene, posed analytically (flat, draped
  over a ball, torn with yarn-level crossings and cut springs). Tearing is simulated
  (fraytool.sim.tearing), but the renderer is pinned independently of the solver: its tests pose
  frames themselves, so a rendering test knows exactly what it draws and a change to the solver or
  the tearing model cannot move a golden image.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

TESTS = Path(__file__).resolve().parent
GOLDEN_SCENE = TESTS / "scenes" / "golden_small.toml"


UNDECLARED = ("scipy",)
"""Packages that fraytool does not declare but that its libraries use when they find them: numba runs
`@`, np.dot and np.linalg in a kernel through scipy's BLAS. A developer's machine often has them; a clean
install does not. The suite hides them (an import raises ImportError, as in a clean venv), so that a
kernel needing one fails here and not first for a new user (tests/test_scenes.py checks it is hidden)."""


class _HideUndeclared:
    """A meta-path finder that refuses UNDECLARED packages and their submodules."""

    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in UNDECLARED:
            raise ModuleNotFoundError(f"No module named {name!r} (hidden by tests/conftest.py: fraytool does "
                                      "not declare it)", name=name)
        return None


def _hide_undeclared():
    import sys

    loaded = sorted(m for m in sys.modules if m.split(".")[0] in UNDECLARED)
    assert not loaded, f"imported before tests/conftest.py could hide them: {loaded}"
    sys.meta_path.insert(0, _HideUndeclared())


_hide_undeclared()

pytest_plugins = ["fraytool.testing"]
"""fraytool's golden-test plugin, as a studio's suite uses it: the --update-goldens option and the
`update_goldens` and `golden` fixtures (docs/golden.md)."""


def pytest_addoption(parser):
    parser.addoption("--update-figures", action="store_true", default=False,
                     help="rewrite the pinned figures in tests/figures/ from the current simulation")


@pytest.fixture(scope="session")
def _gl_session():
    from fraytool.errors import RunError
    from fraytool.render.context import create_context

    try:
        ctx = create_context()
    except RunError as exc:  # the system packages are missing: say which, in one line
        pytest.fail("no headless OpenGL context: install EGL and Mesa (apt-get install libegl1 libegl-mesa0 "
                    f"libgl1-mesa-dri, README Set up): {str(exc).splitlines()[0]}", pytrace=False)
    yield ctx
    ctx.release()


@pytest.fixture
def gl_ctx(_gl_session):
    """The session's GL context; the test fails if it leaves a GL error behind."""
    ctx = _gl_session
    yield ctx
    assert ctx.error == "GL_NO_ERROR", f"GL error state after the test: {ctx.error}"


# -- synthetic frames ----------------------------------------------------------------------------

class PosedCloth:
    """A built scene and helpers to pose its frame records by hand."""

    def __init__(self, scene_path: Path):
        from fraytool.scene import load_scene
        from fraytool.sim.builder import build_model
        from fraytool.sim.record import frame_record

        self.spec = load_scene(scene_path)
        self.model = build_model(self.spec)
        self.topology = self.model.arrays()
        self.rest = frame_record(self.model, self.model.state(), 0)
        self.W = self.model.warp_yarns
        self.H = self.model.weft_yarns
        self.C = self.model.crossing_count

    def copy(self, frame: int = 0):
        r = self.rest
        return replace(r, frame=frame, particle_position_m=r.particle_position_m.copy(),
                       particle_active=r.particle_active.copy(), crossing_yarn_level=r.crossing_yarn_level.copy(),
                       spring_particle_a=r.spring_particle_a.copy(), spring_particle_b=r.spring_particle_b.copy(),
                       spring_alive=r.spring_alive.copy(), body_position_m=r.body_position_m.copy(),
                       body_rotation=r.body_rotation.copy())

    def crossing(self, i: int, j: int) -> int:
        return j * self.W + i

    def draped(self, frame: int = 1):
        """Crossings pushed out of the ball and sagging beyond it (a smooth, drape-like pose)."""
        rec = self.copy(frame)
        x = rec.particle_position_m[: self.C].astype(np.float64)
        centre = self.model.body_initial_position_m[0]
        radius = float(self.model.body_params[0, 0]) + 0.6 * self.model.thickness_m
        d = x - centre
        horiz = np.hypot(d[:, 0], d[:, 2])
        on_ball = horiz < radius
        y_surface = centre[1] + np.sqrt(np.maximum(radius ** 2 - horiz ** 2, 0.0))
        y = np.where(on_ball, y_surface, centre[1] - 0.9 * (horiz - radius) + 0.0)
        ground = self.spec.render.ground_height_m + self.model.thickness_m
        x[:, 1] = np.maximum(np.minimum(x[:, 1], y), ground)
        rec.particle_position_m[: self.C] = x
        rec.particle_position_m[self.C:] = x
        return rec

    def multires_border(self, frame: int = 3):
        """A smooth bump (the cloth lifted by a Gaussian, the ball put away below the ground) as the
        multi-resolution model ([cloth.multires] factor = 4) shows it with only the centre cell
        (crossings 4-8 each way) refined: crossings there keep the bump; every other crossing lies on
        the bilinear interpolation of its cell's four nodes (fraytool.sim.multires), so the border
        between the refined cell and its coarse neighbours is in the picture."""
        from fraytool.sim import multires
        from fraytool.sim.builder import build_model

        cloth = replace(self.spec.cloth, multires=replace(self.spec.cloth.multires, factor=4))
        layout = multires.coarse_layout(build_model(replace(self.spec, cloth=cloth)))
        refined = np.zeros(layout.cell_count, bool)
        refined[layout.cell_count // 2] = True  # the centre cell of 3 x 3
        rec = self.copy(frame)
        x = rec.particle_position_m[: self.C].astype(np.float64)
        centre = x.mean(axis=0)
        r2 = (x[:, 0] - centre[0]) ** 2 + (x[:, 2] - centre[2]) ** 2
        x[:, 1] += 0.04 * np.exp(-r2 / (2 * 0.03 ** 2))
        rec.body_position_m[0] = (0.0, -1.0, 0.0)  # the ball out of sight
        multires.interpolate_slaved(layout, multires.free_crossings(layout, refined), x)
        rec.particle_position_m[: self.C] = x
        rec.particle_position_m[self.C:] = x
        return rec

    def torn(self, frame: int = 2):
        """The draped pose with a tear: weft springs cut across a column, the crossings beside the
        cut at yarn level with their weft and warp masses apart and the cut ends pulled open."""
        from fraytool.grid import base_yarn_points, crossing_normals

        rec = self.draped(frame)
        W, H, C = self.W, self.H, self.C
        cut_i = W // 2 - 1                       # weft springs between crossings cut_i and cut_i+1
        rows = range(2, H - 3)
        for j in rows:
            rec.spring_alive[self.topology["weft_structural_spring"][j, cut_i]] = False
        # warp springs cut along one row, making a T-shaped tear
        for i in range(cut_i + 1, W - 2):
            rec.spring_alive[self.topology["warp_structural_spring"][i, 3]] = False
        x = rec.particle_position_m[:C].astype(np.float64)
        n = crossing_normals(x, W, H)
        weft, warp = base_yarn_points(x, n, self.topology["crossing_weft_on_top"], self.model.thickness_m)
        for j in rows:
            for i, side in ((cut_i - 1, -1.0), (cut_i, -1.0), (cut_i + 1, 1.0), (cut_i + 2, 1.0)):
                c = self.crossing(i, j)
                rec.crossing_yarn_level[c] = True
                rec.particle_active[C + c] = True
                pull = np.array([side * 0.004 * (2 if i in (cut_i, cut_i + 1) else 1), 0.0, 0.0])
                rec.particle_position_m[c] = weft[c] + pull
                rec.particle_position_m[C + c] = warp[c] + 0.3 * pull
        # structural springs of yarn-level crossings end on the couple's masses
        from fraytool.kinds import BEND_WARP, STRUCT_WARP

        kind = self.topology["spring_kind"]
        level = rec.crossing_yarn_level
        ca, cb = self.topology["spring_crossing_a"], self.topology["spring_crossing_b"]
        for ends, cross in ((rec.spring_particle_a, ca), (rec.spring_particle_b, cb)):
            warp_spring = np.isin(kind, (STRUCT_WARP, BEND_WARP)) & level[cross]
            ends[warp_spring] = C + cross[warp_spring]
        return rec


@pytest.fixture(scope="session")
def posed_cloth() -> PosedCloth:
    return PosedCloth(GOLDEN_SCENE)
