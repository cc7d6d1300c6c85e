"""Run `fraytool check` (and, where it passes, `simulate --frames 2`) on many scene files in one
process, as the CLI would: `python tests/fuzz_driver.py OUT_DIR FILE...` prints one JSON line per
file with each command's exit code, stderr, and whether an exception escaped main() (a traceback) or
the case hung (SIGALRM after HANG_S seconds). With `--warm=SCENE` first, that scene is checked and
simulated before the cases, with no alarm: the first simulation compiles the kernels (a minute or more on a
cold numba cache, on a loaded machine), which is not a hang. tests/test_fuzz_scenes.py runs it in a
subprocess."""
from __future__ import annotations

import contextlib
import io
import json
import signal
import sys
import traceback

HANG_S = 120
"""A case that takes longer hangs. Cases take milliseconds, but one whose mutation reaches a feature the warm-up
did not (a scene without tearing, a box) compiles its kernels first: 20-40 s, and over 30 on a machine busy
with the suite's other worker (pytest -n auto)."""


class Hang(Exception):
    pass


def _alarm(signum, frame):
    raise Hang()


def run(argv: list[str], limit_s: int = HANG_S) -> dict:
    from fraytool.commands.main import main

    err = io.StringIO()
    result = {"argv": argv, "code": None, "traceback": None, "hang": False}
    signal.alarm(limit_s)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            result["code"] = main(argv)
    except SystemExit as exc:
        result["code"] = exc.code
    except Hang:
        result["hang"] = True
    except BaseException:  # noqa: BLE001 - anything that escapes main() would be a traceback for the user
        result["traceback"] = traceback.format_exc()
    finally:
        signal.alarm(0)
    result["stderr"] = err.getvalue()
    return result


def main() -> int:
    signal.signal(signal.SIGALRM, _alarm)
    out_dir, files = sys.argv[1], sys.argv[2:]
    if files and files[0].startswith("--warm="):
        warm = files.pop(0)[len("--warm="):]
        for argv in (["check", warm], ["simulate", warm, "--frames", "2", "-o", f"{out_dir}/warm"]):
            done = run(argv, limit_s=0)  # alarm(0): none
            if done["code"] != 0:  # the cases would fail for the base scene's reason, not their own
                print(f"warm-up {argv[0]} failed: {done}", file=sys.stderr)
                return 1
    for k, path in enumerate(files):
        check = run(["check", path])
        sim = None
        if check["code"] == 0:
            sim = run(["simulate", path, "--frames", "2", "-o", f"{out_dir}/case{k}"])
        print(json.dumps({"file": path, "check": check, "simulate": sim}), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
