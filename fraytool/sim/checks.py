"""Scenes carry their own checks: run a scene and evaluate its [checks] table.

Used by `fraytool check --run SCENE` and by the test that runs every shipped scene.
"""
from __future__ import annotations

import numpy as np

from fraytool.scene.spec import SceneSpec
from fraytool.sim.simulation import Simulation


def _attachment_error(sim: Simulation) -> float:
    """Largest distance [m] between a held particle and where its body says it must be."""
    m, s = sim.model, sim.state
    # the rigidly held ones still held (a surface pin follows its mesh; one let go or not yet caught is free)
    rigid = (m.attachment_triangle < 0) if m.attachment_triangle.size else np.ones(m.attachment_count, bool)
    held = rigid & (s.particle_inv_mass[m.attachment_particle] == 0.0)
    if not held.any():
        return 0.0
    offset = s.attachment_offset_m if s.attachment_offset_m.size else m.attachment_offset_m
    target = s.body_position_m[m.attachment_body[held]] + np.einsum(
        "kij,kj->ki", s.body_rotation[m.attachment_body[held]], offset[held])
    return float(np.abs(s.particle_position_m[m.attachment_particle[held]] - target).max())


def run_scene_checks(spec: SceneSpec, frames: int | None = None) -> dict:
    """Simulate the scene's check frames and report each check as passed or failed."""
    c = spec.checks
    count = frames or c.frames or spec.time.frames
    sim = Simulation(spec)
    attach_err = 0.0
    finite = True
    for _ in sim.frames(count):
        attach_err = max(attach_err, _attachment_error(sim))
        finite = finite and bool(np.isfinite(sim.state.particle_position_m).all())
    summary = sim.summary()
    results = {}

    def check(name, ok, value, wanted):
        results[name] = {"passed": bool(ok), "value": value, "wanted": wanted}

    if c.all_finite:
        check("all_finite", finite, finite, True)
    if c.max_strain_below is not None:
        check("max_strain_below", summary["max_strain"] < c.max_strain_below, summary["max_strain"],
              f"< {c.max_strain_below}")
    for key, field, op in (("min_broken_springs", "broken_springs", ">="), ("max_broken_springs", "broken_springs", "<="),
                           ("min_yarn_level_masses", "yarn_level_masses", ">="),
                           ("max_yarn_level_masses", "yarn_level_masses", "<=")):
        wanted = getattr(c, key)
        if wanted is not None:
            value = summary[field]
            check(key, value >= wanted if op == ">=" else value <= wanted, value, f"{op} {wanted}")
    if c.min_second_piece_fraction is not None:
        second = summary["largest_piece_fractions"][1]
        check("min_second_piece_fraction", second >= c.min_second_piece_fraction, second,
              f">= {c.min_second_piece_fraction}")
    if c.max_small_pieces is not None:
        check("max_small_pieces", summary["small_pieces"] <= c.max_small_pieces, summary["small_pieces"],
              f"<= {c.max_small_pieces}")
    if c.attachments_follow and sim.model.attachment_count:
        check("attachments_follow", attach_err <= 1e-9, attach_err, "<= 1e-9 m")
    return {"frames": count, "passed": all(r["passed"] for r in results.values()), "results": results,
            "summary": summary}
