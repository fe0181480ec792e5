"""The paper check: paper-9pos with Table 2's values, navigation profile, our errors next to the paper's.

    python benchmarks/paper_check.py [--seed 7]

Prints a Markdown table: the paper's Table 2 error, our error on one
simulated run (setup (1, -2, 3) deg, lat 40 deg), our reported sigma, the
requirement, and whether 3 sigma meets it.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

import calib  # noqa: F401  (BLAS threads)
from calib.fit.estimator import fit_run
from calib.model import params as P
from calib.model.error_model import ErrorModel, paper_table
from calib.nav.site import Site
from calib.noise.profiles import load_profile
from calib.sequence.definition import load_sequence
from calib.sequence.kinematics import SimConfig
from calib.sim.gimbal_run import SimOptions, simulate


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seed", type=int, default=7)
    args = ap.parse_args()
    seq, prof = load_sequence("paper-9pos"), load_profile("navigation")
    lat = math.radians(40.0)
    cfg = SimConfig(latitude_rad=lat)
    truth = ErrorModel.from_table2()
    run, _ = simulate(
        seq, cfg, truth, prof, options=SimOptions(setup_rotvec=np.radians([1.0, -2.0, 3.0]), seed=args.seed)
    )
    fit = fit_run(run, Site(lat, cfg.gravity), prof)
    err = P.from_si(fit.values - truth.values)
    sig = P.from_si(fit.sigma)
    paper_err = paper_table("table2_simulation", "paper_error")
    print(
        f"paper-9pos, Table 2 values, navigation profile, setup (1, -2, 3) deg, latitude 40 deg, "
        f"seed {args.seed}: converged {fit.converged} in {fit.iterations} iterations, "
        f"chi2/dof {fit.chi2_per_dof:.3f}"
    )
    print()
    print(
        "| param | unit | paper's error (Table 2) | our error | our sigma | requirement | 3 sigma meets it |"
    )
    print("|---|---|---|---|---|---|---|")
    for p in P.PARAMETERS:
        i = p.index
        ok = "yes" if 3 * sig[i] <= p.requirement else "**no**"
        print(
            f"| {p.name} | {p.unit} | {paper_err[i]:+.4g} | {err[i]:+.4g} | {sig[i]:.3g} | "
            f"{p.requirement:g} | {ok} |"
        )


if __name__ == "__main__":
    main()
