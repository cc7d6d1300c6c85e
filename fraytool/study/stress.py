"""The stress scenes (scenes/stress/): stiff and extreme cases that state what they expect.

Each file says in a comment what should happen and why, and states it machine-readably on one
commented TOML line (the scene schema has no key for "this run must be stopped by the guard", and
a comment keeps the scene loadable by every tool):

    #! expect = { outcome = "unstable", frames = 60, stage = "integration" }

- outcome: "stable", "strain_over_limit", "oscillating" or "unstable" (fraytool.study.stability_sweep);
- frames: frames to run after frame 0 (default: the scene's);
- stage (optional, with "unstable"): the stage the guard must name (replay of the failed step);
- max_steps (optional, with "unstable"): the guard must stop the run by this step.
Stable scenes also carry ordinary [checks] (all_finite, max_strain_below) where the schema can say it.
"""
from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Optional

from fraytool.errors import SceneError
from fraytool.resources import scenes_dir
from fraytool.scene import load_scene
from fraytool.study.runner import run_variant
from fraytool.study.stability_sweep import OUTCOMES, classify

EXPECT_PREFIX = "#!"


def stress_dir() -> Path:
    return scenes_dir() / "stress"


def stress_scenes() -> list[Path]:
    return sorted(stress_dir().glob("*.toml"))


def read_expectation(path: Path) -> Optional[dict]:
    """The `#! expect = {...}` line of a scene file, or None if it has none."""
    text = Path(path).read_text(encoding="utf-8")
    lines = [ln[len(EXPECT_PREFIX):].strip() for ln in text.splitlines() if ln.startswith(EXPECT_PREFIX)]
    if not lines:
        return None
    try:
        doc = tomllib.loads("\n".join(lines))
    except tomllib.TOMLDecodeError as exc:
        raise SceneError([f"{path}: the '{EXPECT_PREFIX} expect = {{...}}' line is not valid TOML: {exc}"]) from None
    expect = doc.get("expect")
    if not isinstance(expect, dict) or expect.get("outcome") not in OUTCOMES:
        raise SceneError([f"{path}: '{EXPECT_PREFIX} expect' needs outcome = one of "
                          + ", ".join(f'"{o}"' for o in OUTCOMES)])
    unknown = set(expect) - {"outcome", "frames", "stage", "max_steps"}
    if unknown:
        raise SceneError([f"{path}: '{EXPECT_PREFIX} expect' has unknown keys {sorted(unknown)}; "
                          "allowed: outcome, frames, stage, max_steps"])
    return expect


def check_expectation(path: Path) -> dict:
    """Run a scene for its expected frames and compare the outcome with its expectation.

    Returns {"scene", "expected", "outcome", "passed", "problems", "result"}."""
    expect = read_expectation(path)
    if expect is None:
        raise SceneError([f"{path}: no '{EXPECT_PREFIX} expect = {{...}}' line"])
    spec = load_scene(path)
    frames = int(expect.get("frames", spec.time.frames - 1))
    result = run_variant(spec, frames, record=False)
    outcome = classify(result, spec.cloth.strain.limit)
    problems = []
    if outcome != expect["outcome"]:
        problems.append(f"outcome {outcome}, expected {expect['outcome']}")
    diag = result.diagnostic or {}
    if "stage" in expect and outcome == "unstable" and diag.get("stage") != expect["stage"]:
        problems.append(f"guard named stage {diag.get('stage')!r}, expected {expect['stage']!r}")
    if "max_steps" in expect and outcome == "unstable" and diag.get("step", 0) > expect["max_steps"]:
        problems.append(f"guard stopped the run at step {diag.get('step')}, expected by step {expect['max_steps']}")
    return {"scene": spec.name, "expected": expect, "outcome": outcome, "passed": not problems,
            "problems": problems, "result": result}
