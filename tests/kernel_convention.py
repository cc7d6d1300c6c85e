"""The kernel convention, checked on the source (ast): every numba kernel of fraytool takes at most
MAX_FLAT_ARGUMENTS arguments (more go in named argument groups, as fraytool.sim.tearing.groups), and
writes only the arguments whose names end in `_out` or `_inout` (a group's fields count as the
group's: `springs_inout.spring_alive[s] = False`), never one ending in `_in`.

A write is an assignment or augmented assignment to a subscript of the argument (or of a field of it),
directly or through a local name bound to it (`x = particles_inout.particle_position_m`), or a call of
its `fill` / `sort` / `resize` method or of `np.copyto(argument, ...)`. What a called kernel writes is
checked in that kernel (its own argument names say it).

A parallel kernel writes nothing, in a `prange` loop, through a tuple or a named tuple: numba drops
such writes (numba issues 7135 and 10338, open in 0.68.1), also when the tuple is unpacked in the loop or
the write is in a callee inlined into it. So in the loop: no write to `group.field[...]` or `group[k][...]`,
nor to a name unpacked or taken from a group there; and no call of an `inline="always"` kernel at an
argument it writes that way (a non-inlined callee is safe; take a group's arrays out before the loop, and
hand an inlined callee plain arrays).

No kernel needs a package fraytool does not declare: numba runs `@` on arrays, `np.dot`, `np.vdot`,
`np.inner`, `np.matmul` and `np.linalg.*` through scipy's BLAS and LAPACK, and scipy is not a
dependency (a clean install dies in the kernel's first call with "scipy 0.16+ is required for linear
algebra"). Products of 3-vectors are written out (fraytool.sim.kernels.mesh_contact._dot3)."""
from __future__ import annotations

import ast
from pathlib import Path

MAX_FLAT_ARGUMENTS = 12
WRITABLE_SUFFIXES = ("_out", "_inout")
MUTATING_METHODS = {"fill", "sort", "resize", "itemset", "put"}
BLAS_FUNCTIONS = {"dot", "vdot", "inner", "matmul", "tensordot", "kron"}
"""NumPy functions numba implements through scipy's BLAS (np.linalg.* too, by its module)."""


def _is_numba_kernel(fn: ast.FunctionDef) -> bool:
    for d in fn.decorator_list:
        target = d.func if isinstance(d, ast.Call) else d
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name in ("njit", "jit", "vectorize", "guvectorize"):
            return True
    return False


def _root_name(node: ast.AST):
    """The name at the root of `a[..]`, `a.b[..]`, `a.b` chains (None for anything else)."""
    while isinstance(node, (ast.Subscript, ast.Attribute)):
        node = node.value
    return node.id if isinstance(node, ast.Name) else None


def kernel_signatures(trees: list) -> dict[str, list[str]]:
    """Kernel name -> its argument names, over the parsed modules `trees` (for writes through calls)."""
    return {fn.name: [a.arg for a in fn.args.args] for tree in trees for fn in ast.walk(tree)
            if isinstance(fn, ast.FunctionDef) and _is_numba_kernel(fn)}


def kernel_problems(source: str, filename: str = "<source>", callees: dict | None = None) -> list[str]:
    """Every break of the convention in the kernels of `source`, one line each. `callees` (name ->
    argument names, kernel_signatures) lets an argument handed on to a callee's `_out` / `_inout`
    argument count as written (default: the kernels of `source` itself)."""
    out = []
    tree = ast.parse(source, filename)
    callees = kernel_signatures([tree]) if callees is None else callees
    for fn in ast.walk(tree):
        if not isinstance(fn, ast.FunctionDef) or not _is_numba_kernel(fn):
            continue
        params = [a.arg for a in fn.args.args]
        where = f"{filename}:{fn.lineno} {fn.name}"
        if len(params) > MAX_FLAT_ARGUMENTS:
            out.append(f"{where}: {len(params)} arguments (at most {MAX_FLAT_ARGUMENTS}; group the rest)")
        for node in ast.walk(fn):
            if isinstance(node, (ast.BinOp, ast.AugAssign)) and isinstance(node.op, ast.MatMult):
                out.append(f"{where}: line {node.lineno} uses '@', which numba runs through scipy's BLAS "
                           "(write the products out)")
            elif isinstance(node, ast.Attribute) and (
                    node.attr == "linalg" or (node.attr in BLAS_FUNCTIONS and _root_name(node) in ("np", "numpy"))):
                out.append(f"{where}: line {node.lineno} uses np.{node.attr}, which numba runs through scipy's "
                           "BLAS / LAPACK (write it out)")
        alias = {p: p for p in params}  # local name -> the argument it refers to
        for node in ast.walk(fn):
            if isinstance(node, ast.Assign) and len(node.targets) == 1:
                targets = node.targets[0].elts if isinstance(node.targets[0], ast.Tuple) else [node.targets[0]]
                values = node.value.elts if isinstance(node.value, ast.Tuple) else [node.value]
                if len(values) == 1 and len(targets) > 1:  # a group unpacked: `a, b = springs_inout`
                    values = values * len(targets)
                if len(targets) == len(values):
                    for t, v in zip(targets, values):
                        root = _root_name(v) if isinstance(v, (ast.Name, ast.Attribute)) else None
                        if isinstance(t, ast.Name) and root in alias:
                            alias[t.id] = alias[root]
        written = set()
        for node in ast.walk(fn):
            targets = []
            if isinstance(node, ast.Assign):
                targets = node.targets
            elif isinstance(node, ast.AugAssign):
                targets = [node.target]
            for t in targets:
                for e in (t.elts if isinstance(t, ast.Tuple) else [t]):
                    if isinstance(e, ast.Subscript) and _root_name(e) in alias:
                        written.add(alias[_root_name(e)])
            if isinstance(node, ast.Call):
                f = node.func
                if isinstance(f, ast.Attribute) and f.attr in MUTATING_METHODS and _root_name(f.value) in alias:
                    written.add(alias[_root_name(f.value)])
                if isinstance(f, ast.Attribute) and f.attr == "copyto" and node.args \
                        and _root_name(node.args[0]) in alias:
                    written.add(alias[_root_name(node.args[0])])
                name = f.id if isinstance(f, ast.Name) else None
                for arg, param in zip(node.args, callees.get(name, [])):
                    if param.endswith(WRITABLE_SUFFIXES) and isinstance(arg, (ast.Name, ast.Attribute, ast.Subscript)) \
                            and _root_name(arg) in alias:
                        written.add(alias[_root_name(arg)])
        for p in sorted(written):
            if not p.endswith(WRITABLE_SUFFIXES):
                out.append(f"{where}: writes argument {p!r} (name it {p}_out or {p}_inout"
                           + (", not _in)" if p.endswith("_in") else ")"))
    return out


def _decorator_flag(fn: ast.FunctionDef, name: str, value) -> bool:
    """Whether a numba decorator of fn passes keyword `name` = value (`parallel=True`, `inline="always"`)."""
    for d in fn.decorator_list:
        if isinstance(d, ast.Call):
            for k in d.keywords:
                if k.arg == name and isinstance(k.value, ast.Constant) and k.value.value == value:
                    return True
    return False


def _write_targets(node: ast.AST) -> list:
    """The subscript targets an assignment node writes (`x[..] = `, `a.b[..] += `, tuple targets)."""
    targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(node, ast.AugAssign) else []
    return [e for t in targets for e in (t.elts if isinstance(t, ast.Tuple) else [t]) if isinstance(e, ast.Subscript)]


def _through_group(target: ast.Subscript) -> bool:
    """Whether a subscript target reaches its array through a tuple: `g.field[..]` or `g[k][..]`."""
    return isinstance(target.value, (ast.Subscript, ast.Attribute))


def _group_aliases(body: list, names: set) -> dict:
    """Local names bound in `body` from a group of `names`, unpacked (`a, b = group`) or a field taken
    (`a = group.field`): name -> group. (A subscript, `a = x[k]`, is taken for an array's view.)"""
    out = {}
    for stmt in body:
        for node in ast.walk(stmt):
            if isinstance(node, ast.Assign) and len(node.targets) == 1:
                t, v = node.targets[0], node.value
                root = _root_name(v) if isinstance(v, (ast.Name, ast.Attribute)) else None
                if root not in names and root not in out:
                    continue
                group = out.get(root, root)
                if isinstance(t, ast.Tuple):
                    out.update({e.id: group for e in t.elts if isinstance(e, ast.Name)})
                elif isinstance(t, ast.Name) and isinstance(v, ast.Attribute):
                    out[t.id] = group
    return out


def _group_written(fn: ast.FunctionDef, inline_groups: dict) -> set:
    """The arguments of fn that it writes through a tuple (or hands on to an inlined kernel that does)."""
    params = {a.arg for a in fn.args.args}
    plain = {p: p for p in params}
    for node in ast.walk(fn):  # plain renames: `x = positions`
        if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name) \
                and isinstance(node.value, ast.Name) and node.value.id in plain:
            plain[node.targets[0].id] = plain[node.value.id]
    grouped = _group_aliases(fn.body, set(plain))
    out = set()
    for node in ast.walk(fn):
        for t in _write_targets(node):
            root = _root_name(t)
            if root in grouped:
                out.add(plain.get(grouped[root], grouped[root]))
            elif root in plain and _through_group(t):
                out.add(plain[root])
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in inline_groups:
            for arg, param in zip(node.args, inline_groups[node.func.id][0]):
                if param in inline_groups[node.func.id][1]:
                    root = _root_name(arg) if isinstance(arg, (ast.Name, ast.Attribute, ast.Subscript)) else None
                    if root in plain:
                        out.add(plain[root])
    return {p for p in out if p in params}


def parallel_group_writes(trees: list, filenames: list) -> list[str]:
    """Writes through a tuple in a parallel kernel's prange loop (module docstring), one line each."""
    inline = [fn for tree in trees for fn in ast.walk(tree)
              if isinstance(fn, ast.FunctionDef) and _is_numba_kernel(fn) and _decorator_flag(fn, "inline", "always")]
    groups = {fn.name: ([a.arg for a in fn.args.args], set()) for fn in inline}
    changed = True
    while changed:  # inlined kernels call one another: to a fixed point
        changed = False
        for fn in inline:
            found = _group_written(fn, groups)
            if found - groups[fn.name][1]:
                groups[fn.name][1].update(found)
                changed = True
    out = []
    for tree, filename in zip(trees, filenames):
        for fn in ast.walk(tree):
            if not (isinstance(fn, ast.FunctionDef) and _is_numba_kernel(fn) and _decorator_flag(fn, "parallel", True)):
                continue
            for loop in ast.walk(fn):
                if not (isinstance(loop, ast.For) and isinstance(loop.iter, ast.Call)
                        and getattr(loop.iter.func, "attr", getattr(loop.iter.func, "id", "")) == "prange"):
                    continue
                where = f"{filename}:{fn.lineno} {fn.name}"
                grouped = _group_aliases(loop.body, {a.arg for a in fn.args.args} | {
                    n.id for n in ast.walk(fn) if isinstance(n, ast.Name)})
                for node in (n for stmt in loop.body for n in ast.walk(stmt)):
                    for t in _write_targets(node):
                        if _through_group(t) or _root_name(t) in grouped:
                            out.append(f"{where}: line {node.lineno} writes through a tuple in a prange loop "
                                       "(numba drops it: take the array out of the tuple before the loop)")
                    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in groups:
                        params, written = groups[node.func.id]
                        for arg, param in zip(node.args, params):
                            if param in written:
                                out.append(f"{where}: line {node.lineno} calls inlined {node.func.id}, which writes "
                                           f"its {param!r} through a tuple, in a prange loop (numba drops it: "
                                           "hand it plain arrays)")
    return out


def package_problems(package: Path) -> list[str]:
    paths = sorted(package.rglob("*.py"))
    trees = [ast.parse(p.read_text()) for p in paths]
    callees = kernel_signatures(trees)
    out = []
    for path in paths:
        out += kernel_problems(path.read_text(), str(path.relative_to(package.parent)), callees)
    return out + parallel_group_writes(trees, [str(p.relative_to(package.parent)) for p in paths])
