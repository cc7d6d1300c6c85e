"""Progress of long work on stderr, in one of four modes (`--progress`):

- `bar`: one line redrawn in place (carriage return), for a terminal;
- `log`: a plain line every LOG_EVERY_S seconds and one at the end, for pipes and farm logs:
  `fraytool progress: simulate fig7_square_grab: 40/96 frames (42%), 11.8 frames/s, ETA 4.7 s`;
- `none`: nothing;
- `auto` (the default): `bar` on a terminal, `log` otherwise.

The command line sets the process default (`set_default_mode`); a caller may pass a mode, or the
older True (bar) / False (none) / None (default).
"""
from __future__ import annotations

import sys
import time
from typing import Optional, TextIO, Union

MODES = ("auto", "bar", "log", "none")
LOG_EVERY_S = 5.0
"""Seconds between two `log` lines."""

_default_mode = "auto"


def set_default_mode(mode: str) -> None:
    global _default_mode
    if mode not in MODES:
        raise ValueError(f"progress mode {mode!r}: expected one of {', '.join(MODES)}")
    _default_mode = mode


def resolve_mode(mode: Union[str, bool, None], stream: TextIO) -> str:
    if mode is True:
        return "bar"
    if mode is False:
        return "none"
    mode = _default_mode if mode is None else mode
    if mode == "auto":
        isatty = getattr(stream, "isatty", None)
        return "bar" if isatty is not None and isatty() else "log"
    return mode


class Progress:
    def __init__(self, total: int, label: str, stream: Optional[TextIO] = None,
                 enabled: Union[str, bool, None] = None, stage: str = "", unit: str = "frames"):
        self.total = max(total, 0)
        self.label = f"{stage} {label}" if stage else label
        self.unit = unit
        self.stream = stream if stream is not None else sys.stderr
        self.mode = resolve_mode(enabled, self.stream)
        self.enabled = self.mode != "none"
        self.start = time.perf_counter()
        self.last_log = self.start
        self.done = 0
        self.logged = -1
        self.drawn = False

    def _rate_eta(self, done: int) -> tuple[float, float]:
        elapsed = time.perf_counter() - self.start
        rate = done / elapsed if elapsed > 0 else 0.0
        eta = (self.total - done) / rate if rate > 0 else 0.0
        return rate, eta

    def update(self, done: int, extra: str = "") -> None:
        self.done = done
        if self.mode == "bar":
            rate, eta = self._rate_eta(done)
            width = 24
            filled = int(width * done / self.total) if self.total else width
            bar = "#" * filled + "-" * (width - filled)
            self.stream.write(f"\r{self.label} [{bar}] {done}/{self.total} {rate:5.1f}/s ETA {eta:5.1f}s {extra}   ")
            self.stream.flush()
            self.drawn = True
        elif self.mode == "log":
            now = time.perf_counter()
            if now - self.last_log >= LOG_EVERY_S:
                self.last_log = now
                self._log_line(done)

    def message(self, text: str) -> None:
        """A line of its own on the stream (in `bar` mode the bar goes on below it), in every mode: a message
        is not progress."""
        drawn = self.mode == "bar" and self.drawn
        self.stream.write(("\n" if drawn else "") + text + "\n")
        self.stream.flush()

    def _log_line(self, done: int) -> None:
        self.logged = done
        rate, eta = self._rate_eta(done)
        pct = 100.0 * done / self.total if self.total else 100.0
        self.stream.write(f"fraytool progress: {self.label}: {done}/{self.total} {self.unit} ({pct:.0f}%), "
                          f"{rate:.1f} {self.unit}/s, ETA {eta:.1f} s\n")
        self.stream.flush()

    def close(self) -> None:
        if self.mode == "bar":
            self.stream.write("\n")
            self.stream.flush()
        elif self.mode == "log" and self.logged != self.done and time.perf_counter() - self.start >= LOG_EVERY_S:
            self._log_line(self.done)  # a closing line for work long enough to have logged
