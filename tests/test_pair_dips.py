"""Contacts between step ends (issue 38 item 3): the screen that finds a pair touching inside a
step whose ends are apart (the extension's ``pair_dips.hpp``).

First the screen on distance functions of known shape whose slope respects the screen's bound
(a V through contact, a V that stays apart, a narrow pass, a pair of the contact set), then the
pairs' joints against the model, then real runs of the benchmark's random starts that passed
through contact inside one step before the screen (each now below the penetration bound at
every sample, by an independent query).
"""

from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import packbot
from packbot.collision import CollisionWorld
from packbot.contact.native import native_rhs
from packbot.contact.normal_tolerances import PENETRATION_TOL
from packbot.contact.pairs import pair_joints, reach_bounds

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import robustness_checks as rc

H = 0.01  # the step [s]


@pytest.fixture(scope="module")
def screen(robot):
    """A native right-hand side with the screen's constants, the world, one pair and its bound."""
    world = CollisionWorld(robot)
    rhs = native_rhs(robot.model)
    reach = reach_bounds(robot.model, world)
    rhs.set_reach(reach, 0.05, 0.05)
    start, idx = pair_joints(robot.model, world.pairs)
    rhs.watch.set_pair_joints(start, idx)
    k = next(p.index for p in world.pairs if p.joint2 == 0 and p.joint1 > 2)
    nv = robot.model.nv
    v = np.full(nv, 1.0)  # [rad/s], constant over the step: the speed bound is 1 rad/s
    y0 = np.concatenate([np.zeros(nv), v])
    y1 = np.concatenate([H * v, v])
    joints = idx[start[k] : start[k + 1]]
    slope = float(reach[joints].sum()) * H  # the bound on |dd/ds| [m per unit step]
    return SimpleNamespace(rhs=rhs, k=k, y0=y0, y1=y1, slope=slope)


def _run_screen(sc, d, active=(), start_known=True):
    """The screen of pair sc.k whose distance at the step's fraction s is d(s) [m]."""
    calls: list[float] = []

    class Seg:  # (a step at constant joint speeds: q(theta) = q0 + H v theta)
        t0, h, _hz, y0, y1 = 0.0, H, H, sc.y0, sc.y1

        def _coefficients(self):
            Q = np.zeros((5, len(sc.y0)))
            Q[0] = sc.y0
            Q[1] = np.concatenate([sc.y0[len(sc.y0) // 2 :], np.zeros(len(sc.y0) // 2)])
            return Q

        def __call__(self, t):
            return np.array([t / H])  # (the fraction of the step, for the distance below)

    def distance(k, y):
        assert k == sc.k
        calls.append(float(y[0]))
        return d(float(y[0]))

    pairs = np.array([sc.k], dtype=np.int64)
    found, evals = sc.rhs.watch.pair_dips(
        Seg(),
        (pairs, np.array([d(0.0)])) if start_known else (pairs[:0], np.zeros(0)),
        (pairs, np.array([d(1.0)])),
        np.array(active, dtype=np.int64),
        0.05,
        distance,
    )
    assert evals == len(calls)
    return found, calls


def test_a_pass_through_contact_inside_the_step_is_found(screen):
    # a V at 0.9 of the screen's slope bound, through -1e-4 m at s = 0.37, apart at both ends
    def d(s):
        return -1e-4 + 0.9 * screen.slope * abs(s - 0.37)

    assert d(0.0) > 0.0 and d(1.0) > 0.0
    found, _ = _run_screen(screen, d)
    assert len(found) == 1
    k, s, dist, level = found[0]
    assert k == screen.k and level == 0.0
    assert dist <= 0.0 and dist == pytest.approx(d(s), abs=1e-15)
    assert 0.0 < s <= 1.0


def test_a_narrow_pass_is_found_and_the_earliest_first(screen):
    # two dips below 0; the screen reports one at the earlier, narrower one (2e-5 m deep),
    # though its levels meet the later, deeper one first
    def d(s):
        return min(-2e-5 + screen.slope * abs(s - 0.21), -3e-3 + screen.slope * abs(s - 0.8))

    found, _ = _run_screen(screen, d)
    assert len(found) == 1
    assert found[0][1] < 0.5


def test_a_pair_that_stays_apart_is_proven_clear(screen):
    # a V at the bound's slope, bottom at +1e-6 m, cut flat at 0.2 of the bound's travel: the
    # ends do not prove it clear; the queries do (a half is clear once its ends' distances
    # outweigh its length), a few of them, none in contact
    def d(s):
        return 1e-6 + screen.slope * min(abs(s - 0.37), 0.2)

    unresolved = screen.rhs.watch.unresolved_dips
    found, calls = _run_screen(screen, d)
    assert found == []
    assert 0 < len(calls) <= 64
    assert screen.rhs.watch.unresolved_dips == unresolved  # (proven clear, not given up)
    assert min(d(c) for c in calls) > 0.0


def test_no_query_where_the_ends_prove_the_step_clear(screen):
    # both ends farther than half the bound's travel: nothing inside can touch
    found, calls = _run_screen(screen, lambda s: 0.51 * screen.slope + 0.0 * s)
    assert found == [] and calls == []


def test_an_unknown_start_is_queried(screen):
    def d(s):
        return -1e-4 + 0.9 * screen.slope * abs(s - 0.37)

    found, calls = _run_screen(screen, d, start_known=False)
    assert calls[0] == 0.0  # the start's distance, not in the start's sweep
    assert len(found) == 1


def test_a_pair_of_the_contact_set_is_screened_only_when_apart(screen):
    def through(s):
        return -1e-4 + 0.9 * screen.slope * abs(s - 0.37)

    found, _ = _run_screen(screen, through, active=(screen.k,))
    assert len(found) == 1  # apart at both ends: a touch of other features than its rows'

    def touching(s):  # within the penetration tolerance at the end: its rows hold it
        return 0.5 * PENETRATION_TOL + screen.slope * s * (1.0 - s)

    found, calls = _run_screen(screen, touching, active=(screen.k,))
    assert found == [] and calls == []

    def leaving(s):  # in contact at the start, 3e-5 m through at s = 0.01, then apart
        if s <= 0.01:
            return -3e-3 * s
        return -3e-5 + 0.9 * screen.slope * (s - 0.01)

    assert leaving(0.0) == 0.0 and leaving(1.0) > PENETRATION_TOL
    found, _ = _run_screen(screen, leaving, active=(screen.k,))
    assert len(found) == 1
    _, _, dist, level = found[0]
    assert level == -PENETRATION_TOL and dist <= level  # (a re-patch: below the tolerance)

    found, _ = _run_screen(screen, leaving)  # outside the contact set: in contact at the start
    assert found == []


def test_pair_joints_are_those_between_the_two_bodies(robot):
    world = CollisionWorld(robot)
    start, idx = pair_joints(robot.model, world.pairs)
    model = robot.model
    assert len(start) == len(world.pairs) + 1
    for p in world.pairs:
        got = set(idx[start[p.index] : start[p.index + 1]].tolist())
        # a joint moves one piece relative to the other iff exactly one of them hangs from it
        want = {
            model.joints[j].idx_v
            for j in range(1, model.njoints)
            if (j in model.supports[p.joint1]) != (j in model.supports[p.joint2])
        }
        assert got == want, (p.piece1, p.piece2)


def _depth(robot, start: int, mu: float, e: float, duration: float):
    from robustness import start_poses  # (the benchmark's poses)

    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, restitution=e, sample_dt=1e-3)
    q0 = start_poses(robot, start + 1, 2026, 2 * cfg.contact_tolerance)[start]
    res = packbot.simulate(robot, q0, np.zeros(robot.nq), duration, config=cfg)
    query = rc.PenetrationQuery(robot.model, CollisionWorld(robot, res.environment).geom_model)
    return rc.check_result(res, robot.model, query).depth


@pytest.mark.parametrize(
    ("start", "mu", "e", "duration", "before"),
    [
        (78, 1.2, 0.0, 2.09, "-8.9e-4 m at 2.081 s: the camera head through the left flipper"),
        (35, 0.0, 0.0, 1.09, "-2.66e-4 m at 1.081 s: the head through the flipper's corner"),
        (64, 0.0, 0.3, 0.45, "-2.14e-4 m at 0.4247 s: the palm into the camera head"),
    ],
)
def test_no_pass_through_contact_between_step_ends(robot, start, mu, e, duration, before):
    """Wrist-free random starts (seed 2026) that passed through contact inside one step with
    no event before the screen (``before``; start 64's pair was in the contact set, its rows
    elsewhere); every sample is now above the penetration bound by an independent query."""
    depth = _depth(robot, start, mu, e, duration)
    assert depth.distance >= rc.DEPTH_BOUND, (before, depth)
