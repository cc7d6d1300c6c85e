"""The yarn-level model's two stages (docs/method.md §3.3, §3.4): contact at connected mass couples
(step 5) and transitions plus cuts (step 7). Both run the one YarnTearing (fraytool.sim.tearing) that
the step context holds (StepContext.yarn_tearing)."""
from __future__ import annotations

from fraytool.sim.stages.base import POSITIONS, SLAVED_NEAR_HOT, START_POSITIONS, TOPOLOGY, StepContext
from fraytool.sim.state import State


class YarnContactStage:
    """Step 5: contact projection at every connected couple (§3.3)."""

    name = "yarn_contact"
    kernel = "project_couples"
    reads = frozenset({POSITIONS, START_POSITIONS, TOPOLOGY})
    writes = frozenset({POSITIONS, TOPOLOGY})

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None:
        ctx.yarn_tearing.contact(state, ctx.prev_position_m, dt_s)

    def summary(self, state: State) -> dict:
        return {}


class TearingStage:
    """Step 7: transitions of over-strained springs to the yarn level (yarn-level model only), then
    cuts of springs over their break strain (§3.4, §4.1). With a coarse model it scans only the
    springs at work (StepContext.working_springs) and reads the slaved crossings near hot cells (a
    split reads its neighbours for the couple's normal, its settle the yarn segments it may carry
    through)."""

    name = "tearing"
    kernel = "transition_overstrained, cut_overstrained"
    reads = frozenset({POSITIONS, START_POSITIONS, SLAVED_NEAR_HOT, TOPOLOGY})
    writes = frozenset({POSITIONS, START_POSITIONS, TOPOLOGY})

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None:
        tearing = ctx.yarn_tearing
        tearing.restrict_scans(*ctx.working_springs(state))
        tearing(state, ctx.prev_position_m, dt_s)

    def summary(self, state: State) -> dict:
        return {}
