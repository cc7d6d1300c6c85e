"""The shipped figure to dress (scenes/assets/figure, made by tools/make_figure.py): a closed mesh of a few
thousand triangles with a torso, arms and legs, animated over 60 files, that the tool regenerates bit for bit."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from fraytool.scene import mesh_files

ROOT = Path(__file__).resolve().parent.parent
FIGURE = ROOT / "scenes" / "assets" / "figure"


def test_the_figure_is_a_closed_animated_sequence_of_a_half_metre_figure():
    asset = mesh_files.read_asset(FIGURE / "figure.####.obj", "", 1.0 / 24.0)
    assert asset.closed
    assert asset.key_vertices.shape[0] == 60 and 1000 <= asset.triangles.shape[0] <= 5000
    rest, raised = asset.key_vertices[0], asset.key_vertices[47]
    assert abs(rest[:, 1].min()) < 1e-3 and 0.45 < rest[:, 1].max() < 0.55  # standing on y = 0, 0.5 m tall
    # the arms rise sideways: the figure is wider with them up than down
    assert np.ptp(raised[:, 0]) > np.ptp(rest[:, 0]) + 0.05
    np.testing.assert_array_equal(asset.key_vertices[0], asset.key_vertices[11])  # frames 1-12 stand still


def test_the_tool_writes_the_shipped_files_again(tmp_path):
    run = subprocess.run([sys.executable, str(ROOT / "tools" / "make_figure.py"), "--out", str(tmp_path)],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    for name in ("figure.0001.obj", "figure.0030.obj", "figure.0060.obj"):
        assert (tmp_path / name).read_bytes() == (FIGURE / name).read_bytes(), name
