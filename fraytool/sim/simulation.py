"""Simulation: the Python API that ties a SceneSpec to Model, State and Solver.

    from fraytool.scene import load_scene
    from fraytool.sim import Simulation

    sim = Simulation(load_scene("scenes/drape.toml"))
    for record in sim.frames(10):          # frame 0 is the initial state
        print(record.frame, record.particle_position_m[:, 1].min())
    print(sim.summary())
"""
from __future__ import annotations

from typing import Iterator, Optional

import numpy as np

from fraytool.io.frame_record import FrameRecord
from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from fraytool.scene.spec import SceneSpec
from fraytool.sim.builder import build_model
from fraytool.sim.model import Model
from fraytool.sim.record import frame_record
from fraytool.sim.solver import SolverExplicitPBD
from fraytool.sim.state import State


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

    def step(self) -> None:
        self.solver.step(self.state, self.dt_s)

    def advance_frame(self) -> FrameRecord:
        """Run one frame's steps and return its record."""
        for _ in range(self.steps_per_frame):
            self.solver.step(self.state, self.dt_s)
        self.frame += 1
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
        return np.linalg.norm(d, axis=1) / m.spring_rest_length_m[sel] - 1.0

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
            "strain_iterations_max": self.solver.strain_iterations_max,
            "strain_cap_hits": self.solver.strain_cap_hits,
            "all_finite": bool(np.isfinite(s.particle_position_m).all() and np.isfinite(s.particle_velocity_m_s).all()),
        }
        out.update(self.solver.summary(self.state))
        return out
