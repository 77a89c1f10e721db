#!/usr/bin/env python3
"""Speed of frfbayes' multistart updating against a scipy ``least_squares`` multistart
of the same objective, measured side by side in one run (issue 3's speed requirement).

For every problem file (``*.json`` ProblemSpec, format ``frfbayes-problem/1``) in
``--problems``:

1. ``frfbayes multistart`` runs ``update`` with ``--starts`` and ``--seed`` (timed by the
   binary itself, on all cores, then again on one thread with ``RAYON_NUM_THREADS=1``)
   and exports its start points and the residuals at two points;
2. this script rebuilds the objective in vectorised numpy (generalised eigenproblem by
   ``scipy.linalg.eigh(K, M)``, modal sums, magnitudes, the same normalisation,
   weighting and log option as the Rust ``Problem``), checks it against the exported
   Rust residuals, and runs ``scipy.optimize.least_squares(method="trf")`` from the very
   same starts in the very same internal variables and box (damping on its log scale),
   with scipy's default tolerances, ``jac="2-point"`` and the Rust solver's ``x_scale``;
3. both best costs must agree to ``--cost-rtol`` (1e-4).

It writes ``<report>.md`` and ``<report>.json`` (per-problem and total times, the speed
ratios, best costs, machine and versions) and keeps the Rust outputs in
``<report>_rust/``. The script makes its own virtual environment
(``paper_repro/.venv``, numpy and scipy from PyPI) and re-runs itself inside it.

The command (run from the repository root; ``frfbayes repro`` writes the problems)::

    python3 paper_repro/scipy_multistart.py --problems results/paper_repro/problems \\
        --starts 64 --seed 0 --report results/speed/scipy_vs_rust

The binary is ``--frfbayes PATH`` if given, else it is built with
``cargo build --release`` and copied from ``$CARGO_TARGET_DIR/release`` (or
``target/release``) into ``<report>_rust/``. Synthetic problems for a trial run::

    FRFBAYES_PROBLEM_DIR=/tmp/frfbayes-problems cargo test --release \\
        --test update_multistart_cli -- --ignored --nocapture
"""

import argparse
import json
import os
import platform
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
VENV = HERE / ".venv"
REQUIREMENTS = ["numpy>=1.24", "scipy>=1.11"]


def venv_python():
    return VENV / ("Scripts/python.exe" if os.name == "nt" else "bin/python")


def ensure_venv():
    """Re-executes this script inside paper_repro/.venv, creating it if needed."""
    if Path(sys.prefix).resolve() == VENV.resolve():
        return
    py = venv_python()
    if not py.exists():
        print(f"creating {VENV} ...", file=sys.stderr)
        subprocess.run([sys.executable, "-m", "venv", str(VENV)], check=True)
    probe = subprocess.run([str(py), "-c", "import numpy, scipy"], capture_output=True)
    if probe.returncode != 0:
        print("installing numpy and scipy into the virtual environment ...", file=sys.stderr)
        subprocess.run(
            [str(py), "-m", "pip", "install", "--quiet", *REQUIREMENTS], check=True
        )
    os.execv(str(py), [str(py), str(Path(__file__).resolve()), *sys.argv[1:]])


ensure_venv()

# One BLAS thread unless the caller says otherwise: the objective's matrices are at
# most (pairs x modes) x (modes x frequencies), too small for threads to pay, and on a
# shared 2-core machine OpenBLAS's spinning threads made one scipy start 40x slower
# (2.2 s instead of 53 ms) in our trial. Set OPENBLAS_NUM_THREADS etc. to override.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402
import scipy  # noqa: E402
import scipy.linalg  # noqa: E402
from scipy.optimize import least_squares  # noqa: E402

# A start reaches the best minimum when cost <= best (1 + rtol) + atol: the Rust
# MultistartOptions defaults, so both sides count alike.
AT_BEST_RTOL = 1e-6
AT_BEST_ATOL = 1e-12
# The numpy objective must reproduce the Rust residuals to this fraction of their
# largest magnitude: both evaluate the same formulas in double precision, with
# different (LAPACK vs nalgebra) eigen-solvers; lightly damped poles amplify their
# ~1e-15 relative differences by at most 1/(2 xi) ~ 1e3.
RESIDUAL_RTOL = 1e-9


class Objective:
    """The residuals of frfbayes' ``Problem`` (Eqs. 17-24 of the paper) in numpy."""

    def __init__(self, spec, starts):
        if spec["format"] != "frfbayes-problem/1":
            raise ValueError(f"unsupported problem format {spec['format']!r}")
        model = spec["model"]
        self.k0 = np.array(model["k0"], dtype=float)
        self.m0 = np.array(model["m0"], dtype=float)
        n = self.k0.shape[0]
        self.k_inf = np.array(
            [p["influence"] for p in model["stiffness_parameters"]], dtype=float
        ).reshape(-1, n, n)
        self.m_inf = np.array(
            [p["influence"] for p in model["mass_parameters"]], dtype=float
        ).reshape(-1, n, n)
        self.iota = np.array(model["ground_influence"], dtype=float)
        self.n_alpha, self.n_beta = len(self.k_inf), len(self.m_inf)
        self.damping = spec["damping"]
        self.n_modes = spec["n_modes"]
        self.blocks = []
        for b in spec["blocks"]:
            resp, exc, ground, power = [], [], [], []
            for p in b["pairs"]:
                resp.append(p["response"])
                if p["excitation"] == "ground":
                    exc.append(0)
                    ground.append(True)
                else:
                    exc.append(int(p["excitation"].split(":")[1]))
                    ground.append(False)
                power.append({"receptance": 0, "mobility": 1, "accelerance": 2}[p["kind"]])
            w = np.array(b["omega_rad_s"], dtype=float)
            self.blocks.append(
                (
                    w,
                    np.array(resp),
                    np.array(exc),
                    np.array(ground)[:, None],
                    w[None, :] ** np.array(power)[:, None],
                )
            )
        measured = np.array(spec["magnitude"], dtype=float)
        self.log = spec["objective"]["residual"] == "log_magnitude"
        if spec.get("sigma") is not None:
            self.weights = 1.0 / np.array(spec["sigma"], dtype=float)
        elif self.log:
            self.weights = np.ones_like(measured)
        else:
            self.weights = np.full_like(measured, 1.0 / np.sqrt(np.mean(measured**2)))
        self.target = np.log(measured) if self.log else measured
        # Variables: theta template with fixed values, free indices, log scales.
        variables = starts["variables"]
        self.theta0 = np.array(
            [v["fixed"] if v["fixed"] is not None else v["initial"] for v in variables]
        )
        self.free = np.array(starts["free"], dtype=int)
        self.log_scale = np.array([variables[i]["scale"] == "log" for i in self.free])

    def theta(self, z):
        theta = self.theta0.copy()
        theta[self.free] = np.where(self.log_scale, np.exp(z), z)
        return theta

    def magnitudes(self, theta):
        alpha = theta[: self.n_alpha]
        beta = theta[self.n_alpha : self.n_alpha + self.n_beta]
        d = theta[self.n_alpha + self.n_beta :]
        k = self.k0 + np.tensordot(alpha, self.k_inf, axes=1)
        m = self.m0 + np.tensordot(beta, self.m_inf, axes=1)
        lam, phi = scipy.linalg.eigh(k, m)  # ascending, phi^T M phi = I
        wn = np.sqrt(np.maximum(lam[: self.n_modes], 0.0))
        phi = phi[:, : self.n_modes]
        gamma = phi.T @ (m @ self.iota)
        if self.damping == "rayleigh":
            c = d[0] + d[1] * wn * wn
        else:
            c = 2.0 * d[: self.n_modes] * wn
        out = []
        for w, resp, exc, ground, scale in self.blocks:
            poles = 1.0 / ((wn * wn)[:, None] - (w * w)[None, :] + 1j * c[:, None] * w[None, :])
            coef = phi[resp] * np.where(ground, -gamma[None, :], phi[exc])
            out.append((np.abs(coef @ poles) * scale).ravel())
        return np.concatenate(out)

    def residuals_theta(self, theta):
        mag = self.magnitudes(theta)
        a = np.log(mag) if self.log else mag
        return self.weights * (a - self.target)

    def __call__(self, z):
        return self.residuals_theta(self.theta(z))


def frfbayes_binary(args, work_dir):
    """The binary to time: --frfbayes, or a fresh release build copied into work_dir
    (a shared CARGO_TARGET_DIR may be rebuilt from another branch at any time)."""
    if args.frfbayes:
        return Path(args.frfbayes)
    print("building frfbayes (cargo build --release) ...", file=sys.stderr)
    subprocess.run(["cargo", "build", "--release", "--bin", "frfbayes"], cwd=REPO, check=True)
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    copy = work_dir / "frfbayes"
    shutil.copy2(target / "release" / "frfbayes", copy)
    return copy


def run_rust(binary, args, out, threads=None):
    env = dict(os.environ)
    if threads is not None:
        env["RAYON_NUM_THREADS"] = str(threads)
    cmd = [
        str(binary), "multistart", "--problems", str(args.problems),
        "--starts", str(args.starts), "--seed", str(args.seed), "--out", str(out),
    ]
    print("$", " ".join(cmd), f"(RAYON_NUM_THREADS={threads})" if threads else "", file=sys.stderr)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(cmd, env=env, check=True, stdout=sys.stderr)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    report = json.loads(out.read_text())
    # CPU seconds of the whole command (reading the problems and writing the start
    # files included, a few ms): less sensitive than wall time to other load.
    report["cpu_s"] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return report, cmd


def scipy_multistart(obj, starts, jac, x_scale):
    trf = starts["trf"]
    lower, upper = np.array(starts["lower_z"]), np.array(starts["upper_z"])
    costs, nfev, njev, status = [], 0, 0, []
    best = None
    t0, c0 = time.perf_counter(), time.process_time()
    for z0 in starts["starts_z"]:
        res = least_squares(
            obj, np.array(z0), jac=jac, bounds=(lower, upper), method="trf",
            ftol=trf["ftol"], xtol=trf["xtol"], gtol=trf["gtol"],
            max_nfev=trf["max_evaluations"], x_scale=x_scale,
        )
        costs.append(float(res.cost))
        nfev += int(res.nfev)
        njev += int(res.njev or 0)
        status.append(int(res.status))
        if best is None or res.cost < best.cost:
            best = res
    wall_s, cpu_s = time.perf_counter() - t0, time.process_time() - c0
    threshold = best.cost * (1 + AT_BEST_RTOL) + AT_BEST_ATOL
    return {
        "wall_s": wall_s,
        "cpu_s": cpu_s,
        "best_cost": float(best.cost),
        "theta": obj.theta(best.x).tolist(),
        "n_at_best": int(sum(c <= threshold for c in costs)),
        "nfev": nfev,
        "njev": njev,
        "n_budget_exhausted": status.count(0),
    }


def check_objective(obj, starts):
    """Largest |r_numpy - r_rust| / max |r_rust| over the exported check points."""
    worst = 0.0
    for chk in starts["checks"]:
        r_rust = np.array(chk["residuals"])
        r_py = obj.residuals_theta(np.array(chk["theta"]))
        worst = max(worst, float(np.max(np.abs(r_py - r_rust)) / np.max(np.abs(r_rust))))
    return worst


def machine_info(rust_version):
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        rustc = subprocess.run(["rustc", "--version"], capture_output=True, text=True).stdout.strip()
    except OSError:
        rustc = "unknown"
    return {
        "cpu": cpu,
        "logical_cores": os.cpu_count(),
        "load_average_1_5_15": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
        "platform": platform.platform(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "rustc": rustc,
        "frfbayes": rust_version,
        "blas_threads_env": {
            k: os.environ[k] for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
            if k in os.environ
        },
    }


def markdown(report):
    m, t = report["machine"], report["totals"]
    lines = [
        "# Multistart speed: frfbayes against scipy least_squares",
        "",
        f"{report['n_problems']} problems, {report['n_starts']} starts each (seed "
        f"{report['seed']}), the same objective, box and start points on both sides. "
        f"scipy: `least_squares(method=\"trf\", jac=\"{report['scipy_jac']}\", "
        f"x_scale={report['scipy_x_scale']!r})`, default tolerances, one process. "
        f"frfbayes: analytical Jacobian, {report['rust_threads']} threads, and again on 1 thread.",
        "",
        "| problem | points | free | frfbayes s | frfbayes 1-thread s | scipy s | ratio | "
        "ratio 1-thread | best cost frfbayes | best cost scipy | rel. diff | at best (rs/py) | objective check |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|",
    ]
    for p in report["problems"]:
        one = p.get("rust_1thread_wall_s")
        lines.append(
            f"| {p['name']} | {p['n_residuals']} | {p['n_free']} | {p['rust_wall_s']:.3f} | "
            + (f"{one:.3f}" if one is not None else "-")
            + f" | {p['scipy_wall_s']:.2f} | {p['ratio']:.1f} | "
            + (f"{p['ratio_1thread']:.1f}" if one is not None else "-")
            + f" | {p['rust_best_cost']:.6e} | {p['scipy_best_cost']:.6e} | "
            f"{p['cost_rel_diff']:.1e} | {p['rust_n_at_best']}/{p['scipy_n_at_best']} | "
            f"{p['objective_check_rel']:.1e} |"
        )
    one = t.get("rust_1thread_s")
    lines += [
        "",
        f"**Total**: frfbayes {t['rust_s']:.2f} s ({report['rust_threads']} threads)"
        + (f", {one:.2f} s on 1 thread" if one is not None else "")
        + f"; scipy {t['scipy_s']:.1f} s. **Speed ratio {t['ratio']:.1f}x**"
        + (
            f" ({t['ratio_1thread']:.1f}x per core; CPU time {t['scipy_cpu_s']:.1f} s against "
            f"{t['rust_1thread_cpu_s']:.2f} s, {t['ratio_cpu']:.1f}x)"
            if one is not None
            else ""
        )
        + f"; goal >= 30x: {'met' if t['ratio'] >= 30 else 'NOT met'}.",
        "",
        f"Best costs agree within {report['cost_rtol']:g} (relative) on "
        f"{sum(p['costs_agree'] for p in report['problems'])} of {report['n_problems']} problems.",
        "",
        "Machine: " + ", ".join(
            f"{k} {v}" for k, v in m.items()
        ) + ".",
        "Times are wall clock of the solves only (problem loading excluded); the machine "
        "may be shared, see the load average.",
        "",
        "Commands: `" + " ".join(report["rust_command"]) + "`; `" + report["command"] + "`.",
        "",
    ]
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--problems", type=Path, required=True, help="folder of ProblemSpec *.json")
    ap.add_argument("--starts", type=int, default=64)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--report", type=Path, required=True, help="output stem: <stem>.md, <stem>.json")
    ap.add_argument("--frfbayes", help="path of the frfbayes binary (default: cargo build --release)")
    ap.add_argument("--jac", default="2-point", choices=["2-point", "3-point"])
    ap.add_argument(
        "--x-scale", default="match", choices=["match", "jac", "unit"],
        help="scipy x_scale: the Rust solver's setting (default), 'jac' or 1.0",
    )
    ap.add_argument("--no-single-thread", action="store_true", help="skip the 1-thread Rust run")
    ap.add_argument("--cost-rtol", type=float, default=1e-4)
    args = ap.parse_args()
    args.problems = args.problems.resolve()

    rust_dir = args.report.parent / f"{args.report.name}_rust"
    rust_dir.mkdir(parents=True, exist_ok=True)
    binary = frfbayes_binary(args, rust_dir)
    rust, rust_cmd = run_rust(binary, args, rust_dir / "rust.json")
    rust_1 = None
    if not args.no_single_thread:
        rust_1, _ = run_rust(binary, args, rust_dir / "rust-1thread.json", threads=1)

    problems, all_agree = [], True
    for i, rp in enumerate(rust["problems"]):
        spec = json.loads(Path(rp["file"]).read_text())
        starts = json.loads(Path(rp["starts_file"]).read_text())
        obj = Objective(spec, starts)
        check = check_objective(obj, starts)
        if check > RESIDUAL_RTOL:
            sys.exit(
                f"{rp['name']}: the numpy objective differs from frfbayes' by {check:.2e} "
                f"(relative), more than {RESIDUAL_RTOL:g}: not the same objective"
            )
        if args.x_scale == "match":
            x_scale = "jac" if starts["trf"]["x_scale"] == "jacobian" else 1.0
        else:
            x_scale = "jac" if args.x_scale == "jac" else 1.0
        print(f"scipy: {rp['name']} ({len(starts['starts_z'])} starts) ...", file=sys.stderr)
        sp = scipy_multistart(obj, starts, args.jac, x_scale)
        rel = abs(sp["best_cost"] - rp["best_cost"]) / max(sp["best_cost"], rp["best_cost"])
        agree = rel <= args.cost_rtol
        all_agree &= agree
        entry = {
            "name": rp["name"],
            "n_residuals": rp["n_residuals"],
            "n_free": rp["n_free"],
            "objective_check_rel": check,
            "rust_wall_s": rp["wall_s"],
            "scipy_wall_s": sp["wall_s"],
            "scipy_cpu_s": sp["cpu_s"],
            "ratio": sp["wall_s"] / rp["wall_s"],
            "rust_best_cost": rp["best_cost"],
            "scipy_best_cost": sp["best_cost"],
            "cost_rel_diff": rel,
            "costs_agree": agree,
            "rust_n_at_best": rp["n_at_best"],
            "scipy_n_at_best": sp["n_at_best"],
            "rust_theta": rp["theta"],
            "scipy_theta": sp["theta"],
            "names": rp["names"],
            "rust_evaluations": rp["n_evaluations"],
            "rust_jacobians": rp["n_jacobians"],
            "scipy_nfev": sp["nfev"],
            "scipy_njev": sp["njev"],
            "scipy_budget_exhausted": sp["n_budget_exhausted"],
            "scipy_x_scale": x_scale,
        }
        if rust_1 is not None:
            r1 = rust_1["problems"][i]
            entry["rust_1thread_wall_s"] = r1["wall_s"]
            entry["ratio_1thread"] = sp["wall_s"] / r1["wall_s"]
        problems.append(entry)
        print(
            f"  scipy {sp['wall_s']:.2f} s vs frfbayes {rp['wall_s']:.3f} s "
            f"(x{entry['ratio']:.1f}); best cost {sp['best_cost']:.6e} vs "
            f"{rp['best_cost']:.6e} ({'agree' if agree else 'DIFFER'})",
            file=sys.stderr,
        )

    totals = {
        "rust_s": rust["total_solve_s"],
        "scipy_s": sum(p["scipy_wall_s"] for p in problems),
    }
    totals["ratio"] = totals["scipy_s"] / totals["rust_s"]
    totals["scipy_cpu_s"] = sum(p["scipy_cpu_s"] for p in problems)
    if rust_1 is not None:
        totals["rust_1thread_s"] = rust_1["total_solve_s"]
        totals["ratio_1thread"] = totals["scipy_s"] / totals["rust_1thread_s"]
        totals["rust_1thread_cpu_s"] = rust_1["cpu_s"]
        totals["ratio_cpu"] = totals["scipy_cpu_s"] / rust_1["cpu_s"]
    report = {
        "command": " ".join([Path(sys.argv[0]).name, *sys.argv[1:]]),
        "rust_command": rust_cmd,
        "n_problems": len(problems),
        "n_starts": args.starts,
        "seed": args.seed,
        "scipy_jac": args.jac,
        "scipy_x_scale": problems[0]["scipy_x_scale"],
        "rust_threads": rust["threads"],
        "cost_rtol": args.cost_rtol,
        "totals": totals,
        "problems": problems,
        "machine": machine_info(rust["version"]),
    }
    args.report.parent.mkdir(parents=True, exist_ok=True)
    Path(f"{args.report}.json").write_text(json.dumps(report, indent=2))
    Path(f"{args.report}.md").write_text(markdown(report))
    print(markdown(report))
    if not all_agree:
        sys.exit("best costs differ beyond --cost-rtol on some problems (see the report)")


if __name__ == "__main__":
    main()
