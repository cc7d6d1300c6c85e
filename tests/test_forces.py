"""Spring forces, including compression-only shear, against a slow NumPy reference."""
import numpy as np

from fraytool.sim import build_model
from fraytool.sim.kernels.forces import accumulate_spring_forces
from fraytool.kinds import SHEAR, SHEAR_TWIN
from helpers import small_scene

TOL = 1e-12


def reference_forces(x, kind, a, b, alive, k, rest):
    f = np.zeros_like(x)
    for s in range(len(kind)):
        if not alive[s]:
            continue
        d = x[b[s]] - x[a[s]]
        length = np.linalg.norm(d)
        stretch = length - rest[s]
        if kind[s] in (SHEAR, SHEAR_TWIN) and stretch > 0:
            continue
        fs = k[s] * stretch * d / length
        f[a[s]] += fs
        f[b[s]] -= fs
    return f


def test_spring_forces_match_reference():
    model = build_model(small_scene(nx=7, ny=6))
    state = model.state()
    rng = np.random.default_rng(3)
    x = state.particle_position_m + rng.normal(scale=0.0015, size=state.particle_position_m.shape)
    alive = state.spring_alive & (rng.random(model.spring_count) > 0.1)
    k = state.spring_stiffness_n_per_m * rng.uniform(0.5, 2.0, model.spring_count)
    out = np.zeros_like(x)
    accumulate_spring_forces(model.spring_kind, model.spring_rest_length_m, x, state.spring_particle_a,
                             state.spring_particle_b, alive, k, out)
    ref = reference_forces(x, model.spring_kind, state.spring_particle_a, state.spring_particle_b, alive, k,
                           model.spring_rest_length_m)
    scale = np.abs(ref).max()
    assert scale > 0
    np.testing.assert_allclose(out, ref, rtol=0, atol=TOL * scale)


def test_shear_acts_only_in_compression():
    model = build_model(small_scene(nx=3, ny=3, bend=0.0))
    state = model.state()
    shear = np.nonzero(model.spring_kind == SHEAR)[0][0]
    only = np.zeros(model.spring_count, bool)
    only[shear] = True
    a, b = state.spring_particle_a[shear], state.spring_particle_b[shear]
    out = np.zeros_like(state.particle_position_m)
    for factor, expect_force in ((1.2, False), (0.8, True)):
        x = state.particle_position_m.copy()
        mid = 0.5 * (x[a] + x[b])
        x[a] = mid + factor * (x[a] - mid)
        x[b] = mid + factor * (x[b] - mid)
        accumulate_spring_forces(model.spring_kind, model.spring_rest_length_m, x, state.spring_particle_a,
                                 state.spring_particle_b, only, state.spring_stiffness_n_per_m, out)
        assert (np.abs(out).max() > 0) == expect_force
        if expect_force:  # compressed: pushes the ends apart
            assert np.dot(out[b], x[b] - x[a]) > 0
