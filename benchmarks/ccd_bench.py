"""Benchmark of the self-collision detection (fraytool.collision).

1. Narrow phase: microseconds per edge-edge CCD query over the Wang et al. 2021 sample queries
   (tests/data/ccd-sample-queries), with the false-negative / false-positive counts.
2. Broad phase and batch detection on a seeded 64 x 64 = 4096-particle yarn grid (weft and warp
   yarns, 8064 springs), crumpled, and with its second half folded over the first and falling onto it
   during the step: candidate pairs per second and the time of broad + narrow phase.

Run: ``python benchmarks/ccd_bench.py`` (from the repository root, or with fraytool installed).
Single-threaded; the first run also compiles the numba kernels (cached afterwards).
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
try:
    import fraytool.collision  # noqa: F401
except ImportError:  # running from a checkout without installing
    sys.path.insert(0, str(ROOT))

from fraytool.collision import (  # noqa: E402
    detect_edge_edge_collisions,
    edge_edge_ccd_many,
    find_candidate_pairs,
)
sys.path.insert(0, str(ROOT / "tests"))  # the sample-query reader is test code (tests/ccd_queries.py)
from ccd_queries import load_ccd_query_dir  # noqa: E402

DATA_DIR = ROOT / "tests" / "data" / "ccd-sample-queries"


def bench_sample_queries(repeats: int = 20) -> None:
    sets = load_ccd_query_dir(DATA_DIR)
    x_start = np.concatenate([v[0] for v in sets.values()])
    x_end = np.concatenate([v[1] for v in sets.values()])
    truth = np.concatenate([v[2] for v in sets.values()])
    edge_edge_ccd_many(x_start[:1], x_end[:1], 0.0)  # compile / load the cache
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        hit, _ = edge_edge_ccd_many(x_start, x_end, 0.0)
        best = min(best, time.perf_counter() - t0)
    fn = int(np.sum(truth & ~hit))
    fp = int(np.sum(~truth & hit))
    print(
        f"narrow phase: {len(truth)} sample queries, {best / len(truth) * 1e6:.2f} us/query "
        f"(best of {repeats}), false negatives {fn}, false positives {fp} / {int(np.sum(~truth))}"
    )
    for name, (xs, xe, tr) in sets.items():
        dt = np.inf
        for _ in range(5):
            t0 = time.perf_counter()
            h, _ = edge_edge_ccd_many(xs, xe, 0.0)
            dt = min(dt, time.perf_counter() - t0)
        print(
            f"  {name:52s} {dt / len(tr) * 1e6:7.2f} us/query  FN {int(np.sum(tr & ~h))}  "
            f"FP {int(np.sum(~tr & h))}"
        )


def yarn_grid(fold: bool, n: int = 64, spacing: float = 0.01, seed: int = 0):
    """n x n particles 1 cm apart. Crumpled: 3 mm noise, moving 1 mm (few contacts). Folded:
    0.5 mm noise, rows j >= n/2 folded over rows j < n/2 at 2 mm, falling 4 mm in the step.

    Springs: weft (along i) and warp (along j) structural segments; yarn id = row for weft,
    n + column for warp. Returns x_start, x_end, spring_a, spring_b, spring_alive, spring_yarn.
    """
    rng = np.random.default_rng(seed)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="xy")
    x = np.stack([i * spacing, j * spacing, np.zeros_like(i, dtype=float)], axis=-1).astype(float)
    top = (j >= n // 2) & fold
    x[top, 1] = (n - 1 - j[top]) * spacing + 0.5 * spacing  # folded back, offset half a cell
    x[top, 2] = 0.002
    noise = 0.0005 if fold else 0.003
    x = x.reshape(-1, 3) + noise * rng.standard_normal((n * n, 3))
    x_end = x + (0.0003 if fold else 0.001) * rng.standard_normal(x.shape)
    x_end[top.reshape(-1), 2] -= 0.004
    idx = np.arange(n * n).reshape(n, n)  # idx[j, i]
    weft_a, weft_b = idx[:, :-1].ravel(), idx[:, 1:].ravel()
    warp_a, warp_b = idx[:-1, :].ravel(), idx[1:, :].ravel()
    spring_a = np.concatenate([weft_a, warp_a]).astype(np.int32)
    spring_b = np.concatenate([weft_b, warp_b]).astype(np.int32)
    yarn = np.concatenate([np.repeat(np.arange(n), n - 1), n + np.tile(np.arange(n), n - 1)])
    alive = np.ones(spring_a.shape[0], dtype=bool)
    return x, x_end, spring_a, spring_b, alive, yarn.astype(np.int32)


def bench_grid(fold: bool, repeats: int = 5, thickness: float = 0.001) -> None:
    x, x_end, a, b, alive, yarn = yarn_grid(fold)
    find_candidate_pairs(x, x_end, a, b, alive, thickness, spring_yarn=yarn)  # compile / cache
    detect_edge_edge_collisions(x, x_end, a, b, alive, thickness, spring_yarn=yarn)
    best_bp = best_det = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        pairs = find_candidate_pairs(x, x_end, a, b, alive, thickness, spring_yarn=yarn)
        best_bp = min(best_bp, time.perf_counter() - t0)
        t0 = time.perf_counter()
        hits, t = detect_edge_edge_collisions(x, x_end, a, b, alive, thickness, spring_yarn=yarn)
        best_det = min(best_det, time.perf_counter() - t0)
    print(f"{'folded' if fold else 'crumpled'} yarn grid:")
    print(
        f"  broad phase: {x.shape[0]} particles, {a.shape[0]} springs -> {pairs.shape[0]} candidate "
        f"pairs in {best_bp * 1e3:.2f} ms ({pairs.shape[0] / best_bp / 1e6:.2f} M pairs/s, "
        f"{a.shape[0] / best_bp / 1e6:.2f} M springs/s)"
    )
    print(
        f"  detect (broad + narrow, thickness {thickness} m): {hits.shape[0]} colliding pairs in "
        f"{best_det * 1e3:.2f} ms ({pairs.shape[0] / best_det / 1e6:.2f} M candidate pairs/s), "
        f"earliest t = {t.min() if t.size else float('nan'):.4f}"
    )


if __name__ == "__main__":
    bench_sample_queries()
    bench_grid(fold=False)
    bench_grid(fold=True)
