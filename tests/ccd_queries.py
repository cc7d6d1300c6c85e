"""Reader for edge-edge CCD query files of the Wang et al. 2021 benchmark format.

Wang, Ferguson, Schneider, Jiang, Attene & Panozzo, "A Large Scale Benchmark and an
Inclusion-Based Algorithm for Continuous Collision Detection", ACM TOG 2021. Each CSV holds 8 rows
per query, in the order ea0_t0, ea1_t0, eb0_t0, eb1_t0, ea0_t1, ea1_t1, eb0_t1, eb1_t1, with 7
integer columns: x num, x den, y num, y den, z num, z den, truth (1 = the edges touch). The
denominators are powers of two; ``num / den`` of Python ints is correctly rounded, hence exact.
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np


def load_ccd_queries(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read one CSV of edge-edge queries.

    Returns:
        x_start: positions at t = 0 [m], shape (Q, 4, 3), rows a0, a1, b0, b1, float64;
        x_end: positions at t = 1 [m], shape (Q, 4, 3), float64;
        truth: ground truth (edges touch), shape (Q,), bool.
    """
    rows = []
    with open(path, newline="") as fh:
        for line_no, rec in enumerate(csv.reader(fh), start=1):
            if not rec:
                continue
            if len(rec) != 7:
                raise ValueError(f"{path}:{line_no}: expected 7 integer columns, got {len(rec)}")
            v = [int(x) for x in rec]
            rows.append((v[0] / v[1], v[2] / v[3], v[4] / v[5], v[6]))
    if len(rows) % 8 != 0:
        raise ValueError(f"{path}: {len(rows)} rows is not a multiple of 8 (rows per query)")
    arr = np.array(rows, dtype=np.float64).reshape(-1, 8, 4)
    truth_rows = arr[:, :, 3]
    if np.any(truth_rows != truth_rows[:, :1]):
        raise ValueError(f"{path}: truth value differs between the 8 rows of a query")
    return arr[:, :4, :3].copy(), arr[:, 4:, :3].copy(), truth_rows[:, 0] == 1.0


def load_ccd_query_dir(root: str | Path) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """All ``*.csv`` files under ``root`` (sorted), keyed by their path relative to ``root``."""
    root = Path(root)
    return {
        str(p.relative_to(root)): load_ccd_queries(p) for p in sorted(root.rglob("*.csv"))
    }
