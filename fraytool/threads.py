"""How many threads the simulation kernels use (`--threads N`; numba's NUMBA_NUM_THREADS sets the most).

The parallel kernels (numba prange: spring forces, the explicit Euler updates, strain limiting yarn by
yarn) give the same result, bit for bit, on any number of threads: every thread writes its own
particles or springs, and every sum runs in the same order as on one thread. The thread count therefore
changes only the speed. The farm's workers run one thread each (fraytool.farm.runner.WORKER_ENV)."""
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
