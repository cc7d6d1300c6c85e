"""The render farm: `fraytool batch` runs many shots on Dask distributed (docs/farm.md).

shots.py    job files, scenes and wedges -> Shot (plain, picklable)
tasks.py    the work of one task on a worker: simulate, render a chunk of frames, join, contact sheet
runner.py   the task graph on a Dask client, job.json, re-runs that continue
watch.py    what the client sees while it waits: no worker, lost workers, retries, every attempt
"""
