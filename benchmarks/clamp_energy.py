"""Energy of the report's law: the collapse in every reset and clamp rule and restitution.

Scenario: zero torque from the drive pose, zero initial velocity, the wrist, camera and gripper
joints locked, ``contact_mode="joint_clamp"``, for (reset_rule, clamp_rule, restitution) in
{zero, momentum} x {velocity, jacobian} x {0, 0.2, 0.5, 1} (default 3 s). Prints one row per
setting: the status (``ok`` or the error), the events, the energy change E(end) - E(0) [J], the
energy the velocity resets gained at events (``diagnostics.reset_energy_gain``, the report's
``zero`` reset's own), the largest and the summed energy change between two event instants
(with no torque and no friction: the work of the clamps, plus the integration error; a clamp
never does positive work, so the largest should be rounding), the rest time and the final
angles of the four arm joints.

Run: python benchmarks/clamp_energy.py [--duration S]
"""

from __future__ import annotations

import argparse
import itertools

import numpy as np

import packbot

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


def work_between_events(res: packbot.SimResult) -> list[float]:
    """Energy change [J] over each interval between event instants."""
    out, prev, t_prev = [], float(res.energy[0]), 0.0
    for e in res.events:
        if e.t > t_prev:
            out.append(e.energy_before - prev)
        prev, t_prev = e.energy_after, e.t
    out.append(float(res.energy[-1]) - prev)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=3.0, help="simulated time [s]")
    args = ap.parse_args()
    robot = packbot.load_robot()
    print(f"the collapse under the report's law, {args.duration:g} s simulated")
    head = (
        f"{'reset/clamp':18s} {'e':>4s} {'status':>7s} {'events':>6s} {'dE[J]':>9s} "
        f"{'reset gain[J]':>13s} {'max work[J]':>11s} {'sum work[J]':>11s} {'rest[s]':>7s}  "
        "turret shoulder elbow1 elbow2 [rad]"
    )
    print(head)
    print("-" * len(head))
    settings = itertools.product(("zero", "momentum"), ("velocity", "jacobian"), (0.0, 0.2, 0.5, 1))
    for rule, clamp, e in settings:
        cfg = packbot.SimConfig(
            contact_mode="joint_clamp",
            restitution=e,
            reset_rule=rule,
            clamp_rule=clamp,
            locked_joints=WRIST,
        )
        label = f"{rule}/{clamp}"
        try:
            res = packbot.simulate(
                robot, robot.poses["drive"], np.zeros(robot.nq), args.duration, config=cfg
            )
        except packbot.errors.PackbotError as exc:
            print(f"{label:18s} {e:4.1f} {type(exc).__name__}: {exc}")
            continue
        work = work_between_events(res)
        rest = "-" if res.rest_time is None else f"{res.rest_time:.3f}"
        q = " ".join(f"{x:+.4f}" for x in res.q[-1][:4])
        print(
            f"{label:18s} {e:4.1f} {'ok':>7s} {len(res.events):6d} "
            f"{res.energy[-1] - res.energy[0]:+9.3f} {res.diagnostics.reset_energy_gain:13.3f} "
            f"{max(work):+11.1e} {sum(work):+11.1e} {rest:>7s}  {q}"
        )


if __name__ == "__main__":
    main()
