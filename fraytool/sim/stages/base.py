"""The stage protocol, the step context the stages share, and the names of what they read and write.

A stage reads and writes the State and one StepContext; it never holds another stage. What it touches
is declared in `reads` and `writes` (sets of the names below), and `build_stages` orders the stages and
inserts the syncs the coarse base model needs from those declarations (fraytool.sim.stages).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Optional, Protocol

import numpy as np

from fraytool.sim.kernels.work_split import ParticleLists
from fraytool.sim.model import Model
from fraytool.sim.state import State

STAGE_NAMES = ("forces", "air", "integration", "damping", "contact_before_limit", "strain_limiting", "yarn_contact",
               "collisions", "self_collision", "refinement", "tearing", "seams")
"""Timing buckets, in step order (the velocity updates all count as "integration")."""

# -- what a stage reads and writes -------------------------------------------------------------
FORCES = "forces"
"""StepContext.force_n."""
VELOCITIES = "velocities"
"""State.particle_velocity_m_s of the free particles."""
POSITIONS = "positions"
"""State.particle_position_m of free particles (coarse nodes among them)."""
START_POSITIONS = "start_positions"
"""StepContext.prev_position_m, the positions at the start of the step."""
BODIES = "bodies"
"""State.body_position_m / body_velocity_m_s / body_rotation / body_angular_velocity_rad_s."""
REST_LENGTHS = "rest_lengths"
"""State.spring_rest_length_m (a seam sewn over time shortens its stitches'; a split rescales the springs at
its crossing)."""
TOPOLOGY = "topology"
"""Which springs, couples and cells exist: spring_alive, couple_connected, crossing_yarn_level,
coarse_cell_refined, masses (a writer bumps State.topology_epoch)."""
HANGING = "hanging_crossings"
"""Slaved crossings that a working fine spring pulls on (hanging nodes), on their cells'
interpolation: positions and start-of-step positions."""
SLAVED = "slaved_crossings"
"""Every slaved crossing on its interpolation (positions and start-of-step positions)."""
SLAVED_NEAR_HOT = "slaved_near_hot"
"""Slaved crossings within the band + 1 cells of a hot cell (a spring past the refine strain) on
their interpolation: the ones a split can read (its couple's normal, its settle's yarn segments)."""

SELF_CONTACT = "self_contact"
"""StepContext.coarse.self_contact: the particles of inverse mass 0 (slaved crossings among them) that
self-collision found within the contact distance of another yarn segment this step."""

COARSE_VIEWS = (SLAVED, HANGING, SLAVED_NEAR_HOT)
"""What the coarse base model brings up to date on demand (a reader declares it; build_stages syncs)."""
STALES_VIEWS = (POSITIONS, START_POSITIONS, TOPOLOGY)
"""A write of any of these leaves every coarse view out of date."""


@dataclass(eq=False)
class StepCounters:
    """Running figures of the step, for `fraytool simulate --json` and the guard's save/restore."""

    stage_s: dict = field(default_factory=lambda: dict.fromkeys(STAGE_NAMES, 0.0))
    """Wall time spent per stage since construction [s]."""
    strain_iterations_last: int = 0
    strain_iterations_max: int = 0
    strain_cap_hits: int = 0
    """Steps where strain limiting stopped at the iteration cap without converging."""
    rigid_contacts_last: int = 0
    """Masses in contact with a body in the last rigid-contact pass."""

    def copy(self) -> "StepCounters":
        return StepCounters(dict(self.stage_s), self.strain_iterations_last, self.strain_iterations_max,
                            self.strain_cap_hits, self.rigid_contacts_last)


@dataclass(eq=False)
class StepContext:
    """What the stages of one solver share: scratch arrays of the step, particle lists, the coarse
    model's work lists, the yarn-level model, counters. Never saved: a step rebuilds what it needs."""

    prev_position_m: np.ndarray
    """Positions at the start of the step [m], shape (particle_count, 3), float64."""
    force_n: np.ndarray
    """Spring forces of the step [N], shape (particle_count, 3), float64."""
    body_impulse_n_s: np.ndarray
    """Impulse the cloth received from each body in the last rigid-contact pass [N s], shape (body_count, 3),
    float64 (a scene that tears with a colliding body has two passes per step, each applied on its own)."""
    lists: ParticleLists
    """The free and the moving particles, listed for the per-particle kernels (fraytool.sim.kernels.work_split)."""
    counters: StepCounters = field(default_factory=StepCounters)
    coarse: Optional[Any] = None
    """The coarse base model's work lists (fraytool.sim.stages.multires.CoarseWork) of a multi-resolution
    model, else None."""
    meshes: Optional[Any] = None
    """The mesh bodies' geometry and trees (fraytool.sim.mesh_geometry.MeshGeometry), in scenes with a
    colliding mesh body."""
    yarn_tearing: Optional[Any] = None
    """The yarn-level model's passes (fraytool.sim.tearing.YarnTearing) of a tearing scene, else None."""
    bad_particle: int = -1
    """Set by the velocity post-process: a particle found non-finite or too fast, else -1."""

    @staticmethod
    def for_model(model: Model) -> "StepContext":
        return StepContext(np.zeros((model.particle_count, 3)), np.zeros((model.particle_count, 3)),
                           np.zeros((model.body_count, 3)), ParticleLists())

    def slaved(self, state: State) -> np.ndarray:
        """The crossings slaved to coarse nodes in `state`, ascending (empty without a coarse model)."""
        if self.coarse is None:
            return np.zeros(0, np.int32)
        return self.coarse.slaved_now(state)

    def working_springs(self, state: State):
        """(mask over spring slots of the structural springs at work, the epoch it was made at), or
        (None, -1) when every spring works (no coarse model)."""
        if self.coarse is None:
            return None, -1
        self.coarse.ensure(state)
        return self.coarse.working, self.coarse.built_at


class Stage(Protocol):
    name: str
    kernel: str
    reads: frozenset
    writes: frozenset

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None: ...

    def summary(self, state: State) -> dict: ...


@dataclass(eq=False)
class HookStage:
    """A plain function `fn(state, prev_position_m, dt_s)` run as a stage (for tools and tests that
    plug a pass into the step; see SolverExplicitPBD.insert_stage). It is taken to read and write
    positions (so a coarse model syncs what later stages read after it)."""

    name: str
    fn: Callable[[State, np.ndarray, float], None]
    kernel: str = field(default="")
    reads: frozenset = frozenset({POSITIONS, START_POSITIONS})
    writes: frozenset = frozenset({POSITIONS})

    def __post_init__(self) -> None:
        self.kernel = self.kernel or getattr(self.fn, "__name__", type(self.fn).__name__)

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None:
        self.fn(state, ctx.prev_position_m, dt_s)

    def summary(self, state: State) -> dict:
        return {}
