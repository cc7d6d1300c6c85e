"""Pinned figures of every shipped scene (tests/pinned_figures.py, tests/figures/*.json): what a run of
it does, in numbers, compared with the pinned values within tolerances named in pinned_figures.py and
measured per scene when the file was written (how far a last-bit perturbation carries: the tear of
fig7 is chaotic, the stiff stress scenes are not). Regenerate with
`pytest tests/test_pinned_figures.py --update-figures` and review the diff of tests/figures/."""
from __future__ import annotations

import pytest

from pinned_figures import pin, position_rms_spacings, read_figures, run_figures, shipped_scenes


@pytest.mark.parametrize("scene", shipped_scenes())
def test_a_shipped_scene_does_what_it_did(scene, request):
    if request.config.getoption("--update-figures"):
        pin(scene)
    pinned = read_figures(scene)
    tol = pinned["tolerance"]
    now = run_figures(scene)
    if "unstable_step" in pinned:
        assert abs(now.get("unstable_step", -10 ** 9) - pinned["unstable_step"]) <= tol["unstable_step"]
        return
    assert "unstable_step" not in now, f"{scene} stopped unstable at step {now['unstable_step']}"
    wrong = []
    for key, value in pinned["figures"].items():
        got = now["figures"][key]
        if abs(got - value) > tol["figures"][key]:
            wrong.append(f"{key}: {got} (pinned {value} +- {tol['figures'][key]:.3g})")
    for frame, pts in pinned["positions_m"].items():
        rms = position_rms_spacings(pts, now["positions_m"][frame], pinned["spacing_m"])
        if rms > tol["positions_rms_spacings"][frame]:
            wrong.append(f"positions at frame {frame}: {rms:.3g} spacings RMS from the pinned ones "
                         f"(tolerance {tol['positions_rms_spacings'][frame]:.3g})")
    assert not wrong, f"{scene}: " + "; ".join(wrong)
