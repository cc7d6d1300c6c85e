#!/usr/bin/env python
"""Prove that a refactoring left the simulated frames bit-identical.

    python benchmarks/frames_identical.py --against REV [--frames N] [--scenes a,b,...] [--keep DIR]
    python benchmarks/frames_identical.py --against-dir PATH [--frames N] [--scenes ...] [--keep DIR]

The reference side is REV's code (a temporary detached ``git worktree``) or an existing checkout
(``--against-dir``); the side under test is this checkout's working tree (``--tree``, default: the
checkout holding this script), uncommitted edits included. Every shipped scene (scenes/*.toml and
scenes/stress/*.toml of the tree under test, each side reading its own copy of the file) is run by
both sides as ``python -m fraytool simulate SCENE -o OUT --frames N --json`` in its own subprocess,
with cwd = that tree's root and PYTHONPATH starting with that tree's root (a probe checks that
``import fraytool`` really resolves inside that tree: the editable install points at the main
checkout). N is the scene's own frame count capped by --frames (default 48: the fig scenes tear
well before that; --frames 0 runs every scene to its own end).

Then every file in OUT/frames is compared: the same file names; each .npz array by array (same
keys, dtype, shape, and identical bytes: ``tobytes()``, so NaN payloads and -0.0 count);
manifest.json and unstable.json field by field, where fields that may legitimately differ
(version, scene hash, timings) are reported but do not count. The exit code of the run and its
--json summary are compared too (a summary difference is reported as a note).

Exit status: 0 when every compared scene is identical, 1 otherwise (a difference, a run that failed
on either side, or code or scenes of either tree that changed while the comparison ran: a working
tree edited meanwhile may have mixed two versions), 2 on bad usage. Each tree keeps its own numba cache (its __pycache__
folders): a fresh worktree compiles every kernel on its first run, which takes a minute or more.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

DEFAULT_FRAME_CAP = 48
DEFAULT_TIMEOUT_S = 900

# Manifest / unstable.json fields that may differ between two versions of the code without any
# change of the simulation: reported, never counted as a difference.
IGNORED_FIELDS = {"fraytool_version", "version", "scene_hash", "checksum", "source_hash", "sources_hash", "git",
                  "git_commit", "commit", "created", "created_at", "timestamp", "host", "hostname",
                  "python", "numba", "numpy", "kernel"}
IGNORED_PATTERN = re.compile(r"(wall|elapsed|duration|timestamp|runtime|_ms$|ms_per|per_frame_s|seconds_real)")

PROBE = ("import json, importlib.util, fraytool; "
         "m = importlib.util.find_spec('fraytool.__main__'); "
         "print(json.dumps({'file': fraytool.__file__, 'path': list(fraytool.__path__), "
         "'main': m.origin if m else None}))")


# --------------------------------------------------------------------------------------------
# trees and runs


@dataclass
class Side:
    label: str              # "rev" or "work"
    root: Path              # tree root (holds fraytool/ and scenes/)
    out: Path               # where this side's runs go
    description: str = ""


@dataclass
class Run:
    scene: str
    exit_code: Optional[int] = None
    summary: Optional[dict] = None
    stderr_tail: str = ""
    seconds: float = 0.0
    out: Optional[Path] = None
    missing_scene: bool = False


def python_env(root: Path) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(root)] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else []))
    env.pop("NUMBA_CACHE_DIR", None)  # each tree caches its kernels in its own __pycache__ folders
    env.pop("PYTHONSAFEPATH", None)
    return env


def python_cmd(*args: str) -> list[str]:
    # -s: no user site-packages. Not -I / -E: they would drop PYTHONPATH, and the editable install
    # of the main checkout would win. cwd and PYTHONPATH both point at the tree instead.
    return [sys.executable, "-s", *args]


def probe(side: Side) -> dict:
    """Check that `python -m fraytool` in side's environment imports side's own fraytool. Every
    fraytool submodule is found through fraytool.__path__, so the top-level package decides."""
    p = subprocess.run(python_cmd("-c", PROBE), cwd=side.root, env=python_env(side.root),
                       capture_output=True, text=True, timeout=120)
    if p.returncode != 0:
        raise SystemExit(f"frames_identical: {side.label} tree {side.root}: `import fraytool` failed:\n{p.stderr}")
    info = json.loads(p.stdout.strip().splitlines()[-1])
    want = (side.root / "fraytool").resolve()
    got = Path(info["file"]).resolve().parent
    if got != want or [str(Path(x).resolve()) for x in info["path"]] != [str(want)]:
        raise SystemExit(f"frames_identical: {side.label} tree: fraytool imports from {info['path']}, not {want}")
    if not info["main"] or Path(info["main"]).resolve() != want / "__main__.py":
        raise SystemExit(f"frames_identical: {side.label} tree: no fraytool/__main__.py for `python -m fraytool`")
    return info


def tree_digest(root: Path) -> str:
    """Hash of the code and scenes of a tree (to notice edits made while the comparison runs)."""
    h = hashlib.sha256()
    for sub in ("fraytool", "scenes"):
        for path in sorted((root / sub).rglob("*")):
            if path.suffix in (".py", ".toml") and "__pycache__" not in path.parts:
                h.update(str(path.relative_to(root)).encode())
                try:
                    h.update(path.read_bytes())
                except OSError:
                    h.update(b"<unreadable>")
    return h.hexdigest()


def simulate(side: Side, scene: str, frames: int, timeout_s: float) -> Run:
    run = Run(scene=scene)
    path = side.root / "scenes" / f"{scene}.toml"
    if not path.is_file():
        run.missing_scene = True
        return run
    run.out = side.out / scene.replace("/", "__")
    if run.out.exists():
        shutil.rmtree(run.out)
    run.out.mkdir(parents=True)
    cmd = python_cmd("-m", "fraytool", "simulate", str(path), "-o", str(run.out), "--frames", str(frames), "--json")
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, cwd=side.root, env=python_env(side.root), capture_output=True, text=True,
                           timeout=timeout_s)
        run.exit_code = p.returncode
        stdout, stderr = p.stdout, p.stderr
    except subprocess.TimeoutExpired as exc:
        run.exit_code = None
        stdout = exc.stdout.decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
        stderr = (exc.stderr.decode() if isinstance(exc.stderr, bytes) else (exc.stderr or "")) + \
            f"\n(timed out after {timeout_s:g} s)"
    run.seconds = time.perf_counter() - t0
    (run.out / "stderr.txt").write_text(stderr)
    for line in reversed(stdout.strip().splitlines()):
        try:
            run.summary = json.loads(line)
            break
        except ValueError:
            continue
    lines = [ln for ln in stderr.replace("\r", "\n").splitlines() if ln.strip()]
    run.stderr_tail = lines[-1].strip() if lines else ""
    return run


# --------------------------------------------------------------------------------------------
# comparison


@dataclass
class Diff:
    first_frame: str = ""           # first differing frame record, one line
    frames: int = 0                 # frame records that differ
    others: list[str] = field(default_factory=list)   # every other difference (files, topology, ...)
    notes: list[str] = field(default_factory=list)

    @property
    def identical(self) -> bool:
        return not self.frames and not self.others

    def result(self) -> str:
        parts = []
        if self.frames:
            parts.append(f"first differing {self.first_frame}" + (f" ({self.frames} frames differ)" if self.frames > 1 else ""))
        if self.others:
            parts.append(self.others[0] + (f" (+{len(self.others) - 1} more)" if len(self.others) > 1 else ""))
        return "DIFFERENT: " + "; ".join(parts)


def differing_elements(a: np.ndarray, b: np.ndarray) -> int:
    """Number of elements whose bytes differ (same dtype and shape)."""
    if a.size == 0:
        return 0
    ua = np.ascontiguousarray(a).view(np.uint8).reshape(a.size, -1)
    ub = np.ascontiguousarray(b).view(np.uint8).reshape(b.size, -1)
    return int((ua != ub).any(axis=1).sum())


VERIFICATION_KEYS = {"checksum", "scene_hash"}
"""Keys of a verified .npz (fraytool.io.frame_store) that hash the scene's description: a new scene key
changes them without any change of the arrays they verify, which are compared themselves."""


def compare_npz(pa: Path, pb: Path, notes: Optional[list] = None) -> Optional[str]:
    """None if the two .npz hold the same arrays bit for bit, else the first difference. Arrays only
    in the work tree (fields a change added) and the verification keys go to `notes`, not counted."""
    with np.load(pa, allow_pickle=False) as za, np.load(pb, allow_pickle=False) as zb:
        ka, kb = set(za.files) - VERIFICATION_KEYS, set(zb.files) - VERIFICATION_KEYS
        if ka - kb:
            return f"keys differ: only in rev {sorted(ka - kb)}, only in work {sorted(kb - ka)}"
        if kb - ka and notes is not None:
            note = f"{pa.name}: arrays only in work (added by the change): {sorted(kb - ka)}"
            if note not in notes:
                notes.append(note)
        for k in sorted(ka):
            a, b = za[k], zb[k]
            if a.dtype.str != b.dtype.str:
                return f"array {k}: dtype {a.dtype.str} != {b.dtype.str}"
            if a.shape != b.shape:
                return f"array {k}: shape {a.shape} != {b.shape}"
            if a.tobytes() != b.tobytes():
                n = differing_elements(a, b)
                extra = ""
                if a.dtype.kind == "f":
                    d = np.abs(a.astype(np.float64) - b.astype(np.float64))
                    d = d[np.isfinite(d)]
                    if d.size:
                        extra = f", max |diff| {d.max():.3g}"
                return f"array {k}: {n} of {a.size} elements differ{extra}"
    return None


def ignorable(key: str) -> bool:
    return key in IGNORED_FIELDS or bool(IGNORED_PATTERN.search(key))


def compare_json(a, b, where: str, notes: list[str], strings_are_notes: bool = False) -> Optional[str]:
    """First difference of two JSON values that counts; ignorable ones are appended to notes."""
    if isinstance(a, dict) and isinstance(b, dict):
        first = None
        for k in sorted(set(a) | set(b)):
            sub = f"{where}.{k}"
            if k not in a or k not in b:
                if ignorable(k):
                    notes.append(f"{sub}: only in {'rev' if k in a else 'work'} (ignored)")
                elif first is None:
                    first = f"{sub}: only in {'rev' if k in a else 'work'}"
                continue
            if a[k] == b[k]:
                continue
            if ignorable(k):
                notes.append(f"{sub}: {a[k]!r} -> {b[k]!r} (ignored)")
                continue
            r = compare_json(a[k], b[k], sub, notes, strings_are_notes)
            if first is None:
                first = r
        return first
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        first = None
        for i, (x, y) in enumerate(zip(a, b)):
            r = compare_json(x, y, f"{where}[{i}]", notes, strings_are_notes)
            if first is None:
                first = r
        return first
    if a == b and type(a) is type(b):
        return None
    if strings_are_notes and isinstance(a, str) and isinstance(b, str):
        notes.append(f"{where}: {a!r} -> {b!r} (text, ignored)")
        return None
    return f"{where}: {a!r} != {b!r}"


def file_order(name: str) -> tuple:
    """topology first, then frames in order, then the rest."""
    if name == "topology.npz":
        return (0, name)
    if name.startswith("frame_"):
        return (1, name)
    return (2, name)


def compare_runs(ra: Run, rb: Run) -> Diff:
    diff = Diff()
    if ra.exit_code != rb.exit_code:
        diff.others.append(f"exit code {ra.exit_code} != {rb.exit_code}")
    da, db = ra.out / "frames", rb.out / "frames"
    fa = {p.name for p in da.iterdir()} if da.is_dir() else set()
    fb = {p.name for p in db.iterdir()} if db.is_dir() else set()
    if fa != fb:
        diff.others.append(f"files only in rev {sorted(fa - fb)[:3]}, only in work {sorted(fb - fa)[:3]}")
    for name in sorted(fa & fb, key=file_order):
        pa, pb = da / name, db / name
        if name.endswith(".npz"):
            r = compare_npz(pa, pb, diff.notes)
            if r is None:
                continue
            if name.startswith("frame_"):
                if not diff.frames:
                    diff.first_frame = f"frame {int(name[6:12])}: {r}"
                diff.frames += 1
            else:
                diff.others.append(f"{name} {r}")
        elif name.endswith(".json"):
            a, b = json.loads(pa.read_text()), json.loads(pb.read_text())
            r = compare_json(a, b, name, diff.notes, strings_are_notes=(name != "manifest.json"))
            if r is not None:
                diff.others.append(r)
        elif pa.read_bytes() != pb.read_bytes():
            diff.others.append(f"{name}: bytes differ")
    if len(diff.others) > 1:
        diff.notes += [f"also: {x}" for x in diff.others[1:]]
    if ra.summary is not None and rb.summary is not None and ra.summary != rb.summary:
        keys = sorted(k for k in set(ra.summary) | set(rb.summary) if ra.summary.get(k) != rb.summary.get(k))
        diff.notes.append(f"--json summary differs in {keys} (a note: not frames)")
    return diff


def last_frame_info(run: Run) -> tuple[Optional[int], Optional[int], Optional[int]]:
    """(frames on disk, broken springs after the last frame, change of alive springs frame 0 -> last)."""
    d = run.out / "frames" if run.out else None
    if d is None or not d.is_dir():
        return None, None, None
    frames = sorted(d.glob("frame_*.npz"))
    broken = alive = None
    if (d / "checkpoint.npz").is_file():
        with np.load(d / "checkpoint.npz") as z:
            if "spring_broken" in z.files:
                broken = int(z["spring_broken"].sum())
    if broken is None and run.summary and "broken_springs" in run.summary:
        broken = int(run.summary["broken_springs"])
    if frames:
        with np.load(frames[0]) as z0, np.load(frames[-1]) as z1:
            if "spring_alive" in z0.files and "spring_alive" in z1.files:
                alive = int(z1["spring_alive"].sum()) - int(z0["spring_alive"].sum())
    return len(frames), broken, alive


# --------------------------------------------------------------------------------------------
# driver


def git(root: Path, *args: str, check: bool = True) -> str:
    p = subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True)
    if check and p.returncode != 0:
        raise SystemExit(f"frames_identical: git {' '.join(args)}: {p.stderr.strip()}")
    return p.stdout.strip()


def shipped_scenes(root: Path) -> list[str]:
    scenes = sorted(p.relative_to(root / "scenes").with_suffix("").as_posix() for p in (root / "scenes").glob("*.toml"))
    scenes += sorted(p.relative_to(root / "scenes").with_suffix("").as_posix()
                     for p in (root / "scenes" / "stress").glob("*.toml"))
    return scenes


def scene_frames(path: Path) -> int:
    with open(path, "rb") as f:
        return int(tomllib.load(f)["time"]["frames"])


def select_scenes(all_scenes: list[str], wanted: Optional[str]) -> list[str]:
    if not wanted:
        return all_scenes
    out = []
    for w in (x.strip() for x in wanted.split(",")):
        if not w:
            continue
        w = w.removesuffix(".toml").removeprefix("scenes/")
        hits = [s for s in all_scenes if s == w or s.rsplit("/", 1)[-1] == w]
        if not hits:
            raise SystemExit(f"frames_identical: unknown scene {w!r}; shipped: {', '.join(all_scenes)}")
        out += [h for h in hits if h not in out]
    return out


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="Exit status: 0 all identical, 1 a difference, a failed run or a tree edited during the run, 2 usage.")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--against", metavar="REV", help="git revision to compare with (run from a temporary detached worktree)")
    g.add_argument("--against-dir", metavar="PATH", type=Path, help="an existing checkout to compare with (no worktree)")
    p.add_argument("--tree", type=Path, default=Path(__file__).resolve().parent.parent,
                   help="the tree under test (default: the checkout holding this script, working tree as is)")
    p.add_argument("--frames", type=int, default=DEFAULT_FRAME_CAP, metavar="N",
                   help=f"cap on each scene's own frame count (default {DEFAULT_FRAME_CAP}; 0: no cap)")
    p.add_argument("--scenes", metavar="a,b,...", help="scene names (file stems, or stress/NAME); default: all shipped")
    p.add_argument("--keep", metavar="DIR", type=Path,
                   help="put the worktree and all outputs in DIR and leave them there (a kept worktree of the "
                        "same commit is reused, numba cache included)")
    p.add_argument("--jobs", type=int, default=2, choices=(1, 2),
                   help="2 (default): the two sides run side by side; 1: one simulation at a time")
    p.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT_S, help="seconds per simulation (default %(default)s)")
    args = p.parse_args(argv)
    if args.frames < 0:
        p.error("--frames must be >= 0")
    return args


def main(argv=None) -> int:
    args = parse_args(argv)
    t_start = time.perf_counter()
    tree = args.tree.resolve()
    if not (tree / "fraytool").is_dir():
        raise SystemExit(f"frames_identical: {tree} holds no fraytool/")
    base = args.keep.resolve() if args.keep else Path(tempfile.mkdtemp(prefix="frames_identical_"))
    base.mkdir(parents=True, exist_ok=True)
    worktree: Optional[Path] = None
    repo = tree
    try:
        if args.against is not None:
            repo = Path(git(tree, "rev-parse", "--show-toplevel"))
            sha = git(repo, "rev-parse", "--verify", f"{args.against}^{{commit}}")
            worktree = base / f"rev-{sha[:12]}"
            listed = git(repo, "worktree", "list", "--porcelain")
            if args.keep and worktree.is_dir() and f"worktree {worktree}" in listed.splitlines() \
                    and git(worktree, "rev-parse", "HEAD") == sha and not git(worktree, "status", "--porcelain"):
                print(f"reusing kept worktree {worktree}", file=sys.stderr)
            else:
                if worktree.exists():
                    raise SystemExit(f"frames_identical: {worktree} exists and is not a clean worktree of {sha[:12]}")
                git(repo, "worktree", "add", "--detach", str(worktree), sha)
            rev_root = worktree
            rev_desc = f"{args.against} = {sha[:12]} (worktree {worktree})"
        else:
            rev_root = args.against_dir.resolve()
            if not (rev_root / "fraytool").is_dir():
                raise SystemExit(f"frames_identical: {rev_root} holds no fraytool/")
            rev_desc = f"checkout {rev_root}"
        if rev_root == tree:
            raise SystemExit("frames_identical: both sides are the same tree")
        work_desc = f"working tree {tree}"
        if (tree / ".git").exists():
            head = git(tree, "rev-parse", "--short=12", "HEAD", check=False)
            dirty = git(tree, "status", "--porcelain", "--untracked-files=no", check=False)
            work_desc += f" (HEAD {head}{', with uncommitted edits' if dirty else ', clean'})"
        sides = [Side("rev", rev_root, base / "out" / "rev", rev_desc),
                 Side("work", tree, base / "out" / "work", work_desc)]
        for s in sides:
            info = probe(s)
            print(f"{s.label:4s}: {s.description}\n      python -m fraytool imports {info['file']}", file=sys.stderr)

        scenes = select_scenes(shipped_scenes(tree), args.scenes)
        plan = []
        for sc in scenes:
            own = scene_frames(tree / "scenes" / f"{sc}.toml")
            plan.append((sc, own if args.frames == 0 else min(own, args.frames)))
        digests = {s.label: tree_digest(s.root) for s in sides}

        results: dict[tuple[str, str], Run] = {}

        def run_side(side: Side) -> None:
            for sc, n in plan:
                r = simulate(side, sc, n, args.timeout)
                results[(side.label, sc)] = r
                print(f"  {side.label:4s} {sc:38s} {n:4d} frames  exit {r.exit_code}  {r.seconds:6.1f} s",
                      file=sys.stderr, flush=True)

        if args.jobs == 2:
            threads = [threading.Thread(target=run_side, args=(s,)) for s in sides]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
        else:
            for s in sides:
                run_side(s)
        changed = [s for s in sides if tree_digest(s.root) != digests[s.label]]

        rows, all_ok, notes = [], True, []
        for sc, n in plan:
            ra, rb = results[("rev", sc)], results[("work", sc)]
            if ra.missing_scene:
                rows.append((sc, str(n), "-", "-", "SKIPPED: scene not in rev"))
                continue
            if (rev_root / "scenes" / f"{sc}.toml").read_bytes() != (tree / "scenes" / f"{sc}.toml").read_bytes():
                notes.append(f"{sc}: the scene file differs between the two trees (each side ran its own)")
            fr_a, br_a, al_a = last_frame_info(ra)
            fr_b, br_b, al_b = last_frame_info(rb)
            failed = [(s, r) for s, r in (("rev", ra), ("work", rb)) if not fr_of(r)]
            if failed:
                all_ok = False
                why = "; ".join(f"{s} exit {r.exit_code}: {r.stderr_tail[:110]}" for s, r in failed)
                rows.append((sc, str(n), "-", "-", f"ERROR: {why}"))
                continue
            d = compare_runs(ra, rb)
            notes += [f"{sc}: {x}" for x in d.notes]
            frames_txt = str(n) if fr_a == n and fr_b == n else \
                f"{fr_a} of {n}" if fr_a == fr_b else f"{fr_a}/{fr_b} of {n}"
            if ra.exit_code:
                frames_txt += f" (exit {ra.exit_code}{'' if ra.exit_code == rb.exit_code else f'/{rb.exit_code}'})"
            br = "-" if br_a is None else (str(br_a) if br_a == br_b else f"{br_a}/{br_b}")
            al = "-" if al_a is None else (f"{al_a:+d}" if al_a == al_b else f"{al_a:+d}/{al_b:+d}")
            if d.identical:
                rows.append((sc, frames_txt, br, al, "identical"))
            else:
                all_ok = False
                rows.append((sc, frames_txt, br, al, d.result()))

        print()
        print(f"rev : {sides[0].description}")
        print(f"work: {sides[1].description}")
        print(f"frames per scene: the scene's own, capped at {args.frames}" if args.frames else
              "frames per scene: the scene's own")
        head = ("scene", "frames", "broken", "alive Δ", "result")
        widths = [max(len(head[i]), *(len(r[i]) for r in rows)) for i in range(4)] if rows else [5, 6, 6, 7]
        print("  ".join(h.ljust(w) for h, w in zip(head, widths)) + "  " + head[4])
        print("  ".join("-" * w for w in widths) + "  " + "-" * 10)
        for r in rows:
            print("  ".join(c.ljust(w) for c, w in zip(r, widths)) + "  " + r[4])
        print("(broken: springs broken after the last frame, from checkpoint.npz spring_broken; alive Δ: change of "
              "spring_alive count from frame 0 to the last frame, yarn-level springs that appear count +1; "
              "a/b = rev/work when they differ)")
        if notes:
            print("notes:")
            for x in notes:
                print(f"  {x}")
        for s in changed:
            all_ok = False
            print(f"WARNING: the {s.label} tree's code or scenes changed while the comparison ran; "
                  f"the result may mix two versions: run again")
        n_same = sum(r[4] == "identical" for r in rows)
        print(f"{n_same} of {len(rows)} scenes identical; {time.perf_counter() - t_start:.0f} s")
        print("RESULT: " + ("all identical" if all_ok else "NOT identical"))
        return 0 if all_ok else 1
    finally:
        if worktree is not None and not args.keep:
            p = subprocess.run(["git", "-C", str(repo), "worktree", "remove", "--force", str(worktree)],
                               capture_output=True, text=True)
            if p.returncode != 0:
                shutil.rmtree(worktree, ignore_errors=True)
                subprocess.run(["git", "-C", str(repo), "worktree", "prune"], capture_output=True)
        if not args.keep:
            shutil.rmtree(base, ignore_errors=True)
        else:
            print(f"kept: {base}", file=sys.stderr)


def fr_of(run: Run) -> int:
    """Frames on disk of a run (0 when it wrote none)."""
    if run.out is None:
        return 0
    return len(list((run.out / "frames").glob("frame_*.npz"))) if (run.out / "frames").is_dir() else 0


if __name__ == "__main__":
    sys.exit(main())
