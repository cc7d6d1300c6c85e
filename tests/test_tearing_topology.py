"""The tear topology stays valid after any sequence of splits, transitions, cuts, disconnections
and steps (property-based, hypothesis)."""
from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fraytool.scene import parse_scene
from fraytool.sim.builder import build_model
from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from fraytool.sim.solver import SolverExplicitPBD
from fraytool.sim.tearing import topology_problems

SCENE = """
[scene]
name = "topology"
seed = 1
[time]
step_s = 2e-4
steps_per_frame = 1
frames = 2
fps = 24
[cloth]
warp_yarns = 6
weft_yarns = 5
spacing_m = 0.004
thickness_m = 0.0006
mass_per_crossing_kg = 5e-6
origin_m = [0.0, 0.0, 0.0]
plane = "xy"
{weave}
[cloth.springs]
structural_n_per_m = 40.0
bend_n_per_m = 1.0
shear_n_per_m = 5.0
damping = 0.01
[cloth.tearing]
enabled = true
transition_strain = 0.02
break_strain = 0.05
break_strain_spread = 0.02
[[bodies]]
name = "pin"
shape = "sphere"
radius_m = 0.001
position_m = [0.0, 0.016, 0.0]
collide = false
[[attachments]]
body = "pin"
corner = "top_left"
"""
WEAVES = ['weave = "plain"', 'weave = "twill"\ntwill = "2/2"', 'weave = "satin"\nsatin_shafts = 5',
          'weave = "table"\ntable = [[1, 0, 0], [1, 1, 0], [0, 1, 1]]']
MODELS = [build_model(parse_scene(SCENE.format(weave=w), "topology.toml")) for w in WEAVES]
CROSSINGS = 30
STRUCTURAL = [np.nonzero((m.spring_kind == STRUCT_WEFT) | (m.spring_kind == STRUCT_WARP))[0] for m in MODELS]

operation = st.one_of(
    st.tuples(st.just("split"), st.integers(0, CROSSINGS - 1)),
    st.tuples(st.just("transition"), st.integers(0, 10_000)),
    st.tuples(st.just("cut"), st.integers(0, 10_000)),
    st.tuples(st.just("disconnect"), st.integers(0, CROSSINGS - 1)),
    st.tuples(st.just("shake"), st.integers(0, 2 ** 31 - 1)),
)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(weave=st.integers(0, len(MODELS) - 1), ops=st.lists(operation, min_size=1, max_size=25))
def test_topology_stays_valid_after_any_tear_sequence(weave, ops):
    model = MODELS[weave]
    structural = STRUCTURAL[weave]
    state = model.state()
    solver = SolverExplicitPBD(model)
    tear = solver.tearing
    for op, arg in ops:
        if op == "split":
            tear.split(state, [arg])
        elif op == "transition":
            tear.transition(state, int(structural[arg % len(structural)]))
        elif op == "cut":
            tear.cut(state, int(structural[arg % len(structural)]))
        elif op == "disconnect":
            tear.disconnect(state, arg)
        else:  # a few real steps from a random shake: contact, transitions and cuts by strain
            rng = np.random.default_rng(arg)
            state.particle_velocity_m_s[state.particle_active] += rng.normal(
                0.0, 0.5, (int(state.particle_active.sum()), 3))
            for _ in range(3):
                solver.step(state, 2e-4)
        problems = topology_problems(model, state, tear.topology)
        assert problems == [], (op, arg, problems)
    assert np.isfinite(state.particle_position_m).all()
