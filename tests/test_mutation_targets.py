"""benchmarks/mutation.py's mutations still apply: each one's text occurs exactly once in its file, so a
change of the code cannot leave a mutation behind that tests nothing (two had, until 2026-12-05)."""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _mutations():
    spec = importlib.util.spec_from_file_location("mutation_run", ROOT / "benchmarks" / "mutation.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module          # (its dataclasses look their module up there)
    spec.loader.exec_module(module)
    return module.MUTATIONS


def test_every_mutation_finds_its_text_once():
    mutations = _mutations()
    assert len(mutations) >= 30
    stale = [(m.area, m.what, m.path, (ROOT / m.path).read_text().count(m.old) if (ROOT / m.path).exists() else None)
             for m in mutations if not (ROOT / m.path).exists() or (ROOT / m.path).read_text().count(m.old) != 1]
    assert stale == [], stale
    for m in mutations:
        for test in m.tests:
            assert (ROOT / test.split("::")[0]).exists(), (m.what, test)
