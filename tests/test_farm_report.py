"""A farm that reports (issue 35): `fraytool batch` says when no worker is connected (within 5 s,
then gives up after --connect-timeout with exit 1), logs a line per lost worker and per retried
task, and job.json records every attempt of every task (worker, start, end, outcome).

The cluster tests start a real `dask scheduler` and `dask worker`s as processes on localhost and run
`python -m fraytool batch --scheduler` as a process, as a studio would; a worker is killed (SIGKILL)
while it surely runs the shot's simulation (tests/farm_hold_preload.py holds the first attempt)."""
from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from fraytool.commands.main import main
from helpers import small_scene_text

ROOT = Path(__file__).resolve().parents[1]
TESTS = Path(__file__).resolve().parent


def _env(**extra) -> dict:
    """This checkout first on the path (the processes import its fraytool), workers on one core."""
    from fraytool.farm.runner import WORKER_ENV

    env = {**os.environ, **WORKER_ENV, **extra}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), str(TESTS), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return env


class Cluster:
    """A scheduler (and workers) started as processes; stop() ends exactly those processes."""

    def __init__(self, folder: Path):
        self.folder, self.procs = folder, []
        self.file = folder / "scheduler.json"
        self.log = open(folder / "cluster.log", "w")
        self._start("distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", "0",
                    "--dashboard-address", ":0", "--scheduler-file", str(self.file))
        deadline = time.monotonic() + 60
        while not self.file.is_file() and time.monotonic() < deadline:
            time.sleep(0.1)
        assert self.file.is_file(), (folder / "cluster.log").read_text()[-3000:]
        self.address = json.loads(self.file.read_text())["address"]

    def _start(self, module: str, *args: str, **env) -> subprocess.Popen:
        proc = subprocess.Popen([sys.executable, "-m", module, *args], env=_env(**env), stdout=self.log,
                                stderr=subprocess.STDOUT, cwd=self.folder)
        self.procs.append(proc)
        return proc

    def add_workers(self, count: int, **env) -> None:
        """`count` workers of one thread, without nannies (a killed one stays dead); waits for them."""
        from distributed import Client

        for k in range(count):
            self._start("distributed.cli.dask_worker", self.address, "--nthreads", "1", "--no-nanny",
                        "--no-dashboard", "--name", f"w{k}", "--preload", str(TESTS / "farm_hold_preload.py"), **env)
        with Client(self.address, timeout="30s") as client:
            client.wait_for_workers(count, timeout=120)

    def stop(self) -> None:
        for proc in reversed(self.procs):
            if proc.poll() is None:
                proc.terminate()
        for proc in self.procs:
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        self.log.close()


@pytest.fixture
def cluster(tmp_path):
    c = Cluster(tmp_path)
    yield c
    c.stop()


@pytest.fixture
def scene(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(small_scene_text(frames=6))
    return path


def _batch(scene: Path, address: str, out: Path, *flags: str, stderr) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "fraytool", "batch", str(scene), "--scheduler", address,
                             "-o", str(out), "--resolution", "64x48", "--frames", "0:4", "--progress", "none",
                             *flags], env=_env(), stderr=stderr, stdout=subprocess.DEVNULL, text=True)


def _timed_lines(proc: subprocess.Popen) -> list[tuple[float, str]]:
    """Collect (monotonic time, line) of the process's stderr as the lines come, in a thread."""
    lines: list[tuple[float, str]] = []

    def read():
        for line in proc.stderr:
            lines.append((time.monotonic(), line.rstrip("\n")))

    threading.Thread(target=read, daemon=True).start()
    return lines


def test_no_worker_is_said_within_5_s_and_connect_timeout_exits_1(cluster, scene, tmp_path):
    out = tmp_path / "job"
    proc = _batch(scene, cluster.address, out, "--connect-timeout", "3", stderr=subprocess.PIPE)
    lines = _timed_lines(proc)
    try:
        code = proc.wait(timeout=90)
    finally:
        if proc.poll() is None:
            proc.kill()
    time.sleep(0.2)  # the reader thread takes the last lines
    text = "\n".join(line for _, line in lines)
    assert code == 1, text
    start = next(t for t, line in lines if "1 shot(s) on 0 worker(s)" in line)
    waiting = [(t, line) for t, line in lines if "no worker connected" in line and "run failed" not in line]
    assert waiting, text
    said, line = waiting[0]
    assert said - start < 5.0, text
    assert line == (f"fraytool: batch: no worker connected to {cluster.address} yet; waiting (start one with: "
                    f"dask worker {cluster.address}); giving up after 3 s (--connect-timeout)")
    ended, last = lines[-1]
    assert re.fullmatch(rf"fraytool: run failed: batch: no worker connected to {re.escape(cluster.address)} for 3 s "
                        rf"\(--connect-timeout 3\): the job stopped; \S+job\.json records what was done", last), text
    assert 2.5 <= ended - said < 30, text   # it waited the 3 s, not more than a few poll intervals over
    data = json.loads((out / "job.json").read_text())
    assert data["status"] == "stopped" and "--connect-timeout 3" in data["error"]
    assert data["shots"]["small"]["status"] == "stopped"


def _wait_for_running_attempt(job_json: Path, task: str, worker: str, proc, timeout_s: float = 60) -> None:
    """Until job.json shows the task running on `worker`: the client has heard the attempt start."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and proc.poll() is None:
        try:
            state = json.loads(job_json.read_text())["shots"]["small"]["tasks"].get(task, {})
        except (OSError, ValueError, KeyError):
            state = {}
        if state.get("status") == "running" and [a["worker"] for a in state.get("attempts", [])] == [worker]:
            return
        time.sleep(0.05)
    raise AssertionError(f"{job_json}: the {task} attempt on {worker} was never recorded as running")


def test_a_killed_worker_is_logged_its_task_retried_and_every_attempt_recorded(cluster, scene, tmp_path):
    hold = tmp_path / "hold"
    hold.mkdir()
    cluster.add_workers(2, FRAYTOOL_TEST_HOLD=str(hold))
    out = tmp_path / "job"
    with open(tmp_path / "batch.log", "w") as log:
        proc = _batch(scene, cluster.address, out, stderr=log)
        try:
            deadline = time.monotonic() + 120
            while not (hold / "held.json").is_file() and proc.poll() is None and time.monotonic() < deadline:
                time.sleep(0.05)
            assert (hold / "held.json").is_file(), (tmp_path / "batch.log").read_text()
            held = json.loads((hold / "held.json").read_text())
            _wait_for_running_attempt(out / "job.json", "simulate", held["worker"], proc)
            os.kill(held["pid"], signal.SIGKILL)  # the worker dies while it runs the shot's simulation
            code = proc.wait(timeout=240)
        finally:
            if proc.poll() is None:
                proc.kill()
    text = (tmp_path / "batch.log").read_text()
    assert code == 0, text
    worker = re.escape(held["worker"])
    assert re.search(rf"^fraytool: batch: lost worker {worker} \(\S+:{held['pid']}\): it was running small simulate "
                     r"\(frames 0:4\); the scheduler runs it again on another worker$", text, re.M), text
    retry = re.search(r"^fraytool: batch: retrying small simulate \(frames 0:4\): attempt 2, on (tcp://\S+) "
                      r"\(attempt 1: lost worker\)$", text, re.M)
    assert retry and retry.group(1) != held["worker"], text
    assert "1 of 1 shot(s) done" in text
    tasks = json.loads((out / "job.json").read_text())["shots"]["small"]["tasks"]
    first, *others = tasks["simulate"]["attempts"]
    assert first["worker"] == held["worker"] and first["process"].endswith(f":{held['pid']}")
    assert first["outcome"] == "lost worker" and first["start"] <= first["end"]
    assert len(others) >= 1 and others[-1]["outcome"] == "ok" and others[-1]["worker"] == retry.group(1)
    assert tasks["simulate"]["status"] == "done"
    for name in ("render 0-4", "join"):   # ran once each, on the worker that was left
        (attempt,) = tasks[name]["attempts"]
        assert attempt["outcome"] == "ok" and attempt["worker"] == retry.group(1), name
        assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d[+-]\d{4}", attempt["end"]), attempt


@pytest.mark.parametrize("value", ["0", "-1", "abc", "nan", "inf", "1e9"])
def test_a_bad_connect_timeout_exits_2(value, capsys):
    """Not a positive, finite number of seconds (at most a week): exit 2 before any cluster, the value named."""
    with pytest.raises(SystemExit) as exit_:
        main(["batch", "drape", f"--connect-timeout={value}"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "argument --connect-timeout: expected" in err and repr(value) in err, err


class _FakeClient:
    """What FarmWatch asks of a distributed Client: the scheduler's address and worker count, and
    topic subscriptions (the test sends the events itself)."""

    def __init__(self):
        self.scheduler = type("Rpc", (), {"address": "tcp://10.0.0.1:8786"})()
        self.workers, self.handlers = 0, {}

    def subscribe_topic(self, topic, handler):
        self.handlers[topic] = handler

    def unsubscribe_topic(self, topic):
        del self.handlers[topic]

    def scheduler_info(self, n_workers=-1):
        return {"n_workers": self.workers, "workers": {}}


def test_the_watch_says_no_worker_at_once_again_every_30_s_and_gives_up_after_the_timeout():
    import io

    from fraytool.farm.watch import NO_WORKER_REPEAT_S, FarmWatch, NoWorkerError

    client, stream, now = _FakeClient(), io.StringIO(), [100.0]
    watch = FarmWatch(client, stream, connect_timeout_s=70, clock=lambda: now[0])
    watch.poll()
    assert stream.getvalue() == ("fraytool: batch: no worker connected to tcp://10.0.0.1:8786 yet; waiting (start one "
                                 "with: dask worker tcp://10.0.0.1:8786); giving up after 70 s (--connect-timeout)\n")
    for t in (101.5, 110.0, 129.0):
        now[0] = t
        watch.poll()
    assert stream.getvalue().count("\n") == 1                      # not again before 30 s
    now[0] = 100.0 + NO_WORKER_REPEAT_S
    watch.poll()
    assert "still no worker connected to tcp://10.0.0.1:8786 after 30 s; waiting" in stream.getvalue().splitlines()[-1]
    client.workers, now[0] = 2, 135.0
    watch.poll()
    assert stream.getvalue().splitlines()[-1] == ("fraytool: batch: 2 worker(s) connected to tcp://10.0.0.1:8786 after "
                                                  "35 s without one; the job goes on")
    client.workers, now[0] = 0, 140.0                               # every worker lost: the timeout starts afresh
    watch.poll()
    assert "no worker connected to tcp://10.0.0.1:8786 any more" in stream.getvalue().splitlines()[-1]
    now[0] = 209.0
    watch.poll()
    now[0] = 210.0
    with pytest.raises(NoWorkerError, match=r"no worker connected to tcp://10\.0\.0\.1:8786 for 70 s "
                                            r"\(--connect-timeout 70\): the job stopped"):
        watch.poll()


def test_the_watch_records_each_attempt_and_says_each_retry_and_lost_worker():
    """Attempt events (tasks.run_attempt) and the scheduler's remove-worker event, as Dask delivers
    them: an attempt that raised, its retry that ran on a worker which was lost, the third that ended."""
    import io

    from fraytool.farm.tasks import ATTEMPT_TOPIC
    from fraytool.farm.watch import FarmWatch

    client, stream = _FakeClient(), io.StringIO()
    client.workers = 2
    watch = FarmWatch(client, stream, labels={"render-s-0-4": "s render 0-4 (frames 0:4)"})
    send = client.handlers[ATTEMPT_TOPIC]
    a, b = "tcp://10.0.0.2:4001", "tcp://10.0.0.3:4002"
    send((1.0, {"key": "render-s-0-4", "event": "start", "time": 1000.0, "worker": a, "process": "h2:11"}))
    send((1.0, {"key": "render-s-0-4", "event": "error", "time": 1001.0, "worker": a, "error": "OSError: disk full"}))
    send((1.0, {"key": "render-s-0-4", "event": "start", "time": 1002.0, "worker": a, "process": "h2:11"}))
    client.handlers["all"]((1003.0, {"action": "remove-worker", "worker": a, "processing-tasks": {"render-s-0-4"},
                                     "expected": False}))
    send((1.0, {"key": "render-s-0-4", "event": "start", "time": 1004.0, "worker": b, "process": "h3:12"}))
    watch.poll()
    assert stream.getvalue().splitlines() == [
        f"fraytool: batch: retrying s render 0-4 (frames 0:4): attempt 2, on {a} (attempt 1: error: OSError: disk full)",
        f"fraytool: batch: lost worker {a} (h2:11): it was running s render 0-4 (frames 0:4); the scheduler runs it "
        "again on another worker",
        f"fraytool: batch: retrying s render 0-4 (frames 0:4): attempt 3, on {b} (attempt 2: lost worker)"]
    assert watch.take_changed() == {"render-s-0-4"}
    result = {"rendered": 4, "attempt": {"worker": b, "process": "h3:12", "start": 1004.0, "end": 1006.5}}
    attempts = watch.finished("render-s-0-4", result=result)
    assert result == {"rendered": 4}                                # the attempt went to job.json's attempts
    assert [(x["worker"], x["outcome"], x["seconds"]) for x in attempts] == [
        (a, "error: OSError: disk full", 1.0), (a, "lost worker", 1.0), (b, "ok", 2.5)]
    assert watch.finished("join-s", error=RuntimeError("the render failed")) == []  # never ran: no attempt
    client.handlers["all"]((1010.0, {"action": "remove-worker", "worker": b, "processing-tasks": set(),
                                     "expected": False}))
    watch.poll()
    assert stream.getvalue().splitlines()[-1] == f"fraytool: batch: lost worker {b} (h3:12): it ran no task"
