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
    target = tmp / mutation.path
    text = target.read_text()
    if text.count(mutation.old) != 1:
        shutil.rmtree(tmp, ignore_errors=True)
        raise SystemExit(f"mutation {mutation.what!r}: {mutation.path} holds its text "
                         f"{text.count(mutation.old)} times (once expected)")
    target.write_text(text.replace(mutation.old, mutation.new))
    return tmp


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
    p.add_argument("--only", help="mutation numbers, e.g. 1,5,7")
    p.add_argument("--list", action="store_true", help="list the mutations and exit")
    p.add_argument("--timeout", type=float, default=1200.0, help="seconds per mutation's tests")
    p.add_argument("--root", type=Path, default=ROOT, help="the checkout to mutate (default: this one)")
    args = p.parse_args()
    root = args.root.resolve()
    chosen = list(enumerate(MUTATIONS, 1))
    if args.only:
        wanted = {int(v) for v in args.only.split(",")}
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
