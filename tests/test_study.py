"""The failure study (packbot.study, packbot study): three runs, their metrics, the report.

Every shipped scenario with [[failures]] is studied with a shortened duration; the reports are
written and screenshot in headless Chromium (skipped only where chromium is not installed).
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

import packbot
from packbot.cli import main
from packbot.control.recovery import TaskRecovery
from packbot.errors import ConfigurationError, UnknownNameError
from packbot.failures import Failure
from packbot.scenario import list_scenarios, load_scenario
from packbot.study import RUN_NAMES, StudyResult, study
from packbot.viz.html import screenshot_command
from packbot.viz.study_report import write_study

#: Shipped failure scenarios and the duration each is studied for here [s]: long enough for
#: the reconfigured run to settle where recovery is possible.
DURATIONS = {
    "reconfig_elbow1": 2.5,
    "loose_swing_elbow2": 3.0,
    "frozen_elbow_reach": 2.0,
    "loose_shoulder": 1.2,
    "loose_shoulder_report_law": 1.2,
}
#: Where recovery is possible (the others say why not).
RECOVERABLE = ("reconfig_elbow1", "loose_swing_elbow2")


def test_every_shipped_failure_scenario_is_covered() -> None:
    with_failures = {n for n in list_scenarios() if load_scenario(n).failures}
    assert with_failures == set(DURATIONS)


@pytest.fixture(scope="module")
def studies(robot: packbot.Robot) -> dict[str, StudyResult]:
    return {
        name: study(name, robot=robot, duration=T, workspace_samples=800)
        for name, T in DURATIONS.items()
    }


@pytest.fixture(scope="module")
def reports(studies: dict[str, StudyResult], tmp_path_factory) -> dict[str, Path]:
    out = {}
    for name, res in studies.items():
        folder = tmp_path_factory.mktemp(name)
        write_study(res, folder)
        out[name] = folder
    return out


@pytest.mark.parametrize("name", list(DURATIONS))
def test_three_runs_with_metrics(studies: dict[str, StudyResult], name: str) -> None:
    res = studies[name]
    assert list(res.runs) == list(RUN_NAMES)
    for run in res.runs.values():
        assert run.status == "ok", run.reason
        m = run.metrics
        assert m is not None and run.result is not None
        assert m.duration_s == pytest.approx(DURATIONS[name])
        assert 0 < m.peak_torque_ratio <= 1.0 + 1e-9
        assert m.rms_task_error_m >= 0 and m.final_task_error_m >= 0
    # the healthy run is the task: no error, within tolerance from the failure on
    h = res.healthy.metrics
    assert h is not None and h.final_task_error_m < 1e-9 and h.recover_time_s == res.failure_time
    # the failure costs something, and the failed run never detects (its controller is unaware)
    f = res.failed.metrics
    assert f is not None and f.final_task_error_m > res.tolerance_m and f.detect_time_s is None
    # the reconfigured run detects the failed joint itself, shortly after the failure
    r = res.reconfigured.metrics
    failure = res.failures[0]
    assert r is not None and r.detected_joint == failure.joint
    assert r.detect_time_s is not None and 0 < r.detect_time_s - failure.t < 0.1
    assert r.detected_kind == failure.kind


@pytest.mark.parametrize("name", RECOVERABLE)
def test_reconfigured_ends_nearer_the_task_than_failed(
    studies: dict[str, StudyResult], name: str
) -> None:
    res = studies[name]
    assert res.recovery.possible is True, res.recovery.reasons
    failed, reconf = res.failed.metrics, res.reconfigured.metrics
    assert failed is not None and reconf is not None
    assert reconf.final_task_error_m < 0.2 * failed.final_task_error_m
    assert reconf.recovered and reconf.recover_time_s is not None
    assert not failed.recovered and failed.recover_time_s is None


def test_frozen_elbow_reach_is_out_of_reach(studies: dict[str, StudyResult]) -> None:
    res = studies["frozen_elbow_reach"]
    assert res.recovery.possible is False
    (reason,) = (r for r in res.recovery.reasons if "workspace" in r)
    assert "out of reach with elbow1 frozen" in reason
    check = res.recovery.checks[0]
    assert check["reachable"] is False and check["closest_approach_m"] > 2e-3
    # what the reduced arm achieves is about the closest approach, no better
    m = res.reconfigured.metrics
    assert m is not None and m.final_task_error_m > 2e-3


def test_loose_shoulder_cannot_be_held(studies: dict[str, StudyResult]) -> None:
    res = studies["loose_shoulder"]
    assert res.recovery.possible is False
    assert any(
        r.startswith("a loose joint cannot be held") and "shoulder" in r
        for r in res.recovery.reasons
    ), res.recovery.reasons


def test_loose_joint_settles_at_a_predicted_equilibrium(studies: dict[str, StudyResult]) -> None:
    res = studies["loose_swing_elbow2"]
    by_run = {s.run: s for s in res.loose}
    assert set(by_run) == {"failed", "reconfigured"}
    failed, reconf = by_run["failed"], by_run["reconfigured"]
    # unaware, the arm lets link 3 fall onto elbow2's stop: the predicted "limit" rest
    assert failed.nearest_kind == "limit" and abs(failed.offset_rad) < 1e-6
    # reconfigured, it hangs at the stable root, within the Coulomb band (0.035 rad)
    assert reconf.nearest_kind == "root" and reconf.nearest_stable
    assert abs(reconf.offset_rad) < 0.035
    for s in (failed, reconf):
        assert s.equilibria and any(e.stable for e in s.equilibria)


def test_study_json_holds_the_metrics(
    studies: dict[str, StudyResult], reports: dict[str, Path]
) -> None:
    for name, folder in reports.items():
        data = json.loads((folder / "study.json").read_text())
        assert set(data["runs"]) == set(RUN_NAMES)
        for run_name, entry in data["runs"].items():
            m = studies[name].runs[run_name].metrics
            assert m is not None
            for key in (
                "detect_time_s",
                "recover_time_s",
                "final_task_error_m",
                "rms_task_error_m",
                "peak_torque_nm",
                "peak_torque_ratio",
                "contacts",
                "peak_impact_speed_m_s",
                "energy_final_j",
            ):
                assert entry[key] == getattr(m, key), (name, run_name, key)
        assert data["recovery"]["possible"] == studies[name].recovery.possible
        for fig in ("study_task_error", "study_joints", "study_torques", "study_energy"):
            for ext in ("png", "svg"):
                assert (folder / f"{fig}.{ext}").stat().st_size > 1000
    loose = json.loads((reports["loose_swing_elbow2"] / "study.json").read_text())
    assert {e["run"] for e in loose["loose_equilibria"]} == {"failed", "reconfigured"}
    assert (reports["loose_swing_elbow2"] / "study_equilibria.png").is_file()


def test_report_is_one_self_contained_file(reports: dict[str, Path]) -> None:
    text = (reports["reconfig_elbow1"] / "report.html").read_text()
    assert "http://" not in text.split("<script>")[0] and "<link" not in text
    assert 'src="http' not in text and "src='http" not in text
    assert text.count('class="view"') == 3
    assert "MeshCat.Viewer" in text and "data:image/png;base64," in text


def test_loose_shoulder_contacts_measured(studies: dict[str, StudyResult]) -> None:
    m = studies["loose_shoulder"].failed.metrics
    assert m is not None and m.contacts >= 1 and m.peak_impact_speed_m_s > 0.1


# --------------------------------------------------------------------------- failure kinds
def _variant(name: str, failure: Failure, **config: object) -> packbot.scenario.Scenario:
    sc = load_scenario(name)
    cfg = dataclasses.replace(sc.config, **config) if config else sc.config  # type: ignore[arg-type]
    return dataclasses.replace(sc, failures=(failure,), config=cfg)


@pytest.mark.parametrize(
    "failure",
    [
        Failure(joint="elbow1", kind="weak", t=0.5, scale=0.2),
        Failure(joint="elbow2", kind="stuck", t=0.5, torque=5.0),
        Failure(joint="elbow1", kind="brake", t=0.5, threshold=40.0),
    ],
    ids=lambda f: f.kind,
)
def test_every_failure_kind_is_studied(robot: packbot.Robot, failure: Failure) -> None:
    res = study(_variant("reconfig_elbow1", failure), robot=robot, duration=1.2)
    assert all(r.status == "ok" for r in res.runs.values())
    assert res.recovery.checks[0]["kind"] == failure.kind
    if failure.kind == "stuck":
        assert res.recovery.possible is False
        assert any("stuck" in r for r in res.recovery.reasons)
    summary = json.loads(json.dumps(res.summary()))
    assert summary["failures"][0]["kind"] == failure.kind


def test_a_degrading_motor_is_studied_against_the_limit_at_each_time(
    robot: packbot.Robot,
) -> None:
    """elbow1 weak 0.7 at 0.4 s, then 0.3 at 0.8 s: the failed run's torque ratio is against
    the limit in force (it reaches 1 where the 0.3 motor saturates; against the nominal limit
    it could not pass 0.4, the healthy run's peak), and each step is assessed over its own span
    (the final pose against the last limit alone)."""
    fails = (
        Failure(joint="elbow1", kind="weak", t=0.4, scale=0.7),
        Failure(joint="elbow1", kind="weak", t=0.8, scale=0.3),
    )
    sc = dataclasses.replace(load_scenario("reconfig_elbow1"), failures=fails)
    res = study(sc, robot=robot, duration=1.2)
    assert all(r.status == "ok" for r in res.runs.values())
    j = robot.params.index("elbow1")
    E = robot.params.effort[j]
    failed = res.runs["failed"]
    assert failed.result is not None and failed.metrics is not None
    t, eff = failed.result.t, failed.result.effort[:, j]
    np.testing.assert_allclose(eff[(t > 0.4) & (t < 0.8)], 0.7 * E, rtol=1e-12)
    np.testing.assert_allclose(eff[t > 0.8], 0.3 * E, rtol=1e-12)
    healthy = res.runs["healthy"].metrics
    assert healthy is not None and healthy.peak_torque_ratio < 0.5  # elbow1 needs < 0.5 E
    assert failed.metrics.peak_torque_ratio_joint == "elbow1"
    assert failed.metrics.peak_torque_ratio == pytest.approx(1.0, rel=1e-9)  # 0.3 E, saturated
    first, second = res.recovery.checks
    assert (first["limit_nm"], first["until_s"]) == (pytest.approx(0.7 * E), 0.8)
    assert second["limit_nm"] == pytest.approx(0.3 * E) and "until_s" not in second
    assert first["note"] == "within the weak motor's limit"  # the hold needs < 0.7 E
    assert res.recovery.possible is False  # the final pose needs more than 0.3 E
    assert any("0.3" in r or f"{0.3 * E:.3g}" in r for r in res.recovery.reasons)
    assert len(json.loads(json.dumps(res.summary()))["failures"]) == 2


def test_a_brake_is_studied_in_the_contact_normal_mode(robot: packbot.Robot) -> None:
    """Brakes run in the contact-normal mode (its time-stepping windows hold them with the
    contacts): all three runs simulate."""
    sc = _variant(
        "reconfig_elbow1", Failure(joint="elbow1", kind="brake", t=0.5), joint_friction=False
    )
    res = study(sc, robot=robot, duration=0.8, contact_mode="normal")
    assert res.contact_mode == "normal"
    assert all(run.status == "ok" and run.metrics is not None for run in res.runs.values())


def test_refused_combination_is_reported(robot: packbot.Robot, tmp_path: Path) -> None:
    """A hand-off scenario studied in the contact-normal mode: the simulator refuses that
    combination (a hand-off goes from the report's law to the normal machinery), so every run
    is reported refused with the simulator's reason, and the report says so."""
    sc = _variant(
        "reconfig_elbow1",
        Failure(joint="elbow1", kind="frozen", t=0.5),
        joint_friction=False,
        contact_mode="joint_clamp",
        handoff=True,
    )
    res = study(sc, robot=robot, duration=0.8, contact_mode="normal")
    for run in res.runs.values():
        assert run.status == "refused"
        assert "handoff" in run.reason
        assert run.metrics is None
    assert res.recovery.possible is None
    files = write_study(res, tmp_path)
    data = json.loads(files["study.json"].read_text())
    assert data["runs"]["failed"]["status"] == "refused"
    assert data["runs"]["failed"]["reason"] == res.failed.reason


# --------------------------------------------------------------------------- bad input
def test_bad_inputs_name_the_field(robot: packbot.Robot) -> None:
    with pytest.raises(ConfigurationError) as exc:
        study("collapse", robot=robot)
    assert exc.value.field == "scenario.failures"
    for kwargs, field in (
        ({"tolerance": -1.0}, "tolerance"),
        ({"tolerance": float("nan")}, "tolerance"),
        ({"duration": 0.0}, "duration"),
        ({"contact_mode": "soft"}, "contact_mode"),
        ({"workspace_samples": 5}, "workspace_samples"),
    ):
        with pytest.raises(ConfigurationError) as exc:
            study("reconfig_elbow1", robot=robot, **kwargs)  # type: ignore[arg-type]
        assert exc.value.field == field
    with pytest.raises(ConfigurationError) as exc:
        study(42, robot=robot)  # type: ignore[arg-type]
    assert exc.value.field == "scenario"
    with pytest.raises(UnknownNameError):
        study("no_such_scenario", robot=robot)


def test_task_recovery_checks_its_task() -> None:
    with pytest.raises(ConfigurationError) as exc:
        TaskRecovery(nominal=None, task_t=[0.0, 1.0], task_x=np.zeros((3, 3)))
    assert exc.value.field == "task_x"
    with pytest.raises(ConfigurationError) as exc:
        TaskRecovery(nominal=None, task_t=[1.0, 0.0], task_x=np.zeros((2, 3)))
    assert exc.value.field == "task_t"
    with pytest.raises(ConfigurationError) as exc:
        TaskRecovery(nominal=None, task_t=[0, 1], task_x=np.zeros((2, 3)), loose_options={"x": 1})
    assert exc.value.field == "loose_options.x"


def test_cli_study(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "s"
    rc = main(["study", "reconfig_elbow1", "--duration", "1.3", "--out", str(out), "--no-html"])
    assert rc == 0
    data = json.loads((out / "study.json").read_text())
    assert data["runs"]["reconfigured"]["detect_time_s"] == pytest.approx(1.02)
    assert "recovery possible" in capsys.readouterr().out
    assert not (out / "report.html").exists()
    # a rerun into its own folder is fine; usage errors are one line and exit 2
    assert (
        main(["study", "reconfig_elbow1", "--duration", "1.1", "--out", str(out), "--no-html"]) == 0
    )
    capsys.readouterr()
    for argv in (
        ["study", "collapse", "--out", str(tmp_path / "c")],
        ["study", "reconfig_elbow1", "--tolerance", "-1", "--out", str(tmp_path / "t")],
        ["study", "reconfig_elbow1", "--duration", "0", "--out", str(tmp_path / "d")],
    ):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err


# --------------------------------------------------------------------------- real browser
@pytest.fixture(scope="module")
def chromium() -> str:
    for name in ("chromium", "chromium-browser"):
        path = shutil.which(name)
        if path:
            return path
    pytest.skip("chromium is not installed: the real-browser test is skipped")


def _arm(img: np.ndarray) -> np.ndarray:
    """Pixels of the arm's yellow-tan."""
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return (r > 0.35) & (r - b > 0.2) & (g - b > 0.15)


@pytest.mark.parametrize("name", [n for n in DURATIONS if not n.endswith("_report_law")])
def test_browser_shows_three_animations(
    chromium: str,
    studies: dict[str, StudyResult],
    reports: dict[str, Path],
    name: str,
    tmp_path: Path,
) -> None:
    page = reports[name] / "report.html"
    t_end = DURATIONS[name]
    png = tmp_path / f"{name}.png"
    cmd = screenshot_command(chromium, f"{page.as_uri()}#t={t_end:.3f}", png, tmp_path / "p")
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0 and png.exists(), proc.stderr[-2000:]
    img = np.asarray(imread(png))[..., :3]
    h, w = img.shape[:2]
    top = img[: h * 2 // 3]
    thirds = [top[:, k * w // 3 : (k + 1) * w // 3] for k in range(3)]
    arm = [_arm(p) for p in thirds]
    for k, a in enumerate(arm):  # an arm drawn in each of the three panes
        assert a.sum() > 0.002 * a.size, (name, RUN_NAMES[k])
    # at the end the failed arm is not where the healthy one is
    assert (arm[0] ^ arm[1]).sum() > 0.0005 * arm[0].size


@pytest.mark.parametrize("kind", ["cartesian", "pd"])
def test_every_controller_is_studied(robot: packbot.Robot, kind: str) -> None:
    """A Cartesian or PD hold of the high pose, elbow1 frozen at 0.5 s (the scenario has joint
    friction and a locked jaw): the observer flags elbow1 alone, after the failure (it knows
    the joints' friction and the locked joints: before, the jaw and a camera joint driven past
    its speed limit were flagged at 0.05 s), and the reconfigured run ends within the tolerance,
    nearer the task than the failed one where the failure moved the tool."""
    sc = load_scenario("reconfig_elbow1")
    v = dataclasses.replace(
        sc,
        controller=kind,
        controller_params={"target": "high"},
        failures=(Failure(joint="elbow1", kind="frozen", t=0.5),),
    )
    res = study(v, robot=robot, duration=1.2, workspace_samples=300)
    assert all(r.status == "ok" for r in res.runs.values())
    detections = [e for e in res.reconfigured.controller_log if e.kind == "detect"]
    assert [e.joint for e in detections] == ["elbow1"]
    assert detections[0].t >= 0.5
    failed = res.failed.metrics.final_task_error_m
    reconf = res.reconfigured.metrics.final_task_error_m
    assert reconf <= res.tolerance_m
    if failed > res.tolerance_m:
        assert reconf < failed
