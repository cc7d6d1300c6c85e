"""Leaf cache: each mass keeps the triangle tree's leaves near it, so that its contact queries skip the
walk down the tree (docs/meshes.md, "Leaf cache").

A query of the contact kernels (fraytool.sim.kernels.mesh_contact, mesh_clearance) walks a mesh's
triangle tree (fraytool.sim.kernels.mesh_bvh.next_leaf) and visits, in the tree's fixed order, every
leaf whose box meets the query box: a node's box holds its children's (the refit takes their union,
exactly), so a leaf is reached exactly when its own box meets the query box. On cloth that lies on a
body that walk is most of a mass's test: about 28 nodes for the two or three leaves it finds.

So each (mesh, mass) keeps `centre_m` and the leaves whose boxes meet the cube of half-width
CACHE_MARGINS margins about it, in the tree's order (at most CACHE_LEAVES). A query box inside that cube
is answered from the list: the leaves of the list whose boxes meet the query box, in the list's order,
are those the walk would visit, in its order (a leaf that meets the query box meets the cube). The
kernels then test the same triangles in the same order, and the frames are bit for bit those of the
walk. A query box outside the cube takes the list afresh about its own centre; one larger than the cube
walks the tree. More than CACHE_LEAVES leaves in the cube: the mass walks the tree while its queries stay
in that cube (the list is marked full).

The list holds while the boxes do: a static or rigidly moving mesh is refitted once, an animated one
per interval between its keys, and each refit empties its mesh's lists (fraytool.sim.mesh_geometry).
"""
from __future__ import annotations

from collections import namedtuple

import numba as nb
import numpy as np

from fraytool.sim.kernels.mesh_bvh import next_leaf, overlaps

CACHE_LEAVES = 16
"""Leaves a mass keeps per mesh (a leaf holds up to fraytool.sim.kernels.mesh_bvh.LEAF_SIZE triangles)."""
CACHE_MARGINS = 8.0
"""Half-width of a list's cube, in contact margins: a query box (a mass's path over a step, grown by the
margin, or a clearance renewal's four margins) stays inside it while the mass moves a few margins."""
NO_LIST = -1
"""`count` of a mass without a list."""
FULL = CACHE_LEAVES + 1
"""`count` of a mass whose cube meets more leaves than a list holds (it walks the tree)."""

LeafCacheInOut = namedtuple("LeafCacheInOut", [
    "leaves",     # (M, P, CACHE_LEAVES) int64: tree nodes, the leaves meeting the cube, in the tree's order
    "count",      # (M, P) int64: how many; NO_LIST or FULL (module docstring)
    "centre_m",   # (M, P, 3) body-frame centre of the cube [m]
])
LeafCacheInOut.__doc__ = "Per-mass lists of the triangle tree's leaves near it (module docstring)."


def empty_leaf_cache(meshes: int, particles: int) -> LeafCacheInOut:
    """No lists yet (each mass takes its list at its first query near a mesh)."""
    return LeafCacheInOut(np.zeros((meshes, particles, CACHE_LEAVES), np.int64),
                          np.full((meshes, particles), NO_LIST, np.int64), np.zeros((meshes, particles, 3)))


@nb.njit(cache=True, inline="always")
def _inside(query, centre_m, m, p, half_m):
    """Whether the query box (lo x, y, z, hi x, y, z) lies inside the cube of half-width half_m about
    centre_m[m, p] (False for NaN)."""
    return (query[0] >= centre_m[m, p, 0] - half_m and query[1] >= centre_m[m, p, 1] - half_m
            and query[2] >= centre_m[m, p, 2] - half_m and query[3] <= centre_m[m, p, 0] + half_m
            and query[4] <= centre_m[m, p, 1] + half_m and query[5] <= centre_m[m, p, 2] + half_m)


@nb.njit(cache=True, inline="always")
def cached_leaves(which, meshes_in, query, half_m, leaves_inout, count_inout, centre_m_inout, stack_out):
    """The number of leaves of mass p's list (which = (m, p)) that answers the query box `query` (lo x, y, z,
    hi x, y, z) against mesh m's triangle tree, taken afresh about the query's centre when the query is not
    inside its cube; -1 when the query must walk the tree (a query larger than a cube, which leaves the list as it
    is, or a full list)."""
    m, p = which
    n = count_inout[m, p]
    if n == NO_LIST or not _inside(query, centre_m_inout, m, p, half_m):
        for a in range(3):
            if not query[3 + a] - query[a] <= 2.0 * half_m:
                return -1  # larger than a cube (or NaN): walk, and keep the list for the next query
        for a in range(3):
            centre_m_inout[m, p, a] = 0.5 * (query[a] + query[3 + a])
        lo0, lo1, lo2 = (centre_m_inout[m, p, 0] - half_m, centre_m_inout[m, p, 1] - half_m,
                         centre_m_inout[m, p, 2] - half_m)
        hi0, hi1, hi2 = (centre_m_inout[m, p, 0] + half_m, centre_m_inout[m, p, 1] + half_m,
                         centre_m_inout[m, p, 2] + half_m)
        n = 0
        stack_out[0] = meshes_in.tri_node_start[m]
        top = 1
        while True:
            node, top = next_leaf(stack_out, top, meshes_in.tri_child, meshes_in.tri_box, lo0, lo1, lo2, hi0, hi1,
                                  hi2)
            if node < 0:
                break
            if n == CACHE_LEAVES:
                n = FULL
                break
            leaves_inout[m, p, n] = node
            n += 1
        count_inout[m, p] = n
        if not _inside(query, centre_m_inout, m, p, half_m):
            return -1  # (a query as wide as the cube, rounded off its centre)
    return n if n < FULL else -1


@nb.njit(cache=True, inline="always")
def next_query_leaf(leaves_in, leaf_count, k, stack_inout, top, tree_in, query):
    """The next leaf meeting the query box of a walk down the tree (leaf_count < 0; tree_in = (child, box):
    fraytool.sim.kernels.mesh_bvh.next_leaf, the caller pushes the root) or of a cached list (leaf_count
    entries of leaves_in, k the next): the same leaves in the same order. Returns (leaf or -1, k, top)."""
    child, box = tree_in
    if leaf_count < 0:
        node, top = next_leaf(stack_inout, top, child, box, query[0], query[1], query[2], query[3], query[4],
                              query[5])
        return node, k, top
    while k < leaf_count:
        node = leaves_in[k]
        k += 1
        if overlaps(box, node, query[0], query[1], query[2], query[3], query[4], query[5]):
            return node, k, top
    return -1, k, top
