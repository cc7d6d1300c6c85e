"""Strain limiting by constraint projection (docs/method.md §4.1; Provot 1995; Müller et al. 2007).

A stretched spring of rest length L and current length l > (1 + limit) L is projected back to
l* = (1 + limit) L, moving its ends along u (unit, a to b) by their inverse-mass shares:

    Δx_a = +w_a / (w_a + w_b) (l - l*) u,   Δx_b = -w_b / (w_a + w_b) (l - l*) u

Sweeps run Gauss-Seidel, alternating direction to avoid a drift bias, until a sweep finds every
spring within limit + tolerance or the iteration cap is hit. `limit_strain` is the serial sweep;
the solver runs `limit_strain_groups` (the same sweeps, the springs of one colour group at a time in
parallel) or, for a compliant limit, `limit_strain_lines` (one yarn per thread). Both give the same
bits on any number of threads: a thread moves only masses no other thread of the group touches.
"""
from __future__ import annotations

import math

import numba as nb


@nb.njit(cache=True, fastmath=False, inline="always")
def _move_ends(particle_position_m_inout, a, b, k_a, k_b, ux, uy, uz):
    """x_a += k_a u, x_b -= k_b u: a spring's two ends moved along u, each by its own share."""
    particle_position_m_inout[a, 0] += k_a * ux
    particle_position_m_inout[a, 1] += k_a * uy
    particle_position_m_inout[a, 2] += k_a * uz
    particle_position_m_inout[b, 0] -= k_b * ux
    particle_position_m_inout[b, 1] -= k_b * uy
    particle_position_m_inout[b, 2] -= k_b * uz


@nb.njit(cache=True, fastmath=False, inline="always")
def _project_stretched(s, stretch, spring_rest_length_m, particle_inv_mass, spring_particle_a, spring_particle_b,
                       spring_alive, particle_position_m_inout):
    """Project spring s back to `stretch` x its rest length if it is longer (module docstring); returns
    its excess strain, 0 when it was not projected (within the limit, cut, or both ends held). A spring
    within its limit costs one squared length and a compare; only stretched ones pay for the root."""
    if not spring_alive[s]:
        return 0.0  # a cut spring no longer holds its ends together
    a = spring_particle_a[s]
    b = spring_particle_b[s]
    max_length = stretch * spring_rest_length_m[s]
    dx = particle_position_m_inout[b, 0] - particle_position_m_inout[a, 0]
    dy = particle_position_m_inout[b, 1] - particle_position_m_inout[a, 1]
    dz = particle_position_m_inout[b, 2] - particle_position_m_inout[a, 2]
    d2 = dx * dx + dy * dy + dz * dz
    if d2 <= max_length * max_length:
        return 0.0
    w_a = particle_inv_mass[a]
    w_b = particle_inv_mass[b]
    w = w_a + w_b
    if w == 0.0:
        return 0.0  # both ends held by bodies: nothing can move
    length = math.sqrt(d2)
    c = (length - max_length) / (length * w)
    _move_ends(particle_position_m_inout, a, b, w_a * c, w_b * c, dx, dy, dz)
    return (length - max_length) / spring_rest_length_m[s]


@nb.njit(cache=True, fastmath=False)
def limit_strain(
    # model
    limited_springs, spring_rest_length_m, strain_limit, tolerance, max_iterations,
    # state in
    particle_inv_mass, spring_particle_a, spring_particle_b, spring_alive,
    # state in/out
    particle_position_m_inout,
):
    """Project the springs listed in `limited_springs`; returns (sweeps used, converged)."""
    n = limited_springs.shape[0]
    stretch = 1.0 + strain_limit
    for it in range(max_iterations):
        worst = 0.0
        for k in range(n):
            s = limited_springs[k] if it % 2 == 0 else limited_springs[n - 1 - k]
            excess = _project_stretched(s, stretch, spring_rest_length_m, particle_inv_mass, spring_particle_a,
                                        spring_particle_b, spring_alive, particle_position_m_inout)
            if excess > worst:
                worst = excess
        if worst <= tolerance:
            return it + 1, True
    return max_iterations, max_iterations == 0


@nb.njit(cache=True, fastmath=False, parallel=True)
def limit_strain_groups(
    # model: the springs limited, in colour groups; (strain limit, tolerance, most sweeps)
    limited_springs, group_start, limit_in,
    # state in: (rest lengths, inverse masses, ends a, ends b, alive flags)
    springs_in,
    # scratch: per limited spring (overwritten), per particle (zeroed here)
    checked_at_inout, moved_at_inout,
    # state in/out
    particle_position_m_inout,
):
    """`limit_strain` over springs in groups that share no mass (limited_springs[group_start[g]:
    group_start[g + 1]]): the groups one after another, the springs of a group in parallel; returns
    (sweeps used, converged).

    Inside a group no two springs move the same particle, so the order inside it does not matter and
    the result is the same, bit for bit, as `limit_strain` over the concatenated list (which sweeps
    forward, then backward: the groups in reverse order) on any number of threads.

    Springs left alone: after the first sweep, a spring that its last projection left unmoved
    (within the limit, cut, or held at both ends) and neither of whose ends moved since would be
    left unmoved again, so it is skipped, with an excess of 0 as its projection would return: the
    same result, bit for bit, for less work where only part of the cloth is stretched (a drape
    where it meets the table). ``moved_at[p]``: the stamp (1, 2, ... in the order the group updates
    run) of the update that last moved particle p; ``checked_at[k]``: that of spring k's last
    projection, negative when it moved its ends. A particle is moved by one spring per group at most,
    so the stamps are written race-free. The group's largest excess is a parallel maximum (exact, so
    the same whatever the threads' shares; NaN excesses count as 0, as in the serial sweep)."""
    strain_limit, tolerance, max_iterations = limit_in
    spring_rest_length_m, particle_inv_mass, spring_particle_a, spring_particle_b, spring_alive = springs_in
    stretch = 1.0 + strain_limit
    groups = group_start.shape[0] - 1
    for p in nb.prange(moved_at_inout.shape[0]):
        moved_at_inout[p] = 0
    for it in range(max_iterations):
        worst = 0.0
        for step in range(groups):
            g = step if it % 2 == 0 else groups - 1 - step
            lo = group_start[g]
            hi = group_start[g + 1]
            stamp = it * groups + step + 1
            group_worst = 0.0
            for k in nb.prange(lo, hi):
                s = limited_springs[k]
                a = spring_particle_a[s]
                b = spring_particle_b[s]
                since = checked_at_inout[k]
                if it > 0 and since > 0 and moved_at_inout[a] <= since and moved_at_inout[b] <= since:
                    continue  # left alone: an excess of 0
                excess = _project_stretched(s, stretch, spring_rest_length_m, particle_inv_mass, spring_particle_a,
                                            spring_particle_b, spring_alive, particle_position_m_inout)
                if excess > 0.0:
                    moved_at_inout[a] = stamp
                    moved_at_inout[b] = stamp
                    checked_at_inout[k] = -stamp
                    group_worst = max(group_worst, excess)  # a maximum: exact in any order
                else:
                    checked_at_inout[k] = stamp
            if group_worst > worst:
                worst = group_worst
        if worst <= tolerance:
            return it + 1, True
    return max_iterations, max_iterations == 0


@nb.njit(cache=True, fastmath=False)
def damp_overstretched(
    # model
    limited_springs, spring_rest_length_m, strain_limit, damping_n_s_per_m, dt_s,
    # state in
    particle_inv_mass, spring_particle_a, spring_particle_b, spring_alive, prev_position_m,
    # state in/out
    particle_position_m_inout,
):
    """A dashpot of `damping_n_s_per_m` along every live spring in `limited_springs` that is past
    (1 + strain_limit) x rest length and lengthening in this step, integrated exactly: the rate of
    stretch v = u . ((x_b - x_a) - (x'_b - x'_a)) / dt, x' the previous positions, u the unit
    direction, obeys dv/dt = -c (w_a + w_b) v under the dashpot alone, so over the step it falls to
    v exp(-g), g = c dt (w_a + w_b) (stable at any step, and the same decay per second at every
    step: backward Euler's v / (1 + g) damped a step of the figure scenes 1/8.5 where the exact
    decay is 1/1700, which made the tear depend on the step), the two ends moving in proportion to
    their inverse masses (momentum kept). One pass in the given order.

    Why (docs/tearing.md "Strain limiting"): past the limit the compliant constraint is a stiff
    spring (10x structural in the figure scenes) whose period the figure scenes' step does not
    resolve, so at their step it acts as a hard, inelastic stop and at a sixteenth of it as a
    spring that rings; damped near critically it behaves the same at both. Physically: yarn
    stretched past its elastic range dissipates (fibres slip inside the yarn). Returns nothing."""
    stretch = 1.0 + strain_limit
    for k in range(limited_springs.shape[0]):
        s = limited_springs[k]
        if not spring_alive[s]:
            continue
        a = spring_particle_a[s]
        b = spring_particle_b[s]
        dx = particle_position_m_inout[b, 0] - particle_position_m_inout[a, 0]
        dy = particle_position_m_inout[b, 1] - particle_position_m_inout[a, 1]
        dz = particle_position_m_inout[b, 2] - particle_position_m_inout[a, 2]
        d2 = dx * dx + dy * dy + dz * dz
        max_length = stretch * spring_rest_length_m[s]
        if d2 <= max_length * max_length:
            continue
        w_a = particle_inv_mass[a]
        w_b = particle_inv_mass[b]
        w = w_a + w_b
        if w == 0.0:
            continue
        length = math.sqrt(d2)
        ux = dx / length
        uy = dy / length
        uz = dz / length
        stretched = ((dx - (prev_position_m[b, 0] - prev_position_m[a, 0])) * ux
                     + (dy - (prev_position_m[b, 1] - prev_position_m[a, 1])) * uy
                     + (dz - (prev_position_m[b, 2] - prev_position_m[a, 2])) * uz)  # v dt
        if stretched <= 0.0:
            continue
        g = damping_n_s_per_m * dt_s * w
        f = stretched * -math.expm1(-g) / w  # the impulse along u, times dt / m-weights
        _move_ends(particle_position_m_inout, a, b, w_a * f, w_b * f, ux, uy, uz)


@nb.njit(cache=True, fastmath=False)
def _solve_line(
    first, last, line_springs, stretch, alpha,
    # state in: (rest lengths, inverse masses, ends a, ends b, alive flags)
    springs_in,
    # scratch: (tension, diag, upper, rhs, unit), indexed like line_springs
    solve_inout,
    particle_position_m_inout, stamp, moved_at_out,
):
    """One block-Gauss-Seidel update of the yarn line line_springs[first:last] (see
    `limit_strain_lines`); returns the largest residual strain it met (before its update) and
    whether it had a block (an active spring). The particles it moves get ``moved_at[p] = stamp``."""
    spring_rest_length_m, particle_inv_mass, spring_particle_a, spring_particle_b, spring_alive = springs_in
    tension_inout, diag_inout, upper_inout, rhs_inout, unit_inout = solve_inout
    worst = 0.0
    had_block = False
    k = first
    while k < last:
        # -- gather the next block: consecutive active springs chained end to start ------------
        start = k
        end = k
        while end < last:
            s = line_springs[end]
            if not spring_alive[s]:
                break
            a = spring_particle_a[s]
            b = spring_particle_b[s]
            if end > start and spring_particle_b[line_springs[end - 1]] != a:
                break
            w_a = particle_inv_mass[a]
            w_b = particle_inv_mass[b]
            if w_a + w_b == 0.0:
                break
            rest = spring_rest_length_m[s]
            max_length = stretch * rest
            dx = particle_position_m_inout[b, 0] - particle_position_m_inout[a, 0]
            dy = particle_position_m_inout[b, 1] - particle_position_m_inout[a, 1]
            dz = particle_position_m_inout[b, 2] - particle_position_m_inout[a, 2]
            d2 = dx * dx + dy * dy + dz * dz
            mu = tension_inout[end]
            if (mu == 0.0 and d2 <= max_length * max_length) or d2 == 0.0:
                break  # slack and not pulling (or degenerate): not in the block
            length = math.sqrt(d2)
            unit_inout[end, 0] = dx / length
            unit_inout[end, 1] = dy / length
            unit_inout[end, 2] = dz / length
            residual = length - max_length - alpha * mu
            r = residual / rest
            if r > worst:
                worst = r
            elif mu > 0.0 and -r > worst:
                worst = -r  # pulling harder than the stretch asks: also a residual
            rhs_inout[end] = residual
            diag_inout[end] = w_a + w_b + alpha
            if end > start:
                upper_inout[end - 1] = -w_a * (unit_inout[end - 1, 0] * unit_inout[end, 0] + unit_inout[end - 1, 1] * unit_inout[end, 1]
                                         + unit_inout[end - 1, 2] * unit_inout[end, 2])
            end += 1
        if end == start:
            k = start + 1  # an inactive spring: skip it
            continue
        had_block = True
        # -- Thomas algorithm on the symmetric tridiagonal block [start, end) -------------------
        for i in range(start + 1, end):
            f = upper_inout[i - 1] / diag_inout[i - 1]
            diag_inout[i] -= f * upper_inout[i - 1]
            rhs_inout[i] -= f * rhs_inout[i - 1]
        rhs_inout[end - 1] /= diag_inout[end - 1]
        for i in range(end - 2, start - 1, -1):
            rhs_inout[i] = (rhs_inout[i] - upper_inout[i] * rhs_inout[i + 1]) / diag_inout[i]
        # -- new tensions (>= 0) and the moves they make ------------------------------------
        for i in range(start, end):
            s = line_springs[i]
            mu = tension_inout[i]
            new_mu = mu + rhs_inout[i]
            if new_mu < 0.0:
                new_mu = 0.0
            dmu = new_mu - mu
            tension_inout[i] = new_mu
            if dmu == 0.0:
                continue
            a = spring_particle_a[s]
            b = spring_particle_b[s]
            _move_ends(particle_position_m_inout, a, b, particle_inv_mass[a] * dmu, particle_inv_mass[b] * dmu,
                       unit_inout[i, 0], unit_inout[i, 1], unit_inout[i, 2])
            moved_at_out[a] = stamp
            moved_at_out[b] = stamp
        k = end
    return worst, had_block


@nb.njit(cache=True, fastmath=False)
def _moved_since(first, last, line_springs, spring_particle_a, spring_particle_b, spring_alive, moved_at, since):
    """True if a live spring of the line line_springs[first:last] has an end moved after stamp `since`."""
    for k in range(first, last):
        s = line_springs[k]
        if spring_alive[s] and (moved_at[spring_particle_a[s]] > since or moved_at[spring_particle_b[s]] > since):
            return True
    return False


@nb.njit(cache=True, fastmath=False, parallel=True)
def limit_strain_lines(
    # model: the yarn lines, their groups; (strain limit, tolerance, most sweeps); the compliance
    line_springs, line_start, group_start, limit_in, compliance_s2_per_kg,
    # state in: (rest lengths, inverse masses, ends a, ends b, alive flags)
    springs_in,
    # scratch: (tension, diag, upper, rhs, unit, line_worst, line_status, moved_at); tension, moved_at
    # zeroed here, the others overwritten
    scratch_inout,
    # state in/out
    particle_position_m_inout,
):
    """Strain limiting as a compliant inequality constraint (XPBD, Macklin, Müller & Chentanez 2016),
    solved a whole yarn at a time (block Gauss-Seidel over yarn lines). C = l - (1 + limit) L >= 0 is
    resisted with compliance alpha = 1 / k_limit [m/N] through the multiplier mu >= 0 (tension
    impulse / h^2) accumulated over the step's sweeps, alpha~ = alpha / h^2 (passed in): with
    alpha~ > 0 a pull the limit cannot meet stretches the yarn by a definite amount, so the sweeps
    converge and where and when yarns break no longer depends on the step. The point Gauss-Seidel
    version of the same iteration is the slow reference in tests/strain_reference.py.

    Point Gauss-Seidel moves a correction one spring along the yarn per sweep, so a yarn pulled at
    both ends by grips needs sweeps in proportion to the square of its length and stopped at its cap
    while the grips pulled. Here every sweep solves, for each yarn line (line_springs[line_start[l]:
    line_start[l + 1]], in order along the yarn), the linearised system of all its active springs
    at once: with u_k the unit directions and C_k = l_k - (1 + limit) L_k,

        (J W J^T + alpha~ I) d_mu = C - alpha~ mu,
        (J W J^T)_kk = w_a + w_b,  (J W J^T)_k,k+1 = -w_shared (u_k . u_k+1),

    a tridiagonal system (a chain) solved exactly by the Thomas algorithm (diagonally dominant:
    alpha~ > 0); then mu' = max(0, mu + d_mu) and each end moves by w d_mu' u as in the point
    version. A block is a run of consecutive live springs chained end to start that are pulling or
    past the limit; others separate blocks. The sweeps alternate between the line groups
    (group_start: weft lines [group_start[0], group_start[1]), warp lines after), so weft and warp
    meet at base-level crossings only between groups.

    Lines of one group share no mass, so their order inside the group does not matter: they are solved
    in parallel (numba prange), each line by one thread from start to end, writing its own slice of
    the scratch and its own line_worst entry; the largest residual is taken after the group. The
    result is therefore the same, bit for bit, on any number of threads. Returns (sweeps used,
    converged); `tension` holds the multipliers, indexed like line_springs.

    Lines left alone: a line whose last update had no block (every spring slack, no tension) and none
    of whose live springs' ends moved since (``moved_at``: the stamp of the group update that last
    moved each particle; ``line_status[l]`` = 2 x the stamp of line l's last update + 1 if it had a
    block) would form no block again and change nothing, so after the first sweep it is skipped, with
    a residual of 0 as its update would report: the same result, bit for bit, for a fraction of the
    work (in fig7 about 11 of the 128 yarns have a stretched spring at a step's start)."""
    strain_limit, tolerance, max_iterations = limit_in
    spring_rest_length_m, particle_inv_mass, spring_particle_a, spring_particle_b, spring_alive = springs_in
    (tension_inout, diag_inout, upper_inout, rhs_inout, unit_inout, line_worst_inout, line_status_inout,
     moved_at_inout) = scratch_inout
    solve_inout = (tension_inout, diag_inout, upper_inout, rhs_inout, unit_inout)
    stretch = 1.0 + strain_limit
    alpha = compliance_s2_per_kg
    for k in range(tension_inout.shape[0]):
        tension_inout[k] = 0.0
    for p in range(moved_at_inout.shape[0]):
        moved_at_inout[p] = 0
    groups = group_start.shape[0] - 1
    for it in range(max_iterations):
        worst = 0.0
        for g in range(groups):
            lo = group_start[g]
            hi = group_start[g + 1]
            stamp = it * groups + g + 1
            for l in nb.prange(lo, hi):
                if it > 0 and line_status_inout[l] % 2 == 0 and not _moved_since(
                        line_start[l], line_start[l + 1], line_springs, spring_particle_a, spring_particle_b,
                        spring_alive, moved_at_inout, line_status_inout[l] // 2):
                    line_worst_inout[l] = 0.0
                    continue
                line_worst_inout[l], had_block = _solve_line(
                    line_start[l], line_start[l + 1], line_springs, stretch, alpha, springs_in, solve_inout,
                    particle_position_m_inout, stamp, moved_at_inout)
                line_status_inout[l] = 2 * stamp + (1 if had_block else 0)
            for l in range(lo, hi):
                if line_worst_inout[l] > worst:
                    worst = line_worst_inout[l]
        if worst <= tolerance:
            return it + 1, True
    return max_iterations, max_iterations == 0
