"""Running a Job on Dask distributed: per shot, simulate -> render chunks (in parallel) -> join,
then a contact sheet per wedge; job.json records every task's status, times, outputs and attempts.

The scheduler retries a task whose worker died (the task resumes what was on disk, see tasks.py);
a task that raises is retried RETRIES times, then its shot is marked failed and the others go on.
Lost workers, retries and a cluster without workers are said on stderr as they happen (watch.py).
Re-running a job skips the shots job.json marks done whose outputs are all there.
"""
from __future__ import annotations

import json
import logging
import os
import sys
import time
from pathlib import Path
from typing import TextIO

from fraytool.farm import tasks
from fraytool.farm.contact_sheet import contact_sheet_task
from fraytool.errors import FraytoolError
from fraytool.farm.shots import Job, Shot
from fraytool.farm.watch import FarmWatch, NoWorkerError, iso_time
from fraytool.io.frame_record import atomic_write_bytes
from fraytool import progress as progress_settings

RETRIES = 1
JOB_JSON = "job.json"


_LATER_OPTIONS = ("codec", "fit", "motion_blur", "motion_samples", "supersample")
"""RenderOptions fields added after job.json digests were first written."""


def settings_digest(shot: Shot) -> str:
    """What decides a shot's outputs: scene (file contents or shipped name), overrides, render options."""
    import hashlib

    # options added later (codec, fit) count only when given, so a job.json of an older version still
    # recognises its finished shots
    render = {k: v for k, v in shot.render.__dict__.items() if v is not None or k not in _LATER_OPTIONS}
    h = hashlib.sha256(json.dumps([shot.scene, shot.sets, render], default=str).encode())
    if Path(shot.scene).is_file():
        h.update(Path(shot.scene).read_bytes())
    return h.hexdigest()[:16]


def _outputs_complete(entry: dict, frames) -> bool:
    """The video (MP4 or ProRes .mov) and every PNG (and EXR, when asked for) of the shot's frame range
    are there."""
    outs = entry.get("outputs", {})
    if not outs or not Path(outs.get("video", outs.get("mp4", ""))).is_file():  # "mp4": job.json before ProRes
        return False
    png = Path(outs.get("png", ""))
    exr = Path(outs["exr"]) if outs.get("exr") else None
    return all((png / f"frame_{k:06d}.png").is_file() and (exr is None or (exr / f"frame_{k:06d}.exr").is_file())
               for k in frames.frames())


class JobRecord:
    """job.json, rewritten atomically after every finished task."""

    def __init__(self, job: Job, job_dir: Path):
        self.path = job_dir / JOB_JSON
        try:
            old = json.loads(self.path.read_text())
            old = old if isinstance(old, dict) and isinstance(old.get("shots"), dict) else {}
        except (OSError, ValueError):
            old = {}
        self.data = {"job": job.name, "folder": str(job_dir), "started": iso_time(time.time()),
                     "status": "running", "shots": old.get("shots", {}), "contact_sheets": old.get("contact_sheets", {})}

    def shot(self, name: str) -> dict:
        return self.data["shots"].setdefault(name, {})

    def owner(self, name: str, task: str) -> dict:
        """The entry a task belongs to: its shot's, or its wedge's under "contact_sheets"."""
        if task == "contact sheet":
            return self.data["contact_sheets"].setdefault(name, {})
        return self.shot(name)

    def stop(self, names, reason: str) -> None:
        """The job stopped before it finished (no worker): every unfinished shot and sheet says why."""
        self.data["status"], self.data["error"] = "stopped", reason
        self.data["finished"] = iso_time(time.time())
        for name, task in names:
            entry = self.owner(name, task)
            if entry.get("status") == "running":
                entry["status"], entry["error"] = "stopped", reason
            state = entry.get("tasks", {}).get(task)
            if state is not None and state.get("status") == "running":
                state["status"] = "stopped"
        self.write()

    def write(self) -> None:
        text = json.dumps(self.data, indent=2, sort_keys=True, default=str).encode()
        atomic_write_bytes(self.path, lambda f: f.write(text))


def _chunks(frames, size: int) -> list[tuple[int, int, int]]:
    """(start, end, step) chunks of a FrameRange, `size` frames each."""
    idx = list(frames.frames())
    out = []
    for k in range(0, len(idx), size):
        part = idx[k:k + size]
        out.append((part[0], part[-1] + 1, frames.step))
    return out


def _frames_text(start: int, end: int, step: int = 1) -> str:
    """Frames as --frames writes them: START:END (END excluded), :STEP when not 1."""
    return f"{start}:{end}" + (f":{step}" if step != 1 else "")


def _submit(client, key: str, work, *args):
    """One farm task: `work(*args)` run through tasks.run_attempt (the client sees every attempt),
    retried RETRIES times when it raises."""
    return client.submit(tasks.run_attempt, key, work, *args, key=key, retries=RETRIES, pure=False)


def run_job(job: Job, job_dir: Path, client, stream: TextIO = sys.stderr, progress=None,
            contact_sheets: bool = True, watch: FarmWatch | None = None) -> dict:
    """Submit the job's tasks to a distributed `client`, wait, write job.json; returns its data.
    `watch` (made here when not given) says lost workers, retries and a cluster without workers; it
    raises NoWorkerError after its connect timeout, with job.json written (status "stopped")."""
    job_dir.mkdir(parents=True, exist_ok=True)
    record = JobRecord(job, job_dir)
    futures = {}  # future -> (shot name, task name)
    labels = {}   # task key -> what the log lines call it
    shot_frames_of: dict[str, int] = {}
    final = {}    # shot name -> join future
    groups: dict[str, list[Shot]] = {}
    for shot in job.shots:
        entry = record.shot(shot.name)
        entry.update({"scene": shot.scene, "sets": [[k, v] for k, v in shot.sets], "folder": str(job_dir / shot.name)})
        if shot.error:
            entry.update({"status": "invalid", "error": shot.error, "tasks": {}})
            continue
        out = str(job_dir / shot.name)
        try:
            frames = tasks.shot_frames(shot, Path(out))  # render options checked against this scene
        except FraytoolError as exc:
            entry.update({"status": "invalid", "error": str(exc), "tasks": {}})
            continue
        shot_frames_of[shot.name] = tasks.frames_to_simulate(shot, Path(out))
        digest = settings_digest(shot)
        if entry.get("status") == "done" and entry.get("settings") == digest and _outputs_complete(entry, frames):
            print(f"fraytool: batch: {shot.name}: already done", file=stream)
            if shot.group:
                groups.setdefault(shot.group, []).append(shot)
            continue
        entry.update({"status": "running", "tasks": {}, "error": None, "settings": digest, "outputs": {}})
        key = f"simulate-{shot.name}"
        sim = _submit(client, key, tasks.simulate_task, shot, out, shot_frames_of[shot.name])
        futures[sim] = (shot.name, "simulate")
        labels[key] = f"{shot.name} simulate (frames {_frames_text(0, shot_frames_of[shot.name])})"
        chunks = []
        for start, end, step in _chunks(frames, job.chunk_frames):
            key = f"render-{shot.name}-{start}-{end}"
            f = _submit(client, key, tasks.render_chunk_task, shot, out, start, end, step, sim)
            futures[f] = (shot.name, f"render {start}-{end}")
            labels[key] = f"{shot.name} render {start}-{end} (frames {_frames_text(start, end, step)})"
            chunks.append(f)
        key = f"join-{shot.name}"
        join = _submit(client, key, tasks.join_task, shot, out, chunks)
        futures[join] = (shot.name, "join")
        labels[key] = f"{shot.name} join (frames {_frames_text(frames.start, frames.end, frames.step)})"
        final[shot.name] = join
        if shot.group:
            groups.setdefault(shot.group, []).append(shot)
    for group, members in (groups.items() if contact_sheets else ()):
        waits = [final[s.name] for s in members if s.name in final]
        if len(members) < 2 or not waits and (job_dir / f"{group}_contact_sheet.mp4").exists():
            continue
        key = f"contact-sheet-{group}"
        f = _submit(client, key, contact_sheet_task, members, str(job_dir), group, waits)
        futures[f] = (group, "contact sheet")
        labels[key] = f"{group} contact sheet ({len(members)} shots)"
    record.write()
    own_watch = watch is None
    watch = watch or FarmWatch(client, stream)
    watch.labels.update(labels)
    try:
        _wait(record, futures, watch, StageProgress(futures, shot_frames_of, stream, progress, job.name))
    except NoWorkerError as exc:
        record.stop(set(futures.values()), str(exc))
        raise NoWorkerError(f"{exc}; {record.path} records what was done") from None
    finally:
        if own_watch:
            watch.close()
    shots = record.data["shots"]
    failed = [n for n in (s.name for s in job.shots) if shots[n].get("status") != "done"]
    record.data["status"] = "done" if not failed else "failed"
    record.data["finished"] = iso_time(time.time())
    record.write()
    return record.data


def _wait(record: JobRecord, futures: dict, watch: FarmWatch, stages: "StageProgress") -> None:
    """Record each task as it finishes, and the attempts of running ones as they change, in job.json."""
    owner_of = {fut.key: names for fut, names in futures.items()}

    def running(keys: set) -> None:
        _record_running(record, owner_of, keys, watch)

    watch.before_line = stages.break_line
    try:
        for fut in watch.completed(futures, on_change=running):
            _record_finished(record, *futures[fut], fut, watch)
            watch.changed.discard(fut.key)
            stages.finished(fut)
            record.write()
    except NoWorkerError:
        running(watch.take_changed())
        raise
    finally:
        stages.close()


def _record_running(record: JobRecord, owner_of: dict, keys: set, watch: FarmWatch) -> None:
    """The attempts so far of tasks still running (or waiting for a retry) into job.json."""
    for key in keys & owner_of.keys():
        name, task = owner_of[key]
        tasks_entry = record.owner(name, task).setdefault("tasks", {})
        if tasks_entry.get(task, {}).get("status", "running") == "running":
            tasks_entry[task] = {"status": "running", "attempts": watch.record(key)}
    record.write()


def _record_finished(record: JobRecord, name: str, task: str, fut, watch: FarmWatch) -> None:
    """A finished task's status, result and attempts into its shot's (or wedge's) entry."""
    entry = record.owner(name, task)
    try:
        result = fut.result()
        attempts = watch.finished(fut.key, result=result)
        status = {"status": "done", **result, "attempts": attempts}
    except Exception as exc:  # noqa: BLE001 - a failed task is reported, the others go on
        status = {"status": "failed", "error": tasks.one_line(exc), "attempts": watch.finished(fut.key, error=exc)}
        entry["status"], entry["error"] = "failed", entry.get("error") or f"{task}: {tasks.one_line(exc)}"
    entry.setdefault("tasks", {})[task] = status
    if task == "join" and status["status"] == "done":
        entry["status"] = "done"
        entry["outputs"] = {"video": result["video"], "png": result["png_dir"]}
        if "exr_dir" in result:
            entry["outputs"]["exr"] = result["exr_dir"]
    if task == "contact sheet" and status["status"] == "done":
        entry.update({"status": "done", "outputs": {"mp4": result["mp4"]}})


class StageProgress:
    """Batch progress per stage: frames simulated and rendered, shots joined, each with its rate and
    ETA, as a bar on a terminal or a line every LOG_EVERY_S seconds off one (fraytool.progress)."""

    def __init__(self, futures: dict, frames_of: dict, stream: TextIO, mode, label: str):
        from fraytool.progress import resolve_mode

        self.futures, self.stream = futures, stream
        self.mode = resolve_mode(mode, stream)
        self.drawn = False  # a bar is on the current line
        self.start = self.last = time.perf_counter()
        self.label = label
        self.total = {"simulate": 0, "render": 0, "join": 0}
        self.done = dict.fromkeys(self.total, 0)
        self.weight = {}
        for fut, (name, task) in futures.items():
            stage = task.split()[0]
            if stage == "render":
                a, b = (int(x) for x in task.split()[1].split("-"))
                w = len(range(a, b, 1))
            elif stage == "simulate":
                w = frames_of.get(name, 0)
            else:
                w = 1
            if stage in self.total:
                self.total[stage] += w
                self.weight[fut] = (stage, w)

    def line(self) -> str:
        elapsed = time.perf_counter() - self.start
        parts = []
        for stage, unit in (("simulate", "frames"), ("render", "frames"), ("join", "shots")):
            total, done = self.total[stage], self.done[stage]
            if not total:
                continue
            rate = done / elapsed if elapsed > 0 else 0.0
            eta = f", ETA {(total - done) / rate:.0f} s" if 0 < done < total else ""
            parts.append(f"{stage} {done}/{total} {unit} ({rate:.1f}/s{eta})")
        return f"fraytool progress: batch {self.label}: " + "; ".join(parts)

    def finished(self, fut) -> None:
        stage, w = self.weight.get(fut, (None, 0))
        if stage:
            self.done[stage] += w
        now = time.perf_counter()
        if self.mode == "bar":
            self.stream.write("\r" + self.line() + "   ")
            self.stream.flush()
            self.drawn = True
        elif self.mode == "log" and now - self.last >= progress_settings.LOG_EVERY_S:
            self.last = now
            print(self.line(), file=self.stream, flush=True)

    def break_line(self) -> None:
        """End the bar's line, so that a log line printed next stands on its own."""
        if self.drawn:
            self.stream.write("\n")
            self.drawn = False

    def close(self) -> None:
        if self.mode == "bar":
            self.break_line()
        elif self.mode == "log" and time.perf_counter() - self.start >= progress_settings.LOG_EVERY_S:
            print(self.line(), file=self.stream, flush=True)


WORKER_ENV = {"LP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
              "DASK_LOGGING__DISTRIBUTED": "critical"}
"""One core per worker: the simulation kernels run on one thread in a farm task (tasks.one_thread, also
on remote workers), and Mesa's llvmpipe would otherwise rasterise on every core in every worker (N
workers would fight over the same cores)."""


def local_client(workers: int, stream: TextIO):
    """An embedded LocalCluster: `workers` processes of one thread and one core each (WORKER_ENV)."""
    from distributed import Client, LocalCluster

    for name in ("distributed", "bokeh", "tornado"):
        logging.getLogger(name).setLevel(logging.CRITICAL)
    # failed tasks are reported in job.json and in one line each, not as worker log tracebacks
    os.environ.setdefault("DASK_LOGGING__DISTRIBUTED", "critical")
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                           env=WORKER_ENV)
    return Client(cluster), cluster


def remote_client(address: str):
    from distributed import Client

    for name in ("distributed",):
        logging.getLogger(name).setLevel(logging.ERROR)
    return Client(address, timeout="20s"), None
