"""Slow, obviously-correct NumPy references of the tearing kernels, for the oracle tests.

They follow the definitions of docs/tearing.md with plain NumPy and Python sets, independently of
the numba kernels' arithmetic:
- `closest_points_reference`: segment-segment closest points by trying every candidate of the
  minimisation over [0, 1]^2 (the interior stationary point and the four clamped edges);
- `project_couples_reference`: the contact projection of §3.3, couple by couple, pair by pair;
- `split_reference`: the split of §3.4, using `fraytool.grid.crossing_normals` on the whole cloth;
- `propagation_reference`: the crossings a transition splits (§3.4 propagation), by slicing the
  yarn as a Python list;
- `free_end_lengths_reference`: the fray metric, walking Python lists.
Each works on a dict of copies of the State arrays and returns the new dict.
"""
from __future__ import annotations

import numpy as np

from fraytool.grid import crossing_normals
from fraytool.sim.model import Model
from fraytool.kinds import BEND_WARP, SHEAR, STRUCT_WARP, STRUCT_WEFT

STATE_KEYS = ("particle_position_m", "particle_velocity_m_s", "particle_mass_kg", "particle_inv_mass",
              "particle_active", "crossing_yarn_level", "couple_connected", "spring_particle_a",
              "spring_particle_b", "spring_alive", "spring_broken", "spring_stiffness_n_per_m")


def state_dict(state, prev_position_m=None) -> dict:
    """Copies of the State arrays the tearing kernels touch (+ prev positions)."""
    out = {k: np.array(getattr(state, k), copy=True) for k in STATE_KEYS}
    prev = state.particle_position_m - state.particle_velocity_m_s if prev_position_m is None else prev_position_m
    out["prev_position_m"] = np.array(prev, copy=True)
    return out


def closest_points_reference(pa, qa, pb, qb) -> tuple[float, float, float]:
    """(t_a, t_b, distance) minimising |a(t_a) - b(t_b)| over [0, 1]^2."""
    pa, qa, pb, qb = (np.asarray(v, float) for v in (pa, qa, pb, qb))
    u, v, w0 = qa - pa, qb - pb, pa - pb

    def dist(s, t):
        return float(np.linalg.norm(pa + s * u - (pb + t * v)))

    cands = []
    A = np.array([[u @ u, -(u @ v)], [-(u @ v), v @ v]])
    rhs = np.array([-(u @ w0), v @ w0])
    if abs(np.linalg.det(A)) > 1e-30 * max(1.0, abs(A).max() ** 2):
        s, t = np.linalg.solve(A, rhs)
        if 0 <= s <= 1 and 0 <= t <= 1:
            cands.append((s, t))
    for s in (0.0, 1.0):  # a fixed at an end: project onto b
        t = np.clip(((pa + s * u - pb) @ v) / (v @ v), 0, 1) if v @ v > 0 else 0.0
        cands.append((s, t))
    for t in (0.0, 1.0):
        s = np.clip(((pb + t * v - pa) @ u) / (u @ u), 0, 1) if u @ u > 0 else 0.0
        cands.append((s, t))
    best = min(cands, key=lambda st: dist(*st))
    return float(best[0]), float(best[1]), dist(*best)


def _couple_springs(model: Model, st: dict, c: int) -> tuple[list, list]:
    alive = st["spring_alive"]
    weft = [int(s) for s in model.crossing_weft_springs[c] if s >= 0 and alive[s]]
    warp = [int(s) for s in model.crossing_warp_springs[c] if s >= 0 and alive[s]]
    return weft, warp


def _free_end(model: Model, st: dict, c: int, weft: list, warp: list) -> bool:
    if len(weft) < 2 or len(warp) < 2:
        return True
    for s in weft + warp:
        o = int(model.spring_crossing_a[s] + model.spring_crossing_b[s] - c)
        if st["crossing_yarn_level"][o] and not st["couple_connected"][o]:
            return True
    return False


def project_couples_reference(model: Model, st: dict, couples) -> dict:
    """Contact projection (contact.py docstring) of `couples`, in that order, on a copy of `st`."""
    st = {k: np.array(v, copy=True) for k, v in st.items()}
    x = st["particle_position_m"]
    w = st["particle_inv_mass"]
    pa_, pb_ = st["spring_particle_a"], st["spring_particle_b"]
    T = model.thickness_m
    for c in couples:
        c = int(c)
        if not st["couple_connected"][c]:
            continue
        weft, warp = _couple_springs(model, st, c)
        if not weft or not warp:
            _disconnect_ref(model, st, c)
            continue
        dmin = min(closest_points_reference(x[pa_[a]], x[pb_[a]], x[pa_[b]], x[pb_[b]])[2]
                   for a in weft for b in warp)
        if not dmin <= model.disconnect_distance_m:
            _disconnect_ref(model, st, c)
            continue
        side = 1.0 if model.crossing_weft_on_top[c] else -1.0
        slide = _free_end(model, st, c, weft, warp)
        for sa in weft:
            for sb in warp:
                ends = [pa_[sa], pb_[sa], pa_[sb], pb_[sb]]
                ta, tb, d = closest_points_reference(*(x[e] for e in ends))
                r = (1 - ta) * x[ends[0]] + ta * x[ends[1]] - ((1 - tb) * x[ends[2]] + tb * x[ends[3]])
                nu = np.cross(x[ends[1]] - x[ends[0]], x[ends[3]] - x[ends[2]])
                crossing = np.linalg.norm(nu) > 1e-2 * np.linalg.norm(x[ends[1]] - x[ends[0]]) * np.linalg.norm(
                    x[ends[3]] - x[ends[2]])
                h = side * (r @ nu) / np.linalg.norm(nu) if crossing else d
                p0 = [st["prev_position_m"][e] for e in ends]
                r0 = (1 - ta) * p0[0] + ta * p0[1] - ((1 - tb) * p0[2] + tb * p0[3])
                passed = crossing and h <= 0 and d < T and side * (r0 @ nu) > 0
                if d < 1e-15 or passed:
                    if not crossing:
                        continue
                    e = side * nu / np.linalg.norm(nu)
                    gap = h
                elif slide and d >= T:
                    continue  # a free end apart from the other yarn: left alone
                else:
                    e = r / d
                    gap = d
                beta = np.array([1 - ta, ta, -(1 - tb), -tb])  # d r / d x_end
                wk = w[ends]
                denom = float((wk * beta ** 2).sum())
                if denom == 0.0:
                    continue
                lam = (gap - T) / denom
                for k in range(4):
                    x[ends[k]] = x[ends[k]] - lam * wk[k] * beta[k] * e
    return st


def _disconnect_ref(model: Model, st: dict, c: int) -> None:
    st["couple_connected"][c] = False
    for s in np.nonzero(((model.spring_crossing_a == c) | (model.spring_crossing_b == c))
                        & (model.spring_kind == SHEAR))[0]:
        st["spring_alive"][s] = False
        st["spring_alive"][model.spring_twin[s]] = False


def split_reference(model: Model, st: dict, c: int, attached=()) -> dict:
    """Split base crossing c (split.py docstring) on a copy of `st`; unchanged if c is yarn level
    or in `attached`."""
    st = {k: np.array(v, copy=True) for k, v in st.items()}
    n = model.crossing_count
    lvl = st["crossing_yarn_level"]
    if lvl[c] or c in set(int(a) for a in attached):
        return st
    x = st["particle_position_m"]
    centres = np.where(lvl[:, None], 0.5 * (x[:n] + x[n:]), x[:n])
    normal = crossing_normals(centres, model.warp_yarns, model.weft_yarns)[c]
    s = 1.0 if model.crossing_weft_on_top[c] else -1.0
    old = x[c].copy()
    disp = old - st["prev_position_m"][c]
    x[c] = old + s * 0.5 * model.thickness_m * normal
    x[n + c] = old - s * 0.5 * model.thickness_m * normal
    st["prev_position_m"][c] = x[c] - disp
    st["prev_position_m"][n + c] = x[n + c] - disp
    st["particle_velocity_m_s"][n + c] = st["particle_velocity_m_s"][c]
    m = st["particle_mass_kg"][c]
    st["particle_mass_kg"][[c, n + c]] = m / 2
    st["particle_inv_mass"][[c, n + c]] = 2.0 / m if st["particle_inv_mass"][c] > 0 else 0.0
    st["particle_active"][n + c] = True
    lvl[c] = True
    st["couple_connected"][c] = True

    def upper(k):
        return k if model.crossing_weft_on_top[k] else n + k

    up, low = upper(c), (n + c if upper(c) == c else c)
    A, B = st["spring_particle_a"], st["spring_particle_b"]
    alive, broken, k_s = st["spring_alive"], st["spring_broken"], st["spring_stiffness_n_per_m"]
    for sp in np.nonzero((model.spring_crossing_a == c) | (model.spring_crossing_b == c))[0]:
        kind = model.spring_kind[sp]
        end_a = model.spring_crossing_a[sp] == c
        here, there = (A, B) if end_a else (B, A)
        if kind in (STRUCT_WARP, BEND_WARP):
            here[sp] = n + c
        elif kind == SHEAR:
            o = int(model.spring_crossing_b[sp] if end_a else model.spring_crossing_a[sp])
            t = model.spring_twin[sp]
            born = alive[t] or broken[t]
            if alive[sp] and not born:
                k_s[sp] = k_s[t] = k_s[sp] / 2
                alive[t] = True
                here[sp], here[t] = up, low
                if lvl[o]:
                    there[sp], there[t] = upper(o), (n + o if upper(o) == o else o)
                else:
                    there[sp] = there[t] = o
            elif born:
                for copy in (sp, t):
                    here[copy] = up if there[copy] == upper(o) else low
            else:
                here[sp] = up
    return st


def propagation_reference(model: Model, spring: int, spring_alive, attached=(), inclusive: bool = True) -> set[int]:
    """Crossings that the transition of structural `spring` splits on an untorn cloth (split.py
    docstring): both ends unless held, then from each end outward along the spring's yarn the list of
    crossings, cut at the first dead structural spring and at the first held crossing, and ended
    after (inclusive) or before (exclusive) the first crossing whose weave flag differs from the
    previous one. A held end does not walk."""
    W, H = model.warp_yarns, model.weft_yarns
    held = set(int(a) for a in attached)
    a, b = int(model.spring_crossing_a[spring]), int(model.spring_crossing_b[spring])
    if model.spring_kind[spring] == STRUCT_WEFT:
        j = a // W
        yarn = [j * W + i for i in range(W)]
        links = [int(model.weft_structural_spring[j, i]) for i in range(W - 1)]
    else:
        i = a % W
        yarn = [j * W + i for j in range(H)]
        links = [int(model.warp_structural_spring[i, j]) for j in range(H - 1)]
    flag = [bool(model.crossing_weft_on_top[c]) for c in yarn]
    pa, pb = yarn.index(a), yarn.index(b)
    out = {c for c in (a, b) if c not in held}
    for end, outward in ((pb, range(pb + 1, len(yarn))), (pa, range(pa - 1, -1, -1))):
        if yarn[end] in held:
            continue
        path, prev = [], end
        for p in outward:
            if not spring_alive[links[min(p, prev)]] or yarn[p] in held:
                break
            path.append(p)
            prev = p
        flips = [k for k in range(len(path)) if flag[path[k]] != flag[path[k - 1] if k else end]]
        stop = len(path) if not flips else (flips[0] + 1 if inclusive else flips[0])
        out.update(yarn[p] for p in path[:stop])
    return out


def free_end_lengths_reference(model: Model, st: dict) -> list[float]:
    """Free length of every cut end (fray.py docstring), in structural-slot order."""
    W, H = model.warp_yarns, model.weft_yarns
    x = st["particle_position_m"]
    lvl, con, alive = st["crossing_yarn_level"], st["couple_connected"], st["spring_alive"]
    out = []
    # Yarns as lists of (crossing, spring to the next crossing).
    for s in np.nonzero(((model.spring_kind == STRUCT_WEFT) | (model.spring_kind == STRUCT_WARP))
                        & st["spring_broken"])[0]:
        weft = model.spring_kind[s] == STRUCT_WEFT
        ca, cb = int(model.spring_crossing_a[s]), int(model.spring_crossing_b[s])
        if weft:
            j = ca // W
            crossings = [j * W + i for i in range(W)]
            springs = list(model.weft_structural_spring[j])
        else:
            i = ca % W
            crossings = [j * W + i for j in range(H)]
            springs = list(model.warp_structural_spring[i])
        for start, step in ((crossings.index(ca), -1), (crossings.index(cb), 1)):
            length, p = 0.0, start
            while lvl[crossings[p]] and not con[crossings[p]]:
                q = p + step
                if not 0 <= q < len(crossings):
                    break
                sp = springs[min(p, q)]
                if not alive[sp]:
                    break
                length += float(np.linalg.norm(x[st["spring_particle_b"][sp]] - x[st["spring_particle_a"][sp]]))
                p = q
            out.append(length)
    return out


def assert_named_close(expected: dict, actual: dict, names=None, atol: float = 0.0) -> None:
    """Arrays equal (exactly, or within atol for floats); the message names the array that differs
    and its first differing indices."""
    for name in names or expected.keys():
        a, b = np.asarray(expected[name]), np.asarray(actual[name])
        if a.shape != b.shape:
            raise AssertionError(f"array {name!r}: shape {a.shape} != {b.shape}")
        bad = ~np.isclose(a, b, rtol=0.0, atol=atol) if a.dtype.kind == "f" else a != b
        if bad.any():
            idx = np.argwhere(bad)[:3]
            raise AssertionError(f"array {name!r} differs at {idx.tolist()}: expected {a[tuple(idx[0])]}, "
                                 f"got {b[tuple(idx[0])]}")
