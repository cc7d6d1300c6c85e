"""The yarn-level model's two stages (docs/method.md §3.3, §3.4): contact at connected mass couples
(step 5) and transitions plus cuts (step 7). Both share one YarnTearing (fraytool.sim.tearing)."""
from __future__ import annotations

from fraytool.sim.model import Model
from fraytool.sim.stages.base import StepBuffers
from fraytool.sim.state import State
from fraytool.sim.tearing import YarnTearing


class YarnContactStage:
    """Step 5: contact projection at every connected couple (§3.3)."""

    name = "yarn_contact"
    kernel = "project_couples"

    def __init__(self, tearing: YarnTearing):
        self.tearing = tearing

    def run(self, state: State, buffers: StepBuffers, dt_s: float) -> None:
        self.tearing.contact(state, buffers.prev_position_m, dt_s)

    def summary(self, state: State) -> dict:
        return {}


class TearingStage:
    """Step 7: transitions of over-strained springs to the yarn level (yarn-level model only), then
    cuts of springs over their break strain (§3.4, §4.1)."""

    name = "tearing"
    kernel = "transition_overstrained, cut_overstrained"

    def __init__(self, model: Model):
        self.tearing = YarnTearing(model)
        self.yarn_level = self.tearing.yarn_level

    def run(self, state: State, buffers: StepBuffers, dt_s: float) -> None:
        self.tearing(state, buffers.prev_position_m, dt_s)

    def summary(self, state: State) -> dict:
        return self.tearing.summary(state)
