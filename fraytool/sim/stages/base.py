"""The stage protocol and the scratch buffers a step's stages share (see fraytool.sim.stages)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np

from fraytool.sim.kernels.work_split import ParticleLists
from fraytool.sim.model import Model
from fraytool.sim.state import State

STAGE_NAMES = ("forces", "integration", "damping", "contact_before_limit", "strain_limiting", "yarn_contact",
               "collisions", "self_collision", "refinement", "tearing")
"""Timing buckets, in step order (the velocity updates all count as "integration")."""


@dataclass(eq=False)
class StepBuffers:
    """Scratch arrays one step's stages share (never saved: a step rebuilds them)."""

    prev_position_m: np.ndarray
    """Positions at the start of the step [m], shape (particle_count, 3), float64."""
    force_n: np.ndarray
    """Spring forces of the step [N], shape (particle_count, 3), float64."""
    body_impulse_n_s: np.ndarray
    """Impulse the cloth received from each body in the last rigid-contact pass [N s], shape (body_count, 3),
    float64 (a scene that tears with a colliding body has two passes per step, each applied on its own)."""
    lists: ParticleLists
    """The free and the moving particles, listed for the per-particle kernels (fraytool.sim.kernels.work_split)."""
    bad_particle: int = -1
    """Set by the velocity post-process: a particle found non-finite or too fast, else -1."""

    @staticmethod
    def for_model(model: Model) -> "StepBuffers":
        return StepBuffers(np.zeros((model.particle_count, 3)), np.zeros((model.particle_count, 3)),
                           np.zeros((model.body_count, 3)), ParticleLists())


class Stage(Protocol):
    name: str
    kernel: str

    def run(self, state: State, buffers: StepBuffers, dt_s: float) -> None: ...

    def summary(self, state: State) -> dict: ...


@dataclass(eq=False)
class HookStage:
    """A plain function `fn(state, prev_position_m, dt_s)` run as a stage (for tools and tests that
    plug a pass into the step; see SolverExplicitPBD.insert_stage)."""

    name: str
    fn: Callable[[State, np.ndarray, float], None]
    kernel: str = field(default="")

    def __post_init__(self) -> None:
        self.kernel = self.kernel or getattr(self.fn, "__name__", type(self.fn).__name__)

    def run(self, state: State, buffers: StepBuffers, dt_s: float) -> None:
        self.fn(state, buffers.prev_position_m, dt_s)

    def summary(self, state: State) -> dict:
        return {}
