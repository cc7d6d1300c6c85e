"""Scene files from strangers: 240 mutated scene files (a seeded generator of our own), each run
through `fraytool check` and, where that passes, `simulate --frames 2`, in a subprocess
(tests/fuzz_driver.py). Asserts: no traceback, no hang; check exits 0 for the mutations that keep the
scene valid and 2, with one message line per problem, for those that break it; unknown outcomes
(random byte flips, cuts) exit 0 or 2; a scene that checks simulates (exit 0, or 1 with one line)."""
import json
import random
import re
import subprocess
import sys
from pathlib import Path


from helpers import small_scene_text
import pytest

pytestmark = pytest.mark.fast  # `pytest -m fast` (docs/testing.md)

BASE = small_scene_text(frames=4, steps_per_frame=4, nx=10, ny=10) + """
[cloth.tearing]
enabled = true
break_strain = 0.2

[[bodies]]
name = "ball"
shape = "sphere"
radius_m = 0.01
position_m = [0.0, 0.07, 0.0]

[[attachments]]
body = "ball"
edge = "left"
"""

NUMBER_LINE = re.compile(r'(?m)^([a-z_]+) = (-?[0-9.e+-]+)$')
ANY_LINE = re.compile(r'(?m)^([a-z_]+) = (.+)$')

BAD_VALUES = ['"text"', "nan", "inf", "-inf", "-1.0e308", "1e308", "[1, 2]", "{ a = 1 }", "true", "[]",
              "18446744073709551616", '"' + "x" * 5000 + '"', "[" * 40 + "]" * 40]
EXTREMES = ["1e308", "-1e308", "1e-320", "-1e-320", "0", "-0.0", "1" + "0" * 320, "-" + "9" * 400, "1" + "0" * 5000,
            "4.9e-324", "9223372036854775807", "18446744073709551617", "1e-12", "1e12", "nan", "-inf", "0x7fffffff",
            "1_000_000", "1e4", "-1e4", "10001.0"]
NEVER_VALID_FOR = {"warp_yarns", "weft_yarns", "spacing_m", "thickness_m", "mass_per_crossing_kg", "step_s",
                   "steps_per_frame", "frames", "fps", "structural_n_per_m", "limit", "radius_m"}


def _replace_value(text: str, key: str, value: str) -> str:
    return re.sub(rf'(?m)^{key} = .+$', lambda _: f"{key} = {value}", text, count=1)


def mutations(seed: int = 20261201, count: int = 240) -> list[tuple[str, str, str]]:
    """(kind, expected 'valid' | 'invalid' | 'either', text)."""
    rng = random.Random(seed)
    numbers = NUMBER_LINE.findall(BASE)
    keys = [k for k, _ in ANY_LINE.findall(BASE)]
    cases = []
    while len(cases) < count:
        kind = rng.choice(["bad value", "unknown key", "drop line", "scale number", "comment", "byte flip",
                           "truncate", "duplicate key", "unknown table", "negate positive", "extreme number",
                           "extreme number"])
        text = BASE
        if kind == "bad value":
            key = rng.choice(sorted(NEVER_VALID_FOR))
            cases.append((f"{kind} {key}", "invalid", _replace_value(text, key, rng.choice(BAD_VALUES))))
        elif kind == "negate positive":
            key = rng.choice(sorted(NEVER_VALID_FOR))
            cases.append((f"{kind} {key}", "invalid", _replace_value(text, key, "-3")))
        elif kind == "unknown key":
            lines = text.splitlines()
            at = rng.choice([i for i, ln in enumerate(lines) if ln.startswith("[")])
            lines.insert(at + 1, f"{rng.choice(keys)}x = 1")
            cases.append((kind, "invalid", "\n".join(lines)))
        elif kind == "duplicate key":
            key = rng.choice(keys)
            m = re.search(rf'(?m)^{key} = .+$', text)
            cases.append((f"{kind} {key}", "invalid", text[:m.end()] + "\n" + m.group(0) + text[m.end():]))
        elif kind == "unknown table":
            cases.append((kind, "invalid", text + f"\n[{rng.choice(['clothes', 'cloth.weave', 'camera.lens'])}]\nx = 1\n"))
        elif kind == "drop line":
            lines = text.splitlines()
            at = rng.randrange(len(lines))
            cases.append((f"{kind} {lines[at]!r}", "either", "\n".join(lines[:at] + lines[at + 1:])))
        elif kind == "scale number":
            key, value = rng.choice(numbers)
            if key in ("seed",):
                new = str(rng.randrange(0, 2**63))
            elif key in ("warp_yarns", "weft_yarns", "frames", "steps_per_frame"):
                new = str(max(2, int(float(value) * rng.choice([0.5, 1, 1.5]))))
            else:
                new = repr(float(value) * rng.choice([0.5, 0.9, 1.1, 1.5]))
            cases.append((f"{kind} {key}={new}", "either", _replace_value(text, key, new)))
        elif kind == "extreme number":  # any key, any number a stranger might type: edges of float and int
            key = rng.choice(keys)
            value = rng.choice(EXTREMES)
            if rng.random() < 0.3 and re.search(rf'(?m)^{key} = \[', text):
                value = f"[{value}, {rng.choice(EXTREMES)}, 0.0]"
            cases.append((f"{kind} {key}={value[:30]}", "either", _replace_value(text, key, value)))
        elif kind == "comment":
            lines = text.splitlines()
            lines.insert(rng.randrange(len(lines)), "# " + "".join(rng.choice("abc é✓ =[]") for _ in range(30)))
            cases.append((kind, "valid", "\n".join(lines)))
        elif kind == "byte flip":
            data = bytearray(text.encode())
            for _ in range(rng.randint(1, 4)):
                data[rng.randrange(len(data))] = rng.randrange(256)
            cases.append((kind, "either", bytes(data)))
        elif kind == "truncate":
            cases.append((kind, "either", text[: rng.randrange(len(text))]))
    return cases


def test_generator_covers_every_expectation():
    kinds = {expected for _, expected, _ in mutations()}
    assert kinds == {"valid", "invalid", "either"} and len(mutations()) >= 200


def test_mutated_scene_files_never_crash(tmp_path):
    files, expected = [], []
    for k, (kind, expect, text) in enumerate(mutations()):
        path = tmp_path / f"m{k:03d}.toml"
        if isinstance(text, bytes):
            path.write_bytes(text)
        else:
            path.write_text(text)
        files.append(str(path))
        expected.append((kind, expect))
    driver = Path(__file__).with_name("fuzz_driver.py")
    base = tmp_path / "base.toml"
    base.write_text(BASE)  # simulated first, untimed: it compiles the kernels
    r = subprocess.run([sys.executable, str(driver), str(tmp_path / "out"), f"--warm={base}", *files],
                       capture_output=True, text=True, timeout=900, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    results = [json.loads(line) for line in r.stdout.splitlines()]
    assert len(results) == len(files)
    failures, valid, simulated = [], 0, 0
    for (kind, expect), res in zip(expected, results):
        check, sim = res["check"], res["simulate"]
        where = f"{Path(res['file']).name} ({kind})"
        for name, run in (("check", check), ("simulate", sim)):
            if run is None:
                continue
            if run["traceback"] or run["hang"] or "Traceback" in run["stderr"]:
                failures.append(f"{where}: {name}: {'hang' if run['hang'] else run['traceback'] or run['stderr']}")
        code = check["code"]
        if code not in (0, 2) or (expect == "valid" and code != 0) or (expect == "invalid" and code != 2):
            failures.append(f"{where}: check exit {code}, expected {expect}: {check['stderr'][:300]}")
        if code == 2:
            lines = check["stderr"].splitlines()
            if not lines or not all(ln.startswith("fraytool: error: ") and len(ln) < 600 for ln in lines):
                failures.append(f"{where}: not one clear line per problem: {check['stderr'][:600]!r}")
        if code == 0:
            valid += 1
            simulated += sim["code"] == 0
            failed_lines = [ln for ln in sim["stderr"].splitlines() if ln.startswith("fraytool: run failed: ")]
            if sim["code"] not in (0, 1) or (sim["code"] == 1 and len(failed_lines) != 1):
                failures.append(f"{where}: simulate exit {sim['code']}: {sim['stderr'][:300]}")
    assert not failures, "\n".join(failures[:20])
    assert valid >= 20 and simulated >= 20  # the generator also produces scenes that run
