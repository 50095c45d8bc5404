"""A scenario run over the model's uncertainty (packbot.uncertain_run, ``run --uncertain N``).

The collapse cut to 1.5 s on three arms drawn within the tolerances. Its claims are checked on
the output: every arm falls onto its casings (an impact within 0.3 s), link 3's end is where the
forward kinematics of that arm's final angles put it, above the floor and within the arm's
reach, and the arms end apart by more than the links' length tolerances could move it (the
rest pose itself changes with the model's uncertainty: docs/study.md).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from packbot.cli import main
from packbot.errors import ConfigurationError, PackbotError, UnknownNameError
from packbot.uncertain_batch import ARM_FILE, run_uncertain_runs
from packbot.uncertain_run import LINK3_END, ArmRun, UncertainRun, uncertain_run

SCENARIO = "collapse"
DURATION = 1.5
ARMS = 3
SEED = 2


@pytest.fixture(scope="module")
def unc() -> UncertainRun:
    return uncertain_run(SCENARIO, samples=ARMS, seed=SEED, duration=DURATION)


def test_every_arm_falls_onto_its_casings(unc: UncertainRun) -> None:
    assert unc.counts["ok"] == ARMS and unc.counts["errors"] == 0
    assert np.all(unc.event_counts("impact") >= 1)
    assert np.all(unc.first_times("impact") < 0.3)  # [s]: the fall from the drive pose
    rest = unc.rest_times()
    assert np.all(np.isnan(rest) | ((rest > unc.first_times("impact")) & (rest <= DURATION)))


def test_link3_end_is_the_forward_kinematics_of_the_arm(unc: UncertainRun) -> None:
    """Arm 0 rebuilt from its values: its frame at the final angles is the reported end."""
    import pinocchio as pin

    from packbot.uncertainty import robot_from_values

    robot = robot_from_values(dict(zip(unc.sample.names, unc.sample.values[0], strict=True)))
    arm = unc.arms[0]
    q = robot.q_from(arm.final_q)
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    at = data.oMf[robot.model.getFrameId(LINK3_END)].translation
    np.testing.assert_allclose(arm.link3_end, at, atol=1e-12)  # [m]: the same computation


def test_the_arms_end_apart_within_reach(unc: UncertainRun) -> None:
    import pinocchio as pin

    from packbot.model import load_robot
    from packbot.params import TABLE

    ends = unc.link3_end()
    assert np.all(ends[:, 2] > 0.0)  # [m]: above the floor
    # within reach of the shoulder: the links' lengths (each known within 5 mm), plus 5 cm for
    # the shoulder's offset from the turret's axis and link 2's offset (the turret turns)
    reach = sum(TABLE[f"link{k}.length"].value + 0.005 for k in (1, 2, 3)) + 0.05
    robot = load_robot()
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, robot.pose("drive"))
    shoulder = data.oMf[robot.model.getFrameId("link1")].translation
    assert np.all(np.linalg.norm(ends - shoulder, axis=1) < reach)
    # the three links' lengths are known within 5 mm each: more spread than 15 mm is the pose's
    assert np.ptp(ends[:, 2]) > 0.02
    q = unc.summary()["link3_end_m"]
    for i, axis in enumerate("xyz"):
        assert q[axis]["5"] <= q[axis]["50"] <= q[axis]["95"]
        assert q[axis]["arms"] == ARMS
        assert np.min(ends[:, i]) <= q[axis]["50"] <= np.max(ends[:, i])


def test_summary_text_and_arms_round_trip(unc: UncertainRun) -> None:
    s = json.loads(json.dumps(unc.summary(), allow_nan=False))
    assert set(s["final_q_rad"]) == set(unc.joints)
    assert s["events"]["impact"]["arms_with"] == ARMS
    assert s["link3_end_m"]["frame"] == LINK3_END
    text = unc.text()
    assert "link 3 end z [mm]" in text and "final elbow2 [rad]" in text
    for arm in unc.arms:
        assert ArmRun.from_dict(json.loads(json.dumps(arm.to_dict()))) == arm
    with pytest.raises(UnknownNameError, match="elbow2"):
        unc.final_angles("elbow9")


def test_batch_resumes_and_gives_the_numbers_of_this_process(unc: UncertainRun, tmp_path) -> None:
    out = tmp_path / "r"
    rep = run_uncertain_runs(SCENARIO, out, samples=ARMS, seed=SEED, duration=DURATION, workers=0)
    assert sorted(rep.batch.executed) == [f"arm_{k:04d}" for k in range(ARMS)]
    np.testing.assert_allclose(rep.result.link3_end(), unc.link3_end(), rtol=1e-9, atol=1e-12)
    (out / "arm_0002" / ARM_FILE).unlink()
    again = run_uncertain_runs(SCENARIO, out, samples=ARMS, seed=SEED, duration=DURATION, workers=0)
    assert again.batch.executed == ["arm_0002"]
    np.testing.assert_array_equal(again.result.link3_end(), rep.result.link3_end())
    for name in ("uncertain-run.json", "uncertain_run.png", "uncertain_run.svg"):
        assert (out / name).is_file()
    record = json.loads((out / "runs" / "arm_0000.json").read_text())
    assert record["metrics"]["link3_end_z_m"] == unc.arms[0].link3_end[2]


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"samples": 1}, "samples"),
        ({"seed": -1}, "seed"),
        ({"duration": 0.0}, "duration"),
        ({"method": "grid"}, "method"),
        ({"vary": ["link1.nope"]}, "link1.nope"),
    ],
)
def test_bad_arguments_are_refused(kwargs: dict, field: str) -> None:
    with pytest.raises(PackbotError, match=field):
        uncertain_run(SCENARIO, **({"samples": 2} | kwargs))


def test_cli_prints_and_writes(tmp_path: Path, capsys) -> None:
    out = tmp_path / "c"
    argv = ["run", SCENARIO, "--uncertain", "2", "--seed", "1", "--duration", "0.8"]
    assert main([*argv, "--out", str(out), "--workers", "0", "--no-progress"]) == 0
    printed = capsys.readouterr().out
    assert "uncertain run collapse" in printed and "link 3 end x [mm]" in printed
    data = json.loads((out / "uncertain-run.json").read_text())
    assert data["sample"]["arms"] == 2 and data["figures"] == [
        "uncertain_run.png",
        "uncertain_run.svg",
    ]


@pytest.mark.parametrize(
    ("argv", "word"),
    [
        (["--uncertain", "1"], "samples"),
        (["--uncertain", "2", "--seed", "-1"], "seed"),
        (["--seed", "2"], "--seed"),
        (["--workers", "2"], "--workers"),
        (["--uncertain", "2", "--plot"], "--plot"),
        (["--uncertain", "2", "--duration", "-1"], "duration"),
        (["--uncertain", "two"], "--uncertain"),
    ],
)
def test_cli_bad_input_is_one_line_exit_2(tmp_path, capsys, argv: list, word: str) -> None:
    try:
        rc = main(["run", SCENARIO, "--out", str(tmp_path / "b"), *argv])
    except SystemExit as exc:  # argparse's own usage errors (a value that is not a number)
        rc = exc.code
    assert rc == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and word in err and "Traceback" not in err


def test_a_figure_of_something_else_is_refused(tmp_path: Path) -> None:
    from packbot.viz.uncertain_report import write_uncertain_run

    with pytest.raises(ConfigurationError, match="summary"):
        write_uncertain_run({"arms": []}, tmp_path)


def test_the_reports_rest_does_not_survive_the_tolerances() -> None:
    """docs/study.md's worked example, in kind: over 8 arms (the whole 5 s) some end as the
    report's arm (link 3 propped upright on the shoulder casing, its end above 0.7 m, at rest)
    and some do not; a narrow shoulder casing alone (the box's narrow end) folds link 3."""
    unc = uncertain_run(SCENARIO, samples=8, seed=1)
    z = unc.link3_end()[:, 2]
    propped = z > 0.7  # [m]: the nominal arm's end is at 0.82 m
    assert 1 <= propped.sum() <= 7, z
    assert np.all(~np.isnan(unc.rest_times()[propped]))  # the propped ones are at rest
    one = uncertain_run(SCENARIO, samples=32, seed=1, vary=["casing.shoulder_width"])
    width = one.sample.column("casing.shoulder_width")  # [m]: 0.12 +- 0.024
    up = one.link3_end()[:, 2] > 0.7
    assert np.all(up[width > 0.105]), width[~up]  # wide enough: propped, as the nominal
    assert not np.all(up[width < 0.101])  # the narrow end folds it


def test_your_controller_runs_on_every_arm() -> None:
    """Gravity compensation built on each arm's own model holds the drive pose on every arm
    (where the scenario's zero torque collapses it): the user's controller ran, on that arm."""
    from packbot.control import GravityCompensation
    from packbot.model import load_robot

    unc = uncertain_run(SCENARIO, samples=2, seed=1, duration=0.5, controller=GravityCompensation)
    drive = load_robot().pose("drive")
    for arm in unc.arms:
        assert arm.ok and arm.events.get("impact", 0) == 0
        for k, joint in enumerate(unc.joints):
            assert arm.final_q[joint] == pytest.approx(drive[k], abs=1e-3), joint  # [rad]
