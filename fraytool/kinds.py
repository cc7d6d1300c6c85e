"""Shared words: the integer codes stored in arrays for spring kinds, body shapes and motions.

A leaf module (imports nothing of fraytool), so that every layer, from scene loading to rendering,
names these codes the same way without importing the simulation. The layout they index is in
docs/architecture.md.
"""
from __future__ import annotations

# Spring kinds (spring_kind values).
STRUCT_WEFT = 0
STRUCT_WARP = 1
BEND_WEFT = 2
BEND_WARP = 3
SHEAR = 4
SHEAR_TWIN = 5
STITCH = 6
"""A seam's stitch ([[seams]]): a thread joining two panel edges, acting only in tension."""
SPRING_KIND_NAMES = ("structural_weft", "structural_warp", "bend_weft", "bend_warp", "shear", "shear_twin", "stitch")

# Rigid body shapes and motions (body_shape, body_motion values).
SHAPE_SPHERE, SHAPE_BOX, SHAPE_PLANE, SHAPE_MESH = 0, 1, 2, 3
SHAPE_NAMES = ("sphere", "box", "plane", "mesh")
MOTION_STATIC, MOTION_KINEMATIC, MOTION_DYNAMIC = 0, 1, 2
MOTION_NAMES = ("static", "kinematic", "dynamic")
INTERPOLATION_NAMES = ("linear", "catmull_rom")
"""How a kinematic body's path and orientation keys are interpolated (fraytool.sim.paths)."""
