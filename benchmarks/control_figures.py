"""Figures and numbers of docs/control.md: the reconfiguration run, its baseline, the workspace.

Run from the repository root: ``python benchmarks/control_figures.py`` (about 30 s). Writes
docs/figures/reconfig_error.{png,svg}, reconfig_torques.{png,svg}, workspace_elbow1.{png,svg}
and prints the numbers quoted in the docs.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import numpy as np
import pinocchio as pin
from matplotlib.figure import Figure

import packbot
from packbot.analysis import (
    loose_joint_equilibria,
    plot_workspace,
    reachable_volume,
    workspace,
)
from packbot.control import ReconfigurableController
from packbot.scenario import load_scenario

OUT = Path(__file__).resolve().parent.parent / "docs" / "figures"


def tool_error(robot, qs, target):
    model, data = robot.model, robot.model.createData()
    fid = model.getFrameId("gripper_tool")
    out = []
    for q in qs:
        pin.framesForwardKinematics(model, data, q)
        out.append(np.linalg.norm(data.oMf[fid].translation - target))
    return np.array(out)


def run(robot, sc, **overrides):
    params = dict(sc.controller_params) | overrides
    ctrl = ReconfigurableController(**params)
    res = packbot.simulate(
        robot,
        robot.pose("stand"),
        np.zeros(8),
        sc.duration,
        controller=ctrl,
        config=sc.config,
        failures=list(sc.failures),
    )
    return ctrl, res


def main() -> None:
    robot = packbot.load_robot()
    sc = load_scenario("reconfig_elbow1")
    target = np.array(sc.controller_params["target"])
    ctrl, res = run(robot, sc)
    _, base = run(robot, sc, reconfigure=False)
    t_fail = sc.failures[0].t
    e = tool_error(robot, res.q, target)
    eb = tool_error(robot, base.q, target)
    for ev in ctrl.events:
        print(f"controller event t={ev.t:.3f} {ev.kind} {ev.joint} {ev.detail}")
    print(
        f"final gripper error: reconfigured {e[-1] * 1000:.2f} mm, baseline {eb[-1] * 1000:.1f} mm"
    )
    for lim in (0.05, 0.01):
        k = np.flatnonzero(e > lim)
        print(f"error stays below {lim * 100:.0f} cm from t = {res.t[k[-1] + 1]:.2f} s")
    print(
        f"min signed distance {res.diagnostics.min_distance * 1000:.1f} mm, "
        f"events {[ev.kind for ev in res.events]}"
    )
    ratio = np.abs(res.tau) / robot.params.effort
    peak = dict(zip(robot.joint_names, np.round(ratio.max(0), 2).tolist(), strict=True))
    print("peak |tau|/effort per joint:", peak)

    fig = Figure(figsize=(8, 4), layout="constrained")
    ax = fig.subplots()
    ax.semilogy(res.t, np.maximum(e, 1e-6), label="reconfigurable (detects, re-plans)")
    ax.semilogy(base.t, np.maximum(eb, 1e-6), "--", label="same controller, no re-planning")
    ax.axvline(t_fail, color="k", lw=0.8)
    ax.text(t_fail, 1.0, " elbow1 freezes", va="top")
    det = [ev for ev in ctrl.events if ev.kind == "detect"]
    if det:
        ax.axvline(det[0].t, color="tab:red", lw=0.8, ls=":")
        ax.text(
            det[0].t,
            0.3,
            f" detected ({(det[0].t - t_fail) * 1000:.0f} ms)",
            va="top",
            color="tab:red",
        )
    ax.set(
        xlabel="t [s]", ylabel="|p - p*| [m]", title="gripper_tool position error (reconfig_elbow1)"
    )
    ax.legend(loc="lower left")
    fig.savefig(OUT / "reconfig_error.png", dpi=120)
    fig.savefig(OUT / "reconfig_error.svg")

    joints = ["turret", "shoulder", "elbow1", "elbow2"]
    fig = Figure(figsize=(8, 7), layout="constrained")
    axes = fig.subplots(len(joints), 1, sharex=True)
    for ax, name in zip(axes, joints, strict=True):
        j = robot.params.index(name)
        ax.plot(res.t, res.tau[:, j], label="applied")
        ax.plot(res.t, getattr(res, "tau_cmd", res.tau)[:, j], ":", label="commanded")
        eff = robot.params.effort[j]
        ax.axhline(eff, color="k", ls="--", lw=0.8)
        ax.axhline(-eff, color="k", ls="--", lw=0.8)
        ax.axvline(t_fail, color="tab:red", lw=0.8)
        ax.set_ylabel(f"{name} [N*m]")
    axes[0].legend(loc="upper right", fontsize=8)
    axes[0].set_title("joint torques, effort limits dashed, failure at t = 1 s (red)")
    axes[-1].set_xlabel("t [s]")
    fig.savefig(OUT / "reconfig_torques.png", dpi=120)
    fig.savefig(OUT / "reconfig_torques.svg")

    angle = float(res.q[-1, robot.params.index("elbow1")])
    healthy = workspace(robot, samples=20000, seed=0)
    frozen = workspace(robot, ("elbow1", angle), samples=20000, seed=0)
    vol_h = reachable_volume(robot, healthy, rel_tol=0.01, seed=1)
    vol_f = reachable_volume(robot, frozen, rel_tol=0.01, seed=1)
    plot_workspace(
        [healthy, frozen],
        OUT / "workspace_elbow1",
        labels=[
            f"healthy ({len(healthy.points)} pts, {vol_h.volume_m3:.2f} +- "
            f"{vol_h.stderr_m3:.2f} m$^3$)",
            f"elbow1 frozen at {angle:.2f} rad ({len(frozen.points)} pts, "
            f"{vol_f.volume_m3:.2f} +- {vol_f.stderr_m3:.2f} m$^3$)",
        ],
    )
    print(
        f"reachable volume: healthy {vol_h} ({healthy.free_fraction:.0%} of samples free), "
        f"elbow1 frozen at {angle:.3f} rad {vol_f} ({frozen.free_fraction:.0%} free)"
    )
    for joint in ("shoulder", "elbow1", "elbow2"):
        for eq in loose_joint_equilibria(robot, joint, robot.pose("stand")):
            print(
                f"loose {joint} (stand): {eq.kind} {eq.angle:+.3f} rad, k = {eq.stiffness:+.1f} "
                f"N*m/rad, stable={eq.stable}, g_j = {eq.gravity_torque:+.2f} N*m, "
                f"d_min = {eq.min_distance * 1000:+.0f} mm ({eq.closest_pair})"
            )


if __name__ == "__main__":
    main()
