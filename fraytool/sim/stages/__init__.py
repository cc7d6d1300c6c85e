"""Solver stages: one small protocol for every pass of the step (docs/method.md §4).

A stage is an object with
- ``name``: its place in the step and its timing bucket (one of ``STAGE_NAMES``, in step order);
- ``kernel``: the name the stability guard reports when the stage produced a bad value;
- ``run(state, buffers, dt_s)``: advance ``state`` in place, reading and writing the step's scratch
  ``buffers`` (start-of-step positions, forces, body impulses);
- ``summary(state) -> dict``: figures for ``fraytool simulate --json`` (empty when it has none).

``build_stages(model)`` makes exactly the stages a model needs, in the paper's order (with one
addition: a scene that tears and has a colliding body also runs rigid contact before strain limiting,
docs/tearing.md "Contact with bodies before the strain limit"); the optional
ones (yarn contact and tearing, self-collision) are imported only when the model uses them, so a
scene pays only for what it uses and their numba kernels are never compiled otherwise.
"""
from __future__ import annotations

from fraytool.sim.model import Model
from fraytool.sim.stages.base import STAGE_NAMES, HookStage, Stage, StepBuffers

__all__ = ["STAGE_NAMES", "HookStage", "Stage", "StepBuffers", "build_stages"]


def build_stages(model: Model, speed_limit_m_s: float) -> list:
    """The stages of one step for `model`, in the order of docs/method.md §4 (and its one departure)."""
    from fraytool.sim.stages import core

    runtime = None
    if model.coarse_factor > 1:
        from fraytool.sim.stages import multires  # only multi-resolution scenes

        runtime = multires.MultiresRuntime(model)
        stages: list = [multires.MultiresForces(model, runtime)]
    else:
        stages = [core.SpringForces(model)]
    stages.append(core.VelocityUpdate(model))
    if model.damping > 0.0:
        stages.append(core.Damping(model))
    stages.append(core.PositionUpdate(model))
    if runtime is not None:
        stages.append(multires.SyncSlaved(runtime, "integration", hanging_only=True))
    if model.attachment_count > 0:
        stages.append(core.Attachments(model))
    contact = model.body_count > 0 and bool(model.body_collide.any())
    if contact and model.tearing:
        stages.append(core.RigidContactBeforeLimit(model))  # the limit sees a body's push before breaks
    strain = core.StrainLimiting(model)
    stages.append(strain)
    if runtime is not None:
        runtime.strain_stage = strain  # limits only the springs of refined cells
    tearing = None
    if model.tearing:
        from fraytool.sim.stages.tearing import TearingStage, YarnContactStage  # only scenes that tear

        tearing = TearingStage(model)
        if runtime is not None:
            runtime.tearing = tearing.tearing  # scans only the springs of refined cells
        if tearing.yarn_level:
            stages.append(YarnContactStage(tearing.tearing))
    if contact:
        stages.append(core.RigidContact(model))
        if runtime is not None:
            stages.append(multires.SlavedContact(model, runtime))
    if model.self_collision:
        from fraytool.sim.stages.self_collision import SelfCollision  # only scenes with self-collision

        if runtime is not None:
            stages.append(multires.SyncSlaved(runtime, "self_collision", hanging_only=False))
        stages.append(SelfCollision(model))
    if runtime is not None:
        stages.append(multires.Refinement(model, runtime))
    if tearing is not None:
        stages.append(tearing)
    stages.append(core.VelocityPostProcess(model, speed_limit_m_s))
    return stages
