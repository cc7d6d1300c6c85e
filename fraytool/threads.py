"""How many threads the simulation kernels use (`--threads N`; numba's NUMBA_NUM_THREADS sets the most).

The parallel kernels give the same result, bit for bit, on any number of threads, so the thread
count changes only the speed:
- strain limiting, yarn by yarn (`limit_strain_lines`) or colour group by colour group
  (`limit_strain_groups`): every thread moves its own particles, and the largest residual of a group
  is a maximum (exact in any order);
- the per-particle kernels (velocity and position updates, the velocity post-process, the last pass
  of damping, contact with bodies that do not take the cloth's push): over a list of the particles
  they update cut into a fixed number of equal units (fraytool.sim.kernels.work_split), each
  particle's arithmetic inside one unit.
The command line runs one thread unless asked for more (DEFAULT_THREADS). Still on one thread:
spring forces sum into shared particles in spring order (parallel order-keeping versions were
measured slower per thread than the serial loop: a gather per particle, 2.5x, units of particles
each walking their springs, 1.6-2.3x, so no faster on two cores; on 2026-12-03 a two-phase one,
each spring's force vector in parallel then a per-particle gather of them in spring order, gave the
same bits but 1.10 + 0.62 ms against the serial loop's 1.59 ms per step on two threads, 256 x 256
drape: the loop is bound by memory, not arithmetic; on 2026-12-06 bands of rows, each band's own springs
in parallel then the springs between bands serially, thread-count independent too: 254 ms per frame on
one thread and 150 on two, against the serial loop's 181: the indirection through the banded list costs
more than the second core gains), damping's sums and the contact
impulses on dynamic bodies (a parallel sum rounds differently with the thread count), and
self-collision and tearing (Gauss-Seidel over pairs and couples). The farm's workers run one
thread each (fraytool.farm.runner.WORKER_ENV)."""
from __future__ import annotations

import os

from fraytool.errors import InputError

DEFAULT_THREADS = 1
"""Threads of a `fraytool` command without --threads (and without NUMBA_NUM_THREADS in the environment).

One, because a parallel region waits for its slowest thread: with two threads on a 2-core machine
where another process keeps one core busy, fig6's strain limiting went from 3.0 to 64.9 ms per frame
(numba's OpenMP layer, its threads spinning while they wait). On a quiet machine two threads save
little at the figure scenes' size (fig7: strain limiting 8.6 -> 6.7 ms per frame) and more on big
cloths (256 x 256 drape: 814 -> 476). So more threads are asked for, not assumed: --threads N, or
NUMBA_NUM_THREADS=N in the environment."""


WAIT_POLICY = "ACTIVE"
"""OMP_WAIT_POLICY of a run asked for more than one thread (unless the environment sets one): the
OpenMP threads spin between parallel regions instead of sleeping. A step alternates parallel
kernels with serial ones (spring forces, damping's sums) that outlast the runtime's default spin, so
with sleeping waits every region paid a wake-up: on the 256 x 256 drape at two threads the velocity
and position updates took 117 ms per frame (69 on one thread); spinning, 51, and the frame
703 -> 589 ms. The cost: a spinning thread holds its core while the main thread runs serial code."""


def thread_limit() -> int:
    """The most threads numba may use in this process (NUMBA_NUM_THREADS, default the machine's cores)."""
    import numba

    return int(numba.config.NUMBA_NUM_THREADS)


def set_up_threads(count: int | None) -> None:
    """The CLI's thread setting: `count` (--threads) if given, else NUMBA_NUM_THREADS if the environment
    sets it, else DEFAULT_THREADS.

    More than one thread pays only on free cores: numba's OpenMP threads spin while they wait for the
    others (for a while by the runtime's default; for good with OMP_WAIT_POLICY=ACTIVE, which a run
    of more than one thread sets: WAIT_POLICY), which is what makes a parallel region cheap enough at
    all: with OMP_WAIT_POLICY=PASSIVE (sleeping waits) two threads gained nothing on the 256 x 256
    drape (strain limiting 771 -> 790 ms per frame) and lost on fig7 (9.6 -> 18.6)."""
    if count is not None:
        use_threads(count)
    elif "NUMBA_NUM_THREADS" not in os.environ:
        use_threads(min(DEFAULT_THREADS, thread_limit()))
    elif thread_limit() > 1:
        os.environ.setdefault("OMP_WAIT_POLICY", WAIT_POLICY)


def use_threads(count: int) -> None:
    """Run the kernels on `count` threads (1 .. thread_limit()); an InputError names the allowed range."""
    import numba

    limit = thread_limit()
    if not 1 <= count <= limit:
        raise InputError(f"--threads {count}: allowed 1 to {limit} on this machine (NUMBA_NUM_THREADS or the "
                         "number of cores sets the most)")
    if count > 1:
        # before numba starts its OpenMP threads (the runtime reads it once): see WAIT_POLICY
        os.environ.setdefault("OMP_WAIT_POLICY", WAIT_POLICY)
    numba.set_num_threads(count)
