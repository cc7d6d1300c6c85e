"""Pinned figures of the shipped scenes (tests/figures/*.json, tests/test_pinned_figures.py).

A scene is run through the Python API (the same steps as `fraytool simulate`) for its own frames, capped
at FRAME_CAP, and gives: the `simulate --json` figures that say how much happened (broken springs, torn
crossings, the first frame with a break, pieces, strains, fray lengths) and the positions of SAMPLES
crossings (their base slots) at three frames (a third, two thirds, the end). A scene the guard stops
gives the step it stopped at instead.

The files are written by `pytest tests/test_pinned_figures.py --update-figures` with sorted keys and
rounded values, one value a line, so that a regenerated file reads as a diff in review.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
FIGURES_DIR = Path(__file__).resolve().parent / "figures"
FRAME_CAP = 96
"""Longest run pinned (frames); tablecloth_tear is capped lower (TABLECLOTH_FRAMES) to keep the suite short."""
TABLECLOTH_FRAMES = 60
SHIRT_FRAMES = 16
"""shirt_snag is pinned over its pre-roll (the sewing); benchmarks/shirt_snag_seeds.py runs it whole."""
SAMPLES = 240
"""Crossings sampled for positions (evenly over the grid)."""
FIGURE_KEYS = ("broken_springs", "yarn_level_crossings", "first_break_frame", "pieces", "max_strain",
               "max_woven_strain", "strain_cap_hits", "fray_mean_free_end_m", "fray_max_free_end_m",
               "fray_total_free_end_m", "masses", "all_finite")


def shipped_scenes() -> list[str]:
    """Every shipped scene, as 'name' or 'stress/name'."""
    scenes = sorted(p.stem for p in (ROOT / "scenes").glob("*.toml"))
    return scenes + sorted(f"stress/{p.stem}" for p in (ROOT / "scenes" / "stress").glob("*.toml"))


def frames_of(scene: str, spec) -> int:
    cap = {"tablecloth_tear": TABLECLOTH_FRAMES, "shirt_snag": SHIRT_FRAMES}.get(scene, FRAME_CAP)
    return min(spec.time.frames, cap)


def run_figures(scene: str, perturb_m: float = 0.0) -> dict:
    """The pinned figures of `scene` (see the module docstring). `perturb_m` moves every crossing by
    that much (a deterministic pattern) before the run: how far a last-bit difference carries
    (used to choose the tolerances, docs/testing.md)."""
    from fraytool.scene import load_scene
    from fraytool.sim.simulation import Simulation
    from fraytool.sim.solver import SimulationUnstable

    spec = load_scene(ROOT / "scenes" / f"{scene}.toml")
    frames = frames_of(scene, spec)
    sim = Simulation(spec)
    n = sim.model.crossing_count
    if perturb_m:
        sim.state.particle_position_m[:n] += perturb_m * np.cos(np.arange(3 * n) * np.sign(perturb_m)).reshape(n, 3)
    sample = np.unique(np.linspace(0, n - 1, SAMPLES).round().astype(np.int64))
    at = sorted({max(1, frames // 3), max(1, 2 * frames // 3), frames - 1})
    out: dict = {"scene": scene, "frames": frames, "positions_m": {}}
    first_break = -1
    try:
        while sim.frame + 1 < frames:
            sim.advance_frame()
            if first_break < 0 and sim.state.spring_broken.any():
                first_break = sim.frame
            if sim.frame in at:
                out["positions_m"][str(sim.frame)] = sim.state.particle_position_m[sample].tolist()
    except SimulationUnstable as exc:
        out["unstable_step"] = int(exc.diagnostic.get("step", -1))
        return out
    summary = sim.summary()
    summary["first_break_frame"] = first_break
    out["figures"] = {k: summary[k] for k in FIGURE_KEYS if k in summary}
    out["sample_crossings"] = sample.tolist()
    out["spacing_m"] = float(sim.model.spacing_m)
    return out


def _rounded(value):
    if isinstance(value, float):
        return float(f"{value:.9g}")
    if isinstance(value, list):
        return [_rounded(v) for v in value]
    if isinstance(value, dict):
        return {k: _rounded(v) for k, v in value.items()}
    return value


def write_figures(scene: str, figures: dict) -> Path:
    """tests/figures/<scene>.json, sorted and rounded to 9 digits, a position a line."""
    FIGURES_DIR.mkdir(exist_ok=True)
    path = FIGURES_DIR / f"{scene.replace('/', '__')}.json"
    data = _rounded(figures)
    positions = data.pop("positions_m", {})
    text = json.dumps(data, indent=1, sort_keys=True)[:-2]
    rows = ",\n".join(f'  "{f}": [\n' + ",\n".join(f"   {json.dumps(p)}" for p in pts) + "\n  ]"
                      for f, pts in sorted(positions.items(), key=lambda kv: int(kv[0])))
    path.write_text(text + ',\n "positions_m": {\n' + rows + "\n }\n}\n")
    return path


def read_figures(scene: str) -> dict:
    return json.loads((FIGURES_DIR / f"{scene.replace('/', '__')}.json").read_text())


CHAOS_FACTOR = 5.0
"""A pinned value may move by this many times the most it moved when every crossing was moved by
PERTURBATION_M (two patterns) before the run: a last-bit difference (another CPU, another libm) carries
that far in a scene whose tear is chaotic (fig7's broken springs 125 -> 118), and not at all in a
stable one (stiff_within_bound: 1e-11 spacings)."""
PERTURBATION_M = 1e-13
FLOOR_RELATIVE = 1e-6
"""The least tolerance of a float figure, relative (a stable scene repeats to ~1e-12)."""
FLOOR_SPACINGS = 1e-6
"""The least tolerance of a frame's sampled positions, RMS in yarn spacings."""
CHAOTIC_SPACINGS = 1e-3
"""A scene whose last pinned positions moved more than this under the perturbation is chaotic: two
samples of its spread are not its range, so its figures get at least CHAOTIC_RELATIVE (integers at
least that and 1 more)."""
CHAOTIC_RELATIVE = 0.05


def tolerances(base: dict, perturbed: list) -> dict:
    """The named tolerances of `base` from the runs in `perturbed` (module constants above)."""
    if "unstable_step" in base:
        spread = max(abs(p.get("unstable_step", -1) - base["unstable_step"]) for p in perturbed)
        return {"unstable_step": int(np.ceil(CHAOS_FACTOR * spread))}
    positions = {}
    for frame, pts in base["positions_m"].items():
        spread = max(position_rms_spacings(pts, p["positions_m"][frame], base["spacing_m"]) for p in perturbed)
        positions[frame] = max(FLOOR_SPACINGS, CHAOS_FACTOR * spread)
    last = max(base["positions_m"], key=int) if base["positions_m"] else None
    chaotic = last is not None and positions[last] > CHAOS_FACTOR * CHAOTIC_SPACINGS
    figures = {}
    for key, value in base["figures"].items():
        if isinstance(value, bool):
            figures[key] = 0
            continue
        spread = max(abs(p["figures"][key] - value) for p in perturbed)
        if isinstance(value, int):
            least = int(np.ceil(CHAOTIC_RELATIVE * abs(value))) + 1 if chaotic else 0
            figures[key] = max(least, int(np.ceil(CHAOS_FACTOR * spread)))
        else:
            least = CHAOTIC_RELATIVE * abs(value) if chaotic else FLOOR_RELATIVE * abs(value)
            figures[key] = max(least, CHAOS_FACTOR * spread, 1e-12)
    return {"figures": figures, "positions_rms_spacings": positions}


def position_rms_spacings(a, b, spacing_m: float) -> float:
    """RMS distance between two samples of positions, in yarn spacings."""
    d = np.linalg.norm(np.asarray(a) - np.asarray(b), axis=1) / spacing_m
    return float(np.sqrt((d * d).mean()))


def pin(scene: str) -> Path:
    """Run `scene` as is and with two perturbations, and write its figures with their tolerances."""
    base = run_figures(scene)
    perturbed = [run_figures(scene, PERTURBATION_M), run_figures(scene, -PERTURBATION_M)]
    base["tolerance"] = tolerances(base, perturbed)
    return write_figures(scene, base)
