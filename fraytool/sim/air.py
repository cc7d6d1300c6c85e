"""The air: mean wind, seeded gusts and the drag groups of the air stage (docs/wind.md).

Gusts are a random Fourier-mode field (Kraichnan 1970, "Diffusion by a random velocity field", Phys. Fluids
13: 22-31), one common way to synthesise a smooth, stationary turbulent velocity:

    u_d(x, t) = sum_k a_kd cos(kappa_k . (x - W t) + omega_k t + phi_k),    k = 1 .. GUST_MODES

with wave vectors kappa_k drawn from N(0, I / L^2), frequencies omega_k from N(0, 1 / T^2), phases phi_k uniform,
and amplitudes a_kd = sigma sqrt(2 / N) g_kd, the normal draws g_kd of each component scaled so that
sum_k g_kd^2 = N. Each component then has root mean square sigma over space (exactly, for every seed), its
components are uncorrelated, two points r apart correlate as E[cos(kappa . r)] = exp(-|r|^2 / 2 L^2), and one
point in still mean air (W = 0) correlates with itself tau later as exp(-tau^2 / 2 T^2) (the characteristic
functions of the normal draws). The field is carried along by the mean wind W (Taylor's frozen turbulence)
while it changes on the time scale T. The draws come from the scene seed alone: same seed, same gusts.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from fraytool.sim.model import Model

GUST_MODES = 64
"""Fourier modes of the gust field: enough for a smooth, irregular field; each costs a cosine per crossing and
step."""
GUST_STREAM = 0x6A5717
"""Second word of the gusts' random stream (the first is the seed), apart from the break strains' draws."""

AirModel = namedtuple("AirModel", [
    "crossing_count", "spacing_m", "thickness_m", "half_density_kg_m3", "crossing_panel", "crossing_weft_springs",
    "crossing_warp_springs", "panel_drag_normal", "panel_drag_tangential",
])
AirModel.__doc__ = """Read-only inputs of fraytool.sim.kernels.air.accumulate_air_drag (Model arrays and scalars;
half_density_kg_m3 = rho / 2)."""


class GustModes(namedtuple("GustModes", ["wave_per_m", "omega_rad_s", "phase_rad", "amplitude_m_s"])):
    """The gust field's modes: wave vectors (N, 3) [1/m], frequencies (N,) [rad/s], phases (N,), amplitudes
    (N, 3) [m/s]; N = 0 for steady wind."""


def gust_modes(seed: int, strength_m_s: float, length_m: float, time_s: float, modes: int = GUST_MODES) -> GustModes:
    """The modes of the gust field (module docstring) for `seed`; none when strength_m_s is 0."""
    if strength_m_s <= 0.0:
        return GustModes(np.zeros((0, 3)), np.zeros(0), np.zeros(0), np.zeros((0, 3)))
    rng = np.random.default_rng([int(seed), GUST_STREAM])
    wave = rng.normal(0.0, 1.0 / length_m, (modes, 3))
    omega = rng.normal(0.0, 1.0 / time_s, modes)
    phase = rng.uniform(0.0, 2.0 * np.pi, modes)
    g = rng.normal(0.0, 1.0, (modes, 3))
    g *= np.sqrt(modes / (g * g).sum(axis=0))
    return GustModes(wave, omega, phase, strength_m_s * np.sqrt(2.0 / modes) * g)


def model_gust_modes(model: Model) -> GustModes:
    return gust_modes(model.seed, model.gust_strength_m_s, model.gust_length_m, model.gust_time_s)


def air_velocity_m_s(wind_m_s, gusts: GustModes, points_m: np.ndarray, time_s: float) -> np.ndarray:
    """The air's velocity [m/s] at `points_m` (N, 3) at `time_s`: mean wind plus the gusts' modes (for tools and
    tests; the air stage calls the same kernel)."""
    from fraytool.sim.kernels.air import air_velocity

    points = np.ascontiguousarray(points_m, float).reshape(-1, 3)
    out = np.empty_like(points)
    air_velocity(points, float(time_s), np.asarray(wind_m_s, float), gusts.wave_per_m, gusts.omega_rad_s,
                 gusts.phase_rad, gusts.amplitude_m_s, out)
    return out


def air_model(model: Model) -> AirModel:
    return AirModel(model.crossing_count, float(model.spacing_m), float(model.thickness_m),
                    0.5 * float(model.air_density_kg_m3), model.crossing_panel.astype(np.int32),
                    model.crossing_weft_springs, model.crossing_warp_springs,
                    np.asarray(model.panel_drag_normal, float), np.asarray(model.panel_drag_tangential, float))
