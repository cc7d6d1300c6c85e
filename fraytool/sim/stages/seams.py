"""The seams stage: stitches that break one by one (docs/panels.md "Seams").

A stitch (spring kind STITCH, a thread between two panel edges; fraytool.sim.kernels.forces pulls
along it and never pushes) breaks when its strain passes its own break strain (the seam's, with
[cloth.tearing] break_strain_spread drawn from the seed). Like the method's springs (docs/method.md
§3.4 "springs are cut one by one"), at most one stitch breaks per step, the one furthest past its
limit, so a seam unzips stitch by stitch rather than all at once. Where a seam opens, the panel
edges are free: pulled further they fray as any torn edge. Only scenes with seams build this stage.

A seam sewn over time ([[seams]] sew_s; docs/garments.md) is pulled in by `Sewing`, first in the step: each
of its stitches' rest length goes from its length where the panels were placed to the stitch length
(fraytool.sim.model.sewn_rest_length_m), and StitchBreaking leaves it whole until its sewing is over.
"""
from __future__ import annotations

import numpy as np

from fraytool.kinds import STITCH
from fraytool.sim.model import Model, sewn_rest_length_m
from fraytool.sim.stages.base import POSITIONS, REST_LENGTHS, TOPOLOGY, StepContext
from fraytool.sim.state import State


class StitchBreaking:
    """Break the stitch furthest past its break strain, if any (one per step)."""

    name = "seams"
    kernel = "numpy over the stitches"
    reads = frozenset({POSITIONS, TOPOLOGY})
    writes = frozenset({TOPOLOGY})

    def __init__(self, model: Model):
        self.stitches = np.flatnonzero(model.spring_kind == STITCH)
        self.break_strain = model.spring_break_strain[self.stitches]
        self.sewn_by_s = model.spring_sew_s[self.stitches] if model.spring_sew_s.size else np.zeros(self.stitches.size)

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None:
        s = self.stitches
        alive = state.spring_alive[s] & (self.sewn_by_s <= state.time_s + dt_s)  # a stitch being sewn holds
        if not alive.any():
            return
        x = state.particle_position_m
        length = np.linalg.norm(x[state.spring_particle_b[s]] - x[state.spring_particle_a[s]], axis=1)
        over = np.where(alive, length / state.spring_rest_length_m[s] - 1.0 - self.break_strain, -np.inf)
        k = int(np.argmax(over))
        if over[k] > 0.0:
            state.spring_alive[s[k]] = False
            state.spring_broken[s[k]] = True
            state.bump_topology()

    def summary(self, state: State) -> dict:
        """`stitches` and `broken_stitches` for `fraytool simulate --json`."""
        return {"stitches": int(self.stitches.size),
                "broken_stitches": int(state.spring_broken[self.stitches].sum())}


class Sewing:
    """Pull the seams sewn over time in: their stitches' rest lengths at the end of this step (first in the
    step, so the forces see them). Built only where a seam has sew_s > 0."""

    name = "seams"
    kernel = "numpy over the sewn stitches"
    reads = frozenset()
    writes = frozenset({REST_LENGTHS})

    def __init__(self, model: Model):
        self.model = model
        self.sewn = np.flatnonzero(model.spring_sew_s > 0.0)
        self.until_s = float(model.spring_sew_s.max())

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None:
        if state.time_s > self.until_s:
            return  # sewn: the stitches are ordinary ones (a split may rescale their rest lengths)
        state.spring_rest_length_m[self.sewn] = sewn_rest_length_m(self.model, state.time_s + dt_s, self.sewn)

    def summary(self, state: State) -> dict:
        return {}
