"""The air stage: drag from the air's velocity relative to the cloth, after the spring forces (docs/wind.md).

Built only for a model with drag on some panel (Model.panel_drag_normal not empty): a scene without wind or
drag has no air stage and never compiles its kernels."""
from __future__ import annotations

import numpy as np

from fraytool.sim.air import air_model, model_gust_modes
from fraytool.sim.kernels.air import accumulate_air_drag, air_velocity, crossing_centres
from fraytool.sim.model import Model
from fraytool.sim.stages.base import FORCES, POSITIONS, TOPOLOGY, VELOCITIES, StepContext
from fraytool.sim.state import State


class AirDrag:
    """Step 1 (after the springs): each crossing's drag from the mean wind and the gusts at its centre, added to
    ctx.force_n (fraytool.sim.kernels.air)."""

    name = "air"
    kernel = "accumulate_air_drag"
    reads = frozenset({POSITIONS, VELOCITIES, TOPOLOGY, FORCES})
    writes = frozenset({FORCES})

    def __init__(self, model: Model):
        self.model = model
        self.air = air_model(model)
        self.gusts = model_gust_modes(model)
        self.wind_m_s = np.asarray(model.wind_m_s, float)
        n = model.crossing_count
        self.centre_m = model.crossing_rest_position_m.copy()
        self.air_m_s = np.zeros((n, 3))

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None:
        crossing_centres(self.model.crossing_count, state.particle_position_m, state.particle_mass_kg,
                         state.particle_active, self.centre_m)
        g = self.gusts
        air_velocity(self.centre_m, float(state.time_s), self.wind_m_s, g.wave_per_m, g.omega_rad_s, g.phase_rad,
                     g.amplitude_m_s, self.air_m_s)
        accumulate_air_drag(self.air, state.particle_position_m, state.particle_velocity_m_s, state.particle_mass_kg,
                            state.particle_active, state.spring_alive, state.spring_particle_a,
                            state.spring_particle_b, self.centre_m, self.air_m_s, dt_s, ctx.force_n)

    def summary(self, state: State) -> dict:
        return {}
