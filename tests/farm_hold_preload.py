"""A Dask worker preload for tests/test_farm_report.py (`dask worker --preload tests/farm_hold_preload.py`):
the first simulate attempt among all workers started with it holds. It claims the folder named by
FRAYTOOL_TEST_HOLD, writes its worker's address and pid to held.json there and waits to be killed,
so the test kills the worker that is surely running a task, and knows which. Every later attempt
simulates as usual.

The farm client pickles tasks.simulate_task by reference, so each worker runs what its own module
holds: the held version here."""
import json
import os
import time
from pathlib import Path

from fraytool.farm import tasks

_simulate = vars(tasks).setdefault("_unheld_simulate_task", tasks.simulate_task)
"""The real task (kept on the module: a worker may import its preload file more than once)."""


def _held_simulate(shot, out_dir, frames_needed):
    hold = Path(os.environ["FRAYTOOL_TEST_HOLD"])
    try:
        os.close(os.open(hold / "claimed", os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except FileExistsError:  # the hold was taken: this is the retry
        return _simulate(shot, out_dir, frames_needed)
    from distributed import get_worker

    (hold / "held.tmp").write_text(json.dumps({"pid": os.getpid(), "worker": get_worker().address}))
    (hold / "held.tmp").replace(hold / "held.json")
    while True:  # until the test kills this worker
        time.sleep(0.1)


tasks.simulate_task = _held_simulate
