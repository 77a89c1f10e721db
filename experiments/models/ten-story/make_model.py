#!/usr/bin/env python3
"""Writes the ten-story frame as a Matrix Market model (model.toml + .mtx files here).

A ten-story shear building, floors 1..10 from the ground up, DOF k = floor k (1-based, as
in the campaign format, docs/recording-format.md):

- floor masses m_k (kg): 4.8e4 at floor 1 falling linearly to 3.6e4 at the roof;
- story stiffnesses k_s (N/m): 1.6e8 at story 1 falling linearly to 0.7e8 at story 10
  (story s joins floor s-1, 0 = ground, and floor s);
- one alpha per story and one beta per floor, as paper Eqs. 20-21 with the shear-frame
  convention of frfbayes (`StructuralModel::shear_frame`): K_s = k_s S_s (S_s the unit
  story matrix), K0 = sum_s K_s, M_r = m_r e_r e_r^T, M0 = sum_r M_r, so that
  K(alpha) = sum_s (1 + alpha_s) K_s and M(beta) = sum_r (1 + beta_r) M_r.

Natural frequencies of the nominal model: 1.37 to 16.9 Hz (printed by the test
tests/simulate_ten_story.rs). Deterministic: run `python3 make_model.py` in this folder to
rewrite every file byte for byte.
"""

import os

N = 10
HERE = os.path.dirname(os.path.abspath(__file__))
MASS_KG = [4.8e4 + (3.6e4 - 4.8e4) * i / (N - 1) for i in range(N)]
STIFFNESS_N_PER_M = [1.6e8 + (0.7e8 - 1.6e8) * i / (N - 1) for i in range(N)]


def write_mtx(name, entries, comment):
    """Symmetric coordinate Matrix Market file of the lower-triangle `entries` (1-based)."""
    lines = ["%%MatrixMarket matrix coordinate real symmetric", f"% {comment}",
             f"{N} {N} {len(entries)}"]
    lines += [f"{i} {j} {v!r}" for (i, j), v in sorted(entries.items(), key=lambda e: (e[0][1], e[0][0]))]
    with open(os.path.join(HERE, name), "w") as f:
        f.write("\n".join(lines) + "\n")


def story(s, k):
    """Lower triangle of k S_s: story s (1-based) joins floor s-1 and floor s."""
    e = {(s, s): k}
    if s > 1:
        e[(s - 1, s - 1)] = k
        e[(s, s - 1)] = -k
    return e


def add(a, b):
    out = dict(a)
    for key, v in b.items():
        out[key] = out.get(key, 0.0) + v
    return out


def main():
    k0, m0 = {}, {}
    manifest = ['# Ten-story frame, written by make_model.py (see its docstring); DOF k = floor k.',
                'k0 = "K0.mtx"', 'm0 = "M0.mtx"', ""]
    for s in range(1, N + 1):
        e = story(s, STIFFNESS_N_PER_M[s - 1])
        write_mtx(f"K{s}.mtx", e, f"story {s}: k = {STIFFNESS_N_PER_M[s - 1]!r} N/m")
        k0 = add(k0, e)
        manifest += ["[[alpha]]", f'name = "k{s}"', 'unit = "-"', f'matrix = "K{s}.mtx"', ""]
    for r in range(1, N + 1):
        e = {(r, r): MASS_KG[r - 1]}
        write_mtx(f"M{r}.mtx", e, f"floor {r}: m = {MASS_KG[r - 1]!r} kg")
        m0 = add(m0, e)
        manifest += ["[[beta]]", f'name = "m{r}"', 'unit = "-"', f'matrix = "M{r}.mtx"', ""]
    write_mtx("K0.mtx", k0, "sum of the story matrices")
    write_mtx("M0.mtx", m0, "sum of the floor mass matrices")
    with open(os.path.join(HERE, "model.toml"), "w") as f:
        f.write("\n".join(manifest))


if __name__ == "__main__":
    main()
