#!/usr/bin/env python3
"""Writes the effect-interval coverage study's cases (issue 14, item 4): for each effect
family, campaigns with the effect at a random size and location, and the true values of
the parameters `diagnose` reports. Run from this folder:

    python3 make_coverage.py

It writes coverage/<id>.toml and coverage/cases.toml (edit this script, not them). The
protocol and the frame are the benchmark's (make_cases.py); per case the noise scale is
log-uniform on [0.5, 2]. Sizes (uniform unless said):

- base_flexibility: m_b 3-10 kg, base frequency sqrt(k_b / m_b) / 2 pi 5-10 Hz,
  zeta_b 0.01-0.06;
- nonproportional_damping: a dashpot of 2-5 N s/m across story 1-4;
- secondary_oscillator: 3-8 % of floor 1-4's true mass, tuned to 0.9-6 Hz, zeta 1-3 %;
- sensor_timing: 4-20 ms late, on the force, the displacements, or two accelerometers;
- sensor_dynamics: a second-order low-pass of 20-45 Hz, zeta 0.4-0.7, on every
  accelerometer or two of them.

The cubic spring (stiffness_nonlinearity) is left out: one diagnosis takes about 20 min.
The draws come from Python's Mersenne Twister seeded with 20261128; the simulation
seeds are 9001.. (c1-c6 of the five families, then c7-c12, then c13-c24). Diagnose each family with only its own hypothesis (the interval, not
the verdict, is measured here), e.g.

    frfbayes diagnose-benchmark --cases experiments/models/discrepancy/coverage/cases.toml \
        --work runs/coverage --only $(ids of the family) --hypotheses <family> --report ...
"""

import math
import os
import random

from make_cases import TRUTH, case_entry, effect_truth, model_toml

# Cases c1-c6 of every family came first (2026-11-28); c7-c12 were added (2026-12-01)
# as a second batch drawn after them, so the first 30 cases stay as they were; c13-c24
# (2026-12-03) are a third batch, sized before any of them was diagnosed (24 per family),
# drawn after the first 60, which stay as they were.
BATCHES = [range(1, 7), range(7, 13), range(13, 25)]
ACCS = ["acc1", "acc2", "acc3", "acc4"]


def base_flexibility(rng):
    m = rng.uniform(3.0, 10.0)
    f = rng.uniform(5.0, 10.0)
    zeta = rng.uniform(0.01, 0.06)
    k = m * (2 * math.pi * f) ** 2
    c = 2 * zeta * math.sqrt(k * m)
    return {}, f"""
[[effect]]
kind = "base_flexibility"
mass_kg = {m:.4g}
stiffness_n_per_m = {k:.6g}
damping_n_s_per_m = {c:.4g}
""", f"m_b {m:.3g} kg, f_b {f:.3g} Hz, zeta_b {zeta:.3g}"


def nonproportional_damping(rng):
    story = rng.randint(1, 4)
    c = rng.uniform(2.0, 5.0)
    return {"story": story}, f"""
[[effect]]
kind = "dashpot"
story = {story}
coefficient_n_s_per_m = {c:.4g}
""", f"dashpot {c:.3g} N s/m across story {story}"


def secondary_oscillator(rng):
    floor = rng.randint(1, 4)
    m = TRUTH["floor_mass_kg"][floor - 1] * rng.uniform(0.03, 0.08)
    f = rng.uniform(0.9, 6.0)
    zeta = rng.uniform(0.01, 0.03)
    k = m * (2 * math.pi * f) ** 2
    return {"floor": floor}, f"""
[[effect]]
kind = "oscillator"
floor = {floor}
mass_kg = {m:.4g}
stiffness_n_per_m = {k:.6g}
damping_ratio = {zeta:.4g}
""", f"{m:.3g} kg at floor {floor}, {f:.3g} Hz, zeta {zeta:.3g}"


def pick_channels(rng):
    return sorted(rng.sample(ACCS, 2))


def sensor_timing(rng):
    offset = rng.uniform(0.004, 0.020)
    where = rng.choice(["force", "displacement", "pair"])
    if where == "force":
        loc, sel = {"channels": ["force"]}, 'channels = ["force"]'
    elif where == "displacement":
        loc, sel = {"quantity": "displacement"}, 'quantity = "displacement"'
    else:
        pair = pick_channels(rng)
        loc, sel = {"channels": pair}, f'channels = ["{pair[0]}", "{pair[1]}"]'
    return loc, f"""
[[sensor_effect]]
kind = "time_offset"
{sel}
offset_s = {offset:.5g}
""", f"{where} {1000 * offset:.3g} ms late"


def sensor_dynamics(rng):
    f = rng.uniform(20.0, 45.0)
    zeta = rng.uniform(0.4, 0.7)
    if rng.random() < 0.5:
        loc, sel, where = {"quantity": "acceleration"}, 'quantity = "acceleration"', "all acc"
    else:
        pair = pick_channels(rng)
        loc, sel = {"channels": pair}, f'channels = ["{pair[0]}", "{pair[1]}"]'
        where = "+".join(pair)
    return loc, f"""
[[sensor_effect]]
kind = "low_pass"
{sel}
natural_frequency_hz = {f:.4g}
damping_ratio = {zeta:.4g}
""", f"{where}: low-pass {f:.3g} Hz, zeta {zeta:.3g}"


FAMILIES = [base_flexibility, nonproportional_damping, secondary_oscillator, sensor_timing,
            sensor_dynamics]


def main():
    rng = random.Random(20261128)
    index = [
        "# Effect-interval coverage study (issue 14, item 4). Written by make_coverage.py.",
        "# truth: the true values of the effect parameters diagnose reports (scoring only).",
        "",
        'hypotheses = ["base_flexibility", "nonproportional_damping", "secondary_oscillator",',
        '              "stiffness_nonlinearity", "sensor_timing", "sensor_dynamics"]',
    ]
    os.makedirs("coverage", exist_ok=True)
    seed = 9000
    for batch in BATCHES:
        for family in FAMILIES:
            for j in batch:
                seed += 1
                cid = f"{family.__name__}-c{j}"
                loc, effects, size = family(rng)
                scale = round(2.0 ** rng.uniform(-1.0, 1.0), 3)
                text = model_toml(cid, family.__name__, scale, seed, effects,
                                  writer="make_coverage.py", folder="coverage/")
                with open(os.path.join("coverage", f"{cid}.toml"), "w") as f:
                    f.write(text)
                index += case_entry(cid, family.__name__, loc, size, scale, seed,
                                    effect_truth(effects))
    with open(os.path.join("coverage", "cases.toml"), "w") as f:
        f.write("\n".join(index) + "\n")


if __name__ == "__main__":
    main()
