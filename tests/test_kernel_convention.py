"""Every numba kernel follows one convention, checked on the source (tests/kernel_convention.py): at most
12 flat arguments (grouped beyond that), and writes only to arguments named `*_out` / `*_inout`."""
from pathlib import Path

import pytest
from kernel_convention import MAX_FLAT_ARGUMENTS, kernel_problems, package_problems

pytestmark = pytest.mark.fast  # `pytest -m fast` (docs/testing.md)

PACKAGE = Path(__file__).resolve().parent.parent / "fraytool"


def test_every_kernel_of_fraytool_follows_the_convention():
    assert package_problems(PACKAGE) == []


INJECTED = '''
import numba as nb

@nb.njit(cache=True)
def flat(a0, a1, a2, a3, a4, a5, a6, a7, a8, a9, a10, a11, a12):
    return a0

@nb.njit(cache=True)
def writes_its_input(x_in, y_out):
    x_in[0] = 1.0
    y_out[0] = 2.0

@nb.njit(cache=True, parallel=True)
def writes_unsuffixed(positions, springs_inout):
    x = positions
    x[0, 0] += 1.0
    alive = springs_inout.spring_alive
    alive[0] = False

@nb.njit
def unpacks_a_group(springs_in, out_inout):
    a, alive = springs_in
    alive[3] = True
    out_inout[0] = a[0]

@nb.njit
def hands_on_to_a_writer(values, rows_in):
    writes_its_input(rows_in, values)

@nb.njit(cache=True, inline="always")
def needs_blas(a_in, b_in):
    return a_in @ b_in + np.dot(a_in, b_in) + np.linalg.norm(a_in)

def not_a_kernel(x_in):
    x_in[0] = 1.0
'''


def test_the_check_fails_on_an_injected_kernel_of_each_kind():
    problems = kernel_problems(INJECTED, "injected.py")
    assert [p.split(": ", 1)[0] for p in problems] == [
        "injected.py:5 flat", "injected.py:9 writes_its_input", "injected.py:14 writes_unsuffixed",
        "injected.py:21 unpacks_a_group", "injected.py:27 hands_on_to_a_writer"] + [
        "injected.py:31 needs_blas"] * 3, problems
    assert f"13 arguments (at most {MAX_FLAT_ARGUMENTS}" in problems[0]
    assert "writes argument 'x_in'" in problems[1] and "not _in" in problems[1]
    assert "writes argument 'positions'" in problems[2]  # through a local name; a group's field is fine
    assert "writes argument 'springs_in'" in problems[3]  # a field of an unpacked read-only group
    assert "writes argument 'values'" in problems[4]  # handed on to a callee's _out argument
    assert "uses '@'" in problems[5] and "np.dot" in problems[6] and "np.linalg" in problems[7]
