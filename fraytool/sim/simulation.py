"""Simulation: the Python API that ties a SceneSpec to Model, State and Solver.

    from fraytool.scene import load_scene
    from fraytool.sim import Simulation

    sim = Simulation(load_scene("scenes/drape.toml"))
    for record in sim.frames(10):          # frame 0 is the initial state
        print(record.frame, record.particle_position_m[:, 1].min())
    print(sim.summary())
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Iterator, Optional

import numpy as np

from fraytool.io.frame_record import FrameRecord
from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from fraytool.scene.spec import SceneSpec
from fraytool.sim.builder import build_model
from fraytool.sim.model import Model
from fraytool.sim.pieces import piece_figures, woven_strain
from fraytool.sim.record import frame_record
from fraytool.sim.solver import SolverExplicitPBD
from fraytool.sim.state import State


@dataclass
class ShotFigures:
    """Figures over the whole shot so far, sampled at every frame (saved with the checkpoint, so a
    resumed run reports the same as an unbroken one)."""

    max_woven_strain: float = 0.0
    """Largest strain over live structural springs between woven crossings (fraytool.sim.pieces)."""
    max_woven_strain_frame: int = 0
    max_woven_strain_spring: int = -1
    small_pieces_max: int = 0
    """Most pieces of fewer than SMALL_PIECE_MASSES masses seen at any frame."""
    small_pieces_first_frame: int = -1
    """First frame with a small piece, -1 if none."""
    strain_cap_hits_before: int = 0
    """Strain-limiting cap hits of the run before a resume."""
    strain_iterations_max_before: int = 0
    """Most strain-limiting sweeps in one step of the run before a resume."""

    def arrays(self) -> dict[str, np.ndarray]:
        return {f"shot_{f.name}": np.asarray(getattr(self, f.name)) for f in fields(self)}

    @staticmethod
    def from_arrays(data) -> "ShotFigures":
        out = ShotFigures()
        for f in fields(ShotFigures):
            key = f"shot_{f.name}"
            if key in data:
                setattr(out, f.name, type(getattr(out, f.name))(np.asarray(data[key])))
        return out


class Simulation:
    """A scene being simulated: model (static), state (current), solver, frame counter."""

    def __init__(self, spec: SceneSpec, model: Optional[Model] = None, state: Optional[State] = None,
                 frame: int = 0):
        self.spec = spec
        self.model = model if model is not None else build_model(spec)
        self.state = state if state is not None else self.model.state()
        self.solver = SolverExplicitPBD(self.model)
        self.frame = frame
        """Index of the frame the current state belongs to."""
        self.dt_s = spec.time.step_s
        self.steps_per_frame = spec.time.steps_per_frame
        self.shot = ShotFigures()
        """Figures over the shot (max woven strain, small pieces), updated at every frame."""
        self._observe()

    def _observe(self) -> None:
        """Update the shot figures with the current state (every frame)."""
        strain, spring = woven_strain(self.model, self.state)
        if strain > self.shot.max_woven_strain:
            self.shot.max_woven_strain = strain
            self.shot.max_woven_strain_frame = self.frame
            self.shot.max_woven_strain_spring = spring
        if self.model.tearing:
            small = piece_figures(self.model, self.state)["small_pieces"]
            if small and self.shot.small_pieces_first_frame < 0:
                self.shot.small_pieces_first_frame = self.frame
            self.shot.small_pieces_max = max(self.shot.small_pieces_max, small)

    def checkpoint_arrays(self) -> dict[str, np.ndarray]:
        """What a checkpoint holds: the State and the shot figures."""
        shot = ShotFigures(**{f.name: getattr(self.shot, f.name) for f in fields(ShotFigures)})
        shot.strain_cap_hits_before += self.solver.strain_cap_hits
        shot.strain_iterations_max_before = max(shot.strain_iterations_max_before, self.solver.strain_iterations_max)
        return {**self.state.arrays(), **shot.arrays()}

    def restore_shot(self, data) -> None:
        """Take the shot figures of a checkpoint (on resume)."""
        self.shot = ShotFigures.from_arrays(data)

    def step(self) -> None:
        """One step. In a multi-resolution model the slaved crossings are brought up to date at the end
        of a frame (advance_frame; or call solver.end_frame after your last step)."""
        self.solver.step(self.state, self.dt_s)

    def advance_frame(self) -> FrameRecord:
        """Run one frame's steps and return its record."""
        for _ in range(self.steps_per_frame):
            self.solver.step(self.state, self.dt_s)
        self.solver.end_frame(self.state, self.dt_s)
        self.frame += 1
        self._observe()
        return self.record()

    def record(self) -> FrameRecord:
        return frame_record(self.model, self.state, self.frame)

    def frames(self, count: Optional[int] = None) -> Iterator[FrameRecord]:
        """Yield the current frame's record, then advance until `count` frames (default: the scene's)."""
        count = self.spec.time.frames if count is None else count
        if self.frame < count:
            yield self.record()
        while self.frame + 1 < count:
            yield self.advance_frame()

    def structural_strain(self) -> np.ndarray:
        """Strain of every live structural spring."""
        m, s = self.model, self.state
        sel = ((m.spring_kind == STRUCT_WEFT) | (m.spring_kind == STRUCT_WARP)) & s.spring_alive
        x = s.particle_position_m
        d = x[s.spring_particle_b[sel]] - x[s.spring_particle_a[sel]]
        return np.linalg.norm(d, axis=1) / s.spring_rest_length_m[sel] - 1.0

    def summary(self) -> dict:
        """Figures of the current state (the `--json` summary of `fraytool simulate`)."""
        s = self.state
        strain = self.structural_strain()
        out = {
            "scene": self.spec.name,
            "frames": self.frame + 1,
            "time_s": s.time_s,
            "masses": int(s.particle_active.sum()),
            "springs": int(s.spring_alive.sum()),
            "broken_springs": int(s.spring_broken.sum()),
            "yarn_level_masses": int(2 * s.crossing_yarn_level.sum()),
            "max_strain": float(strain.max()) if strain.size else 0.0,
            "strain_iterations_max": max(self.shot.strain_iterations_max_before, self.solver.strain_iterations_max),
            "strain_cap_hits": self.shot.strain_cap_hits_before + self.solver.strain_cap_hits,
            "strain_limit": float(self.model.strain_limit),
            "max_woven_strain": self.shot.max_woven_strain,
            "max_woven_strain_frame": self.shot.max_woven_strain_frame,
            "all_finite": bool(np.isfinite(s.particle_position_m).all() and np.isfinite(s.particle_velocity_m_s).all()),
        }
        if self.model.tearing:
            out.update(piece_figures(self.model, self.state))
            out["small_pieces_max"] = self.shot.small_pieces_max
            out["small_pieces_first_frame"] = self.shot.small_pieces_first_frame
        out.update(self.solver.summary(self.state))
        return out

    def woven_strain_warning(self, tolerance: float = 0.01) -> Optional[str]:
        """One line when strain limiting did not hold where the cloth is woven (max woven strain over
        the shot above limit + tolerance): by how much and where; None when it held."""
        m, shot = self.model, self.shot
        if shot.max_woven_strain <= m.strain_limit + tolerance:
            return None
        s = shot.max_woven_strain_spring
        ca, cb = int(m.spring_crossing_a[s]), int(m.spring_crossing_b[s])
        w = m.warp_yarns
        yarn = f"weft yarn {ca // w}" if int(m.spring_kind[s]) == STRUCT_WEFT else f"warp yarn {ca % w}"
        return (f"strain limiting did not hold where the cloth is woven: strain {shot.max_woven_strain:.4f} "
                f"(limit {m.strain_limit:g} + {tolerance:g}) at frame {shot.max_woven_strain_frame} on spring {s} "
                f"({yarn}, crossings ({ca % w},{ca // w})-({cb % w},{cb // w})); "
                f"strain-limiting cap hits: {shot.strain_cap_hits_before + self.solver.strain_cap_hits}"
                + ("; expected where a grip or a ball pulls harder than the limit holds: the compliant limit "
                   "([cloth.strain] stiffness_n_per_m) lets a woven yarn stretch past it until it breaks "
                   "(docs/tearing.md, \"Strain limiting\")" if m.strain_stiffness_n_per_m > 0.0 else ""))
