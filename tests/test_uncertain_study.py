"""The failure study over the model's uncertainty (packbot.uncertain_study, --uncertain N).

One short study (reconfig_elbow1 cut to DURATION s) on a few arms; its numbers are checked by
order and by tolerance, never by bit pattern.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import packbot
from packbot.cli import main
from packbot.errors import ConfigurationError, PackbotError, UnknownNameError
from packbot.study import RUN_NAMES
from packbot.uncertain_batch import run_uncertain_study
from packbot.uncertain_study import (
    METRICS,
    TRACE_POINTS,
    ArmStudy,
    UncertainStudy,
    percentiles,
    uncertain_study,
    wilson_interval,
)
from packbot.uncertainty import sample_values

SCENARIO = "reconfig_elbow1"
#: Simulated time of each run [s]: the failure (1 s) and the reconfiguration after it.
DURATION = 1.3
ARMS = 8
FAST = {"duration": DURATION, "workspace_samples": 300}


@pytest.fixture(scope="module")
def unc() -> UncertainStudy:
    return uncertain_study(SCENARIO, samples=ARMS, seed=3, **FAST)


@pytest.fixture(scope="module")
def again() -> UncertainStudy:
    return uncertain_study(SCENARIO, samples=ARMS, seed=3, **FAST)


def test_every_arm_is_studied_and_counted(unc: UncertainStudy) -> None:
    assert len(unc) == ARMS
    c = unc.counts
    assert c["arms"] == ARMS
    assert c["ok"] + max(c[f"{r}_not_ok"] for r in RUN_NAMES) >= 1
    for arm in unc.arms:
        assert set(arm.status) == set(RUN_NAMES)
        for run in RUN_NAMES:
            assert (arm.metrics[run] is None) == (arm.status[run] != "ok")


def test_quantiles_are_ordered_and_spread(unc: UncertainStudy) -> None:
    for run in RUN_NAMES:
        for metric in ("final_task_error_m", "peak_torque_ratio", "rms_task_error_m"):
            q = unc.quantiles(run, metric)
            assert list(q) == [5, 50, 95]
            assert q[5] <= q[50] <= q[95], (run, metric, q)
    for run in ("failed", "reconfigured"):
        q = unc.quantiles(run, "final_task_error_m")
        assert q[95] - q[5] > 1e-6, q  # the arms differ: so do their errors [m]
        assert q[5] >= 0
    # the healthy run is its own task: no error on any arm
    assert unc.quantiles("healthy", "final_task_error_m")[95] < 1e-9


def test_the_same_seed_gives_the_same_numbers(unc: UncertainStudy, again: UncertainStudy) -> None:
    np.testing.assert_array_equal(unc.sample.values, again.sample.values)
    for run in RUN_NAMES:
        for metric in ("final_task_error_m", "peak_torque_ratio"):
            a, b = unc.quantiles(run, metric), again.quantiles(run, metric)
            for p in a:
                assert a[p] == pytest.approx(b[p], rel=1e-9, abs=1e-12)
    assert unc.recovery_probability == again.recovery_probability
    assert [n for n, _ in unc.sensitivity("failed", "final_task_error_m")] == [
        n for n, _ in again.sensitivity("failed", "final_task_error_m")
    ]


@pytest.fixture(scope="module")
def other() -> UncertainStudy:
    return uncertain_study(SCENARIO, samples=2, seed=4, **FAST)


def test_another_seed_gives_other_numbers(unc: UncertainStudy, other: UncertainStudy) -> None:
    assert np.max(np.abs(other.sample.values - sample_values(2, 3).values)) > 0
    a = unc.values("failed", "final_task_error_m")[:2]  # seed 3's first two arms
    b = other.values("failed", "final_task_error_m")
    assert np.max(np.abs(a - b)) > 1e-6  # [m]


def test_a_local_pool_gives_the_numbers_of_this_process(other: UncertainStudy, tmp_path) -> None:
    pooled = run_uncertain_study(SCENARIO, tmp_path / "p", samples=2, seed=4, workers=2, **FAST)
    assert pooled.result.workers == "2 local processes"
    assert {r.worker.split(":")[0] for r in pooled.batch.records.values()} == {"local"}
    assert pooled.result.counts == other.counts
    for run in RUN_NAMES:
        a = pooled.result.values(run, "final_task_error_m")
        b = other.values(run, "final_task_error_m")
        # the same code on another process: only a BLAS thread count's rounding differs
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)


def test_each_arm_keeps_its_task_error_and_the_band_holds_it(unc: UncertainStudy) -> None:
    t = unc.trace_time
    assert t[0] == 0.0 and t[-1] == pytest.approx(DURATION) and len(t) == TRACE_POINTS
    for run in RUN_NAMES:
        band = unc.task_error_band(run)
        finite = np.isfinite(band[50])
        assert finite.sum() > 0.9 * TRACE_POINTS
        assert np.all(band[5][finite] <= band[50][finite] + 1e-15)
        assert np.all(band[50][finite] <= band[95][finite] + 1e-15)
    # the failed run's error grows after the failure (1 s); before it, the three runs agree
    before = unc.trace_time < 0.9
    failed, healthy = unc.task_error_band("failed"), unc.task_error_band("healthy")
    assert np.nanmax(failed[95][before]) < 1e-6  # [m]: the same commanded motion
    assert failed[50][-1] > 10 * max(healthy[50][-1], 1e-6)
    # the band's last point is the arms' final error, up to the grid's interpolation
    finals = unc.quantiles("failed", "final_task_error_m")
    assert failed[50][-1] == pytest.approx(finals[50], rel=1e-6)
    # an arm round-trips through its file exactly
    for arm in unc.arms:
        assert ArmStudy.from_dict(json.loads(json.dumps(arm.to_dict()))) == arm


def test_percentiles() -> None:
    p = percentiles([1.0, 2.0, float("nan"), 3.0, float("inf")])
    assert p == {5: pytest.approx(1.1), 50: 2.0, 95: pytest.approx(2.9)}
    grid = percentiles([[1.0, np.nan], [3.0, np.nan]])
    assert grid[50][0] == 2.0 and np.isnan(grid[50][1])
    with pytest.raises(ConfigurationError, match="values"):
        percentiles(np.zeros((2, 2, 2)))


def test_recovery_probability_and_its_interval(unc: UncertainStudy) -> None:
    p = unc.recovery_probability
    lo, hi = unc.recovery_interval
    assert 0.0 <= p <= 1.0
    assert 0.0 <= lo <= p <= hi <= 1.0
    assert unc.recovery_trials + unc.counts["reconfigured_not_ok"] == ARMS
    assert unc.recovery_successes == sum(a.recovered is True for a in unc.arms)


def test_wilson_interval() -> None:
    # the textbook case: 8 of 10 -> (0.490, 0.943)
    lo, hi = wilson_interval(8, 10)
    assert lo == pytest.approx(0.4902, abs=1e-4) and hi == pytest.approx(0.9433, abs=1e-4)
    lo, hi = wilson_interval(4, 4)
    assert hi == 1.0 and 0.4 < lo < 0.6
    lo, hi = wilson_interval(0, 4)
    assert lo == 0.0 and 0.4 < hi < 0.6
    with pytest.raises(ConfigurationError, match="successes"):
        wilson_interval(5, 4)


def test_sensitivity_ranks_the_sampled_parameters(unc: UncertainStudy) -> None:
    ranked = unc.sensitivity("failed", "final_task_error_m")
    names = [n for n, _ in ranked]
    assert sorted(names) == sorted(unc.sample.names)
    assert set(names) <= set(packbot.params.toleranced())
    rhos = [abs(r) for _, r in ranked if not math.isnan(r)]
    assert rhos, "no parameter correlates: the metric is constant?"
    assert rhos == sorted(rhos, reverse=True)
    assert all(r <= 1.0 + 1e-12 for r in rhos)
    # NaN (undefined) ranks last
    flags = [math.isnan(r) for _, r in ranked]
    assert flags == sorted(flags)


def test_summary_is_json(unc: UncertainStudy) -> None:
    s = unc.summary()
    text = json.dumps(s, allow_nan=False)
    back = json.loads(text)
    assert back["sample"]["arms"] == ARMS and back["sample"]["seed"] == 3
    q = back["quantiles"]["failed"]["final_task_error_m"]
    assert q["5"] <= q["50"] <= q["95"]
    assert back["recovery"]["interval_method"] == "Wilson score"
    top = back["sensitivity"]["top"]["failed"]["final_task_error_m"]
    assert 1 <= len(top) <= 10 and top[0]["parameter"] in unc.sample.names
    assert len(back["arms"]) == ARMS
    assert len(back["task_error_band"]["t_s"]) == TRACE_POINTS
    assert len(back["task_error_band"]["failed"]["95"]) == TRACE_POINTS
    assert len(back["final_task_error_m"]["reconfigured"]) == ARMS
    assert back["failure_time_s"] == 1.0
    assert "uncertain study" in unc.text()


def test_report_figures_and_page(unc: UncertainStudy, tmp_path) -> None:
    from packbot.viz.uncertain_report import STUDY_FIGURES, write_uncertain_report

    summary = unc.summary()
    summary["scenario"] = "<b>reconfig</b>"  # a page escapes what it shows
    files = write_uncertain_report(summary, tmp_path)
    for stem in STUDY_FIGURES:
        assert files[f"{stem}.png"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert files[f"{stem}.svg"].stat().st_size > 1000
    page = files["report.html"].read_text()
    assert "<b>reconfig</b>" not in page and "&lt;b&gt;reconfig&lt;/b&gt;" in page
    assert page.count("data:image/png;base64,") == len(STUDY_FIGURES)
    back = json.loads(files["uncertain.json"].read_text())
    assert back["figures"] == sorted(n for n in files if n.endswith((".png", ".svg")))
    with pytest.raises(ConfigurationError, match="summary"):
        write_uncertain_report({"scenario": "x"}, tmp_path)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"samples": 1}, "samples"),
        ({"samples": 2.5}, "samples"),
        ({"seed": -1}, "seed"),
        ({"seed": "x"}, "seed"),
        ({"method": "grid"}, "method"),
        ({"duration": -1.0}, "duration"),
    ],
)
def test_bad_arguments_are_refused(kwargs: dict, field: str) -> None:
    with pytest.raises(PackbotError, match=field):
        uncertain_study(SCENARIO, **({"samples": 2} | kwargs))


def test_unknown_run_or_metric_names(unc: UncertainStudy) -> None:
    with pytest.raises(UnknownNameError, match="healthy") as exc:
        unc.quantiles("broken", "final_task_error_m")
    assert exc.value.name == "broken"
    with pytest.raises(UnknownNameError, match="final_task_error_m") as exc:
        unc.sensitivity("failed", "final_error")
    assert exc.value.name == "final_error" and "final_task_error_m" in exc.value.valid
    assert "wall_time_s" not in METRICS and "final_task_error_m" in METRICS


def test_cli_writes_uncertain_json_and_resumes(tmp_path, capsys) -> None:
    out = tmp_path / "u"
    argv = ["study", SCENARIO, "--uncertain", "2", "--seed", "5", "--duration", "1.1"]
    argv += ["--out", str(out), "--workers", "0", "--no-progress"]
    assert main(argv) == 0
    data = json.loads((out / "uncertain.json").read_text())
    assert data["sample"] == data["sample"] | {"arms": 2, "seed": 5}
    assert "recovery" in data and "quantiles" in data
    printed = capsys.readouterr().out
    assert "uncertain study" in printed and "uncertain.json" in printed
    assert (out / "report.html").is_file() and (out / "arm_0001" / "arm.json").is_file()
    assert main(argv) == 0  # again: both arms read back, none studied
    assert "2 finished before" in capsys.readouterr().out
    assert json.loads((out / "uncertain.json").read_text())["batch"]["skipped"] == 2


@pytest.mark.parametrize(
    ("argv", "word"),
    [
        (["--uncertain", "1"], "samples"),
        (["--uncertain", "4", "--seed", "-2"], "seed"),
        (["--seed", "3"], "--seed"),
        (["--uncertain", "2", "--workers", "-1"], "workers"),
        (["--uncertain", "2", "--timeout", "-1"], "timeout"),
        (["--uncertain", "2", "--overwrite"], "--overwrite"),
        (["--uncertain", "x"], "--uncertain"),
        (["--scheduler", "tcp://127.0.0.1:1"], "--scheduler"),
    ],
)
def test_cli_bad_input_is_one_line_exit_2(tmp_path, capsys, argv: list, word: str) -> None:
    try:
        rc = main(["study", SCENARIO, "--out", str(tmp_path / "b"), *argv])
    except SystemExit as exc:  # argparse's own usage errors (a value that is not a number)
        rc = exc.code
    assert rc == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and word in err


def test_cli_refuses_uncertain_for_a_study_matrix(tmp_path, capsys) -> None:
    rc = main(["study", "study-frozen-elbows", "--uncertain", "4", "--out", str(tmp_path / "m")])
    assert rc == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--uncertain" in err and "matrix" in err


def test_a_scenario_sent_to_another_process_passes_its_own_checks() -> None:
    """The implicit floor is told by value: a pickled copy of a scenario is still valid."""
    import pickle

    from packbot.scenario import load_scenario

    sc = load_scenario("collapse_physical")
    copy = pickle.loads(pickle.dumps(sc))
    assert copy.environment.obstacles[0] is not sc.environment.obstacles[0]
    copy.validate()  # (it raised "'floor' used twice" when the floor was told by identity)
