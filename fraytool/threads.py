"""How many threads the simulation kernels use (`--threads N`; numba's NUMBA_NUM_THREADS sets the most).

The parallel kernels (numba prange: strain limiting yarn by yarn, `limit_strain_lines`, or colour group
by colour group, `limit_strain_groups`) give the same result, bit for bit, on any number of threads:
every thread moves its own particles, and the largest residual is taken after each group. The thread
count therefore changes only the speed. The command line runs one thread unless asked for more (DEFAULT_THREADS). The other kernels run on one thread: spring forces sum into
shared particles in spring order (a parallel order-keeping version, per particle or per chunk, was
measured 1.5-2x slower per thread than the serial loop, so no faster on two cores), the explicit
Euler updates are too cheap for a parallel region to pay, and self-collision and tearing are
sequential by design (Gauss-Seidel over pairs and couples). The farm's workers run one thread each (fraytool.farm.runner.WORKER_ENV)."""
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


def thread_limit() -> int:
    """The most threads numba may use in this process (NUMBA_NUM_THREADS, default the machine's cores)."""
    import numba

    return int(numba.config.NUMBA_NUM_THREADS)


def set_up_threads(count: int | None) -> None:
    """The CLI's thread setting: `count` (--threads) if given, else NUMBA_NUM_THREADS if the environment
    sets it, else DEFAULT_THREADS.

    More than one thread pays only on free cores: numba's OpenMP threads spin while they wait for the
    others (OMP_WAIT_POLICY active, the runtime's default), which is what makes a parallel region
    cheap enough at all: with OMP_WAIT_POLICY=PASSIVE (sleeping waits) two threads gained nothing on
    the 256 x 256 drape (strain limiting 771 -> 790 ms per frame) and lost on fig7 (9.6 -> 18.6)."""
    if count is not None:
        use_threads(count)
    elif "NUMBA_NUM_THREADS" not in os.environ:
        use_threads(min(DEFAULT_THREADS, thread_limit()))


def use_threads(count: int) -> None:
    """Run the kernels on `count` threads (1 .. thread_limit()); an InputError names the allowed range."""
    import numba

    limit = thread_limit()
    if not 1 <= count <= limit:
        raise InputError(f"--threads {count}: allowed 1 to {limit} on this machine (NUMBA_NUM_THREADS or the "
                         "number of cores sets the most)")
    numba.set_num_threads(count)
