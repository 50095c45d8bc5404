"""The report's collapse over the model's uncertainty: where link 3 ends, and what decides it.

Run: ``python benchmarks/uncertain_collapse.py [N] [SEED]`` (default 128 arms, seed 1; about
20 s on 2 cores). The collapse (sims/collapse.toml: zero torque from the drive pose, the
report's joint-clamp law, 5 s) on N arms drawn within the parameter table's tolerances
(``packbot.uncertain_run``). Prints:

- the quantiles of the final angles and of link 3's end (frame ``gripper_link``), and the nominal
  arm's;
- the share of arms that end as the report's arm does, link 3 propped upright on the shoulder
  casing (link 3's end above :data:`PROPPED_Z`), with its 95 % Wilson interval, and how many of
  the others came to rest;
- the parameters whose drawn values differ most between the propped arms and the others
  (Spearman rho with the propped flag; the Mann-Whitney p-value);
- one parameter at a time (``vary=[name]``, 32 arms, the others nominal): how many arms stay
  propped, and the drawn values of those that do not.

docs/study.md ("A run over the model's uncertainty") quotes one run. The counts are the same on
any machine for the same seed unless an arm lies on the edge between the two outcomes.
"""

from __future__ import annotations

import logging
import sys

import numpy as np
from scipy.stats import mannwhitneyu, spearmanr

from packbot.params import TABLE
from packbot.uncertain_run import LINK3_END, uncertain_run
from packbot.uncertain_study import wilson_interval

log = logging.getLogger("uncertain_collapse")

SCENARIO = "collapse"
#: Link 3's end above this height is propped upright (the nominal arm's: 0.82 m) [m].
PROPPED_Z = 0.7
#: The parameters tried one at a time: the top of the ranking.
ONE_AT_A_TIME = 8


def main(argv: list[str]) -> None:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    logging.getLogger("packbot").setLevel(logging.ERROR)  # the joint-clamp law's energy notes
    n = int(argv[0]) if argv else 128
    seed = int(argv[1]) if len(argv) > 1 else 1
    from packbot.scenario import load_scenario, run_scenario

    nominal = run_scenario(load_scenario(SCENARIO))
    end = nominal.frame_positions(LINK3_END)[-1]
    unc = uncertain_run(SCENARIO, samples=n, seed=seed)
    log.info("%s", unc.text())
    log.info(
        "nominal arm: link 3 ends at (%.1f, %.1f, %.1f) mm, elbow2 %.3f rad, at rest from %.3f s",
        *(1000 * end),
        nominal.q[-1, nominal.joint("elbow2")],
        nominal.rest_time,
    )
    z = unc.link3_end()[:, 2]
    up = z > PROPPED_Z
    rest = ~np.isnan(unc.rest_times())
    k = int(up.sum())
    lo, hi = wilson_interval(k, n)
    log.info("")
    log.info(
        "propped upright (link 3's end above %.2f m): %d of %d arms, p = %.2f (95 %% Wilson "
        "interval %.2f .. %.2f); at rest at the end: %d of the propped, %d of the %d others",
        PROPPED_Z,
        k,
        n,
        k / n,
        lo,
        hi,
        int(rest[up].sum()),
        int(rest[~up].sum()),
        n - k,
    )
    for joint in ("turret", "shoulder", "elbow2"):
        a = unc.final_angles(joint)
        log.info(
            "  final %s [rad]: propped %s, others %s",
            joint,
            np.round(np.percentile(a[up], [5, 50, 95]), 3),
            np.round(np.percentile(a[~up], [5, 50, 95]), 3) if (~up).any() else "-",
        )
    rows = []
    for j, name in enumerate(unc.sample.names):
        x = unc.sample.values[:, j]
        rho = float(spearmanr(x, up.astype(float)).statistic)
        p = float(mannwhitneyu(x[up], x[~up]).pvalue) if 0 < k < n else float("nan")
        rows.append((abs(rho), rho, p, name))
    rows.sort(reverse=True)
    log.info("")
    log.info("| parameter | nominal +- tolerance (basis) | Spearman rho with propped | p |")
    log.info("|---|---|---|---|")
    for _, rho, p, name in rows[:ONE_AT_A_TIME]:
        t = TABLE[name].tolerance
        assert t is not None
        log.info(
            "| `%s` | %.4g +- %.3g %s (%s) | %+.2f | %.1e |",
            name,
            TABLE[name].value,
            t.plus_minus,
            TABLE[name].unit,
            t.basis,
            rho,
            p,
        )
    log.info("")
    log.info("| varied alone (32 arms) | propped | the others' drawn values |")
    log.info("|---|---|---|")
    for _, _, _, name in rows[:ONE_AT_A_TIME]:
        one = uncertain_run(SCENARIO, samples=32, seed=seed, vary=[name])
        z1 = one.link3_end()[:, 2]
        up1 = z1 > PROPPED_Z
        x = one.sample.values[:, 0]
        others = ", ".join(f"{v:.4g}" for v in np.sort(x[~up1])) or "-"
        log.info("| `%s` | %d of 32 | %s |", name, int(up1.sum()), others)


if __name__ == "__main__":
    main(sys.argv[1:])
