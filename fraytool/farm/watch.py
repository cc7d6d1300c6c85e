"""What the client of a farm job sees of its cluster while it waits, said on stderr and kept for
job.json:

- no worker connected: said at the first look (within a second of the job's start, or of the last
  worker leaving), again every NO_WORKER_REPEAT_S, and given up on after --connect-timeout
  (NoWorkerError, exit 1);
- each worker lost, with the tasks it was running;
- each retried task: attempt number, shot, stage, frames, and how the attempt before it ended;
- every attempt of every task: worker, start, end, outcome (`ok`, `error: <one line>`, `lost worker`).

Sources: the scheduler's own events on its topic "all" (a worker removed, with the tasks it was
processing), the farm tasks' events (tasks.run_attempt: an attempt started, an attempt raised), the
tasks' results, and the scheduler's worker count, asked every WORKER_COUNT_EVERY_S. The event
handlers run on the client's event-loop thread and only queue; everything else runs in the caller's
thread, in `poll` and `finished`.
"""
from __future__ import annotations

import queue
import time
from typing import Callable, Iterable, Iterator, Optional, TextIO

from fraytool.errors import RunError
from fraytool.farm.tasks import ATTEMPT_TOPIC, one_line

CLUSTER_TOPIC = "all"
"""The topic on which the Dask scheduler logs its cluster events (add-worker, remove-worker)."""
POLL_S = 0.2
"""Seconds between two looks at the finished futures and the queued events."""
WORKER_COUNT_EVERY_S = 1.0
"""Seconds between two questions to the scheduler: how many workers are connected?"""
NO_WORKER_REPEAT_S = 30.0
"""Seconds between two "no worker connected" lines while the job waits for one."""

OK, LOST, RUNNING = "ok", "lost worker", "running"
"""Outcomes of an attempt (and `error: <one line>`); RUNNING until it ends."""


class NoWorkerError(RunError):
    """No worker was connected for --connect-timeout seconds: the job stops (exit 1)."""


def iso_time(epoch_s: float) -> str:
    """Local time as job.json writes all its times ("started", "finished", attempts): 2026-08-01T14:03:07+0200."""
    return time.strftime("%Y-%m-%dT%H:%M:%S%z", time.localtime(epoch_s))


def attempt_json(attempt: dict) -> dict:
    """One attempt as job.json records it: worker (Dask address), process (host:pid), start, end,
    seconds and outcome (end and seconds null while it runs)."""
    start, end = attempt.get("start"), attempt.get("end")
    return {"worker": attempt.get("worker"), "process": attempt.get("process"),
            "start": iso_time(start) if start is not None else None,
            "end": iso_time(end) if end is not None else None,
            "seconds": round(end - start, 3) if start is not None and end is not None else None,
            "outcome": attempt["outcome"]}


class FarmWatch:
    """The cluster as a job's client sees it (module docstring). `labels` names the tasks in the log
    lines (task key -> e.g. "small render 0-24 (frames 0:24)"); `connect_timeout_s` None waits for a
    worker as long as it takes; `local` says the cluster is the embedded one (its nannies restart
    lost workers, so the hint is not `dask worker`)."""

    def __init__(self, client, stream: TextIO, labels: Optional[dict] = None,
                 connect_timeout_s: Optional[float] = None, local: bool = False,
                 clock: Callable[[], float] = time.monotonic):
        self.client, self.stream = client, stream
        self.address = client.scheduler.address
        self.labels: dict[str, str] = dict(labels or {})
        self.connect_timeout_s, self.local, self.clock = connect_timeout_s, local, clock
        self.attempts: dict[str, list[dict]] = {}
        self.changed: set[str] = set()
        """Task keys whose attempts changed since the caller last took them (`take_changed`)."""
        self.before_line: Callable[[], None] = lambda: None
        """Called before each line is printed (ends a progress bar's line)."""
        self._events: queue.SimpleQueue = queue.SimpleQueue()
        self._processes: dict[str, str] = {}       # worker address -> host:pid, from attempt events
        self._no_worker_since: Optional[float] = None
        self._said_at: Optional[float] = None
        self._counted_at: Optional[float] = None
        self._had_workers = False
        for topic in (CLUSTER_TOPIC, ATTEMPT_TOPIC):
            client.subscribe_topic(topic, lambda event, topic=topic: self._events.put((topic, event)))

    def close(self) -> None:
        """Stop listening (best effort: the client may be closing already)."""
        for topic in (CLUSTER_TOPIC, ATTEMPT_TOPIC):
            try:
                self.client.unsubscribe_topic(topic)
            except Exception:  # noqa: BLE001 - a closed client needs no unsubscribing
                pass

    def say(self, line: str) -> None:
        self.before_line()
        print(f"fraytool: batch: {line}", file=self.stream, flush=True)

    def label(self, key: str) -> str:
        return self.labels.get(key, str(key))

    # -- waiting --------------------------------------------------------------------------------

    def completed(self, futures: Iterable, on_change: Optional[Callable[[set], None]] = None) -> Iterator:
        """The futures as they finish (as distributed.as_completed), looking at the cluster between
        them (`poll`); `on_change(keys)` is told which tasks' attempts changed meanwhile."""
        from distributed import as_completed

        pending = as_completed(list(futures))
        while not pending.is_empty():
            self.poll()
            if on_change is not None and self.changed:
                on_change(self.take_changed())
            batch = pending.next_batch(block=False)
            if not batch:
                time.sleep(POLL_S)
            yield from batch

    def poll(self) -> None:
        """Handle the queued events, then (every WORKER_COUNT_EVERY_S) the worker count. Raises
        NoWorkerError when no worker has been connected for connect_timeout_s."""
        self._drain_events()
        now = self.clock()
        if self._counted_at is None or now - self._counted_at >= WORKER_COUNT_EVERY_S:
            self._counted_at = now
            self._check_worker_count(self._worker_count(), now)

    def take_changed(self) -> set:
        keys, self.changed = self.changed, set()
        return keys

    # -- attempts -------------------------------------------------------------------------------

    def finished(self, key: str, result: Optional[dict] = None, error: Optional[BaseException] = None) -> list[dict]:
        """A task's future finished with `result` (its "attempt" entry, from tasks.run_attempt, is
        taken out) or `error`: its last attempt is closed; returns its attempts as job.json records
        them. A task that failed because a task it needs failed never ran: no attempt."""
        self._drain_events()
        if result is not None:
            info = result.pop("attempt", None)
            if info is not None and not self._close(key, info["worker"], info["end"], OK):
                self._add(key, {**info, "outcome": OK})   # its start event did not reach us
        elif error is not None:
            self._close(key, None, time.time(), f"error: {one_line(error)}")
        return self.record(key)

    def record(self, key: str) -> list[dict]:
        return [attempt_json(a) for a in self.attempts.get(key, [])]

    def _add(self, key: str, attempt: dict) -> list[dict]:
        tries = self.attempts.setdefault(key, [])
        tries.append(attempt)
        self.changed.add(key)
        return tries

    def _close(self, key: str, worker: Optional[str], end: float, outcome: str) -> bool:
        """End the running attempt of `key` (on `worker`, when given); False when none runs."""
        for attempt in reversed(self.attempts.get(key, [])):
            if attempt["outcome"] == RUNNING and worker in (None, attempt["worker"]):
                attempt["end"], attempt["outcome"] = end, outcome
                self.changed.add(key)
                return True
        return False

    def _started(self, key: str, worker: str, process: Optional[str], start: float) -> None:
        """An attempt began: a second or later one is a retry, said in a line."""
        if process:
            self._processes[worker] = process
        while self._close(key, None, start, LOST):  # a task moves on only when its worker is gone
            pass
        tries = self._add(key, {"worker": worker, "process": process, "start": start, "end": None,
                                "outcome": RUNNING})
        if len(tries) > 1:
            self.say(f"retrying {self.label(key)}: attempt {len(tries)}, on {worker} "
                     f"(attempt {len(tries) - 1}: {tries[-2]['outcome']})")

    def _running_on(self, worker: str) -> list[str]:
        return [key for key, tries in self.attempts.items()
                if tries and tries[-1]["outcome"] == RUNNING and tries[-1]["worker"] == worker]

    # -- events ---------------------------------------------------------------------------------

    def _drain_events(self) -> None:
        while True:
            try:
                topic, (stamp, message) = self._events.get_nowait()
            except queue.Empty:
                return
            if not isinstance(message, dict):
                continue
            if topic == ATTEMPT_TOPIC:
                self._attempt_event(message)
            elif message.get("action") == "remove-worker":
                self._worker_removed(stamp, message)
            elif message.get("action") == "add-worker":
                self._had_workers = True

    def _attempt_event(self, message: dict) -> None:
        key, worker = message.get("key"), message.get("worker")
        if message.get("event") == "start":
            self._started(key, worker, message.get("process"), message["time"])
        elif message.get("event") == "error":
            self._close(key, worker, message["time"], f"error: {message.get('error')}")

    def _worker_removed(self, stamp: float, message: dict) -> None:
        """A worker left: its running attempts are lost; a line names it and them."""
        worker = message.get("worker")
        running, held = self._running_on(worker), []
        for key in running:
            self._close(key, worker, stamp, LOST)
        who = f"{worker} ({self._processes[worker]})" if worker in self._processes else str(worker)
        if running:
            what = "it was running " + "; ".join(self.label(k) for k in running)
        else:
            held = sorted(str(k) for k in message.get("processing-tasks") or () if k in self.labels)
            what = "it held " + "; ".join(self.label(k) for k in held) + " (not started)" if held else "it ran no task"
        if message.get("expected"):
            self.say(f"worker {who} left the cluster; {what}")
        else:
            self.say(f"lost worker {who}: {what}" + ("; the scheduler runs it again on another worker"
                                                     if running or held else ""))

    # -- no worker ------------------------------------------------------------------------------

    def _worker_count(self) -> int:
        info = self.client.scheduler_info(n_workers=0)  # the count alone (older distributed: every worker)
        return int(info.get("n_workers", len(info.get("workers", ()))))

    def _check_worker_count(self, count: int, now: float) -> None:
        """Say when no worker is connected (at once, then every NO_WORKER_REPEAT_S), say when one
        is again, raise NoWorkerError after connect_timeout_s without one."""
        if count > 0:
            if self._said_at is not None:
                self.say(f"{count} worker(s) connected to {self.address} after "
                         f"{now - self._no_worker_since:.0f} s without one; the job goes on")
            self._no_worker_since = self._said_at = None
            self._had_workers = True
            return
        if self._no_worker_since is None:
            self._no_worker_since = now
        waited = now - self._no_worker_since
        if self.connect_timeout_s is not None and waited >= self.connect_timeout_s:
            raise NoWorkerError(f"batch: no worker connected to {self.address} for {waited:.0f} s "
                                f"(--connect-timeout {self.connect_timeout_s:g}): the job stopped")
        if self._said_at is None or now - self._said_at >= NO_WORKER_REPEAT_S:
            self.say(self._no_worker_line(waited, again=self._said_at is not None))
            self._said_at = now

    def _no_worker_line(self, waited: float, again: bool) -> str:
        if again:
            state = f"still no worker connected to {self.address} after {waited:.0f} s"
        elif self._had_workers:
            state = f"no worker connected to {self.address} any more"
        else:
            state = f"no worker connected to {self.address} yet"
        hint = ("waiting for the local cluster to start its workers" if self.local
                else f"waiting (start one with: dask worker {self.address})")
        limit = (f"; giving up after {self.connect_timeout_s:g} s (--connect-timeout)"
                 if self.connect_timeout_s is not None else "")
        return f"{state}; {hint}{limit}"
