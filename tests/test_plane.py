"""[cloth] plane: the weft runs along the first letter's axis, the warp along the second (docs/scene-format.md),
for each of the three planes."""
import numpy as np
import pytest

from fraytool.scene import parse_scene
from fraytool.sim.builder import build_model

pytestmark = pytest.mark.fast  # `pytest -m fast` (docs/testing.md)

SCENE = """
[time]
step_s = 0.0002
steps_per_frame = 2
frames = 2
[cloth]
warp_yarns = 3
weft_yarns = 4
spacing_m = 0.01
thickness_m = 0.0008
mass_per_crossing_kg = 2e-5
plane = "{plane}"
origin_m = [0.1, 0.2, 0.3]
[cloth.springs]
structural_n_per_m = 20.0
"""


@pytest.mark.parametrize("plane", ["xz", "xy", "yz"])
def test_the_weft_runs_along_the_first_letter_and_the_warp_along_the_second(plane):
    model = build_model(parse_scene(SCENE.format(plane=plane), "plane.toml"))
    rest = model.crossing_rest_position_m
    axis = {"x": np.array([1.0, 0, 0]), "y": np.array([0, 1.0, 0]), "z": np.array([0, 0, 1.0])}
    weft = model.weft_structural_spring[0, 0]  # joins (i, j) and (i + 1, j): along a weft yarn
    warp = model.warp_structural_spring[0, 0]  # joins (i, j) and (i, j + 1): along a warp yarn
    along_weft = rest[model.spring_crossing_b[weft]] - rest[model.spring_crossing_a[weft]]
    along_warp = rest[model.spring_crossing_b[warp]] - rest[model.spring_crossing_a[warp]]
    np.testing.assert_allclose(along_weft, 0.01 * axis[plane[0]], atol=1e-15)
    np.testing.assert_allclose(along_warp, 0.01 * axis[plane[1]], atol=1e-15)
    np.testing.assert_allclose(rest.min(axis=0), [0.1, 0.2, 0.3], atol=1e-15)  # from origin_m, in the plane

