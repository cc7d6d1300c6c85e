"""The cloth's pieces (connected components over live yarn springs and connected couples) and
damping per piece (Müller et al. 2007 §3.5 applied to each piece on its own)."""
from __future__ import annotations

from collections import deque

import numpy as np
from fraytool.sim.kernels.work_split import all_slots

from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from fraytool.scene import parse_scene
from fraytool.sim.builder import build_model
from fraytool.sim.kernels.damping import pbd_damping_pieces
from fraytool.sim.pieces import SMALL_PIECE_MASSES, particle_pieces, piece_figures
from fraytool.sim.tearing import YarnTearing

SCENE = """
[scene]
name = "pieces"
seed = 3
[time]
step_s = 2e-4
steps_per_frame = 1
frames = 2
fps = 24
[cloth]
warp_yarns = 10
weft_yarns = 8
spacing_m = 0.004
thickness_m = 0.0006
mass_per_crossing_kg = 5e-6
origin_m = [0.0, 0.0, 0.0]
plane = "xy"
weave = "plain"
[cloth.springs]
structural_n_per_m = 40.0
damping = 0.1
[cloth.tearing]
enabled = true
ineffective_length = 1
"""


def _model():
    model = build_model(parse_scene(SCENE, "pieces.toml"))
    return model, model.state(), YarnTearing(model)


def _pieces_reference(model, state):
    """Breadth-first search over the same graph, in plain Python: sets of particle slots."""
    n = model.particle_count
    adj = [[] for _ in range(n)]
    for s in range(model.spring_count):
        if state.spring_alive[s] and model.spring_kind[s] in (STRUCT_WEFT, STRUCT_WARP):
            a, b = int(state.spring_particle_a[s]), int(state.spring_particle_b[s])
            adj[a].append(b)
            adj[b].append(a)
    C = model.crossing_count
    for c in range(C):
        if state.crossing_yarn_level[c] and state.couple_connected[c]:
            adj[c].append(C + c)
            adj[C + c].append(c)
    seen, out = set(), []
    for p in range(n):
        if not state.particle_active[p] or p in seen:
            continue
        comp, queue = {p}, deque([p])
        seen.add(p)
        while queue:
            q = queue.popleft()
            for r in adj[q]:
                if r not in seen:
                    seen.add(r)
                    comp.add(r)
                    queue.append(r)
        out.append(frozenset(comp))
    return set(out)


def test_pieces_match_a_breadth_first_search_on_random_tears():
    rng = np.random.default_rng(11)
    structural = np.flatnonzero(np.isin(_model()[0].spring_kind, (STRUCT_WEFT, STRUCT_WARP)))
    for trial in range(20):
        model, state, tear = _model()
        tear.split(state, rng.choice(model.crossing_count, size=rng.integers(0, 40), replace=False))
        for s in rng.choice(structural, size=rng.integers(0, 60), replace=False):
            tear.cut(state, int(s))
        for c in np.flatnonzero(state.couple_connected):
            if rng.random() < 0.3:
                tear.disconnect(state, int(c))
        labels, count = particle_pieces(model, state)
        got = {frozenset(np.flatnonzero(labels == k).tolist()) for k in range(count)}
        assert got == _pieces_reference(model, state), trial
        assert (labels[~state.particle_active] == -1).all()


def test_piece_figures_count_small_pieces_and_mass_fractions():
    model, state, tear = _model()
    W = model.warp_yarns
    # cut weft yarn 3 out of the weave between columns 2 and 5: 3 crossings, split and disconnected
    snippet = [3 * W + i for i in (3, 4, 5)]
    tear.split(state, snippet)
    tear.cut(state, int(model.weft_structural_spring[3, 2]))
    tear.cut(state, int(model.weft_structural_spring[3, 5]))
    for c in snippet:
        tear.disconnect(state, c)
    fig = piece_figures(model, state)
    assert fig["pieces"] == 2 and fig["small_pieces"] == 1  # the 3 weft masses; the rest is one piece
    total = state.particle_mass_kg[state.particle_active].sum()
    weft_snippet = state.particle_mass_kg[snippet].sum()
    assert np.isclose(fig["largest_piece_fractions"][1], weft_snippet / total)
    assert np.isclose(sum(fig["largest_piece_fractions"]), 1.0)
    assert SMALL_PIECE_MASSES == 5


def test_damping_per_piece_keeps_the_relative_speed_of_two_pieces_flying_apart():
    """Two halves, each moving rigidly (one translating, one spinning about its centre): damping
    removes only non-rigid motion of each piece, so every velocity is unchanged (a single damped
    body would pull both towards their common motion)."""
    model, state, tear = _model()
    W = model.warp_yarns
    for j in range(model.weft_yarns):
        tear.cut(state, int(model.weft_structural_spring[j, 4]))  # between columns 4 and 5
    labels, count = particle_pieces(model, state)
    assert count == 2
    x, v = state.particle_position_m, state.particle_velocity_m_s
    left = labels == labels[0]
    right = labels == labels[W - 1]
    v[left] = [0.0, 0.0, -1.0]
    centre = x[right].mean(axis=0)
    omega = np.array([0.0, 0.0, 3.0])
    v[right] = np.array([0.5, 0.0, 1.0]) + np.cross(omega, x[right] - centre)
    before = v.copy()
    pbd_damping_pieces(*all_slots(len(x)), x, v, state.particle_mass_kg, state.particle_inv_mass, labels, count, 0.5)
    np.testing.assert_allclose(v, before, atol=1e-12)
    # one body (all in piece 0): the pieces' relative motion is damped
    one = np.where(labels >= 0, 0, -1)
    pbd_damping_pieces(*all_slots(len(x)), x, v, state.particle_mass_kg, state.particle_inv_mass, one, 1, 0.5)
    assert np.abs(v - before).max() > 0.1


def test_damping_per_piece_conserves_each_pieces_momentum():
    model, state, tear = _model()
    for j in range(model.weft_yarns):
        tear.cut(state, int(model.weft_structural_spring[j, 4]))
    labels, count = particle_pieces(model, state)
    rng = np.random.default_rng(2)
    x, v, m = state.particle_position_m, state.particle_velocity_m_s, state.particle_mass_kg
    v[:] = rng.normal(size=v.shape)
    v[~state.particle_active] = 0.0
    before = [((m[labels == k, None] * v[labels == k]).sum(axis=0),
               (m[labels == k, None] * np.cross(x[labels == k], v[labels == k])).sum(axis=0)) for k in range(count)]
    pbd_damping_pieces(*all_slots(len(x)), x, v, m, state.particle_inv_mass, labels, count, 0.3)
    for k in range(count):
        p = (m[labels == k, None] * v[labels == k]).sum(axis=0)
        L = (m[labels == k, None] * np.cross(x[labels == k], v[labels == k])).sum(axis=0)
        np.testing.assert_allclose(p, before[k][0], atol=1e-15)
        np.testing.assert_allclose(L, before[k][1], atol=1e-17)
