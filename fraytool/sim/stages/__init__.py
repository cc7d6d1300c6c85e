"""Solver stages: one small protocol for every pass of the step (docs/method.md §4).

A stage is an object with
- ``name``: its place in the step and its timing bucket (one of ``STAGE_NAMES``, in step order);
- ``kernel``: the name the stability guard reports when the stage produced a bad value;
- ``reads`` / ``writes``: what it touches (the names in fraytool.sim.stages.base: positions, forces,
  topology, the coarse model's views of its slaved crossings, ...);
- ``run(state, ctx, dt_s)``: advance ``state`` in place, reading and writing the step context ``ctx``
  (StepContext: start-of-step positions, forces, particle lists, the coarse model's work lists, the
  yarn-level model, counters);
- ``summary(state) -> dict``: figures for ``fraytool simulate --json`` (empty when it has none).

``build_stages(model, ...)`` makes exactly the stages a model needs, in the paper's order (with one
addition: a scene that tears and has a colliding body also runs rigid contact before strain limiting,
docs/tearing.md "Contact with bodies before the strain limit"), then ``plan_syncs`` inserts, from the
declarations alone, the syncs a coarse base model needs. The optional stages (yarn contact and
tearing, self-collision, multi-resolution) are imported only when the model uses them, so a scene pays
only for what it uses and their numba kernels are never compiled otherwise.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from fraytool.kinds import STITCH
from fraytool.sim.model import Model
from fraytool.sim.stages.base import (COARSE_VIEWS, HANGING, SLAVED, SLAVED_NEAR_HOT, STAGE_NAMES, STALES_VIEWS,
                                      HookStage, Stage, StepContext, StepCounters)

__all__ = ["STAGE_NAMES", "HookStage", "Stage", "StepContext", "StepCounters", "StepPlan", "build_stages",
           "plan_syncs"]


@dataclass(eq=False)
class StepPlan:
    """The stages a model declares, in step order (before syncs), and the handles tools read."""

    stages: list
    """The model's stages in step order, without the coarse syncs (plan_syncs adds them)."""
    self_collision: Optional[Stage] = None
    """The self-collision stage (its counters and settings, for tools and tests), else None."""


def contact_kinds(model: Model) -> tuple[bool, bool]:
    """(a colliding analytic body, a colliding mesh body): which contact passes the scene pays for."""
    from fraytool.kinds import SHAPE_MESH

    collide = model.body_collide if model.body_count else np.zeros(0, bool)
    mesh = model.body_shape == SHAPE_MESH
    return bool((collide & ~mesh).any()), bool((collide & mesh).any())


def build_stages(model: Model, speed_limit_m_s: float, ctx: StepContext) -> StepPlan:
    """The stages of one step for `model`, in the order of docs/method.md §4 (and its one departure);
    sets the parts of `ctx` the stages share (the coarse model's work lists, the yarn-level model)."""
    from fraytool.sim.stages import core

    coarse = model.coarse_factor > 1
    if coarse:
        from fraytool.sim.stages import multires  # only multi-resolution scenes

        ctx.coarse = multires.CoarseWork(model)
        stages: list = [multires.MultiresForces(model)]
    else:
        stages = [core.SpringForces(model)]
    if model.panel_drag_normal.size:
        from fraytool.sim.stages.air import AirDrag  # only scenes with air drag

        stages.append(AirDrag(model))
    if model.spring_sew_s.size:
        from fraytool.sim.stages.seams import Sewing  # only scenes with a seam sewn over time

        stages.insert(0, Sewing(model))
    stages.append(core.VelocityUpdate(model))
    if model.damping > 0.0:
        stages.append(core.Damping(model))
    stages.append(core.PositionUpdate(model))
    if model.attachment_count > 0:
        stages.append(core.Attachments(model))
    analytic, meshes = contact_kinds(model)
    contact = analytic or meshes
    geometry = None
    if meshes:
        from fraytool.sim.mesh_geometry import MeshGeometry
        from fraytool.sim.stages import mesh_contact  # only scenes with mesh bodies

        geometry = ctx.meshes = MeshGeometry(model)
    if contact and model.tearing:
        if analytic:
            stages.append(core.RigidContactBeforeLimit(model))  # the limit sees a body's push before breaks
        if meshes:
            stages.append(mesh_contact.MeshContactBeforeLimit(model, geometry, after_analytic=analytic))
    stages.append(core.StrainLimiting(model))
    tearing_stage = None
    if model.tearing:
        from fraytool.sim.stages.tearing import TearingStage, YarnContactStage  # only scenes that tear
        from fraytool.sim.tearing import YarnTearing

        ctx.yarn_tearing = YarnTearing(model, meshes=geometry)
        if ctx.yarn_tearing.yarn_level:
            stages.append(YarnContactStage())
        tearing_stage = TearingStage()
    if contact:
        if analytic:
            stages.append(core.RigidContact(model))
        if meshes:
            stages.append(mesh_contact.MeshContact(model, geometry, after_analytic=analytic))
        if coarse and analytic:
            stages.append(multires.SlavedContact(model))
    self_collision = None
    if model.self_collision:
        from fraytool.sim.stages.self_collision import SelfCollision  # only scenes with self-collision

        self_collision = SelfCollision(model)
        stages.append(self_collision)
    if coarse:
        stages.append(multires.Refinement(model))
    if tearing_stage is not None:
        stages.append(tearing_stage)
    if (model.spring_kind == STITCH).any():
        from fraytool.sim.stages.seams import StitchBreaking  # only scenes with seams

        stages.append(StitchBreaking(model))
    stages.append(core.VelocityPostProcess(model, speed_limit_m_s))
    return StepPlan(stages, self_collision)


def _covers(view: str) -> tuple:
    """The views a sync of `view` brings up to date (every slaved crossing covers the others)."""
    return (SLAVED, HANGING, SLAVED_NEAR_HOT) if view == SLAVED else (view,)


def _walk(stages: list, fresh: set, sync_factory) -> tuple[list, set]:
    out: list = []
    for stage in stages:
        need = [v for v in COARSE_VIEWS if v in stage.reads and v not in fresh]
        if SLAVED in need:
            need = [SLAVED]
        if need:
            out.append(sync_factory(tuple(need), stage.name))
            for v in need:
                fresh.update(_covers(v))
        out.append(stage)
        if stage.writes & set(STALES_VIEWS):
            fresh = set()
    return out, fresh


def plan_syncs(stages: list, ctx: StepContext) -> list:
    """`stages` with a coarse sync (fraytool.sim.stages.multires.CoarseSync) before every stage that
    reads a view of the slaved crossings (``reads`` holds HANGING, SLAVED or SLAVED_NEAR_HOT) which a
    stage since the last sync left out of date (``writes`` holds positions, start positions or
    topology). The step repeats, so the walk starts from what the previous step left: every view is
    up to date after the solver's completion call, and after a step what the last writer left. No
    coarse model: the stages as they are."""
    if ctx.coarse is None:
        return list(stages)
    from fraytool.sim.stages.multires import CoarseSync

    _, after_step = _walk(stages, set(COARSE_VIEWS), CoarseSync)
    planned, _ = _walk(stages, after_step, CoarseSync)
    return planned
