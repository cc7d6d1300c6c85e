#!/usr/bin/env python
"""Mutation run: does the test suite catch small wrong changes of the code?

    python benchmarks/mutation.py [--jobs 2] [--only N,M,...] [--list] [--timeout S]

Each entry of MUTATIONS is one small change (a constant 1 % off, a sign flipped, a check removed, an
off-by-one) in one area (tearing, strain limiting, self-collision, rigid contact, multi-resolution,
rendering, io, farm). For each, a copy of the checkout (the files git knows, as they are in the working
tree) gets the change, and the tests named for that area run on it (`python -m pytest -x -q`, with the
copy first on PYTHONPATH). The mutation is *caught* when they fail, *survived* when they pass. Prints a
line per mutation (area, caught / survived, seconds) and the totals; exit 0 when at least 90 % are
caught, 1 otherwise. Each copy compiles its own numba kernels (a changed source drops the cache), so a
mutation costs a minute or two; --jobs 2 runs two at a time (one per core).

Survivors and why they are accepted are listed in docs/testing.md. This is a benchmark, not part of
the suite (`.ci/run` does not run it).
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
GOAL = 0.90


@dataclass(frozen=True)
class Mutation:
    area: str
    what: str
    path: str
    old: str
    new: str
    tests: tuple


M = Mutation
MESH_TESTS = ("tests/test_mesh_magnitudes.py", "tests/test_mesh_check.py", "tests/test_mesh_bodies.py")
CLEARANCE_TESTS = ("tests/test_mesh_clearance.py",)
LEAF_CACHE_TESTS = ("tests/test_mesh_leaf_cache.py",)
MULTIRES_MESH_TESTS = ("tests/test_multires_mesh.py",)
MULTIRES_PANEL_TESTS = ("tests/test_multires_panels.py",)
SEAM_TESTS = ("tests/test_seams.py",)
GARMENT_TESTS = ("tests/test_sewing.py", "tests/test_surface_pins.py")
AIR_TESTS = ("tests/test_wind.py",)
CAMERA_TESTS = ("tests/test_camera_keys.py", "tests/test_framing.py::test_framing_counts_what_leaves_the_picture_and_what_is_behind_the_eye")
PANEL_TESTS = ("tests/test_panels.py", "tests/test_tear_control.py", "tests/test_seams.py", "tests/test_plane.py",
               "tests/test_cuts.py")
GOLDEN_TESTS = ("tests/test_verdicts_and_outputs.py", "tests/test_scene_keys.py", "tests/test_golden.py")
OUTPUT_TESTS = ("tests/test_verdicts_and_outputs.py", "tests/test_output_faults.py", "tests/test_render_cli.py")
FARM_TESTS = ("tests/test_verdicts_and_outputs.py", "tests/test_farm_report.py")
MUTATIONS = [
    # -- strain limiting
    M("strain limiting", "hard limit 1 % looser in the stage", "fraytool/sim/stages/core.py",
      "limit = (m.strain_limit, m.strain_tolerance", "limit = (1.01 * m.strain_limit, m.strain_tolerance",
      ("tests/test_magnitudes.py", "tests/test_strain_limit.py")),
    M("strain limiting", "compliant line solve 1 % looser", "fraytool/sim/kernels/strain_limit.py",
      "    stretch = 1.0 + strain_limit\n    alpha = compliance_s2_per_kg",
      "    stretch = 1.0 + 1.01 * strain_limit\n    alpha = compliance_s2_per_kg",
      ("tests/test_magnitudes.py", "tests/test_strain_limit.py")),
    M("strain limiting", "dashpot off", "fraytool/sim/stages/core.py",
      "if m.strain_damping_n_s_per_m > 0.0:", "if m.strain_damping_n_s_per_m > 1e30:",
      ("tests/test_magnitudes.py", "tests/test_strain_limit.py")),
    M("strain limiting", "colour groups converge early (10x tolerance)", "fraytool/sim/kernels/strain_limit.py",
      "            if group_worst > worst:\n                worst = group_worst\n        if worst <= tolerance:",
      "            if group_worst > worst:\n                worst = group_worst\n        if worst <= 10.0 * tolerance:",
      ("tests/test_strain_limit.py", "tests/test_magnitudes.py")),
    # -- tearing
    M("tearing", "break strain 1 % higher", "fraytool/sim/tearing/cut.py",
      "limit = (1.0 + spring_break_strain[s]) * spring_rest_length_m[s]",
      "limit = (1.0 + 1.01 * spring_break_strain[s]) * spring_rest_length_m[s]",
      ("tests/test_tearing_cut.py", "tests/test_tearing_scenes.py", "tests/test_pinned_figures.py")),
    M("tearing", "transition strain 1 % higher", "fraytool/sim/tearing/split.py",
      "stretch = 1.0 + transition_strain", "stretch = 1.0 + 1.01 * transition_strain",
      ("tests/test_tearing_split.py", "tests/test_pinned_figures.py")),
    M("tearing", "split masses not halved", "fraytool/sim/tearing/split.py",
      "    particle_mass_kg[c] = 0.5 * m\n", "    particle_mass_kg[c] = 0.55 * m\n",
      ("tests/test_tearing_split.py",)),
    M("tearing", "couples disconnect 10 % later", "fraytool/sim/tearing/contact.py",
      "if not (dmin <= disconnect_distance_m):", "if not (dmin <= 1.1 * disconnect_distance_m):",
      ("tests/test_tearing_contact.py", "tests/test_pinned_figures.py")),
    M("tearing", "ineffective length off by one", "fraytool/sim/tearing/cut.py",
      "if fragment_left_in[s] < ineffective_length or fragment_right_in[s] < ineffective_length:",
      "if fragment_left_in[s] <= ineffective_length or fragment_right_in[s] <= ineffective_length:",
      ("tests/test_tearing_cut.py", "tests/test_pinned_figures.py")),
    # -- self-collision
    M("self-collision", "friction impulse sign flipped", "fraytool/sim/kernels/self_collision.py",
      "    c0 = lam * n0 - f * t0", "    c0 = lam * n0 + f * t0",
      ("tests/test_magnitudes.py", "tests/test_self_collision.py")),
    M("self-collision", "cross-plane pre-test 1 % looser", "fraytool/collision/narrow.py",
      "return gap > 0.0 and gap * gap > gap_m * gap_m * nn",
      "return gap > 0.0 and gap * gap > 0.98 * gap_m * gap_m * nn",
      ("tests/test_magnitudes.py", "tests/test_narrow_pretests.py")),
    M("self-collision", "contact distance 10 % shorter", "fraytool/sim/stages/self_collision.py",
      "self.contact_distance_m = CONTACT_FRACTION * model.thickness_m",
      "self.contact_distance_m = 0.9 * CONTACT_FRACTION * model.thickness_m",
      ("tests/test_magnitudes.py", "tests/test_self_collision.py")),
    M("self-collision", "pushes stop short (90 % of the gap)", "fraytool/sim/kernels/self_collision.py",
      "    lam = (contact_distance_m - gap) / denom", "    lam = 0.9 * (contact_distance_m - gap) / denom",
      ("tests/test_magnitudes.py", "tests/test_self_collision.py")),
    # -- rigid contact
    M("rigid contact", "friction limit doubled", "fraytool/sim/kernels/rigid_contact.py",
      "nx, ny, nz, friction * (-d))", "nx, ny, nz, 2.0 * friction * (-d))",
      ("tests/test_rigid_bodies.py", "tests/test_pinned_figures.py")),
    M("rigid contact", "contact margin 10 % thinner", "fraytool/sim/stages/core.py",
      "bodies_in(m, state, self.collide), 0.5 * m.thickness_m, dt_s", "bodies_in(m, state, self.collide), 0.45 * m.thickness_m, dt_s",
      ("tests/test_rigid_bodies.py", "tests/test_pinned_figures.py")),
    M("rigid contact", "reaction on dynamic bodies halved", "fraytool/sim/rigid.py",
      "state.body_velocity_m_s[dyn] -= body_impulse_ns[dyn] / model.body_mass_kg[dyn, None]",
      "state.body_velocity_m_s[dyn] -= 0.5 * body_impulse_ns[dyn] / model.body_mass_kg[dyn, None]",
      ("tests/test_rigid_bodies.py", "tests/test_pinned_figures.py")),
    M("rigid contact", "sphere radius read 1 % small in contact", "fraytool/sim/kernels/rigid_contact.py",
      "d, nx, ny, nz = r - bodies_in.params[k, 0] - margin_m, ex / r, ey / r, ez / r",
      "d, nx, ny, nz = r - 0.99 * bodies_in.params[k, 0] - margin_m, ex / r, ey / r, ez / r",
      ("tests/test_rigid_bodies.py", "tests/test_pinned_figures.py")),
    # -- multi-resolution
    M("multi-resolution", "slaved forces handed on at 90 %", "fraytool/sim/kernels/multires.py",
      "                particle_force_n_inout[node, 0] += w * fx",
      "                particle_force_n_inout[node, 0] += 0.9 * w * fx",
      ("tests/test_multires.py",)),
    M("multi-resolution", "slaved contact moves nodes 10 % short", "fraytool/sim/kernels/multires.py",
      "        g = crossing_weight[s, q] * particle_inv_mass[node] / norm",
      "        g = 0.9 * crossing_weight[s, q] * particle_inv_mass[node] / norm",
      ("tests/test_multires.py",)),
    M("multi-resolution", "no sync of the hanging nodes before strain limiting", "fraytool/sim/stages/core.py",
      "    reads = frozenset({POSITIONS, START_POSITIONS, HANGING, TOPOLOGY})",
      "    reads = frozenset({POSITIONS, START_POSITIONS, TOPOLOGY})",
      ("tests/test_multires.py", "tests/test_step_contract.py")),
    M("multi-resolution", "refine band one cell narrower", "fraytool/sim/kernels/multires.py",
      "    mark_band(hot_inout, band, cells_x, cells_y, new_inout)",
      "    mark_band(hot_inout, band - 1, cells_x, cells_y, new_inout)",
      ("tests/test_multires.py",)),
    # -- rendering
    M("rendering", "Kajiya-Kay exponent 10 % off", "shaders/yarn.vert",
      "pow(cos_cone, u_shininess)", "pow(cos_cone, 1.1 * u_shininess)", ("tests/test_render_golden.py",)),
    M("rendering", "broken ends fade over half the length", "fraytool/render/tube.py",
      "                a = min(a, (s[k] - s[first]) / fade_length_m)",
      "                a = min(a, 2.0 * (s[k] - s[first]) / fade_length_m)",
      ("tests/test_render_geometry.py", "tests/test_render_golden.py")),
    M("rendering", "sRGB encoding exponent 2.2", "fraytool/render/color.py",
      "1.055 * c ** (1.0 / 2.4) - 0.055", "1.055 * c ** (1.0 / 2.2) - 0.055",
      ("tests/test_render_gl.py", "tests/test_render_outputs.py")),
    M("rendering", "centripetal knots become chordal", "fraytool/render/spline.py",
      "(d0 * d0 + d1 * d1 + d2 * d2) ** (0.5 * alpha)", "(d0 * d0 + d1 * d1 + d2 * d2) ** (0.5 * 2.0 * alpha)",
      ("tests/test_render_geometry.py", "tests/test_render_golden.py")),
    # -- io
    M("io", "frame checksums not checked", "fraytool/io/frame_store.py",
      "    if arrays_checksum(arrays, stored_hash) != str(checksum):",
      "    if False and arrays_checksum(arrays, stored_hash) != str(checksum):",
      ("tests/test_magnitudes.py", "tests/test_output_faults.py")),
    M("io", "manifest checksum not checked", "fraytool/io/frame_store.py",
      "        if not isinstance(data, dict) or data.get(\"checksum\") != _manifest_checksum(data):",
      "        if not isinstance(data, dict):",
      ("tests/test_output_faults.py",)),
    M("io", "resume re-simulates from frame 0", "fraytool/sim/run.py",
      "    if good > 0 and survey.resumable_from_checkpoint():",
      "    if False and good > 0 and survey.resumable_from_checkpoint():",
      ("tests/test_magnitudes.py", "tests/test_frames_determinism.py")),
    M("io", "stale lock after 12 s", "fraytool/io/lock.py",
      "STALE_AFTER_S = 120.0", "STALE_AFTER_S = 12.0", ("tests/test_output_faults.py",)),
    # -- farm
    M("farm", "wedge range loses its last value", "fraytool/farm/shots.py",
      "        count = int(math.floor((b - a) / step + 1e-9)) + 1",
      "        count = int(math.floor((b - a) / step + 1e-9))",
      ("tests/test_batch.py",)),
    M("farm", "a retried task starts from scratch", "fraytool/farm/tasks.py",
      "    resume = store.manifest() is None or store.matches(scene_hash(spec))",
      "    resume = False",
      ("tests/test_batch.py",)),
    # -- mesh contact (issue 50: each pinned by what it does, tests/test_mesh_magnitudes.py)
    M("mesh", "contact margin 5 % larger", "fraytool/sim/stages/mesh_contact.py",
      "margin = 0.5 * m.thickness_m", "margin = 0.525 * m.thickness_m", MESH_TESTS),
    M("mesh", "least face-on of equally near triangles", "fraytool/sim/kernels/mesh_contact.py",
      "(tie and (align > best_align or", "(tie and (align < best_align or", MESH_TESTS),
    M("mesh", "a sequence that renumbers its triangles accepted", "fraytool/scene/mesh_files.py",
      " or not np.array_equal(tri, triangles)", "", MESH_TESTS),
    M("mesh", "sharp-edge angle 31.5 degrees", "fraytool/meshes.py",
      "SHARP_DEG = 30.0", "SHARP_DEG = 31.5", MESH_TESTS),
    M("mesh", "an open mesh's borders not sharp", "fraytool/scene/mesh_files.py",
      "    sharp = counts != 2\n", "    sharp = counts > 2\n", MESH_TESTS),
    M("mesh", "broad-phase box from the later key only", "fraytool/sim/mesh_geometry.py",
      "for k in range(first, max(last, first) + 1)", "for k in range(max(last, first), max(last, first) + 1)",
      MESH_TESTS),
    M("mesh", "friction 10 % weaker on meshes", "fraytool/sim/kernels/mesh_contact.py",
      "gx, gy, gz, friction * max(depth, 0.0))", "gx, gy, gz, 0.9 * friction * max(depth, 0.0))", MESH_TESTS),
    M("mesh", "one resolution pass per mass", "fraytool/sim/kernels/mesh_contact.py",
      "PASSES = 3\n", "PASSES = 1\n", MESH_TESTS),
    M("mesh", "a closed mesh's inward normals kept", "fraytool/scene/mesh_files.py",
      "if closed and _signed_volume(keys[0], tri) < 0.0:", "if closed and _signed_volume(keys[0], tri) > 0.0:",
      MESH_TESTS),
    M("mesh", "a non-finite vertex accepted", "fraytool/scene/mesh_files.py",
      "    bad = ~np.isfinite(keys)\n    if bad.any():", "    bad = ~np.isfinite(keys)\n    if False:", MESH_TESTS),
    M("mesh", "scale not applied", "fraytool/sim/body_layout.py",
      "keys.append((a.key_vertices * scale).reshape(-1, 3))", "keys.append((a.key_vertices * 1.0).reshape(-1, 3))",
      MESH_TESTS),
    M("mesh", "sequence_start_s ignored", "fraytool/sim/body_layout.py",
      "a.key_time_s + (bd.start_s + bd.sequence_start_s)", "a.key_time_s + bd.start_s", MESH_TESTS),
    M("mesh", "an open mesh without its warning", "fraytool/sim/builder.py",
      "        if not asset.closed:", "        if False:", MESH_TESTS),
    M("mesh", "border edges counted with the inner ones", "fraytool/sim/mesh_report.py",
      "return int((counts == 1).sum())", "return int((counts <= 2).sum())", MESH_TESTS),
    M("mesh", "a mesh sequence held one key late", "fraytool/meshes.py",
      "    j = int(np.searchsorted(times, time_s, side=\"right\"))\n    i = j - 1",
      "    j = int(np.searchsorted(times, time_s, side=\"right\"))\n    i = max(j - 2, 0)", MESH_TESTS),
    # -- panels, seams, tear control
    M("seams", "the first stitch past its limit breaks, not the furthest", "fraytool/sim/stages/seams.py",
      "k = int(np.argmax(over))", "k = int(np.argmax(over > 0.0))", SEAM_TESTS),
    M("seams", "stitches 10 % longer at rest", "fraytool/sim/builder.py",
      "rest_m = seam.stitch_length_m or self.cloth.spacing_m", "rest_m = 1.1 * (seam.stitch_length_m or self.cloth.spacing_m)",
      SEAM_TESTS),
    M("seams", "stitch break strain 10 % higher", "fraytool/sim/builder.py",
      "np.maximum(s.break_strain + t.break_strain_spread", "np.maximum(1.1 * s.break_strain + t.break_strain_spread",
      SEAM_TESTS),
    M("seams", "stitches 10 % softer", "fraytool/sim/builder.py",
      "np.full(len(pairs), seam.stiffness_n_per_m)", "np.full(len(pairs), 0.9 * seam.stiffness_n_per_m)",
      SEAM_TESTS),
    M("seams", "a stitch pushes", "fraytool/sim/kernels/forces.py",
      "if stretch < 0.0 and kind == STITCH:", "if stretch < -1e30 and kind == STITCH:", SEAM_TESTS),
    M("seams", "a stitch breaks 1 % past its limit", "fraytool/sim/stages/seams.py",
      "        if over[k] > 0.0:", "        if over[k] > 0.01:", SEAM_TESTS),
    M("seams", "a seam's first break recorded a frame late", "fraytool/sim/simulation.py",
      "record[newly] = self.frame", "record[newly] = self.frame + 1", SEAM_TESTS),
    M("seams", "a seam's first break is its last", "fraytool/sim/tear_control_figures.py",
      '"first_break_frame": int(frames.min())', '"first_break_frame": int(frames.max())', SEAM_TESTS),
    M("panels", "a spring hemmed when either end is", "fraytool/sim/builder.py",
      "is_structural(kind) & hemmed[a] & hemmed[b]", "is_structural(kind) & (hemmed[a] | hemmed[b])", PANEL_TESTS),
    M("panels", "a hem 1.9 times as strong", "fraytool/sim/builder.py",
      "hemmed[a] & hemmed[b]] *= 2.0", "hemmed[a] & hemmed[b]] *= 1.9", PANEL_TESTS),
    M("panels", "a weak line weakens springs outside its panel", "fraytool/sim/builder.py",
      "springs = num.spring_index[k][near]", "springs = np.flatnonzero(near)", PANEL_TESTS),
    M("panels", "a weak line's factor 5 % off", "fraytool/sim/builder.py",
      "draw[springs] *= self.weak_lines[index].factor", "draw[springs] *= 1.05 * self.weak_lines[index].factor",
      PANEL_TESTS),
    M("panels", "a weak line 10 % wider", "fraytool/sim/builder.py",
      "<= 0.5 * line.width_m)", "<= 0.55 * line.width_m)", PANEL_TESTS),
    M("panels", "a tear map's range 5 % wider", "fraytool/sim/panel_layout.py",
      "mean = lo + (hi - lo) * sample_map(", "mean = lo + 1.05 * (hi - lo) * sample_map(", PANEL_TESTS),
    M("panels", "a tear map read upside down", "fraytool/scene/panel_shape.py",
      "py = np.clip(np.floor((1.0 - (uv_m[:, 1] - v0) / (v1 - v0)) * rows)",
      "py = np.clip(np.floor(((uv_m[:, 1] - v0) / (v1 - v0)) * rows)", PANEL_TESTS),
    M("panels", "scissors a step late", "fraytool/sim/tearing/__init__.py",
      "(self._scissor_time_s <= state.time_s + dt_s)", "(self._scissor_time_s <= state.time_s)", PANEL_TESTS),
    M("panels", "scissors 5 % slower", "fraytool/sim/builder.py",
      "times = cut.start_s + f[hit] * (cut.end_s - cut.start_s)",
      "times = cut.start_s + f[hit] * 1.05 * (cut.end_s - cut.start_s)", PANEL_TESTS),
    M("panels", "yz panels' weft along z", "fraytool/sim/panel_layout.py",
      '"yz": (1, 2)}', '"yz": (2, 1)}', PANEL_TESTS),
    # -- golden, outputs, farm
    # -- garments: sewing, surface pins, release, catch, gravity's start
    M("garments", "sewing pulls linearly, with a jolt", "fraytool/sim/model.py",
      "return np.where(sew_s > 0.0, u * u * (3.0 - 2.0 * u), 1.0)", "return np.where(sew_s > 0.0, u, 1.0)",
      GARMENT_TESTS),
    M("garments", "a stitch being sewn can break", "fraytool/sim/stages/seams.py",
      "alive = state.spring_alive[s] & (self.sewn_by_s <= state.time_s + dt_s)", "alive = state.spring_alive[s]",
      GARMENT_TESTS),
    M("garments", "a surface pin loses its normal offset", "fraytool/sim/surface_pins.py",
      "+ self.offset_m[mine, None] * unit_normals(corners))", "+ 0.0 * unit_normals(corners))", GARMENT_TESTS),
    M("garments", "a release ignores the held mass's weight", "fraytool/sim/stages/core.py",
      "pull = ctx.force_n[p] + state.particle_mass_kg[p, None] * self.model.gravity_at_m_s2(state.time_s)",
      "pull = ctx.force_n[p]", GARMENT_TESTS),
    M("garments", "a hook catches a step late", "fraytool/sim/stages/core.py",
      "now = k[(self.model.attachment_catch_s[k] >= state.time_s) & (self.model.attachment_catch_s[k] < state.time_s + dt_s)]",
      "now = k[(self.model.attachment_catch_s[k] >= state.time_s - dt_s) & (self.model.attachment_catch_s[k] < state.time_s)]",
      GARMENT_TESTS),
    M("garments", "gravity from the start", "fraytool/sim/model.py",
      "return self.gravity_m_s2 if time_s >= self.gravity_start_s else np.zeros(3)", "return self.gravity_m_s2",
      GARMENT_TESTS),
    # -- air: drag, wind, gusts; the moving camera
    M("air", "drag pressure doubled", "fraytool/sim/air.py",
      "0.5 * float(model.air_density_kg_m3)", "1.0 * float(model.air_density_kg_m3)", AIR_TESTS),
    M("air", "no tangential drag on a loose yarn", "fraytool/sim/kernels/air.py",
      "_add_drag(p, r0, r1, r2, t0 / tl, t1 / tl, t2 / tl, half_rho * ct * area, half_rho * cn * area,",
      "_add_drag(p, r0, r1, r2, t0 / tl, t1 / tl, t2 / tl, 0.0 * ct * area, half_rho * cn * area,", AIR_TESTS),
    M("air", "drag without its impulse cap", "fraytool/sim/kernels/air.py",
      "c = min(share * k * speed, particle_mass_kg[p] / dt_s)", "c = share * k * speed", AIR_TESTS),
    M("air", "gusts 10 % longer than asked", "fraytool/sim/air.py",
      "wave = rng.normal(0.0, 1.0 / length_m, (modes, 3))", "wave = rng.normal(0.0, 0.9 / length_m, (modes, 3))",
      AIR_TESTS),
    M("air", "the gusts stand still in the mean wind", "fraytool/sim/kernels/air.py",
      "x0 = point_m[n, 0] - wind_m_s[0] * time_s", "x0 = point_m[n, 0]", AIR_TESTS),
    M("camera", "the camera ignores its keys", "fraytool/render/camera.py",
      "spec = camera_at(spec, time_s)", "spec = spec", CAMERA_TESTS),
    M("golden", "a warning then a failure is a warning", "fraytool/golden/compare.py",
      "if status == FAIL or self.status == PASS:", "if self.status == PASS:", GOLDEN_TESTS),
    M("golden", "image failpercent doubled", "fraytool/golden/compare.py",
      'if f["fail_percent"] > tol.failpercent:', 'if f["fail_percent"] > 2.0 * tol.failpercent:', GOLDEN_TESTS),
    M("golden", "SSIM floor 0.01 lower", "fraytool/golden/compare.py",
      'if f["ssim"] < tol.ssim_min:', 'if f["ssim"] < tol.ssim_min - 0.01:', GOLDEN_TESTS),
    M("golden", "geometry tolerance 1.5 times", "fraytool/golden/compare.py",
      'elif g["max_yarn_distance_thickness"] > tol.geometry_thickness:',
      'elif g["max_yarn_distance_thickness"] > 1.5 * tol.geometry_thickness:', GOLDEN_TESTS),
    M("golden", "one torn spring more allowed", "fraytool/golden/compare.py",
      '- int(golden["torn_springs"])) > tol.torn_springs:', '- int(golden["torn_springs"])) > tol.torn_springs + 1:',
      GOLDEN_TESTS),
    M("golden", "the report's worst SSIM is the best", "fraytool/golden/report.py",
      '"max_yarn_distance_thickness": max, "ssim": min,', '"max_yarn_distance_thickness": max, "ssim": max,',
      GOLDEN_TESTS),
    M("golden", "the world's keys left out of the differences", "fraytool/scene/load.py",
      "        if was == now:\n            continue", '        if was == now or key.startswith("world"):\n            continue',
      GOLDEN_TESTS),
    M("golden", "the ring not drawn", "fraytool/golden/run.py",
      "        if pixel is not None:\n            verdict.figures", "        if False:\n            verdict.figures",
      GOLDEN_TESTS),
    M("outputs", "a run missing only its last frame is complete", "fraytool/commands/check_outputs.py",
      "        if complete < planned:", "        if complete < planned - 1:", OUTPUT_TESTS),
    M("outputs", "the frame after the first damaged one not checked", "fraytool/io/frame_store.py",
      "for k in range(good + 1, frames):  # name", "for k in range(good + 2, frames):  # name", OUTPUT_TESTS),
    M("outputs", "two PNG sets in one folder pass", "fraytool/commands/check_outputs.py",
      "    if len(kinds) < 2:\n        return []", "    if len(kinds) < 3:\n        return []", OUTPUT_TESTS),
    M("outputs", "look-dev into another folder simulates again", "fraytool/commands/render.py",
      "if other.dir.resolve() != store.dir.resolve() and _holds(other, digest, needed):",
      "if False and _holds(other, digest, needed):", OUTPUT_TESTS),
    M("outputs", "a render that simulates again does not name the changed keys", "fraytool/commands/render.py",
      "        changed = key_changes(simulation_keys(old_spec), simulation_keys(spec))", "        changed = []",
      OUTPUT_TESTS),
    M("farm", "a lost worker's attempt recorded as a success", "fraytool/farm/watch.py",
      "while self._close(key, None, start, LOST):", "while self._close(key, None, start, OK):", FARM_TESTS),
    M("mesh", "a clearance bound that forgets the mesh's travel", "fraytool/sim/kernels/mesh_clearance.py",
      "    return d - r - (clear.travel_m[m] - clear.travel_at_m[m, p])", "    return d - r", CLEARANCE_TESTS),
    M("mesh", "a segment's clearance without its length", "fraytool/sim/kernels/mesh_contact.py",
      "return 0.5 * (da + db - length) >", "return 0.5 * (da + db) >", CLEARANCE_TESTS),
    M("mesh", "a clearance bound from the path's end only", "fraytool/sim/kernels/mesh_clearance.py",
      "    r = math.sqrt(max(_dist2(x0, y0, z0, ref, p), _dist2(x1, y1, z1, ref, p)))",
      "    r = math.sqrt(_dist2(x1, y1, z1, ref, p))",
      CLEARANCE_TESTS),
    M("mesh", "a segment's own bound that forgets its ends' moves", "fraytool/sim/kernels/mesh_clearance.py",
      "    return d - r - (clear.travel_m[m] - seg_travel_at_m[m, s])",
      "    return d - (clear.travel_m[m] - seg_travel_at_m[m, s])", CLEARANCE_TESTS),
    M("mesh", "a segment's distance blind to where it crosses a triangle", "fraytool/sim/kernels/mesh_clearance.py",
      "            if (da > 0.0 and db < 0.0) or (da < 0.0 and db > 0.0):  # through the plane",
      "            if False:  # through the plane", CLEARANCE_TESTS),
    M("mesh", "an edge's CCD skipped by the distance at the step's end", "fraytool/sim/kernels/mesh_contact.py",
      "            if dist - _largest_move(seg_start, seg_end_inout, e0s, e1s, e0e, e1e) <= CCD_SCALE * _largest_abs(",
      "            if dist <= CCD_SCALE * _largest_abs(", MESH_TESTS + CLEARANCE_TESTS),
    M("mesh", "a segment's corner test left to its sharp edges' pass", "fraytool/sim/kernels/mesh_contact.py",
      "                through = meshes_in.closed[m] and left <= through_skip_m(clear, m, largest)",
      "                through = False", MESH_TESTS + CLEARANCE_TESTS),
    M("multires", "a coarse cell's mesh bound that forgets the mesh's travel", "fraytool/sim/kernels/multires_mesh.py",
      "                    - (travel_m[m] - bounds_inout.group_travel_at_m[mi, c]) > floor:",
      "                    - 0.0 > floor:", MULTIRES_MESH_TESTS),
    M("multires", "a coarse cell's mesh bound that forgets its nodes' moves", "fraytool/sim/kernels/multires_mesh.py",
      "            if bounds_inout.group_value_m[mi, c] - math.sqrt(moved2) \\",
      "            if bounds_inout.group_value_m[mi, c] - 0.0 * moved2 \\", MULTIRES_MESH_TESTS),
    M("multires", "cells an outline cuts may be coarse", "fraytool/sim/multires.py",
      "    refined |= ~layout.cell_whole  # a panel's outline, mask or the grid between panels",
      "    pass", MULTIRES_PANEL_TESTS),
    M("multires", "a seam's crossings start slaved", "fraytool/sim/multires.py",
      "    refined[sewn[sewn >= 0]] = True", "    pass", MULTIRES_PANEL_TESTS),
    M("multires", "a thin smooth mesh tested by depth", "fraytool/sim/multires.py",
      "        return tightest < THIN_SEGMENTS * segment", "        return False", MULTIRES_MESH_TESTS),
    M("multires", "the free ends of segments with a slaved end not tested", "fraytool/sim/kernels/multires_mesh.py",
      "        for i in range(mixed_free.shape[0]):", "        for i in range(0):", MULTIRES_MESH_TESTS),
    M("multires", "a coarse bend spring across a slit", "fraytool/sim/multires.py",
      "        straight = np.where(on_row, row_count, np.where(ia == ib, col_count, 0)) == 0",
      "        straight = np.ones(ia.shape, bool)", MULTIRES_PANEL_TESTS),
    M("multires", "a slaved crossing in self-contact does not refine", "fraytool/sim/stages/multires.py",
      "            count += self._refine_self_contact(rt, state)", "            pass", ("tests/test_self_collision.py",)),
    M("multires", "the coarse model's lever unbounded", "fraytool/sim/stages/self_collision.py",
      "LEVER_MAX if model.coarse_factor > 1 else np.inf", "np.inf", ("tests/test_self_collision.py",)),
    M("multires", "the passes leave out a pair with one movable end", "fraytool/collision/candidates.py",
      "        keep[k] = (particle_inv_mass[spring_particle_a[i]] > 0.0 or particle_inv_mass[spring_particle_b[i]] > 0.0",
      "        keep[k] = (particle_inv_mass[spring_particle_a[i]] > 0.0 and particle_inv_mass[spring_particle_b[i]] > 0.0",
      ("tests/test_self_collision.py",)),
    M("self-collision", "the check skips the segments even after a change of topology",
      "fraytool/sim/stages/self_collision.py", "state.topology_epoch != self._segments_at", "False",
      ("tests/test_self_collision.py", "tests/test_tearing_scenes.py")),
    M("tearing", "the cut scan starts one spring after the pre-scan's first", "fraytool/sim/tearing/__init__.py",
      "self._fragment_left, self._fragment_right, first)", "self._fragment_left, self._fragment_right, first + 1)",
      ("tests/test_tearing_cut.py",)),
    M("tearing", "the pre-scan misses springs just over their limit", "fraytool/sim/tearing/cut.py",
      "spring_particle_b[s]) <= bound * bound:", "spring_particle_b[s]) <= 1.01 * bound * bound:",
      ("tests/test_tearing_cut.py", "tests/test_tearing_split.py")),
    M("tearing", "the cut rule's scans marked current in a step that ran none", "fraytool/sim/tearing/__init__.py",
      "        if first >= 0:\n            # the scans read spring_alive",
      "        if first < 0:\n            self._runs_at = state.topology_epoch\n        if first >= 0:\n"
      "            # the scans read spring_alive", ("tests/test_tearing_cut.py",)),
    M("mesh", "a leaf list used for a query reaching out of its cube", "fraytool/sim/kernels/mesh_leaf_cache.py",
      "    return (query[0] >= centre_m[m, p, 0] - half_m and",
      "    return (query[0] >= centre_m[m, p, 0] - 2.0 * half_m and", LEAF_CACHE_TESTS),
    M("mesh", "a leaf list's leaves not tested against the query box", "fraytool/sim/kernels/mesh_leaf_cache.py",
      "        if overlaps(box, node, query[0], query[1], query[2], query[3], query[4], query[5]):",
      "        if True:", LEAF_CACHE_TESTS),
    M("mesh", "a full leaf list read as its first leaves", "fraytool/sim/kernels/mesh_leaf_cache.py",
      "    return n if n < FULL else -1", "    return min(n, CACHE_LEAVES)", LEAF_CACHE_TESTS),
    M("mesh", "a refit that keeps the leaf lists", "fraytool/sim/mesh_geometry.py",
      "        self.leaf_cache.count[m] = NO_LIST", "        pass", LEAF_CACHE_TESTS),
]


def _tracked(root: Path) -> list[str]:
    """The files of the checkout (git's list; every file but caches and outputs outside a git checkout)."""
    r = subprocess.run(["git", "ls-files", "-co", "--exclude-standard"], cwd=root, capture_output=True, text=True)
    if r.returncode == 0:
        files = r.stdout.split("\n")
    else:
        files = [str(p.relative_to(root)) for p in root.rglob("*") if p.is_file()
                 and "__pycache__" not in p.parts and ".git" not in p.parts]
    return [f for f in files if f and not f.startswith("outputs/") and (root / f).is_file()]


def prepare(root: Path, mutation: Mutation) -> Path:
    """A copy of the checkout in a temporary folder with `mutation` applied."""
    tmp = Path(tempfile.mkdtemp(prefix="fraytool-mutant-"))
    for f in _tracked(root):
        dest = tmp / f
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(root / f, dest)
    _copy_kernel_cache(root, tmp)
    target = tmp / mutation.path
    text = target.read_text()
    if text.count(mutation.old) != 1:
        shutil.rmtree(tmp, ignore_errors=True)
        raise SystemExit(f"mutation {mutation.what!r}: {mutation.path} holds its text "
                         f"{text.count(mutation.old)} times (once expected)")
    target.write_text(text.replace(mutation.old, mutation.new))
    return tmp


def _copy_kernel_cache(root: Path, tmp: Path) -> None:
    """The checkout's compiled kernels (numba's cache beside the sources, with their times, and fraytool's
    stamp of what each kernel file depends on) into the copy: there only the mutated file's kernels and
    those that import it compile again (fraytool/_numba_cache.py), not every kernel of the package."""
    for cached in (root / "fraytool").rglob("__pycache__/*"):
        if cached.suffix in (".nbi", ".nbc") or cached.name == "numba_sources.json":
            dest = tmp / cached.relative_to(root)
            dest.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(cached, dest)


def run_one(root: Path, index: int, mutation: Mutation, timeout_s: float) -> tuple[int, bool, float, str]:
    t0 = time.perf_counter()
    tree = prepare(root, mutation)
    try:
        env = {**os.environ, "PYTHONPATH": str(tree), "NUMBA_NUM_THREADS": "1"}
        try:
            r = subprocess.run([sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider",
                                *mutation.tests], cwd=tree, env=env, capture_output=True, text=True,
                               timeout=timeout_s)
            caught = r.returncode != 0
            tail = (r.stdout.strip().splitlines() or [""])[-1]
        except subprocess.TimeoutExpired:
            caught, tail = True, f"timed out after {timeout_s:.0f} s (counted as caught)"
    finally:
        shutil.rmtree(tree, ignore_errors=True)
    return index, caught, time.perf_counter() - t0, tail


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--only", help="mutation numbers, e.g. 1,5,7 or 32-78")
    p.add_argument("--list", action="store_true", help="list the mutations and exit")
    p.add_argument("--timeout", type=float, default=1200.0, help="seconds per mutation's tests")
    p.add_argument("--root", type=Path, default=ROOT, help="the checkout to mutate (default: this one)")
    args = p.parse_args()
    root = args.root.resolve()
    chosen = list(enumerate(MUTATIONS, 1))
    if args.only:
        wanted = set()
        for part in args.only.split(","):
            lo, _, hi = part.partition("-")
            wanted.update(range(int(lo), int(hi or lo) + 1))
        chosen = [(i, m) for i, m in chosen if i in wanted]
    if args.list:
        for i, m in chosen:
            print(f"{i:3d}  {m.area:17s} {m.what}  ({m.path}; {', '.join(m.tests)})")
        return 0
    for _, m in chosen:  # every mutation applies once, before anything runs
        text = (root / m.path).read_text()
        if text.count(m.old) != 1:
            print(f"mutation {m.what!r}: {m.path} holds its text {text.count(m.old)} times", file=sys.stderr)
            return 2
    t0 = time.perf_counter()
    caught_count = 0
    with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        futures = [pool.submit(run_one, root, i, m, args.timeout) for i, m in chosen]
        for f in futures:
            i, caught, seconds, tail = f.result()
            m = MUTATIONS[i - 1]
            caught_count += caught
            print(f"{i:3d}  {m.area:17s} {'caught  ' if caught else 'SURVIVED'} {seconds:6.0f} s  {m.what}"
                  f"  [{tail}]", flush=True)
    share = caught_count / max(1, len(chosen))
    print(f"caught {caught_count} of {len(chosen)} ({100 * share:.0f} %), survived {len(chosen) - caught_count}; "
          f"{time.perf_counter() - t0:.0f} s in all with --jobs {args.jobs}")
    return 0 if share >= GOAL else 1


if __name__ == "__main__":
    sys.exit(main())
