#!/usr/bin/env python3
"""Writes the false-alarm study's null cases: campaigns in which nothing is missing from
the nominal model's family (a shear frame with modal damping), with the truth, the noise
level, its colour and the impacts drawn at random per case. Run from this folder:

    python3 make_nulls.py

It writes nulls/null-NN.toml and nulls/cases.toml (edit this script, not them). Every
case is the benchmark's protocol (make_cases.py: weak and strong impact per hammer test,
the 0.03 m/s^2 chirp) on a different frame:

- floor masses: the benchmark truth times U(0.92, 1.08) each;
- story stiffnesses: times U(0.88, 1.12) each (so the frame's modes move by several %);
- modal damping ratios: times U(0.6, 1.6) each;
- noise scale: log-uniform on [0.5, 2] times the recorded campaign's;
- noise colour: cases 1-10 white, 11-30 red (`ar1_coefficient`: AR(1) at the 500 Hz
  output rate, phi from {0.5, 0.8, 0.9, 0.95} in turn, same sd): over the 0-10 Hz band
  the noise power is 2.9-3.0 (phi 0.5), 6.8-9 (0.8), 7.9-19 (0.9) and 5.6-39 (0.95)
  times a white noise's of the same sd, falling with frequency across the band;
- impact peaks: weak U(15, 25) N, strong U(100, 140) N.

The draws come from Python's Mersenne Twister seeded with 20261127, so the files are
reproducible; the simulation seeds are 8001..8030.
"""

import os
import random

from make_cases import TRUTH, case_entry, model_toml

N_CASES = 30
N_WHITE = 10
PHIS = [0.5, 0.8, 0.9, 0.95]


def draw_case(rng, i):
    truth = {
        "floor_mass_kg": [round(m * rng.uniform(0.92, 1.08), 3) for m in TRUTH["floor_mass_kg"]],
        "story_stiffness_n_per_m": [
            round(k * rng.uniform(0.88, 1.12), 1) for k in TRUTH["story_stiffness_n_per_m"]
        ],
        "xi": [round(x * rng.uniform(0.6, 1.6), 5) for x in TRUTH["xi"]],
    }
    scale = round(2.0 ** rng.uniform(-1.0, 1.0), 3)
    impacts = {
        f: (round(rng.uniform(15.0, 25.0), 1), round(rng.uniform(100.0, 140.0), 1))
        for f in range(1, 5)
    }
    ar1 = 0.0 if i <= N_WHITE else PHIS[(i - N_WHITE - 1) % len(PHIS)]
    return truth, scale, impacts, ar1


def main():
    rng = random.Random(20261127)
    index = [
        "# False-alarm study: null cases (nothing missing). Written by make_nulls.py.",
        "# Read by `frfbayes diagnose-benchmark --cases experiments/models/discrepancy/nulls/cases.toml`.",
        "",
        'hypotheses = ["base_flexibility", "nonproportional_damping", "secondary_oscillator",',
        '              "stiffness_nonlinearity", "sensor_timing", "sensor_dynamics"]',
    ]
    os.makedirs("nulls", exist_ok=True)
    for i in range(1, N_CASES + 1):
        cid = f"null-{i:02d}"
        seed = 8000 + i
        truth, scale, impacts, ar1 = draw_case(rng, i)
        text = model_toml(cid, "none", scale, seed, "", truth=truth, impacts=impacts, ar1=ar1,
                          writer="make_nulls.py", folder="nulls/")
        with open(os.path.join("nulls", f"{cid}.toml"), "w") as f:
            f.write(text)
        colour = "white" if ar1 == 0.0 else f"red noise phi {ar1:g}"
        size = (f"nothing missing; noise x{scale:g}, {colour}; k x"
                + "/".join(f"{k / k0:.3f}" for k, k0 in zip(truth["story_stiffness_n_per_m"],
                                                              TRUTH["story_stiffness_n_per_m"])))
        index += case_entry(cid, "none", {}, size, scale, seed)
    with open(os.path.join("nulls", "cases.toml"), "w") as f:
        f.write("\n".join(index) + "\n")


if __name__ == "__main__":
    main()
