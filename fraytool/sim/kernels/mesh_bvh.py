"""Bounding-volume hierarchies over a mesh body's triangles or sharp edges (docs/meshes.md, "Broad phase").

One tree per mesh, built once, top down: each range of primitives is sorted along the longest axis of
its centroids' box and split at the middle (an object-median split), down to LEAF_SIZE primitives.
Against the Morton order it replaced (Lauterbach et al. 2009), a point query on mannequin_snag's torso
visits 28 nodes instead of 46. The sharp edges' trees keep the Morton order: a yarn segment is moved off
the edges it meets one after the other, in the tree's order, so that order is part of the result (a
thin blade's two bottom edges, tests/test_mesh_bodies.py, hold the cloth in it); the triangle passes'
results do not depend on the tree (ties go to the lowest index). The nodes are in pre-order (a child's index is above its parent's), so a
refit is one backward pass: leaves take their primitives' boxes, inner nodes the union of their
children's. A static or rigidly moving mesh is refitted once (its queries are made in the body's
frame); an animated one is refitted over each interval between two of its keys, with boxes holding the
primitive at both keys (the linear interpolation between them stays inside), so one refit serves every
step there.

Trees of all meshes share flat arrays: `node_start[m]` is mesh m's root; a node's children are global
node indices (-1 in a leaf); a leaf's primitives are `order[lo:hi]` (global primitive indices).
"""
from __future__ import annotations

from collections import namedtuple

import numba as nb
import numpy as np

LEAF_SIZE = 4

Bvh = namedtuple("Bvh", [
    "node_start",   # (M+1,) int64: mesh m's nodes are [node_start[m], node_start[m+1]), its root the first
    "child",        # (N, 2) int64: children (global node indices), -1 in a leaf
    "prim_range",   # (N, 2) int64: the node's primitives are order[lo:hi]
    "box",          # (N + P, 6) float64: lo x, y, z, hi x, y, z (body frame) [m]: the N nodes', then each
                    # primitive's own (row N + p), so that a leaf's primitives can be tested one by one
    "order",        # (P,) int64: primitive indices in tree order
])
Bvh.__doc__ = "Flat BVH arrays of every mesh's tree (module docstring)."


def _morton(centroids: np.ndarray) -> np.ndarray:
    """30-bit Morton codes of points in their bounding box."""
    lo = centroids.min(axis=0)
    span = np.maximum(centroids.max(axis=0) - lo, 1e-300)
    q = np.clip(((centroids - lo) / span * 1023.0).astype(np.int64), 0, 1023)
    code = np.zeros(centroids.shape[0], np.int64)
    for bit in range(10):
        for axis in range(3):
            code |= ((q[:, axis] >> bit) & 1) << (3 * bit + (2 - axis))
    return code


@nb.njit(cache=True)
def median_order(centroids, leaf_size):
    """Primitive order of the object-median tree (module docstring): every range that `_build` splits
    (at its middle) is sorted along the longest axis of its centroids' box first. A stable sort, from
    index order: the same centroids give the same order."""
    n = centroids.shape[0]
    order = np.arange(n)
    stack = np.empty((128, 2), np.int64)
    stack[0, 0] = 0
    stack[0, 1] = n
    top = 1
    while top > 0:
        top -= 1
        lo, hi = stack[top, 0], stack[top, 1]
        if hi - lo <= leaf_size:
            continue
        axis = 0
        widest = -1.0
        for a in range(3):
            c_lo, c_hi = np.inf, -np.inf
            for q in range(lo, hi):
                c_lo = min(c_lo, centroids[order[q], a])
                c_hi = max(c_hi, centroids[order[q], a])
            if c_hi - c_lo > widest:
                widest = c_hi - c_lo
                axis = a
        keys = np.empty(hi - lo)
        for q in range(lo, hi):
            keys[q - lo] = centroids[order[q], axis]
        order[lo:hi] = order[lo:hi][np.argsort(keys, kind="mergesort")]
        mid = (lo + hi) // 2
        stack[top, 0], stack[top, 1] = mid, hi
        stack[top + 1, 0], stack[top + 1, 1] = lo, mid
        top += 2
    return order


@nb.njit(cache=True)
def _build(count, leaf_size, child_out, prim_range_out):
    """Pre-order tree over `count` sorted primitives; returns the node count."""
    stack = np.empty(128, np.int64)
    prim_range_out[0, 0] = 0
    prim_range_out[0, 1] = count
    nodes = 1
    top = 0
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        node = stack[top]
        lo = prim_range_out[node, 0]
        hi = prim_range_out[node, 1]
        if hi - lo <= leaf_size:
            child_out[node, 0] = -1
            child_out[node, 1] = -1
            continue
        mid = (lo + hi) // 2
        left = nodes
        right = nodes + 1
        nodes += 2
        child_out[node, 0] = left
        child_out[node, 1] = right
        prim_range_out[left, 0] = lo
        prim_range_out[left, 1] = mid
        prim_range_out[right, 0] = mid
        prim_range_out[right, 1] = hi
        stack[top] = right
        stack[top + 1] = left
        top += 2
    return nodes


def build(centroids_per_mesh: list[np.ndarray], prim_offsets: list[int], median: bool = True) -> Bvh:
    """Trees over each mesh's primitives (centroids in the body frame; primitive p of mesh m is global
    index prim_offsets[m] + p): object-median trees, or with median=False in Morton order. Boxes are left
    empty: `refit` fills them."""
    starts, children, ranges, orders = [0], [], [], []
    node_off = 0
    for cent, off in zip(centroids_per_mesh, prim_offsets):
        n = cent.shape[0]
        cap = 2 * n + 1  # leaves hold from LEAF_SIZE // 2 + 1 primitives up: fewer than n nodes of each kind
        child = np.empty((cap, 2), np.int64)
        prange_ = np.empty((cap, 2), np.int64)
        count = _build(n, LEAF_SIZE, child, prange_) if n else 0
        if n == 0:
            child[0] = -1
            prange_[0] = 0
            count = 1
        child = child[:count]
        child[child >= 0] += node_off
        children.append(child)
        ranges.append(prange_[:count] + sum(o.shape[0] for o in orders))
        if n == 0:
            orders.append(np.zeros(0, np.int64))
        elif median:
            orders.append(median_order(np.ascontiguousarray(cent, np.float64), LEAF_SIZE).astype(np.int64) + off)
        else:
            orders.append(np.argsort(_morton(cent), kind="stable").astype(np.int64) + off)
        node_off += count
        starts.append(node_off)
    child = np.concatenate(children) if children else np.zeros((0, 2), np.int64)
    return Bvh(np.asarray(starts, np.int64), child, np.concatenate(ranges) if ranges else np.zeros((0, 2), np.int64),
               np.zeros((child.shape[0] + sum(o.shape[0] for o in orders), 6)),
               np.concatenate(orders) if orders else np.zeros(0, np.int64))


@nb.njit(cache=True)
def refit(first_node, last_node, child, prim_range, order, prim_box, box_out):
    """Boxes of nodes [first_node, last_node) (one mesh's tree) from the primitives' boxes prim_box
    (P, 6), children before parents."""
    for node in range(last_node - 1, first_node - 1, -1):
        if child[node, 0] < 0:
            for a in range(3):
                box_out[node, a] = np.inf
                box_out[node, 3 + a] = -np.inf
            for q in range(prim_range[node, 0], prim_range[node, 1]):
                p = order[q]
                for a in range(3):
                    box_out[node, a] = min(box_out[node, a], prim_box[p, a])
                    box_out[node, 3 + a] = max(box_out[node, 3 + a], prim_box[p, 3 + a])
        else:
            left = child[node, 0]
            right = child[node, 1]
            for a in range(3):
                box_out[node, a] = min(box_out[left, a], box_out[right, a])
                box_out[node, 3 + a] = max(box_out[left, 3 + a], box_out[right, 3 + a])


@nb.njit(cache=True)
def primitive_boxes(prims, vertices_a, vertices_b, box_out):
    """Box of each primitive (rows of vertex indices: triangles or edges) holding it at both vertex sets."""
    for p in range(prims.shape[0]):
        for a in range(3):
            lo = np.inf
            hi = -np.inf
            for c in range(prims.shape[1]):
                v = prims[p, c]
                lo = min(lo, vertices_a[v, a], vertices_b[v, a])
                hi = max(hi, vertices_a[v, a], vertices_b[v, a])
            box_out[p, a] = lo
            box_out[p, 3 + a] = hi


def refit_mesh(bvh: Bvh, m: int, prims: np.ndarray, prim_start: np.ndarray, vertices_a: np.ndarray,
               vertices_b: np.ndarray) -> None:
    """Refit mesh m's tree, its primitives' boxes first (rows prim_start[m]:prim_start[m+1] of `prims`,
    vertex indices into the concatenated vertex sets), between two vertex sets (the same for a static mesh)."""
    lo, hi = int(prim_start[m]), int(prim_start[m + 1])
    prim_box = bvh.box[bvh.child.shape[0]:]
    primitive_boxes(prims[lo:hi], vertices_a, vertices_b, prim_box[lo:hi])
    refit(bvh.node_start[m], bvh.node_start[m + 1], bvh.child, bvh.prim_range, bvh.order, prim_box, bvh.box)


# Traversal (the contact kernels, fraytool.sim.kernels.mesh_contact and mesh_clearance)

@nb.njit(cache=True, inline="always")
def overlaps(box, node, lo0, lo1, lo2, hi0, hi1, hi2):
    """Whether row `node` of a box array meets the query box [lo, hi]."""
    return not (box[node, 0] > hi0 or box[node, 3] < lo0 or box[node, 1] > hi1 or box[node, 4] < lo1
                or box[node, 2] > hi2 or box[node, 5] < lo2)


@nb.njit(cache=True, inline="always")
def prim_overlaps(box, child, j, lo0, lo1, lo2, hi0, hi1, hi2):
    """Whether primitive j's own box (row N + j of a tree's `box`, N its node count: child.shape[0]) meets
    the query box: a leaf's primitives are tested only then (a primitive outside the query box is farther
    than its pad from everything the query asks about)."""
    return overlaps(box, child.shape[0] + j, lo0, lo1, lo2, hi0, hi1, hi2)


@nb.njit(cache=True, inline="always")
def next_leaf(stack_inout, top, child, box, lo0, lo1, lo2, hi0, hi1, hi2):
    """The next leaf of a BVH traversal whose box meets the query box [lo, hi]: pops nodes off
    stack_inout (top entries; the caller pushes the root), pushes the children of inner nodes that
    meet it. Returns (leaf node, new top), or (-1, 0) when the traversal is done."""
    while top > 0:
        top -= 1
        node = stack_inout[top]
        if not overlaps(box, node, lo0, lo1, lo2, hi0, hi1, hi2):
            continue
        if child[node, 0] < 0:
            return node, top
        stack_inout[top] = child[node, 0]
        stack_inout[top + 1] = child[node, 1]
        top += 2
    return -1, 0
