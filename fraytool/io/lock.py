"""One writer per output folder: `<out>/.fraytool.lock`, held by process id and host.

The lock file is created with O_CREAT | O_EXCL (atomic on local file systems and on NFS v3 and
later) and holds JSON: pid, host, command, start time. While held, a daemon thread touches it every
HEARTBEAT_S seconds. A second `simulate` into the same folder stops with an OutputError (exit 1) naming
the holder; a second `render` (a farm shard) waits for it, then reuses the frames it simulated. A lock is stale, and taken over, when its process is gone (same host: the pid is not alive)
or, for a holder on another host whose pid cannot be checked, when it has not been touched for
STALE_AFTER_S seconds (a dead machine on a shared file system).

Locks are re-entrant within a process: `render` holds the folder and calls the simulation, which
asks for the same lock.
"""
from __future__ import annotations

import json
import os
import socket
import threading
import time
from pathlib import Path
from typing import Optional

from fraytool.errors import OutputError

LOCK_NAME = ".fraytool.lock"
HEARTBEAT_S = 20.0
STALE_AFTER_S = 120.0
WAIT_POLL_S = 0.5

_held: dict[str, "_Held"] = {}
_held_guard = threading.Lock()


class _Held:
    def __init__(self, path: Path, token: str):
        self.path = path
        self.token = token
        self.depth = 1
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._beat, name="fraytool-lock-heartbeat", daemon=True)
        self.thread.start()

    def _beat(self) -> None:
        while not self.stop.wait(HEARTBEAT_S):
            try:
                os.utime(self.path)
            except OSError:
                pass


def pid_alive(pid: int) -> bool:
    """True if a process with this id runs on this host (or is ours)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _read(path: Path) -> Optional[dict]:
    from fraytool.files import not_a_regular_file

    why = not_a_regular_file(path)
    if why == "no such file":
        return None
    if why is not None:  # a FIFO or a folder where the lock goes: not fraytool's to wait on or remove
        raise OutputError(f"{path}: {why}, where fraytool keeps the folder's lock: remove it, or write elsewhere (-o)")
    try:
        data = json.loads(path.read_text())
        return data if isinstance(data, dict) else {}
    except FileNotFoundError:
        return None
    except (OSError, ValueError):
        return {}  # half-written or garbage: judged by its age


def _stale(path: Path, holder: dict) -> bool:
    host, pid = holder.get("host"), holder.get("pid")
    if host == socket.gethostname() and isinstance(pid, int):
        return not pid_alive(pid)
    try:
        age = time.time() - path.stat().st_mtime
    except FileNotFoundError:
        return True
    return age > STALE_AFTER_S


def _describe(holder: dict) -> str:
    return (f"pid {holder.get('pid', '?')} on host {holder.get('host', '?')}, "
            f"`fraytool {holder.get('command', '?')}` since {holder.get('started', '?')}")


def held_by_live_process(out_dir: Path) -> bool:
    """True if another live run holds out_dir's lock (its files may be mid-write)."""
    path = Path(out_dir) / LOCK_NAME
    holder = _read(path)
    if holder is None:
        return False
    if holder.get("host") == socket.gethostname() and holder.get("pid") == os.getpid():
        return False
    return not _stale(path, holder)


class OutputLock:
    """`with OutputLock(out_dir, "simulate"):` holds out_dir for this process."""

    def __init__(self, out_dir: Path, command: str = "", wait_stream=None):
        """`wait_stream`: wait for a live holder (saying so once on that stream) instead of failing."""
        self.wait_stream = wait_stream
        self.out_dir = Path(out_dir)
        self.path = self.out_dir / LOCK_NAME
        self.command = command
        self.key = str(self.path.absolute())

    def __enter__(self) -> "OutputLock":
        with _held_guard:
            held = _held.get(self.key)
            if held is not None:
                held.depth += 1
                return self
        self.out_dir.mkdir(parents=True, exist_ok=True)
        token = f"{socket.gethostname()}:{os.getpid()}:{time.time_ns()}"
        info = json.dumps({"pid": os.getpid(), "host": socket.gethostname(), "command": self.command,
                           "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "token": token}).encode()
        attempts, said = 0, False
        while attempts < 3:
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                holder = _read(self.path)
                if holder is None:
                    attempts += 1
                    continue  # released between our open and our read: try again
                if not _stale(self.path, holder):
                    if self.wait_stream is None:
                        raise OutputError(f"{self.out_dir}: in use by another fraytool run ({_describe(holder)}): "
                                          "wait for it to finish or choose another output folder with -o (if no "
                                          f"fraytool runs there, delete {self.path})") from None
                    if not said:
                        print(f"fraytool: waiting for {self.out_dir}: in use by another fraytool run "
                              f"({_describe(holder)})", file=self.wait_stream)
                        said = True
                    time.sleep(WAIT_POLL_S)
                    continue
                self._take_over(holder)
                attempts += 1
                continue
            with os.fdopen(fd, "wb") as f:
                f.write(info)
            with _held_guard:
                _held[self.key] = _Held(self.path, token)
            return self
        raise OutputError(f"{self.path}: could not take the output folder's lock (another run keeps taking it); "
                          "try again")

    def _take_over(self, stale: dict) -> None:
        """Move a stale lock aside; if what was moved is not the stale lock we judged (another run took
        it over first), put it back."""
        aside = self.path.with_name(f"{LOCK_NAME}.stale.{os.getpid()}")
        try:
            os.replace(self.path, aside)
        except FileNotFoundError:
            return
        if _read(aside) != stale and stale:
            try:
                os.link(aside, self.path)  # fails if yet another run holds the name now: theirs stands
            except OSError:
                pass
        aside.unlink(missing_ok=True)

    def __exit__(self, *exc) -> None:
        with _held_guard:
            held = _held[self.key]
            held.depth -= 1
            if held.depth:
                return
            del _held[self.key]
        held.stop.set()
        holder = _read(self.path)
        if holder is not None and holder.get("token") == held.token:
            self.path.unlink(missing_ok=True)
