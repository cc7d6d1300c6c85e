"""Outward-rounded interval arithmetic on float64 scalars, as numba kernels.

An interval is a pair ``(lo, hi)`` of float64 with ``lo <= hi``. Every operation computes its
bounds in ordinary round-to-nearest arithmetic and then widens them outward, so the returned
interval always contains the exact real result for any reals in the input intervals.

Outward rounding (``round_down`` / ``round_up``): for a computed ``c = RN(e)`` of an exact real
``e``, the neighbouring floats of ``c`` bracket ``e`` (``|c - e| <= ulp/2``). We step out by at
least one ulp with three flops instead of a libm ``nextafter`` call:

    round_down(c) = c - (|c| * 2^-52 + 2^-1022)      round_up(c) = c + (|c| * 2^-52 + 2^-1022)

``|c| * 2^-52 >= ulp(c)`` for every normal ``c``, and ``2^-1022`` (the smallest normal, larger
than the ulp 2^-1074 of any subnormal) covers ``c = 0`` and the subnormal range; ``c - d`` with
``d >= ulp(c)`` rounds (monotonically) to at most ``c - ulp(c)``, a float, so the result is
``<= nextafter(c, -inf) <= e``. The test suite checks
this against ``math.nextafter``. All kernels are compiled with ``fastmath=False`` so that LLVM
neither reassociates nor contracts these expressions.

Reference for interval inclusion functions: R. E. Moore, R. B. Kearfott, M. J. Cloud,
"Introduction to Interval Analysis", SIAM 2009, ch. 2-3.
"""
from __future__ import annotations

import numba

_EPS = 2.0**-52
"""Relative one-ulp step (machine epsilon)."""
_TINY = 2.0**-1022
"""Smallest positive normal float64 (a normal constant: subnormal operands are slow on x86)."""


@numba.njit(cache=True, fastmath=False, inline="always")
def round_down(c: float) -> float:
    """A float <= every real that rounds to ``c`` (at least one ulp below ``c``)."""
    return c - (abs(c) * _EPS + _TINY)


@numba.njit(cache=True, fastmath=False, inline="always")
def round_up(c: float) -> float:
    """A float >= every real that rounds to ``c`` (at least one ulp above ``c``)."""
    return c + (abs(c) * _EPS + _TINY)


@numba.njit(cache=True, fastmath=False, inline="always")
def iv_add(alo: float, ahi: float, blo: float, bhi: float) -> tuple[float, float]:
    """[a] + [b] = [alo + blo, ahi + bhi], rounded outward."""
    return round_down(alo + blo), round_up(ahi + bhi)


@numba.njit(cache=True, fastmath=False, inline="always")
def iv_sub(alo: float, ahi: float, blo: float, bhi: float) -> tuple[float, float]:
    """[a] - [b] = [alo - bhi, ahi - blo], rounded outward."""
    return round_down(alo - bhi), round_up(ahi - blo)


@numba.njit(cache=True, fastmath=False, inline="always")
def iv_mul(alo: float, ahi: float, blo: float, bhi: float) -> tuple[float, float]:
    """[a] * [b] = hull of the four endpoint products, rounded outward."""
    p0 = alo * blo
    p1 = alo * bhi
    p2 = ahi * blo
    p3 = ahi * bhi
    return round_down(min(min(p0, p1), min(p2, p3))), round_up(max(max(p0, p1), max(p2, p3)))


@numba.njit(cache=True, fastmath=False, inline="always")
def iv_scale_nonneg(s: float, alo: float, ahi: float) -> tuple[float, float]:
    """s * [a] for an exact float ``s >= 0``, rounded outward."""
    return round_down(s * alo), round_up(s * ahi)


@numba.njit(cache=True, fastmath=False, inline="always")
def iv_abs_max(lo: float, hi: float) -> float:
    """max |x| over [lo, hi] (exact: no arithmetic)."""
    return max(abs(lo), abs(hi))


@numba.njit(cache=True, fastmath=False, inline="always")
def iv_gap_to_zero(lo: float, hi: float) -> float:
    """min |x| over [lo, hi]: 0 when the interval contains 0 (exact: no arithmetic)."""
    if lo > 0.0:
        return lo
    if hi < 0.0:
        return -hi
    return 0.0
