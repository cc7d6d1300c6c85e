"""Simulation: the Python API that ties a SceneSpec to Model, State and Solver.

    from fraytool.scene import load_scene
    from fraytool.sim import Simulation

    sim = Simulation(load_scene("scenes/drape.toml"))
    for record in sim.frames(10):          # frame 0 is the initial state
        print(record.frame, record.particle_position_m[:, 1].min())
    print(sim.summary())
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Iterator, Optional

import numpy as np

from fraytool.io.frame_record import FrameRecord
from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from fraytool.scene.spec import SceneSpec
from fraytool.sim.builder import build_model
from fraytool.sim.model import Model, broken_cloth_springs
from fraytool.sim.pieces import crossings_near_grips, piece_figures, woven_strain, woven_strain_away
from fraytool.sim.record import frame_record
from fraytool.sim.solver import SolverExplicitPBD
from fraytool.sim.state import State
from fraytool.sim.tear_control_figures import tear_control_figures, tracked_springs


WOVEN_STRAIN_TOLERANCE = 0.01
"""Strain over the limit that the woven-strain warning lets pass (rounding of the projection)."""


@dataclass
class ShotFigures:
    """Figures over the whole shot so far, sampled at every frame (saved with the checkpoint, so a
    resumed run reports the same as an unbroken one)."""

    max_woven_strain: float = 0.0
    """Largest strain over live structural springs between woven crossings (fraytool.sim.pieces)."""
    max_woven_strain_frame: int = 0
    max_woven_strain_spring: int = -1
    max_woven_strain_away: float = 0.0
    """The same away from grips and colliding bodies (fraytool.sim.pieces.woven_strain_away), with the hard
    limit only, sampled at the frames where max_woven_strain passed the limit + WOVEN_STRAIN_TOLERANCE."""
    max_woven_strain_away_frame: int = 0
    max_woven_strain_away_spring: int = -1
    small_pieces_max: int = 0
    """Most pieces of fewer than SMALL_PIECE_MASSES masses seen at any frame."""
    small_pieces_first_frame: int = -1
    """First frame with a small piece, -1 if none."""
    strain_cap_hits_before: int = 0
    """Strain-limiting cap hits of the run before a resume."""
    strain_iterations_max_before: int = 0
    """Most strain-limiting sweeps in one step of the run before a resume."""
    tracked_break_frame: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    """The first frame at which each of the seams' stitches and weakened springs
    (fraytool.sim.tear_control_figures.tracked_springs) was broken, -1 while whole."""

    def arrays(self) -> dict[str, np.ndarray]:
        return {f"shot_{f.name}": np.asarray(getattr(self, f.name)) for f in fields(self)}

    @staticmethod
    def from_arrays(data) -> "ShotFigures":
        out = ShotFigures()
        for f in fields(ShotFigures):
            key = f"shot_{f.name}"
            if key in data:
                value = getattr(out, f.name)
                setattr(out, f.name, np.array(data[key], np.int64) if isinstance(value, np.ndarray)
                        else type(value)(np.asarray(data[key])))
        return out


class Simulation:
    """A scene being simulated: model (static), state (current), solver, frame counter."""

    def __init__(self, spec: SceneSpec, model: Optional[Model] = None, state: Optional[State] = None,
                 frame: int = 0):
        self.spec = spec
        self.model = model if model is not None else build_model(spec)
        self.state = state if state is not None else self.model.state()
        self.solver = SolverExplicitPBD(self.model)
        """Seam stitches: `broken_springs` counts the cloth's springs, the seams stage counts these."""
        self.frame = frame
        """Index of the frame the current state belongs to."""
        self.dt_s = spec.time.step_s
        self.steps_per_frame = spec.time.steps_per_frame
        self.shot = ShotFigures()
        """Figures over the shot (max woven strain, small pieces), updated at every frame."""
        self._tracked = tracked_springs(self.model)
        """The seams' stitches and weakened springs, whose break frames the shot figures keep."""
        self.shot.tracked_break_frame = np.full(self._tracked.size, -1, np.int64)
        self._near_grips = None
        """Crossings near a held crossing (fraytool.sim.pieces.crossings_near_grips), made when first needed."""
        self._observe()

    def _observe(self) -> None:
        """Update the shot figures with the current state (every frame)."""
        strain, spring = woven_strain(self.model, self.state)
        if strain > self.shot.max_woven_strain:
            self.shot.max_woven_strain = strain
            self.shot.max_woven_strain_frame = self.frame
            self.shot.max_woven_strain_spring = spring
        m = self.model
        if m.strain_stiffness_n_per_m == 0.0 and strain > m.strain_limit + WOVEN_STRAIN_TOLERANCE:
            if self._near_grips is None:
                self._near_grips = crossings_near_grips(m)
            contact = self.solver.self_collision
            away, spring = woven_strain_away(m, self.state, self._near_grips,
                                             contact.contact_particles(self.state) if contact is not None else None,
                                             meshes=self.solver.context.meshes)
            if away > self.shot.max_woven_strain_away:
                self.shot.max_woven_strain_away = away
                self.shot.max_woven_strain_away_frame = self.frame
                self.shot.max_woven_strain_away_spring = spring
        if self._tracked.size:
            record = self.shot.tracked_break_frame
            if record.size != self._tracked.size:  # a checkpoint written before these figures were kept
                record = self.shot.tracked_break_frame = np.full(self._tracked.size, -1, np.int64)
            newly = np.asarray(self.state.spring_broken, bool)[self._tracked] & (record < 0)
            record[newly] = self.frame
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
        """One step. Before reading the state, call `complete()` (advance_frame does): in a
        multi-resolution model the steps leave the slaved crossings where a stage last read them."""
        self.solver.step(self.state, self.dt_s)

    def advance_frame(self) -> FrameRecord:
        """Run one frame's steps and return its record."""
        for _ in range(self.steps_per_frame):
            self.solver.step(self.state, self.dt_s)
        self.complete()
        self.frame += 1
        self._observe()
        return self.record()

    def complete(self) -> None:
        """Bring every field of the state up to date after `step` calls (SolverExplicitPBD.complete)."""
        self.solver.complete(self.state, self.dt_s)

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

    def broken_springs(self) -> int:
        """Springs of the cloth broken so far (fraytool.sim.model.broken_cloth_springs)."""
        return broken_cloth_springs(self.model.spring_kind, self.state.spring_broken)

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
            "broken_springs": self.broken_springs(),
            "yarn_level_masses": int(2 * s.crossing_yarn_level.sum()),
            "max_strain": float(strain.max()) if strain.size else 0.0,
            "strain_iterations_max": max(self.shot.strain_iterations_max_before, self.solver.strain_iterations_max),
            "strain_cap_hits": self.shot.strain_cap_hits_before + self.solver.strain_cap_hits,
            "strain_limit": float(self.model.strain_limit),
            "max_woven_strain": self.shot.max_woven_strain,
            "max_woven_strain_frame": self.shot.max_woven_strain_frame,
            "max_woven_strain_away": self.shot.max_woven_strain_away,
            "all_finite": bool(np.isfinite(s.particle_position_m).all() and np.isfinite(s.particle_velocity_m_s).all()),
        }
        if self.model.tearing:
            out.update(piece_figures(self.model, self.state))
            out["small_pieces_max"] = self.shot.small_pieces_max
            out["small_pieces_first_frame"] = self.shot.small_pieces_first_frame
        out.update(self.solver.summary(self.state))
        if self._tracked.size:
            out.update(tear_control_figures(self.model, self.state.spring_broken, self.shot.tracked_break_frame,
                                            self.spec))
        return out

    def woven_strain_warning(self, tolerance: float = WOVEN_STRAIN_TOLERANCE) -> Optional[str]:
        """One line when the hard strain limit did not hold where the cloth is woven, away from grips and
        colliding bodies (ShotFigures.max_woven_strain_away above limit + tolerance): by how much and
        where; None otherwise. Near a grip or a body the strain is theirs to make; with a compliant limit
        ([cloth.strain] stiffness_n_per_m > 0) a woven yarn stretches past the limit by design until it
        breaks. Both stay in the --json figures (max_woven_strain, max_woven_strain_away)."""
        m, shot = self.model, self.shot
        if m.strain_stiffness_n_per_m > 0.0 or shot.max_woven_strain_away <= m.strain_limit + tolerance:
            return None
        s = shot.max_woven_strain_away_spring
        ca, cb = int(m.spring_crossing_a[s]), int(m.spring_crossing_b[s])
        gi, gj = m.crossing_grid_i, m.crossing_grid_j
        yarn = f"weft yarn {gj[ca]}" if int(m.spring_kind[s]) == STRUCT_WEFT else f"warp yarn {gi[ca]}"
        return (f"strain limiting did not hold where the cloth is woven, away from grips and bodies: strain "
                f"{shot.max_woven_strain_away:.4f} (limit {m.strain_limit:g} + {tolerance:g}) at frame "
                f"{shot.max_woven_strain_away_frame} on spring {s} ({yarn}, crossings ({gi[ca]},{gj[ca]})-"
                f"({gi[cb]},{gj[cb]})); strain-limiting cap hits: "
                f"{shot.strain_cap_hits_before + self.solver.strain_cap_hits}: raise [cloth.strain] max_iterations "
                f"or shorten the step")
