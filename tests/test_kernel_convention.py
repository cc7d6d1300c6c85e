"""Every numba kernel follows one convention, checked on the source (tests/kernel_convention.py): at most
12 flat arguments (grouped beyond that), writes only to arguments named `*_out` / `*_inout`, and writes
nothing through a tuple in a parallel loop."""
import ast
from pathlib import Path

import pytest
from kernel_convention import MAX_FLAT_ARGUMENTS, kernel_problems, package_problems, parallel_group_writes

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


PARALLEL = '''
import numba as nb

@nb.njit(parallel=True)
def writes_a_field_in_the_loop(t_inout):
    for i in nb.prange(4):
        t_inout.a[i] = 1.0

@nb.njit(inline="always")
def unpacks_and_writes(g_inout, i):
    a, b = g_inout
    a[i] = 1.0

@nb.njit(inline="always")
def hands_its_group_on(g_inout, i):
    unpacks_and_writes(g_inout, i)

@nb.njit(inline="always")
def writes_a_plain_array(h_out, i):
    h_out[i] = 2.0

@nb.njit(parallel=True)
def calls_an_inlined_group_writer(g_inout):
    for i in nb.prange(4):
        hands_its_group_on(g_inout, i)

@nb.njit(parallel=True)
def unpacks_in_the_loop(g_inout):
    for i in nb.prange(4):
        a, b = g_inout
        a[i] = 1.0

@nb.njit(parallel=True)
def takes_the_arrays_out_first(g_inout, h_out):
    a, b = g_inout
    for i in nb.prange(4):
        a[i] = 1.0
        writes_a_plain_array(h_out, i)
        unpacks_and_writes_not_inlined(g_inout, i)

@nb.njit
def unpacks_and_writes_not_inlined(g_inout, i):
    a, b = g_inout
    a[i] = 1.0

@nb.njit
def serial_field_write(t_inout):
    for i in range(4):
        t_inout.a[i] = 1.0
'''


def test_writes_through_a_tuple_in_a_parallel_loop_are_found():
    """numba drops them (numba issues 7135, 10338): a field written in the loop, a callee inlined into it that
    writes through its group argument (directly or through another inlined callee), a group unpacked in the
    loop; not arrays taken out before the loop, a plain array handed to an inlined callee, a non-inlined
    callee, or a serial loop."""
    tree = ast.parse(PARALLEL)
    problems = parallel_group_writes([tree], ["p.py"])
    assert [p.split(": ", 1)[0] for p in problems] == [
        "p.py:5 writes_a_field_in_the_loop", "p.py:23 calls_an_inlined_group_writer",
        "p.py:28 unpacks_in_the_loop"], problems
    assert "writes its 'g_inout' through a tuple" in problems[1]


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
