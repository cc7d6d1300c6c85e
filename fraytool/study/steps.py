"""Step-size variants of a scene for the studies: a scene at a fraction of its step, at a number of
frames, and the names of the step sizes (shared by the accuracy and the tearing studies)."""
from __future__ import annotations

import dataclasses as dc

from fraytool.scene.spec import SceneSpec

TEAR_STEP_FACTORS = (1.0, 0.5, 0.25, 0.125, 0.0625)
"""Steps of the tearing study as multiples of the scene's: h0, h0/2, h0/4, h0/8 (reference), h0/16 (check)."""
TEAR_REFERENCE_FACTOR = 0.125
"""The tearing study's reference step: h0/8."""


def with_frames(spec: SceneSpec, frames: int) -> SceneSpec:
    return dc.replace(spec, time=dc.replace(spec.time, frames=frames + 1))


def with_step_factor(spec: SceneSpec, factor: float) -> SceneSpec:
    """Step h0 * factor with the same simulated time per frame and the same damping per second."""
    t = spec.time
    spf = t.steps_per_frame / factor
    if abs(spf - round(spf)) > 1e-9 or round(spf) < 1:
        raise ValueError(f"step factor {factor:g} gives {spf:g} steps per frame (not a whole number)")
    k0 = spec.cloth.springs.damping
    damping = k0 if factor == 1.0 or k0 >= 1.0 else 1.0 - (1.0 - k0) ** factor
    springs = dc.replace(spec.cloth.springs, damping=damping)
    return dc.replace(spec, time=dc.replace(t, step_s=t.step_s * factor, steps_per_frame=int(round(spf))),
                      cloth=dc.replace(spec.cloth, springs=springs))


def with_seed(spec: SceneSpec, seed: int) -> SceneSpec:
    """The scene drawn from another seed (break limits)."""
    return dc.replace(spec, scene=dc.replace(spec.scene, seed=int(seed)))


def step_label(factor: float) -> str:
    if factor >= 1:
        return "h0" if factor == 1 else f"{factor:g} h0"
    return f"h0/{round(1 / factor):d}"
