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


_OS_ADVICE = {
    "EACCES": "make the folder writable or choose another output folder with -o",
    "EPERM": "make the folder writable or choose another output folder with -o",
    "EROFS": "the file system is read-only: choose another output folder with -o",
    "ENOSPC": "free some space (or choose another output folder with -o), then run the command again "
              "(simulate with --resume): what was written is kept",
    "EDQUOT": "the disk quota is used up: free some space, then run the command again (simulate with "
              "--resume): what was written is kept",
    "EEXIST": "a file is in the way of a folder: move it or choose another output folder with -o",
    "ENOTDIR": "a file is in the way of a folder: move it or choose another output folder with -o",
    "EISDIR": "a folder is in the way of a file: move it or choose another output folder with -o",
    "ENAMETOOLONG": "choose a shorter output folder with -o",
    "EIO": "the storage reported an I/O error: check the disk, then run the command again (simulate with "
           "--resume)",
}


def os_error_message(exc: OSError) -> str:
    """One line for an OSError: the path, the cause and what to do."""
    import errno

    name = errno.errorcode.get(exc.errno or 0, "")
    path = exc.filename if exc.filename is not None else "(no path)"
    cause = exc.strerror or str(exc) or type(exc).__name__
    advice = _OS_ADVICE.get(name, "check the path and the disk, then run again")
    return f"{path}: {cause}: {advice}"


class OutputError(RunError):
    """An output file or folder could not be written or read back (I/O failure, damaged files, a
    folder held by another run). Exit code 1."""
