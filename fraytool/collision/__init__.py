"""Self-collision detection for yarn segments (springs), docs/method.md §4.2.

- :func:`edge_edge_ccd`, :func:`edge_edge_ccd_kernel`, :func:`edge_edge_ccd_many`: conservative
  edge-edge continuous collision detection over one step (narrow phase,
  :mod:`fraytool.collision.ccd`).
- :func:`find_candidate_pairs`: swept-box sort-and-sweep in grid columns (broad phase,
  :mod:`fraytool.collision.broadphase`).
- :func:`detect_edge_edge_collisions`: broad + narrow phase for all springs
  (:mod:`fraytool.collision.detect`).

- :mod:`fraytool.collision.candidates`: candidate pairs kept valid across steps (re-box, patch);
  :mod:`fraytool.collision.narrow`: separation pre-tests and the CCD over candidate pairs.

Pure geometry: nothing here knows the solver. The self-collision stage that uses it (response,
failsafe) is :mod:`fraytool.sim.stages.self_collision`, loaded only for scenes with self-collision on.
"""
from fraytool.collision.broadphase import find_candidate_pairs, find_candidate_pairs_kernel
from fraytool.collision.ccd import (
    NO_HIT_TIME,
    edge_edge_ccd,
    edge_edge_ccd_kernel,
    edge_edge_ccd_many,
)
from fraytool.collision.detect import (
    detect_edge_edge_collisions,
    detect_edge_edge_collisions_kernel,
)

__all__ = [
    "NO_HIT_TIME",
    "detect_edge_edge_collisions",
    "detect_edge_edge_collisions_kernel",
    "edge_edge_ccd",
    "edge_edge_ccd_kernel",
    "edge_edge_ccd_many",
    "find_candidate_pairs",
    "find_candidate_pairs_kernel",
]
