"""Exception types that the command line turns into clear messages and exit codes.

`InputError` (exit 2) is for anything wrong in what the user gave: a scene file, a flag.
`RunError` (exit 1) is for a run that failed: an unstable simulation, no GL context, a write error.
"""
from __future__ import annotations


class FraytoolError(Exception):
    """Base of the errors that the CLI reports without a traceback."""

    exit_code = 1


class InputError(FraytoolError):
    """Bad user input: a scene file or a command-line value. Exit code 2."""

    exit_code = 2


class SceneError(InputError):
    """One or more problems in a scene file; each message names file, key, value and what is allowed."""

    def __init__(self, messages: list[str]):
        self.messages = list(messages)
        super().__init__("\n".join(self.messages))


class RunError(FraytoolError):
    """A run that could not complete (unstable simulation, no GL context, I/O failure). Exit code 1."""

    exit_code = 1
