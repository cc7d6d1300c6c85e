"""The leaf cache (fraytool.sim.kernels.mesh_leaf_cache): a mass's cached list answers a query with the leaves
a walk down the triangle tree visits, in the walk's order, however the mass moves and whatever the query's
size; a refit empties the lists; and the mass pass moves the cloth the same, bit for bit, whatever the lists
hold."""
from __future__ import annotations

import numpy as np
import pytest

from fraytool.sim.builder import ModelBuilder
from fraytool.sim.kernels.bodies import bodies_in
from fraytool.sim.kernels.mesh_bvh import next_leaf
from fraytool.sim.kernels.mesh_contact import STACK, collide_meshes
from fraytool.sim.kernels.mesh_leaf_cache import (CACHE_LEAVES, CACHE_MARGINS, FULL, NO_LIST, cached_leaves,
                                                  empty_leaf_cache, next_query_leaf)
from fraytool.sim.kernels.work_split import all_slots
from fraytool.sim.mesh_geometry import MeshGeometry

trimesh = pytest.importorskip("trimesh")

MARGIN = 0.0003
HALF = CACHE_MARGINS * MARGIN


def _geometry(subdivisions=3, radius=0.05, keys=None, n=4):
    """A model with a cloth of n x n crossings and an icosphere mesh (static, or `keys` frames of it)."""
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    v, faces = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    b = ModelBuilder(seed=1)
    half = 0.5 * (n - 1) * 0.004
    b.add_cloth(warp_yarns=n, weft_yarns=n, spacing_m=0.004, thickness_m=2 * MARGIN, mass_per_crossing_kg=2e-5,
                structural_n_per_m=20.0, origin_m=(-half, radius, -half))
    if keys is None:
        b.add_mesh("ball", vertices_m=v, triangles=faces)
    else:
        frames = np.stack([v * (1.0 + 0.1 * k) for k in range(keys)])
        b.add_mesh("ball", vertices_m=frames, triangles=faces, key_times_s=np.linspace(0.0, 0.02, keys),
                   motion="kinematic")
    model = b.finalize()
    return model, MeshGeometry(model)


def _walk(meshes, query):
    """The leaves a walk down mesh 0's triangle tree visits for the query box, in its order."""
    stack = np.empty(STACK, np.int64)
    stack[0] = meshes.tri_node_start[0]
    top, out = 1, []
    while True:
        node, top = next_leaf(stack, top, meshes.tri_child, meshes.tri_box, *query)
        if node < 0:
            return out
        out.append(int(node))


def _through_cache(meshes, cache, p, query):
    """The leaves the kernels visit for the query box through mass p's list (or a walk when it says so), and
    the count cached_leaves returned."""
    stack = np.empty(STACK, np.int64)
    n = cached_leaves((0, p), meshes, query, HALF, cache.leaves, cache.count, cache.centre_m, stack)
    stack[0] = meshes.tri_node_start[0]
    top, k, out = 1, 0, []
    while True:
        node, k, top = next_query_leaf(cache.leaves[0, p], n, k, stack, top, (meshes.tri_child, meshes.tri_box),
                                       query)
        if node < 0:
            return out, n
        out.append(int(node))


def _box(centre, half):
    return tuple(float(x) for x in np.concatenate([centre - half, centre + half]))


def test_a_list_answers_every_query_as_the_walk_does_while_a_mass_wanders_over_the_surface():
    model, g = _geometry()
    meshes = g.meshes_in(model)
    cache = empty_leaf_cache(1, 3)
    rng = np.random.default_rng(11)
    kinds = {"list": 0, "walk": 0, "taken": 0}
    for p in range(3):
        x = rng.standard_normal(3)
        x *= 0.05 / np.linalg.norm(x)  # on the sphere
        for _ in range(400):
            x = x + rng.normal(0.0, 0.6 * MARGIN, 3)  # a random walk of a few margins a query
            before = (int(cache.count[0, p]), cache.centre_m[0, p].copy())
            half = rng.choice([MARGIN, 4 * MARGIN, 0.5 * HALF, 1.5 * HALF])  # some queries larger than the cube
            query = _box(x + rng.uniform(-MARGIN, MARGIN, 3), np.full(3, half) + rng.uniform(0, MARGIN, 3))
            got, n = _through_cache(meshes, cache, p, query)
            assert got == _walk(meshes, query)
            kinds["walk" if n < 0 else "list"] += 1
            kinds["taken"] += before[0] != cache.count[0, p] or not np.array_equal(before[1], cache.centre_m[0, p])
            assert cache.count[0, p] == NO_LIST or 0 <= cache.count[0, p] <= FULL
    # the test walks every path: lists used, lists taken afresh, and queries too large for a list
    assert kinds["list"] > 600 and kinds["walk"] > 100 and 20 < kinds["taken"] < kinds["list"]


def test_a_cube_with_more_leaves_than_a_list_holds_walks_the_tree():
    model, g = _geometry(subdivisions=6, radius=0.004)  # 81,920 tiny triangles: a cube meets hundreds of leaves
    meshes = g.meshes_in(model)
    cache = empty_leaf_cache(1, 1)
    x = np.array([0.0, 0.004, 0.0])
    query = _box(x, np.full(3, MARGIN))
    assert len(_walk(meshes, _box(x, np.full(3, HALF)))) > CACHE_LEAVES
    got, n = _through_cache(meshes, cache, 0, query)
    assert n == -1 and cache.count[0, 0] == FULL
    assert got == _walk(meshes, query)
    got, n = _through_cache(meshes, cache, 0, _box(x + 0.1 * MARGIN, np.full(3, MARGIN)))  # kept: full still
    assert n == -1 and cache.count[0, 0] == FULL


def test_a_refit_empties_its_meshs_lists():
    model, g = _geometry(keys=3)
    meshes = g.meshes_in(model)
    g.at_step(0.0, 0.001)
    query = _box(np.array([0.0, 0.05, 0.0]), np.full(3, MARGIN))
    _, n = _through_cache(meshes, g.leaf_cache, 0, query)
    assert n >= 0 and g.leaf_cache.count[0, 0] >= 0
    g.at_step(0.001, 0.002)  # the same interval between keys: no refit, the list stays
    assert g.leaf_cache.count[0, 0] >= 0
    g.at_step(0.011, 0.012)  # the next interval: refitted
    assert g.leaf_cache.count[0, 0] == NO_LIST


def _pass(model, g, state, prev, cache):
    x = state.particle_position_m.copy()
    clear = g.clearance._replace(clearance_m=np.full_like(g.clearance.clearance_m, -1.0),
                                 reference_m=np.zeros_like(g.clearance.reference_m),
                                 travel_at_m=np.zeros_like(g.clearance.travel_at_m))
    hits = collide_meshes(*all_slots(model.particle_count), g.meshes_in(model), bodies_in(model, state), MARGIN,
                          1e-4, state.particle_inv_mass, prev, x, clear, cache)
    return hits, x, clear


def test_the_mass_pass_moves_the_cloth_the_same_whatever_the_lists_hold():
    model, g = _geometry(n=24)
    state = model.state()
    rng = np.random.default_rng(5)
    n = model.particle_count
    d = rng.standard_normal((n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    prev = d * (0.05 + rng.uniform(-1.0, 3.0, (n, 1)) * MARGIN)  # about the surface, some inside the margin
    state.particle_position_m[:] = prev + rng.normal(0.0, MARGIN, (n, 3))
    state.particle_inv_mass[:] = 1.0
    fresh = empty_leaf_cache(1, n)
    walked = empty_leaf_cache(1, n)
    walked.count[:] = FULL  # full lists about each path's middle: the queries inside them walk the tree
    walked.centre_m[0] = 0.5 * (prev + state.particle_position_m)
    warmed = empty_leaf_cache(1, n)
    _pass(model, g, state, prev + 2.0 * MARGIN, warmed)  # lists taken about other points
    assert (warmed.count[0] >= 0).sum() > n // 4
    results = [_pass(model, g, state, prev, c) for c in (fresh, walked, warmed)]
    assert results[0][0] > 20  # masses in contact
    assert (walked.count[0] == FULL).sum() > 0.9 * n
    for hits, x, clear in results[1:]:
        assert hits == results[0][0]
        assert x.tobytes() == results[0][1].tobytes()
        assert clear.clearance_m.tobytes() == results[0][2].clearance_m.tobytes()
