"""Where a yarn can carry breaking tension: the two yarn-topology scans behind the cut rule
(docs/tearing.md "Cutting"; numba kernels over the yarns, O(crossings) per step).

- Fragments: a yarn is cut into pieces by its broken springs; for every live structural spring, how
  many crossings its piece holds on each side of it, up to the nearest free end (a cut, or the
  yarn's end at the cloth border). Tension in a yarn builds up from a free end only through friction
  at the crossings it passes, over the *ineffective length* of fibre mechanics (the length over
  which a broken fibre recovers its load, Cox 1952; for yarns in a weave a few crossings): a spring
  closer than that to a free end cannot be loaded to its break, so no break leaves a yarn piece
  shorter than `ineffective_length` crossings.
- Free runs: along a yarn, a run of yarn-level crossings (mass couples, connected or not) joined by
  live springs is *anchored* when both its ends reach base-level crossings (the intact weave grips
  the yarn there) and *free* when it reaches a cut or the cloth border: such a yarn slides out
  towards its loose end instead of holding tension, so its springs (and the springs joining the run
  to its anchor) do not break.
"""
from __future__ import annotations

import numba as nb
import numpy as np


ANCHORED = 1 << 30
"""Fragment size on a side held by a body: a grip pulls the yarn, whatever its distance to a free end."""


@nb.njit(cache=True, fastmath=False)
def _yarn_fragments(springs, crossings, crossing_attached, spring_alive, left_out, right_out):
    """Along one yarn (n structural springs joining its n + 1 crossings, in order): for every live
    spring k, the crossings its yarn piece holds on each side of it up to the nearest cut or the
    yarn's end: left_out[s] = k - a + 1, right_out[s] = b - k, with [a, b] the piece's crossings.
    A side that reaches a held crossing (an attachment) first counts as ANCHORED: the body pulls the
    yarn there, so tension does not fade towards that side."""
    n = springs.shape[0]
    a = 0
    for k in range(n):
        c = crossings[k]
        if c >= 0 and crossing_attached[c]:
            a = -ANCHORED
        s = springs[k]
        if s < 0 or not spring_alive[s]:  # a cut, or a shaped panel's border (no spring there)
            a = k + 1
            continue
        left_out[s] = k - a + 1
    b = n  # crossing index of the piece's right end
    for k in range(n - 1, -1, -1):
        c = crossings[k + 1]
        if c >= 0 and crossing_attached[c]:
            b = ANCHORED
        s = springs[k]
        if s < 0 or not spring_alive[s]:
            b = k
            continue
        right_out[s] = b - k


@nb.njit(cache=True, fastmath=False)
def yarn_fragments(model_in, springs_in, left_out, right_out):
    """For every live structural spring, the yarn crossings on each side of it up to the nearest free
    yarn end (a cut, or the yarn's end at the cloth border), ANCHORED where a held crossing comes first:
    `_yarn_fragments` on every yarn."""
    warp_yarns, weft_yarns = model_in.warp_yarns, model_in.weft_yarns
    weft_structural_spring, warp_structural_spring = model_in.weft_structural_spring, model_in.warp_structural_spring
    crossing_grid = model_in.crossing_grid
    crossing_attached = model_in.crossing_attached
    spring_alive = springs_in.spring_alive
    weft_crossings = np.empty(warp_yarns, np.int64)
    for j in range(weft_yarns):
        for i in range(warp_yarns):
            weft_crossings[i] = crossing_grid[j, i]
        _yarn_fragments(weft_structural_spring[j], weft_crossings, crossing_attached, spring_alive, left_out, right_out)
    warp_crossings = np.empty(weft_yarns, np.int64)
    for i in range(warp_yarns):
        for j in range(weft_yarns):
            warp_crossings[j] = crossing_grid[j, i]
        _yarn_fragments(warp_structural_spring[i], warp_crossings, crossing_attached, spring_alive, left_out, right_out)


@nb.njit(cache=True, fastmath=False)
def _alive(s, spring_alive):
    """Spring slot s (-1: none, at a shaped panel's border) is there and alive."""
    return s >= 0 and spring_alive[s]


@nb.njit(cache=True, fastmath=False)
def _mark_free_runs(crossings, springs, crossing_yarn_level, spring_alive, free_out):
    """Along one yarn (its crossings in order and the structural springs between them), flag the
    crossings of every run that reaches a free yarn end (module docstring)."""
    n = crossings.shape[0]
    start = 0
    while start < n:
        if crossings[start] < 0 or not crossing_yarn_level[crossings[start]]:
            start += 1
            continue
        end = start  # the run: yarn-level crossings joined by live springs, crossings[start..end]
        while end + 1 < n and _alive(springs[end], spring_alive) and crossing_yarn_level[crossings[end + 1]]:
            end += 1
        # a side is free at the border (or a shaped panel's) or across a cut spring; anchored at a
        # base-level crossing
        free = (start == 0 or not _alive(springs[start - 1], spring_alive)
                or end == n - 1 or not _alive(springs[end], spring_alive))
        if free:
            for k in range(start, end + 1):
                free_out[crossings[k]] = True
        start = end + 1


@nb.njit(cache=True, fastmath=False)
def free_yarn_runs(model_in, crossings_in, springs_in, weft_free_out, warp_free_out):
    """Flag the yarn-level crossings whose weft (resp. warp) is on a free run: a run of yarn-level
    crossings along that yarn, joined by live springs, that reaches a free yarn end (a cut or the
    border) before a base-level crossing anchors it (module docstring)."""
    warp_yarns, weft_yarns = model_in.warp_yarns, model_in.weft_yarns
    weft_structural_spring, warp_structural_spring = model_in.weft_structural_spring, model_in.warp_structural_spring
    crossing_grid = model_in.crossing_grid
    crossing_yarn_level = crossings_in.crossing_yarn_level
    spring_alive = springs_in.spring_alive
    weft_free_out[:] = False
    warp_free_out[:] = False
    weft_crossings = np.empty(warp_yarns, np.int64)
    for j in range(weft_yarns):
        for i in range(warp_yarns):
            weft_crossings[i] = crossing_grid[j, i]
        _mark_free_runs(weft_crossings, weft_structural_spring[j], crossing_yarn_level, spring_alive, weft_free_out)
    warp_crossings = np.empty(weft_yarns, np.int64)
    for i in range(warp_yarns):
        for j in range(weft_yarns):
            warp_crossings[j] = crossing_grid[j, i]
        _mark_free_runs(warp_crossings, warp_structural_spring[i], crossing_yarn_level, spring_alive, warp_free_out)
