#!/usr/bin/env python3
"""Writes a six-DOF model that is not a shear frame, as Matrix Market files (model.toml +
.mtx files here), for the fast general-model posterior test (tests/bayes_general.rs).

A spring network of two columns of three levels: DOF 1 and 2 are level 1 (left, right),
3 and 4 level 2, 5 and 6 level 3 (1-based, as in the campaign format). Every DOF moves
along one common axis; springs join DOF pairs (or a DOF and the ground):

- `k1` (alpha 1): level-1 columns, ground-1 and ground-2, 2.0e5 N/m each;
- `k2` (alpha 2): upper columns 1-3, 2-4, 3-5, 4-6, 1.5e5 N/m each;
- `k3` (alpha 3): beams 1-2, 3-4, 5-6, 0.6e5 N/m each;
- `k4` (alpha 4): braces 1-4 and 3-6, 0.4e5 N/m each;
- `m1` (beta 1): lumped 120 kg at DOFs 1 and 2;
- `m2` (beta 2): a bar of 200 kg between DOFs 3 and 4 with its consistent mass
  `(200/6) [[2, 1], [1, 2]]` (off-diagonal mass);
- `m3` (beta 3): lumped 80 kg at DOFs 5 and 6.

`K(alpha) = sum_s (1 + alpha_s) K_s`, `M(beta) = sum_r (1 + beta_r) M_r` (paper Eqs.
20-21; `K0`, `M0` are the sums). The stiffness couples non-neighbouring DOFs (braces) and
the mass matrix is not diagonal, so neither the shear-frame fast path nor a diagonal
mass applies. Natural frequencies of the nominal model: printed by this script.
Deterministic: `python3 make_model.py` here rewrites every file byte for byte.
"""

import os

N = 6
HERE = os.path.dirname(os.path.abspath(__file__))
GROUPS_K = [
    ("k1", 2.0e5, [(0, 1), (0, 2)]),
    ("k2", 1.5e5, [(1, 3), (2, 4), (3, 5), (4, 6)]),
    ("k3", 0.6e5, [(1, 2), (3, 4), (5, 6)]),
    ("k4", 0.4e5, [(1, 4), (3, 6)]),
]
GROUPS_M = [
    ("m1", {(1, 1): 120.0, (2, 2): 120.0}),
    ("m2", {(3, 3): 400.0 / 6.0, (4, 4): 400.0 / 6.0, (4, 3): 200.0 / 6.0}),
    ("m3", {(5, 5): 80.0, (6, 6): 80.0}),
]


def write_mtx(name, entries, comment):
    """Symmetric coordinate Matrix Market file of the lower-triangle `entries` (1-based)."""
    lines = ["%%MatrixMarket matrix coordinate real symmetric", f"% {comment}",
             f"{N} {N} {len(entries)}"]
    lines += [f"{i} {j} {v!r}" for (i, j), v in sorted(entries.items(), key=lambda e: (e[0][1], e[0][0]))]
    with open(os.path.join(HERE, name), "w") as f:
        f.write("\n".join(lines) + "\n")


def spring(i, j, k):
    """Lower triangle of a spring k between DOFs i and j (1-based; 0 = ground)."""
    e = {}
    for d in (i, j):
        if d > 0:
            e[(d, d)] = e.get((d, d), 0.0) + k
    if i > 0 and j > 0:
        e[(max(i, j), min(i, j))] = -k
    return e


def add(a, b):
    out = dict(a)
    for key, v in b.items():
        out[key] = out.get(key, 0.0) + v
    return out


def main():
    k0, m0 = {}, {}
    manifest = ["# Six-DOF spring network (not a shear frame), written by make_model.py (see its docstring).",
                'k0 = "K0.mtx"', 'm0 = "M0.mtx"', ""]
    for name, k, springs in GROUPS_K:
        e = {}
        for i, j in springs:
            e = add(e, spring(i, j, k))
        write_mtx(f"{name.upper()}.mtx", e, f"{name}: springs {springs}, {k!r} N/m each")
        k0 = add(k0, e)
        manifest += ["[[alpha]]", f'name = "{name}"', 'unit = "-"', f'matrix = "{name.upper()}.mtx"', ""]
    for name, e in GROUPS_M:
        write_mtx(f"{name.upper()}.mtx", e, f"{name}: mass matrix entries (kg)")
        m0 = add(m0, e)
        manifest += ["[[beta]]", f'name = "{name}"', 'unit = "-"', f'matrix = "{name.upper()}.mtx"', ""]
    write_mtx("K0.mtx", k0, "sum of the stiffness matrices")
    write_mtx("M0.mtx", m0, "sum of the mass matrices")
    with open(os.path.join(HERE, "model.toml"), "w") as f:
        f.write("\n".join(manifest))
    try:
        import numpy as np
        from scipy.linalg import eigh
        full = lambda e: (lambda a: a + np.tril(a, -1).T)(
            np.array([[e.get((i, j), 0.0) for j in range(1, N + 1)] for i in range(1, N + 1)]))
        w2 = eigh(full(k0), full(m0), eigvals_only=True)
        print("natural frequencies (Hz):", [round(float(np.sqrt(v) / (2 * np.pi)), 3) for v in w2])
    except ImportError:
        pass


if __name__ == "__main__":
    main()
