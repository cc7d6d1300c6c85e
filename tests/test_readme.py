"""The README is read by newcomers in two minutes: short, no dated figures, every command named."""
import re
from pathlib import Path
import pytest

pytestmark = pytest.mark.fast  # `pytest -m fast` (docs/testing.md)

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()

DATED = re.compile(r"\b20\d\d-\d\d-\d\d\b|\b\d+(\.\d+)? ?ms per frame\b|\b\d+(\.\d+)? ?(MB|GB) peak\b")


def readme_problems(text: str) -> list[str]:
    """What breaks the README's rules: over 120 lines, a line over 200 characters, a dated figure."""
    problems = []
    lines = text.splitlines()
    if len(lines) > 120:
        problems.append(f"{len(lines)} lines (at most 120)")
    problems += [f"line {i}: {len(ln)} characters" for i, ln in enumerate(lines, 1) if len(ln) > 200]
    problems += [f"line {i}: dated figure {m.group(0)!r}" for i, ln in enumerate(lines, 1)
                 for m in [DATED.search(ln)] if m]
    return problems


def test_the_readme_is_short_and_has_no_dated_figures():
    assert readme_problems(README) == []


def test_the_rules_catch_a_long_line_a_long_readme_and_a_dated_figure():
    assert readme_problems("x" * 201) == ["line 1: 201 characters"]
    assert readme_problems("\n".join(["a"] * 121)) == ["121 lines (at most 120)"]
    assert len(readme_problems("fig7 on 2026-12-03: 112 ms per frame")) == 1


def test_every_command_has_its_line_and_every_linked_doc_exists():
    from fraytool.commands.main import COMMANDS

    for name in COMMANDS:
        assert f"`fraytool {name} " in README, name
    for link in re.findall(r"\]\((docs/[^)#]+)", README):
        assert (ROOT / link).is_file(), link


SET_UP = ["python3 -m venv .venv && . .venv/bin/activate", 'python -m pip install -e ".[test,usd]"',
          "python -m pytest -n auto"]


def test_the_readme_set_up_is_the_one_ci_runs_in_a_fresh_venv():
    """CI makes the README's venv (no system site-packages, so the machine's own packages hide nothing) and
    runs its install and test commands in it, in that order; the system packages are the README's."""
    ci = (ROOT / ".ci" / "run").read_text()
    ci_lines = [ln.strip() for ln in ci.splitlines()]
    at = [ci_lines.index(line) for line in SET_UP]
    assert at == sorted(at), "CI runs the set-up lines out of order"
    for line in SET_UP:
        assert f"    {line}" in README, line
    assert "system-site-packages" not in ci and "rm -rf .venv" in ci
    apt = re.search(r"apt-get install ([^\n`]+)", README).group(1).split()
    assert {"libegl1", "libegl-mesa0", "libgl1-mesa-dri", "chromium"} <= set(apt)
    assert all(pkg in ci for pkg in apt), apt
