"""Simulation: Builder -> Model (static) + State (changes) -> Solver (docs/method.md §3-§4).

Never imports rendering: the renderer reads only FrameRecords and the saved topology.
"""
from fraytool.sim.builder import ModelBuilder, ModelBuilderError, build_model, scene_builder
from fraytool.sim.model import Model
from fraytool.sim.simulation import Simulation
from fraytool.sim.solver import SimulationUnstable, SolverExplicitPBD
from fraytool.sim.state import State

__all__ = ["ModelBuilder", "ModelBuilderError", "build_model", "scene_builder", "Model", "State", "Simulation", "SolverExplicitPBD",
           "SimulationUnstable"]
