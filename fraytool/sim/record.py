"""The frame record of a State: what the renderer reads (fraytool.io.FrameRecord, float32 positions)."""
from __future__ import annotations

import numpy as np

from fraytool.io.frame_record import FrameRecord
from fraytool.sim.model import Model
from fraytool.sim.state import State


def frame_record(model: Model, state: State, frame: int) -> FrameRecord:
    """Record of `state` as frame `frame`; inactive couple slots hold their crossing's position."""
    pos = state.particle_position_m.astype(np.float32)
    n = model.crossing_count
    idle = ~state.particle_active[n:]
    pos[n:][idle] = pos[:n][idle]
    return FrameRecord(
        frame=frame,
        time_s=state.time_s,
        particle_position_m=pos,
        particle_active=state.particle_active.copy(),
        crossing_yarn_level=state.crossing_yarn_level.copy(),
        spring_particle_a=state.spring_particle_a.copy(),
        spring_particle_b=state.spring_particle_b.copy(),
        spring_alive=state.spring_alive.copy(),
        body_position_m=state.body_position_m.astype(np.float32),
        body_rotation=state.body_rotation.astype(np.float32),
    )
