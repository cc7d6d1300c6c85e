"""The package's layers hold (docs/architecture.md, "Layers"): no import from a lower layer to a
higher one and no import circle, counting imports inside functions too (parsed with ast)."""
from __future__ import annotations

import ast
from pathlib import Path
import pytest

pytestmark = pytest.mark.fast  # `pytest -m fast` (docs/testing.md)

PACKAGE = Path(__file__).resolve().parents[1] / "fraytool"

LAYER = {
    "__main__": 7,
    "commands": 6,
    "farm": 5, "export": 5, "golden": 5,
    "testing": 6, "api": 7,
    "render": 4, "study": 4,
    "sim": 3,
    "collision": 2, "io": 2,
    "scene": 1,
    # leaf modules: import nothing of fraytool but other leaves
    "kinds": 0, "errors": 0, "grid": 0, "progress": 0, "resources": 0, "resident_memory": 0, "_numba_cache": 0, "files": 0, "geometry": 0,
    "threads": 0, "meshes": 0, "rotation": 0, "": 0,
}
"""Layer of each top-level package or module of fraytool (higher imports lower, never the reverse)."""


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _is_module(name: str) -> bool:
    rel = Path(*name.split(".")[1:])
    return (PACKAGE / rel).with_suffix(".py").is_file() or (PACKAGE / rel / "__init__.py").is_file()


def _imports(path: Path) -> set[str]:
    """Every fraytool module `path` imports, at module level or inside functions. `from pkg import
    sub` of a submodule counts as an import of the submodule only."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "fraytool":
            names = [f"{node.module}.{a.name}" for a in node.names]
            subs = [n for n in names if _is_module(n)]
            out.update(subs)
            if len(subs) < len(names):
                out.add(node.module)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.split(".")[0] == "fraytool")
    return out


def _graph() -> dict[str, set[str]]:
    modules = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    return {m: {t for t in _imports(p) if t in modules and t != m} for m, p in modules.items()}


def _top(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def test_every_top_level_part_has_a_layer():
    tops = {_top(m) for m in _graph()}
    assert tops <= set(LAYER), f"no layer declared for {sorted(tops - set(LAYER))} (tests/test_layers.py, docs/architecture.md)"


def test_no_import_goes_up_a_layer():
    wrong = []
    for module, targets in sorted(_graph().items()):
        for target in sorted(targets):
            if target == "fraytool":
                continue  # the package root holds only the version (and the numba cache guard)
            a, b = _top(module), _top(target)
            # up a layer, or sideways between siblings (render/study, collision/io); leaves may use leaves
            if a != b and (LAYER[b] > LAYER[a] or (LAYER[b] == LAYER[a] and LAYER[a] > 0)):
                wrong.append(f"{module} (layer {LAYER[a]}) imports {target} (layer {LAYER[b]})")
    assert not wrong, "imports against the layers:\n" + "\n".join(wrong)


def test_no_import_circle():
    graph = _graph()
    # package __init__ re-exports: an import of a package means its __init__ module
    state: dict[str, int] = {}
    stack: list[str] = []
    cycles = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for t in sorted(graph.get(m, ())):
            if state.get(t) == 1:
                cycles.append(" -> ".join(stack[stack.index(t):] + [t]))
            elif t not in state:
                visit(t)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)
    assert not cycles, "import circles:\n" + "\n".join(cycles)


def test_the_checker_sees_a_wrong_way_import(tmp_path):
    """The parser finds imports inside functions (the kind that hid the old circles)."""
    f = tmp_path / "m.py"
    f.write_text("def f():\n    from fraytool.render.camera import Camera\n    import fraytool.sim.solver\n")
    assert _imports(f) == {"fraytool.render.camera", "fraytool.sim.solver"}
