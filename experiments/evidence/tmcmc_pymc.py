#!/usr/bin/env python3
"""What the field uses, on our evidence validation problems (issue 14, item 3).

PyMC's sequential Monte Carlo (``pm.sample_smc``: transitional MCMC of Ching & Chen
2007, with the adaptive tempering and independent Metropolis-Hastings kernel of PyMC;
quoFEM, Korali and UQpy use the same scheme) reports the log marginal likelihood of a
model. This script runs it on the nested linear-Gaussian problems that
``cargo test --release --test evidence_validation export_problems -- --ignored`` writes
to ``experiments/evidence/problems.json`` (designs, data, box priors and the exact
``ln Z`` of both models, computed in ``src/infer/validation.rs``), each model with
``--seeds`` seeds, and prints and writes (``--report``, ``.json`` and ``.md``) the same
table as the Rust measurement ``measure_estimators``: bias and sd over seeds of
``Delta ln Z = ln Z_ext - ln Z_base`` and of ``ln Z_ext``, and wall time per model.

The models are written exactly as the Rust targets: ``theta ~ Uniform(box)``,
``phi ~ Uniform(box)``, ``e = phi`` or ``exp(phi)``, ``y ~ Normal(A theta + B e, sigma)``.

The script makes its own virtual environment (``experiments/evidence/.venv``, PyMC from
PyPI) and re-runs itself inside it. From the repository root::

    nice -n 10 python3 experiments/evidence/tmcmc_pymc.py --seeds 4 \\
        --report results/evidence/pymc_smc
"""

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent
VENV = HERE / ".venv"
REQUIREMENTS = ["pymc>=5.10,<6"]


def ensure_venv():
    """Re-executes this script inside experiments/evidence/.venv, creating it if needed."""
    if Path(sys.prefix).resolve() == VENV.resolve():
        return
    py = VENV / ("Scripts/python.exe" if os.name == "nt" else "bin/python")
    if not py.exists():
        print(f"creating {VENV} ...", file=sys.stderr)
        subprocess.run([sys.executable, "-m", "venv", str(VENV)], check=True)
    probe = subprocess.run([str(py), "-c", "import pymc"], capture_output=True)
    if probe.returncode != 0:
        print("installing PyMC into the virtual environment ...", file=sys.stderr)
        subprocess.run([str(py), "-m", "pip", "install", "--quiet", *REQUIREMENTS], check=True)
    os.execv(str(py), [str(py), str(Path(__file__).resolve()), *sys.argv[1:]])


ensure_venv()

# One thread per process: the 2-core machine is shared, and PyMC runs one chain here.
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pymc as pm  # noqa: E402


def log_evidence(problem, extended, seed, draws):
    """PyMC SMC's ln Z of one model, and the wall time in seconds."""
    a = np.asarray(problem["a"])
    y = np.asarray(problem["y"])
    lo_b, hi_b = np.asarray(problem["base_bounds"]).T
    t0 = time.perf_counter()
    with pm.Model():
        theta = pm.Uniform("theta", lower=lo_b, upper=hi_b, shape=len(lo_b))
        mu = pm.math.dot(a, theta)
        if extended:
            b = np.asarray(problem["b"])
            lo_e, hi_e = np.asarray(problem["effect_bounds"]).T
            phi = pm.Uniform("phi", lower=lo_e, upper=hi_e, shape=len(lo_e))
            e = pm.math.exp(phi) if problem["effect_scale"] == "log" else phi
            mu = mu + pm.math.dot(b, e)
        pm.Normal("y", mu=mu, sigma=problem["sigma"], observed=y)
        idata = pm.sample_smc(
            draws=draws,
            chains=1,
            cores=1,
            random_seed=seed,
            progressbar=False,
            compute_convergence_checks=False,
        )
    seconds = time.perf_counter() - t0
    lml = idata.sample_stats["log_marginal_likelihood"].values
    # One chain; the last stage's running value is the estimate (PyMC keeps one entry
    # per stage, as an object array of lists in some versions).
    flat = np.asarray(lml, dtype=object).ravel()
    last = flat[-1]
    value = float(np.asarray(last, dtype=float).ravel()[-1])
    return value, seconds


def stats(values, exact):
    v = np.asarray(values, dtype=float)
    sd = float(v.std(ddof=1)) if len(v) > 1 else float("nan")
    return float(v.mean() - exact), sd


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--problems", default=str(HERE / "problems.json"))
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--draws", type=int, default=2000, help="particles (PyMC's default 2000)")
    ap.add_argument("--only", default="", help="run only problems whose name contains this")
    ap.add_argument("--report", default="")
    args = ap.parse_args()
    problems = json.loads(Path(args.problems).read_text())
    rows, runs = [], []
    for p in problems:
        if args.only and args.only not in p["name"]:
            continue
        per_seed = []
        for s in range(args.seeds):
            zb, tb = log_evidence(p, False, 100 * s + 1, args.draws)
            ze, te = log_evidence(p, True, 100 * s + 2, args.draws)
            per_seed.append((zb, ze, tb, te))
            runs.append({"problem": p["name"], "seed": s, "ln_z_base": zb, "ln_z_ext": ze,
                         "seconds_base": tb, "seconds_ext": te})
            print(f"{p['name']} seed {s}: base {zb - p['ln_z_base']:+.3f} ext "
                  f"{ze - p['ln_z_extension']:+.3f} ({tb:.1f} + {te:.1f} s)", flush=True)
        exact_delta = p["ln_z_extension"] - p["ln_z_base"]
        bd, sdd = stats([ze - zb for zb, ze, _, _ in per_seed], exact_delta)
        be, sde = stats([ze for _, ze, _, _ in per_seed], p["ln_z_extension"])
        secs = float(np.mean([(tb + te) / 2 for _, _, tb, te in per_seed]))
        rows.append({"problem": p["name"], "k": len(p["effect_bounds"]), "exact_delta": exact_delta,
                     "gain": p["gain"], "bias_delta": bd, "sd_delta": sdd, "bias_ext": be,
                     "sd_ext": sde, "seconds_per_model": secs, "seeds": args.seeds})
    head = ("| problem | k | exact Delta ln Z | gain | method | bias Delta | sd Delta | "
            "bias ln Z_ext | sd ln Z_ext | s per model |\n|---|---|---|---|---|---|---|---|---|---|")
    lines = [head] + [
        f"| {r['problem']} | {r['k']} | {r['exact_delta']:.3f} | {r['gain']:.2f} | PyMC SMC "
        f"({args.draws} particles, IMH) | {r['bias_delta']:+.3f} | {r['sd_delta']:.3f} | "
        f"{r['bias_ext']:+.3f} | {r['sd_ext']:.3f} | {r['seconds_per_model']:.1f} |"
        for r in rows
    ]
    print("\n".join(lines))
    if args.report:
        out = Path(args.report)
        out.parent.mkdir(parents=True, exist_ok=True)
        meta = {"pymc": pm.__version__, "numpy": np.__version__, "python": platform.python_version(),
                "machine": platform.machine(), "draws": args.draws, "seeds": args.seeds}
        out.with_suffix(".json").write_text(json.dumps({"meta": meta, "rows": rows, "runs": runs}, indent=1))
        out.with_suffix(".md").write_text(
            f"PyMC {pm.__version__} SMC on experiments/evidence/problems.json\n\n" + "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
