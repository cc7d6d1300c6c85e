"""How many threads the simulation kernels use (`--threads N`; numba's NUMBA_NUM_THREADS sets the most).

The parallel kernels (numba prange: strain limiting yarn by yarn, `limit_strain_lines`, or colour group
by colour group, `limit_strain_groups`) give the same result, bit for bit, on any number of threads:
every thread moves its own particles, and the largest residual is taken after each group. The thread
count therefore changes only the speed. The other kernels run on one thread: spring forces sum into
shared particles in spring order (a parallel order-keeping version, per particle or per chunk, was
measured 1.5-2x slower per thread than the serial loop, so no faster on two cores), the explicit
Euler updates are too cheap for a parallel region to pay, and self-collision and tearing are
sequential by design (Gauss-Seidel over pairs and couples). The farm's workers run one thread each (fraytool.farm.runner.WORKER_ENV)."""
from __future__ import annotations

from fraytool.errors import InputError


def thread_limit() -> int:
    """The most threads numba may use in this process (NUMBA_NUM_THREADS, default the machine's cores)."""
    import numba

    return int(numba.config.NUMBA_NUM_THREADS)


def use_threads(count: int) -> None:
    """Run the kernels on `count` threads (1 .. thread_limit()); an InputError names the allowed range."""
    import numba

    limit = thread_limit()
    if not 1 <= count <= limit:
        raise InputError(f"--threads {count}: allowed 1 to {limit} on this machine (NUMBA_NUM_THREADS or the "
                         "number of cores sets the most)")
    numba.set_num_threads(count)
