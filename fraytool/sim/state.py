"""State: everything a step changes. A State snapshot captures positions and the tear.

Tearing changes topology without resizing arrays: particles and springs have alive/active flags,
and a split re-points spring ends (spring_particle_a/b) from the base slot to a couple mass.

`topology_epoch` is the one change counter of the topology: every pass that changes it (split, cut,
disconnect, refine) calls `bump_topology`, and every cache derived from the topology (particle lists,
pieces, couple lists, the coarse model's work lists) is keyed on it. Epochs are drawn from one counter
per process, so two states with the same epoch have the same topology (a copy keeps its original's
epoch; a state loaded from arrays gets a new one). Code that edits masses, flags or spring ends by
hand calls `bump_topology` after it.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field, fields

import numpy as np

_EPOCHS = itertools.count(1)


def new_topology_epoch() -> int:
    """An epoch no state of this process has had."""
    return next(_EPOCHS)



@dataclass(eq=False)
class State:
    time_s: float
    step_index: int
    particle_position_m: np.ndarray
    """Shape (particle_count, 3), float64."""
    particle_velocity_m_s: np.ndarray
    """Shape (particle_count, 3), float64."""
    particle_mass_kg: np.ndarray
    """Shape (particle_count,), float64; 0 for inactive slots."""
    particle_inv_mass: np.ndarray
    """1/mass [1/kg] for free particles; 0 for inactive and attached ones. Shape (particle_count,)."""
    particle_active: np.ndarray
    """Shape (particle_count,), bool."""
    crossing_yarn_level: np.ndarray
    """True once a crossing has split into a weft/warp mass couple, shape (crossing_count,), bool."""
    couple_connected: np.ndarray
    """A split crossing whose weft and warp are still in contact, shape (crossing_count,), bool."""
    spring_particle_a: np.ndarray
    """Particle at end a, shape (spring_count,), int32."""
    spring_particle_b: np.ndarray
    """Shape (spring_count,), int32."""
    spring_alive: np.ndarray
    """Shape (spring_count,), bool."""
    spring_broken: np.ndarray
    """Springs cut because their strain passed their break strain (§4.1), shape (spring_count,), bool."""
    spring_stiffness_n_per_m: np.ndarray
    """Current stiffness [N/m] (shear springs halve on duplication), shape (spring_count,)."""
    spring_rest_length_m: np.ndarray
    """Current rest length [m], shape (spring_count,), float64: the model's, except that a split
    rescales the springs at the crossing so that moving the couple's masses ±T/2 leaves every
    spring's strain as it was (docs/tearing.md "Split")."""
    body_position_m: np.ndarray
    """Shape (body_count, 3), float64."""
    body_velocity_m_s: np.ndarray
    """Shape (body_count, 3), float64."""
    body_rotation: np.ndarray
    """Current orientation (body to world), shape (body_count, 3, 3), float64: the model's at rest, turned
    by a kinematic body's orientation keys (fraytool.sim.rigid)."""
    body_angular_velocity_rad_s: np.ndarray
    """World-frame angular velocity over the last step [rad/s], shape (body_count, 3), float64; zero for a
    body that does not turn."""
    coarse_cell_refined: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    """Multi-resolution model ([cloth.multires] factor > 1): the coarse cells refined to yarn resolution
    so far, shape (cell_count,), bool (fraytool.sim.multires); empty at yarn resolution everywhere."""
    attachment_offset_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """Held masses' offsets in their body's frame [m] as caught (Model.attachment_catch_s), shape (attachments, 3);
    empty where every attachment holds from the start (the Model's offsets hold)."""
    topology_epoch: int = field(default_factory=new_topology_epoch)
    """The topology's change counter (module docstring): not saved, a loaded state gets a new one."""

    def bump_topology(self) -> None:
        """Record a change of topology (springs, couples, cells, masses or active flags)."""
        self.topology_epoch = new_topology_epoch()

    def copy(self) -> "State":
        kw = {f.name: (getattr(self, f.name).copy() if isinstance(getattr(self, f.name), np.ndarray)
                       else getattr(self, f.name)) for f in fields(self)}
        return State(**kw)

    def arrays(self) -> dict[str, np.ndarray]:
        """Every saved field as an array (full precision), for checkpoints (not the topology epoch)."""
        return {f.name: np.asarray(getattr(self, f.name)) for f in fields(self) if f.name != "topology_epoch"}

    @staticmethod
    def from_arrays(data, rest_rotation=None) -> "State":
        """The State of `arrays()`. A checkpoint from before turning bodies has no body_rotation: the
        bodies' orientations at rest (Model.body_rotation) are given as `rest_rotation` (required then),
        their angular velocity is zero."""
        kw = {}
        for f in fields(State):
            if f.name == "topology_epoch":
                continue  # not saved: a new one
            if f.name in ("coarse_cell_refined", "attachment_offset_m") and f.name not in data:
                continue  # a checkpoint from before the feature: the default (empty)
            if f.name == "body_rotation" and f.name not in data:
                if rest_rotation is None:
                    raise KeyError("body_rotation (a checkpoint from before turning bodies needs rest_rotation)")
                kw[f.name] = np.array(rest_rotation, dtype=np.float64)
                continue
            if f.name == "body_angular_velocity_rad_s" and f.name not in data:
                kw[f.name] = np.zeros((np.asarray(data["body_position_m"]).shape[0], 3))
                continue
            v = np.asarray(data[f.name])
            if f.name == "time_s":
                kw[f.name] = float(v)
            elif f.name == "step_index":
                kw[f.name] = int(v)
            else:
                kw[f.name] = v.copy()
        return State(**kw)
