"""Weave patterns as over/under tables (docs/method.md §3.1).

A weave repeat is a boolean table `top[j][i]`, True where the weft yarn j lies on top of warp
yarn i at their crossing; the cloth tiles it: crossing (i, j) uses top[j % rows][i % cols].
"""
from __future__ import annotations

import math


def plain() -> tuple[tuple[bool, ...], ...]:
    """Plain weave: each weft goes over one warp and under the next; rows alternate."""
    return ((True, False), (False, True))


def twill(floats: str) -> tuple[tuple[bool, ...], ...]:
    """Twill "a/b": each weft passes over `a` warps then under `b`, shifted by one warp per row.

    The diagonal (twill line) comes from the shift. "2/1", "2/2", "3/1" are common.
    Raises ValueError for a malformed ratio.
    """
    parts = floats.split("/")
    if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
        raise ValueError('expected "a/b" with positive integers, e.g. "2/1" or "2/2"')
    over, under = int(parts[0]), int(parts[1])
    if over < 1 or under < 1 or over + under > 64:
        raise ValueError("floats must be >= 1 each and repeat (a + b) <= 64")
    n = over + under
    return tuple(tuple(((i - j) % n) < over for i in range(n)) for j in range(n))


def satin(shafts: int) -> tuple[tuple[bool, ...], ...]:
    """Weft-faced satin with `shafts` threads per repeat: weft floats over shafts-1 warps.

    The warp-on-top points move by the smallest step s (2 <= s <= shafts-2) coprime with the
    repeat, so that no two of them touch (the usual satin counter).
    """
    step = next(s for s in range(2, shafts - 1) if math.gcd(s, shafts) == 1)
    return tuple(tuple(i != (j * step) % shafts for i in range(shafts)) for j in range(shafts))


def from_rows(rows: list[list[int]]) -> tuple[tuple[bool, ...], ...]:
    """An explicit table of 0/1 rows (1 = weft on top)."""
    return tuple(tuple(bool(v) for v in row) for row in rows)
