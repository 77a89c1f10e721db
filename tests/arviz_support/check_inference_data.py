"""Opens a run's inference_data.nc with one ArviZ call and checks it against posterior.json.

Usage: check_inference_data.py RUN_DIR [NC_FILE]

NC_FILE defaults to inference_data.nc. For a `frfbayes real` study's folder the
`log_likelihood` group holds one term per likelihood block (`block`) and `observed_data`
the blocks' data along `value` with a `block` coordinate: the script checks that every
block of the one has data in the other.

- `az.from_netcdf(RUN_DIR / "inference_data.nc")` is the one call; the groups posterior,
  sample_stats, log_likelihood and observed_data must be there, the posterior's variables
  must be posterior.json's parameters (some of them for a `real` study's file, which
  names its study in the attribute `frfbayes_study`), and their means posterior.json's
  means.
- ArviZ's rank-normalised R-hat and bulk/tail ESS must match ours within their Monte Carlo
  error (tolerances below), and `az.loo` must run and give a finite elpd. Our R-hat
  treats each ensemble as a chain, our ESS each walker (src/mcmc/convergence.rs), so:
  `az.rhat(idata)` on the file's chains (= ensembles) against our R-hat, and `az.ess` on
  the walker chains (from the file's `walker` and `walker_draw` coordinates) against our
  ESS.
- Printed for comparison, not checked: `az.ess` on the file's ensemble chains and
  `az.rhat` on walker chains (emcee's mapping, `az.from_emcee`).

Prints one JSON object with the figures (the Rust test shows it); exits non-zero with a
message on the first failed check.

Tolerances (derived, not tuned):
- R-hat. With M split chains of N_c effective draws each, the chain means scatter with
  variance sigma^2 / N_c, so B/W ~ chi2(M - 1)/(M - 1) / N_c and R-hat^2 - 1 has a
  standard deviation sqrt(2 / (M - 1)) / N_c; R-hat's is half that:
  sd(R-hat) = M sqrt(2 / (M - 1)) / (2 ESS_bulk), with N_c = ESS_bulk / M and M = 2 x
  ensembles. We require |ArviZ - ours| < 1 sd.
- ESS. ESS = N / tau with N the total draws; the integrated autocorrelation time estimated
  with a window of W lags has relative variance 2 (2 W + 1) / N (Madras & Sokal 1988,
  Sokal 1997, Eq. 3.19). With Sokal's window W = 5 tau (tau = N / ESS, in draws), the
  relative Monte Carlo sd of an ESS estimate is sqrt(2 (10 tau + 1) / N). We require
  |ArviZ / ours - 1| < 1 sd for bulk and tail ESS.
"""

import json
import math
import sys
from pathlib import Path

import arviz as az
import numpy as np


def fail(msg):
    print(f"FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


def scalar(ds, name):
    return float(np.asarray(ds[name]).reshape(-1)[0])


def walker_chains(idata, name):
    """(ensembles x walkers, walker draws): ArviZ chains = walkers, as az.from_emcee."""
    post = idata.posterior
    w = np.asarray(post["walker"])
    t = np.asarray(post["walker_draw"])
    x = np.asarray(post[name])
    n_w, n_t = int(w.max()) + 1, int(t.max()) + 1
    out = np.empty((x.shape[0], n_w, n_t))
    out[:, w, t] = x
    return out.reshape(x.shape[0] * n_w, n_t)


def check_blocks(idata):
    """A `real` study's file: every log-likelihood block has data, every datum a block."""
    obs = idata.observed_data
    if "block" not in obs.coords and "block" not in obs:
        return None
    n_block = idata.log_likelihood.sizes["block"]
    blocks = np.unique(np.asarray(obs["block"]))
    if list(blocks) != list(range(n_block)):
        fail(f"observed_data blocks {blocks} != the {n_block} log-likelihood blocks")
    names = obs["observations"].attrs["block_names"].split(", ")
    if len(names) != n_block:
        fail(f"{len(names)} block names for {n_block} blocks")
    return {"blocks": n_block, "block_names": names, "values": obs.sizes["value"]}


def main(run_dir, nc_name="inference_data.nc"):
    idata = az.from_netcdf(run_dir / nc_name)  # the one call
    ours = json.loads((run_dir / "posterior.json").read_text())
    for g in ["posterior", "sample_stats", "log_likelihood", "observed_data"]:
        if g not in idata.groups():
            fail(f"group {g} missing: {idata.groups()}")
    for v in ["lp", "acceptance_rate"]:
        if v not in idata.sample_stats:
            fail(f"sample_stats has no {v}")
    names = [p["name"] for p in ours["parameters"]]
    # HDF5 lists a group's members by name (the file keeps no creation order). A `real`
    # study may leave out quantities that are no function of a draw (tower-hmd's gains,
    # drawn conditionally): its variables must be some of posterior.json's.
    study = idata.posterior.attrs.get("frfbayes_study")
    file_vars = sorted(idata.posterior.data_vars)
    if study is not None:
        if not file_vars or not set(file_vars) <= set(names):
            fail(f"posterior variables {file_vars} are not among {names}")
    elif file_vars != sorted(names):
        fail(f"posterior variables {list(idata.posterior.data_vars)} != {names}")
    n_chain = idata.posterior.sizes["chain"]
    if n_chain != ours["n_ensembles"]:
        fail(f"{n_chain} chains for {ours['n_ensembles']} ensembles")

    # R-hat: ArviZ chains = ensembles, as the file is laid out (ours pools each ensemble's
    # walkers, split in time). ESS: ArviZ chains = walkers, as ours (the file's walker and
    # walker_draw coordinates give that view); ArviZ's ESS of the file's ensemble chains
    # is reported beside it.
    rhat = az.rhat(idata)
    n_total = idata.posterior.sizes["chain"] * idata.posterior.sizes["draw"]
    m_split = 2 * n_chain
    rows = []
    for p in ours["parameters"]:
        name = p["name"]
        if name not in idata.posterior:
            continue
        mean = float(idata.posterior[name].mean())
        if not math.isclose(mean, p["mean"], rel_tol=1e-9, abs_tol=1e-300):
            fail(f"{name}: mean {mean} != posterior.json {p['mean']}")
        walkers = walker_chains(idata, name)
        row = {
            "name": name,
            "rhat": [p["rhat"], scalar(rhat, name)],
            "ess_bulk": [p["ess_bulk"], float(az.ess(walkers, method="bulk"))],
            "ess_tail": [p["ess_tail"], float(az.ess(walkers, method="tail"))],
        }
        sd_rhat = m_split * math.sqrt(2.0 / (m_split - 1)) / (2.0 * p["ess_bulk"])
        if abs(row["rhat"][1] - row["rhat"][0]) > sd_rhat:
            fail(f"{name}: R-hat ArviZ {row['rhat'][1]} vs ours {row['rhat'][0]} (sd {sd_rhat:.2e})")
        row["rhat_sd"] = sd_rhat
        for key in ["ess_bulk", "ess_tail"]:
            tau = n_total / row[key][0]
            rel_sd = math.sqrt(2.0 * (10.0 * tau + 1.0) / n_total)
            rel = row[key][1] / row[key][0] - 1.0
            if abs(rel) > rel_sd:
                fail(f"{name}: {key} ArviZ {row[key][1]:.1f} vs ours {row[key][0]:.1f} "
                     f"({rel:+.2%}, sd {rel_sd:.2%})")
            row[f"{key}_rel_diff"] = rel
            row[f"{key}_rel_sd"] = rel_sd
        x = np.asarray(idata.posterior[name])
        row["ensemble_chains"] = {
            "ess_bulk": float(az.ess(x, method="bulk")),
            "ess_tail": float(az.ess(x, method="tail")),
        }
        row["walker_chains_rhat"] = float(az.rhat(walkers))
        rows.append(row)

    loo = az.loo(idata)
    elpd = float(loo["elpd_loo"])
    if not math.isfinite(elpd):
        fail(f"az.loo gave elpd {elpd}")
    k = np.asarray(loo.pareto_k)
    blocks = check_blocks(idata)
    print(json.dumps({
        "file": nc_name,
        "blocks": blocks,
        "arviz": az.__version__,
        "groups": list(idata.groups()),
        "chains": n_chain,
        "draws": idata.posterior.sizes["draw"],
        "log_likelihood_draws": idata.log_likelihood.sizes["draw"],
        "points": idata.observed_data.sizes[list(idata.observed_data.sizes)[0]],
        "loo": {"elpd_loo": elpd, "p_loo": float(loo["p_loo"]), "se": float(loo["se"]),
                "pareto_k_max": float(k.max()), "pareto_k_gt_0.7": int((k > 0.7).sum())},
        "parameters": rows,
    }, indent=1))


if __name__ == "__main__":
    main(Path(sys.argv[1]), *sys.argv[2:3])
