"""Argument groups of the tearing kernels: named tuples of the arrays a kernel reads and writes.

A kernel takes a few groups instead of 25-odd positional arrays (grouped by role, as the kernels of
mujoco_warp are), and its parameter names say what it does with each group: `model_in` (read only), `springs_in` (read),
`springs_inout` (read and written), ... A group holds references to the Model's, the topology's
and the State's own arrays, never copies, so a write through `springs_inout.spring_alive` lands in
`State.spring_alive`. Field names are the array names of Model, TearTopology and State.

- `TearModel`: the static model arrays and topology tables, built once per YarnTearing.
- `TearParticles`, `TearCrossings`, `TearSprings`: the State arrays of particles, crossings and
  springs, built by `state_groups` at each call (three tuples of references, a few microseconds;
  State is a mutable dataclass, so a tuple kept across calls could outlive a replaced array).
The step's previous positions are no State field (a step buffer): kernels take that array alone.

numba types a namedtuple of arrays and scalars as a struct (one type per class and field types) and
caches kernels taking them like any other (cache=True: the classes are pickled by reference, so they
live here, at module level, and must not be renamed without a cache wipe, which
fraytool._numba_cache does on any source change anyway).
"""
from __future__ import annotations

from collections import namedtuple

from fraytool.sim.model import Model
from fraytool.sim.state import State
from fraytool.sim.tearing.topology import TearTopology

__all__ = ["TearModel", "TearParticles", "TearCrossings", "TearSprings", "tear_model", "state_groups"]

TearModel = namedtuple("TearModel", [
    # scalars
    "warp_yarns", "weft_yarns", "yarn_count", "thickness_m", "disconnect_distance_m", "transition_strain",
    "propagation_inclusive", "ineffective_length",
    # crossings (Model)
    "crossing_weft_on_top", "crossing_weft_springs", "crossing_warp_springs", "crossing_grid",
    # springs (Model)
    "spring_kind", "spring_crossing_a", "spring_crossing_b", "spring_twin",
    "spring_break_strain", "weft_structural_spring", "warp_structural_spring",
    # lookup tables (TearTopology)
    "crossing_spring_start", "crossing_spring_list", "crossing_attached", "structural_springs",
    "structural_yarn", "structural_bend_start", "structural_bend_list", "structural_shear_start",
    "structural_shear_list",
])
TearModel.__doc__ = """Read-only inputs of the tearing kernels: Model scalars and arrays, TearTopology tables
(yarn_count = warp_yarns + weft_yarns, the length of the per-yarn tables)."""

TearParticles = namedtuple("TearParticles", [
    "particle_position_m", "particle_velocity_m_s", "particle_mass_kg", "particle_inv_mass", "particle_active",
])
TearParticles.__doc__ = "State arrays of the particles (masses), shape (particle_count, ...)."

TearCrossings = namedtuple("TearCrossings", ["crossing_yarn_level", "couple_connected"])
TearCrossings.__doc__ = "State arrays of the crossings (split? couple still in contact?), shape (crossing_count,)."

TearSprings = namedtuple("TearSprings", [
    "spring_particle_a", "spring_particle_b", "spring_alive", "spring_broken", "spring_stiffness_n_per_m",
    "spring_rest_length_m",
])
TearSprings.__doc__ = "State arrays of the springs (ends, alive/broken flags, stiffness), shape (spring_count,)."


def tear_model(model: Model, topology: TearTopology) -> TearModel:
    """The `model_in` group of `model` and its lookup tables (references, no copies)."""
    m, t = model, topology
    return TearModel(
        warp_yarns=m.warp_yarns, weft_yarns=m.weft_yarns, yarn_count=m.warp_yarns + m.weft_yarns,
        thickness_m=m.thickness_m, disconnect_distance_m=m.disconnect_distance_m,
        transition_strain=m.transition_strain, propagation_inclusive=m.propagation_inclusive,
        ineffective_length=m.ineffective_length,
        crossing_weft_on_top=m.crossing_weft_on_top, crossing_weft_springs=m.crossing_weft_springs,
        crossing_warp_springs=m.crossing_warp_springs, crossing_grid=t.crossing_grid,
        spring_kind=m.spring_kind, spring_crossing_a=m.spring_crossing_a, spring_crossing_b=m.spring_crossing_b,
        spring_twin=m.spring_twin,
        spring_break_strain=m.spring_break_strain, weft_structural_spring=m.weft_structural_spring,
        warp_structural_spring=m.warp_structural_spring,
        crossing_spring_start=t.crossing_spring_start, crossing_spring_list=t.crossing_spring_list,
        crossing_attached=t.crossing_attached, structural_springs=t.structural_springs,
        structural_yarn=t.structural_yarn, structural_bend_start=t.structural_bend_start,
        structural_bend_list=t.structural_bend_list, structural_shear_start=t.structural_shear_start,
        structural_shear_list=t.structural_shear_list,
    )


def state_groups(state: State) -> tuple[TearParticles, TearCrossings, TearSprings]:
    """The particle, crossing and spring groups of `state` (references to its arrays)."""
    s = state
    return (
        TearParticles(s.particle_position_m, s.particle_velocity_m_s, s.particle_mass_kg, s.particle_inv_mass,
                      s.particle_active),
        TearCrossings(s.crossing_yarn_level, s.couple_connected),
        TearSprings(s.spring_particle_a, s.spring_particle_b, s.spring_alive, s.spring_broken,
                    s.spring_stiffness_n_per_m, s.spring_rest_length_m),
    )
