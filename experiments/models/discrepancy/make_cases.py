#!/usr/bin/env python3
"""Writes the missing-physics benchmark cases: one simulation model per case and
cases.toml (the expected verdict and location of each). Run from this folder:

    python3 make_cases.py

The models are the four-story frame of ../four-story-truth.toml (same structure,
damping, nominal model, sampling, tests and channels) with one protocol change shared
by every case, so that the protocol does not give the answer away: each hammer test has
a weak (~20 N) then a strong (~120 N) impact, and the shake-table chirp is 0.03 m/s^2
(story drifts of the strong impacts and of the chirp are then alike, ~2-3 mm).
The design figures in README.md come from `cargo test --release --test
discrepancy_cases -- --nocapture`, which also checks every case against the ranges.
"""

import math
import tomllib

NOISE = {  # the recorded campaign's noise (std at 500 Hz), scaled per case
    "force_n": 0.02,
    "ground_acceleration_m_per_s2": 0.002,
    "acceleration_m_per_s2": 0.005,
    "displacement_m": 2e-6,
}

# (id, verdict, location, noise scale, seed, effects TOML, size)
CASES = [
    ("none-1", "none", {}, 1.0, 1001, "", "nothing missing"),
    ("none-2", "none", {}, 0.5, 1002, "", "nothing missing"),
    ("none-3", "none", {}, 2.0, 1003, "", "nothing missing"),
    ("base_flexibility-1", "base_flexibility", {}, 1.0, 2001, """
[[effect]]
kind = "base_flexibility"
mass_kg = 5.0
stiffness_n_per_m = 8900.0
damping_n_s_per_m = 10.0
""", "m_b 5 kg, k_b 8900 N/m, c_b 10 N s/m"),
    ("base_flexibility-2", "base_flexibility", {}, 0.5, 2002, """
[[effect]]
kind = "base_flexibility"
mass_kg = 10.0
stiffness_n_per_m = 4500.0
damping_n_s_per_m = 30.0
""", "m_b 10 kg, k_b 4500 N/m, c_b 30 N s/m"),
    ("base_flexibility-3", "base_flexibility", {}, 2.0, 2003, """
[[effect]]
kind = "base_flexibility"
mass_kg = 3.0
stiffness_n_per_m = 10600.0
damping_n_s_per_m = 5.0
""", "m_b 3 kg, k_b 10600 N/m, c_b 5 N s/m"),
    ("nonproportional_damping-1", "nonproportional_damping", {"story": 1}, 1.0, 3001, """
[[effect]]
kind = "dashpot"
story = 1
coefficient_n_s_per_m = 3.0
""", "dashpot 3 N s/m across story 1"),
    ("nonproportional_damping-2", "nonproportional_damping", {"story": 3}, 0.5, 3002, """
[[effect]]
kind = "dashpot"
story = 3
coefficient_n_s_per_m = 4.0
""", "dashpot 4 N s/m across story 3"),
    ("nonproportional_damping-3", "nonproportional_damping", {"story": 2}, 2.0, 3003, """
[[effect]]
kind = "dashpot"
story = 2
coefficient_n_s_per_m = 3.0
""", "dashpot 3 N s/m across story 2"),
    ("secondary_oscillator-1", "secondary_oscillator", {"floor": 4}, 1.0, 4001, """
[[effect]]
kind = "oscillator"
floor = 4
mass_kg = 0.25
stiffness_n_per_m = 8.0
damping_ratio = 0.03
""", "0.25 kg (4.9% of floor 4), 0.90 Hz, zeta 3%"),
    ("secondary_oscillator-2", "secondary_oscillator", {"floor": 2}, 0.5, 4002, """
[[effect]]
kind = "oscillator"
floor = 2
mass_kg = 0.4
stiffness_n_per_m = 193.4
damping_ratio = 0.02
""", "0.4 kg (8.1% of floor 2), 3.50 Hz, zeta 2%"),
    ("secondary_oscillator-3", "secondary_oscillator", {"floor": 3}, 2.0, 4003, """
[[effect]]
kind = "oscillator"
floor = 3
mass_kg = 0.15
stiffness_n_per_m = 160.1
damping_ratio = 0.01
""", "0.15 kg (3.0% of floor 3), 5.20 Hz, zeta 1%"),
    ("stiffness_nonlinearity-1", "stiffness_nonlinearity", {"story": 1}, 1.0, 5001, """
[[effect]]
kind = "stiffness_nonlinearity"
story = 1
k3_n_per_m3 = 1.5e8
""", "cubic k3 1.5e8 N/m^3 across story 1 (hardening)"),
    ("stiffness_nonlinearity-2", "stiffness_nonlinearity", {"story": 2}, 0.5, 5002, """
[[effect]]
kind = "stiffness_nonlinearity"
story = 2
k3_n_per_m3 = 2.5e8
""", "cubic k3 2.5e8 N/m^3 across story 2 (hardening)"),
    ("stiffness_nonlinearity-3", "stiffness_nonlinearity", {"story": 3}, 2.0, 5003, """
[[effect]]
kind = "stiffness_nonlinearity"
story = 3
k3_n_per_m3 = 5e8
""", "cubic k3 5e8 N/m^3 across story 3 (hardening)"),
    ("sensor_timing-1", "sensor_timing", {"channels": ["force"]}, 1.0, 6001, """
[[sensor_effect]]
kind = "time_offset"
channels = ["force"]
offset_s = 0.010
""", "force channel 10 ms late"),
    ("sensor_timing-2", "sensor_timing", {"quantity": "displacement"}, 0.5, 6002, """
[[sensor_effect]]
kind = "time_offset"
quantity = "displacement"
offset_s = 0.020
""", "displacement channels 20 ms late"),
    ("sensor_timing-3", "sensor_timing", {"channels": ["acc2", "acc4"]}, 2.0, 6003, """
[[sensor_effect]]
kind = "time_offset"
channels = ["acc2", "acc4"]
offset_s = 0.006
""", "acc2 and acc4 6 ms late"),
    ("sensor_dynamics-1", "sensor_dynamics", {"quantity": "acceleration"}, 1.0, 7001, """
[[sensor_effect]]
kind = "low_pass"
quantity = "acceleration"
natural_frequency_hz = 40.0
damping_ratio = 0.6
""", "accelerometers: 2nd-order low-pass 40 Hz, zeta 0.6"),
    ("sensor_dynamics-2", "sensor_dynamics", {"quantity": "acceleration"}, 0.5, 7002, """
[[sensor_effect]]
kind = "low_pass"
quantity = "acceleration"
natural_frequency_hz = 20.0
damping_ratio = 0.4
""", "accelerometers: 2nd-order low-pass 20 Hz, zeta 0.4"),
    ("sensor_dynamics-3", "sensor_dynamics", {"channels": ["acc1", "acc3"]}, 2.0, 7003, """
[[sensor_effect]]
kind = "low_pass"
channels = ["acc1", "acc3"]
natural_frequency_hz = 30.0
damping_ratio = 0.7
""", "acc1 and acc3: 2nd-order low-pass 30 Hz, zeta 0.7"),
]

# Weak then strong impact per hammer test (peak N), like the recorded campaign's spread.
IMPACTS = {1: (21.0, 122.0), 2: (19.0, 118.0), 3: (22.0, 125.0), 4: (18.0, 115.0)}


def effect_truth(effects):
    """The true values of the effect parameters `diagnose` reports (diagnosis.json,
    `effects[i].effect_parameters`, same names and units) for a case's one effect."""
    table = tomllib.loads(effects) if effects.strip() else {}
    entries = table.get("effect", []) + table.get("sensor_effect", [])
    if len(entries) != 1:
        return {}
    e = entries[0]
    two_pi = 2.0 * math.pi
    if e["kind"] == "base_flexibility":
        m, k, c = e["mass_kg"], e["stiffness_n_per_m"], e["damping_n_s_per_m"]
        return {"base_mass": m, "base_frequency": math.sqrt(k / m) / two_pi,
                "base_damping_ratio": c / (2.0 * math.sqrt(k * m))}
    if e["kind"] == "dashpot":
        return {"damper_coefficient": e["coefficient_n_s_per_m"]}
    if e["kind"] == "oscillator":
        m, k = e["mass_kg"], e["stiffness_n_per_m"]
        return {"oscillator_mass": m, "oscillator_frequency": math.sqrt(k / m) / two_pi,
                "oscillator_damping_ratio": e["damping_ratio"]}
    if e["kind"] == "stiffness_nonlinearity":
        return {"k3": e["k3_n_per_m3"]}
    if e["kind"] == "time_offset":
        return {"time_offset": e["offset_s"]}
    if e["kind"] == "low_pass":
        return {"sensor_frequency": e["natural_frequency_hz"],
                "sensor_damping_ratio": e["damping_ratio"]}
    raise ValueError(f"unknown effect kind {e['kind']}")


def truth_toml(values):
    items = ", ".join(f"{k} = {v!r}" for k, v in values.items())
    return "{ " + items + " }" if items else "{}"


def case_entry(cid, verdict, loc, size, scale, seed, truth=None):
    """The `[[case]]` lines of one case in a cases.toml."""
    lines = [
        "",
        "[[case]]",
        f'id = "{cid}"',
        f'model = "{cid}.toml"',
        f'verdict = "{verdict}"',
        f"location = {location_toml(loc)}",
        f'size = "{size}"',
        f"noise_scale = {float(scale)!r}",
        f"seed = {seed}",
    ]
    if truth:
        lines.append(f"truth = {truth_toml(truth)}")
    return lines


def location_toml(loc):
    items = []
    for k, v in loc.items():
        if isinstance(v, list):
            items.append(f'{k} = [{", ".join(chr(34) + x + chr(34) for x in v)}]')
        elif isinstance(v, str):
            items.append(f'{k} = "{v}"')
        else:
            items.append(f"{k} = {v}")
    return "{ " + ", ".join(items) + " }" if items else "{}"


# The true frame of ../four-story-truth.toml; make_nulls.py varies it.
TRUTH = {
    "floor_mass_kg": [5.155, 4.953, 4.949, 5.090],
    "story_stiffness_n_per_m": [1090.0, 1258.0, 1378.0, 2666.0],
    "xi": [0.017, 0.0115, 0.006, 0.004],
}


def toml_list(values):
    return "[" + ", ".join(repr(float(v)) for v in values) + "]"


def model_toml(cid, verdict, scale, seed, effects, truth=TRUTH, impacts=IMPACTS, ar1=0.0,
               writer="make_cases.py", folder=""):
    noise = "\n".join(f"{k} = {v * scale:g}" for k, v in NOISE.items())
    if ar1:
        noise += f"\nar1_coefficient = {ar1:g}                 # red noise: AR(1) at the output rate"
    hammers = "\n".join(
        f"""[[test]]
name = "hammer-floor{f}"
kind = "hammer"
excited_floor = {f}
duration_s = 120.0
pulse_duration_s = 0.003
impacts = [{{ time_s = 2.0003, peak_force_n = {w} }}, {{ time_s = 62.0003, peak_force_n = {s} }}]
"""
        for f, (w, s) in impacts.items()
    )
    return f"""# Missing-physics benchmark case {cid} (expected verdict: {verdict}); see README.md.
# Written by {writer}: edit that, not this file.
#
#   frfbayes simulate --model experiments/models/discrepancy/{folder}{cid}.toml --out <campaign>

title = "four-story frame (benchmark case {cid})"
seed = {seed}

[structure]
kind = "shear_frame"
floor_mass_kg = {toml_list(truth["floor_mass_kg"])}
story_stiffness_n_per_m = {toml_list(truth["story_stiffness_n_per_m"])}

[damping]
model = "modal"
xi = {toml_list(truth["xi"])}

[nominal]
floor_mass_kg = [4.64, 4.64, 4.64, 4.64]
story_stiffness_n_per_m = [1019.0, 1217.0, 1420.0, 2473.0]

[sampling]
output_rate_hz = 500.0
oversampling = 10
passband_fraction = 0.8
stopband_attenuation_db = 100.0

[noise]                                  # {scale:g} x the recorded campaign's
{noise}

{hammers}
[[test]]
name = "shake-table-chirp"
kind = "shake_table"
ring_down_s = 70.0

[test.chirp]
f0_hz = 0.0
f1_hz = 10.0
start_s = 0.0
sweep_duration_s = 60.0
taper_s = 1.0
amplitude_m_per_s2 = 0.03
{effects}"""


def main():
    index = [
        "# Missing-physics benchmark: expected verdict and location of every case.",
        "# Written by make_cases.py; read by the `diagnose` benchmark. Verdicts are the",
        "# hypothesis names (or \"none\"); location is {} for the whole structure, or",
        "# { story = s }, { floor = f }, { channels = [...] }, { quantity = \"...\" }.",
        "# truth: the true values of the effect parameters diagnose reports (scoring only).",
        "",
        'hypotheses = ["base_flexibility", "nonproportional_damping", "secondary_oscillator",',
        '              "stiffness_nonlinearity", "sensor_timing", "sensor_dynamics"]',
    ]
    for cid, verdict, loc, scale, seed, effects, size in CASES:
        with open(f"{cid}.toml", "w") as f:
            f.write(model_toml(cid, verdict, scale, seed, effects))
        index += case_entry(cid, verdict, loc, size, scale, seed, effect_truth(effects))
    with open("cases.toml", "w") as f:
        f.write("\n".join(index) + "\n")


if __name__ == "__main__":
    main()
