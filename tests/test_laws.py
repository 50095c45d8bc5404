"""The contact laws behind their protocol (packbot.contact.base.ContactLaw), and the loop's pieces.

Each law is driven here directly, as the loop drives it: built on a System with a Drive, an
event log and diagnostics, then ``start`` / ``handle`` at the state a full run recorded just
before an event. The law alone must reproduce that event to the last bit (the run and the
law take the same path). And the loop stays a loop: no contact-law branch in integrator.py, no
law importing it.
"""

import ast
import math
from pathlib import Path

import numpy as np
import pytest

import packbot
import packbot.contact as contact
from packbot.contact.base import ContactLaw, Crossing, ForceReport
from packbot.drive import Drive
from packbot.recorder import EventLog
from packbot.result import Diagnostics, Event
from packbot.schedule import Schedule
from packbot.system import System

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
PACKAGE = Path(packbot.__file__).parent
PROTOCOL = (
    "rebuild",
    "start",
    "accel",
    "torque_accel",
    "step_bound",
    "watch",
    "handle",
    "after_step",
    "forces",
)


def _law(robot, cfg, q_full):
    """(law, system, event log) built as the loop builds them, at a full configuration."""
    sys = System(robot, q_full, cfg, None)
    drive = Drive(robot, cfg, None)
    drive.phase(sys, [])
    events = EventLog(cfg.max_events)
    return contact.make_law(cfg, sys, drive, events, Diagnostics()), sys, events


def _state(sys, res, t):
    """The integrated state recorded just before and the full velocities just after t."""
    k = np.flatnonzero(res.t == t)
    assert len(k) >= 2, f"no pre/post samples at t = {t}"
    y = np.concatenate([sys.reduce(res.q[k[0]]), sys.reduce(res.v[k[0]])])
    return y, res.v[k[-1]]


def _pair_index(world, event):
    return next(
        i for i, p in enumerate(world.pairs) if (p.piece1, p.piece2) == (event.piece1, event.piece2)
    )


# ------------------------------------------------------------------ the protocol
@pytest.mark.parametrize(
    ("fields", "cls"),
    [
        ({"contact_mode": "none"}, contact.NoneLaw),
        ({"contact_mode": "joint_clamp"}, contact.JointClampLaw),
        ({"contact_mode": "normal"}, contact.NormalLaw),
        ({"contact_mode": "joint_clamp", "handoff": True}, contact.HandoffLaw),
        ({}, contact.NormalLaw),  # the default
    ],
)
def test_make_law_builds_the_configured_law_with_the_whole_protocol(robot, fields, cls):
    cfg = packbot.SimConfig(locked_joints=WRIST, **fields)
    law, sys, _ = _law(robot, cfg, robot.pose("drive"))
    assert type(law) is cls
    for name in PROTOCOL:
        assert callable(getattr(law, name)), name
    n = sys.nv
    y = np.concatenate([sys.reduce(robot.pose("drive")), np.zeros(n)])
    assert law.start(0.0, y, check=True) is y  # nothing in contact, nothing on a stop
    a_free = np.arange(n, dtype=float)
    np.testing.assert_array_equal(law.accel(y[:n], y[n:], a_free), a_free)  # free mode
    assert 0.0 < law.step_bound(y) <= cfg.max_step
    assert law.forces().held() == ()


@pytest.mark.parametrize("joints", [("camera_pan",), ("gripper_roll", "elbow2"), None])
def test_the_step_bound_keeps_every_point_within_half_the_margin(robot, joints):
    """The contact-normal mode's step bound h = margin / (2 reach . |v|): moving every joint at
    its velocity for h (random configurations), no vertex of any piece travels more than half
    the query margin; a wrist joint spinning alone gets a step about ten times REACH_BOUND's
    (the report's law's)."""
    import pinocchio as pin

    from packbot.contact.pairs import REACH_BOUND

    cfg = packbot.SimConfig(contact_mode="normal")
    law, sys, _ = _law(robot, cfg, robot.pose("drive"))
    world, model = sys.world, sys.model
    assert world is not None
    data, gd = model.createData(), pin.GeometryData(world.geom_model)
    rng = np.random.default_rng(11)
    n = sys.nv
    for _ in range(10):
        q = rng.uniform(model.lowerPositionLimit, model.upperPositionLimit)
        v = np.zeros(n)
        idx = range(n) if joints is None else [robot.joint_names.index(j) for j in joints]
        for j in idx:
            v[j] = rng.uniform(2.0, 8.0) * rng.choice([-1.0, 1.0])
        h = law.step_bound(np.concatenate([q, v]))
        assert h < cfg.max_step
        moved = 0.0
        pin.updateGeometryPlacements(model, data, world.geom_model, gd, q)
        before = [np.asarray(M.homogeneous).copy() for M in gd.oMg]
        for s in np.linspace(0.0, 1.0, 11)[1:]:  # along the step (q linear in t)
            pin.updateGeometryPlacements(model, data, world.geom_model, gd, q + s * h * v)
            for g, go in enumerate(world.geom_model.geometryObjects):
                pts = np.asarray(go.geometry.points()) if hasattr(go.geometry, "points") else None
                if pts is None or go.parentJoint == 0:
                    continue
                H0, H1 = before[g], gd.oMg[g].homogeneous
                d = (pts @ H1[:3, :3].T + H1[:3, 3]) - (pts @ H0[:3, :3].T + H0[:3, 3])
                moved = max(moved, float(np.linalg.norm(d, axis=1).max()))
        assert 0.0 < moved <= 0.5 * cfg.margin
        if joints == ("camera_pan",):
            flat = 0.5 * cfg.margin / (REACH_BOUND * float(np.abs(v).sum()))
            assert h > 8.0 * flat
            clamp, _, _ = _law(robot, packbot.SimConfig(contact_mode="joint_clamp"), q)
            assert clamp.step_bound(np.concatenate([q, v])) == pytest.approx(flat, rel=1e-12)


@pytest.mark.parametrize("mode", ["none", "joint_clamp"])
def test_locked_accelerations_from_the_unlocked_block_equal_those_from_minv(robot, mode):
    """torque_accel's reduced solve (M_UU a_U = tau_U - h_U, a = 0 on the locked joints) gives the
    accelerations of the M^-1 path (ABA, then the locked block's solve), every lock set of two
    joints or more with at most three unlocked, at random states; with one lock it is that path."""
    from itertools import combinations

    cfg = packbot.SimConfig(locked_joints=WRIST, contact_mode=mode)
    law, sys, _ = _law(robot, cfg, robot.pose("drive"))
    n = sys.nv
    rng = np.random.default_rng(7)
    used = 0
    for k in range(1, n + 1):
        for held in combinations(range(n), k):
            law.locks.set_held({j: 1e9 for j in held})
            for _ in range(3):
                q = rng.uniform(sys.lower, sys.upper)
                v = rng.normal(size=n)
                tau = rng.normal(scale=20.0, size=n)
                via_minv = law.locks.accelerations(sys.aba(q, v, tau), sys.minv(q))
                a = law.torque_accel(q, v, tau)
                if k == 1:
                    np.testing.assert_array_equal(a, via_minv)
                    continue
                used += 1
                assert np.all(a[list(held)] == 0.0)  # exactly: the locked joints stand still
                np.testing.assert_allclose(a, via_minv, rtol=1e-9, atol=1e-9)
    assert used > 0
    law.locks.set_held({})
    q = robot.pose("drive")[sys.free]
    np.testing.assert_array_equal(
        law.torque_accel(q, np.ones(n), np.ones(n)), sys.aba(q, np.ones(n), np.ones(n))
    )


def test_a_law_that_adds_rows_keeps_the_free_accelerations_path(robot):
    cfg = packbot.SimConfig(locked_joints=WRIST, contact_mode="normal")
    law, sys, _ = _law(robot, cfg, robot.pose("drive"))
    n = sys.nv
    law.locks.set_held({0: 1e9, 1: 1e9, 2: 1e9})
    q, v, tau = robot.pose("drive")[sys.free], np.ones(n), np.full(n, 3.0)
    np.testing.assert_array_equal(law.torque_accel(q, v, tau), law.accel(q, v, sys.aba(q, v, tau)))


def test_full_state_in_one_buffer_equals_the_two_maps(robot):
    cfg = packbot.SimConfig(locked_joints=WRIST, contact_mode="joint_clamp")
    sys = System(robot, robot.pose("stand"), cfg, None)
    n = sys.nv
    y = np.arange(1.0, 2 * n + 1.0)
    qf, vf = sys.qv_full(y)
    np.testing.assert_array_equal(qf, sys.q_full(y[:n]))
    np.testing.assert_array_equal(vf, sys.v_full(y[n:]))


def test_the_loop_has_no_contact_law_branch_and_no_law_imports_it():
    src = (PACKAGE / "integrator.py").read_text()
    assert len(src.splitlines()) < 500
    tree = ast.parse(src)
    names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
    names |= {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)}
    assert not names & {"contact_mode", "handoff", "normal", "mixed", "locks", "world", "active"}
    imported = {
        f"{n.module}.{a.name}"
        for n in ast.walk(tree)
        if isinstance(n, ast.ImportFrom)
        for a in n.names
        if n.module and n.module.startswith("packbot.contact")
    }
    assert imported <= {
        "packbot.contact.make_law",
        "packbot.contact.base.Crossing",
        "packbot.contact.base.SETTLE",
        "packbot.contact.base.StepSpan",
    }
    for path in [*PACKAGE.joinpath("contact").glob("*.py"), PACKAGE / "drive.py"]:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                assert node.module != "packbot.integrator", path
                assert node.module != "packbot.schedule", path


def test_the_protocol_is_the_loops_calls_only():
    """ContactLaw holds what the loop calls and nothing else, at most 8 members: each is
    called by the loop (or its recorder and ticks), and the loop calls no other method of the
    law; the samples and a freeze read the law's forces through its ForceReport."""
    members = {
        name
        for name, value in vars(ContactLaw).items()
        if not name.startswith("_") and (callable(value) or isinstance(value, property))
    }
    assert members == {
        "start",
        "torque_accel",
        "step",
        "watch",
        "handle",
        "after_step",
        "forces",
    }
    assert len(members) <= 8
    report = {name for name in vars(ForceReport) if not name.startswith("_")}
    assert report == {"held", "friction", "contacts"}
    called, read = set(), set()
    for name in ("integrator.py", "recorder.py", "ticks.py"):
        tree = ast.parse((PACKAGE / name).read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Attribute | ast.Name):
                owner = node.value.attr if isinstance(node.value, ast.Attribute) else node.value.id
                if owner == "law":
                    called.add(node.attr)
            if (
                isinstance(node, ast.Attribute)
                and isinstance(node.value, ast.Call)
                and isinstance(node.value.func, ast.Attribute)
                and node.value.func.attr == "forces"
            ):
                read.add(node.attr)
    assert called == members
    assert read == report  # (the report's members, each read through law.forces())


# ------------------------------------------------------------------ each law alone
def test_none_law_stops_a_joint_at_its_limit(robot):
    cfg = packbot.SimConfig(contact_mode="none", locked_joints=WRIST)
    q = robot.pose("drive").copy()
    j_full = robot.params.index("elbow2")
    q[j_full] = robot.params.upper[j_full]
    law, sys, events = _law(robot, cfg, q)
    j = list(sys.names).index("elbow2")
    n = sys.nv
    v = np.zeros(n)
    v[j] = 1.5
    y = np.concatenate([sys.reduce(q), v])
    y_new = law.start(0.0, y, check=True)
    assert y_new[n + j] == 0.0  # e = 0: stopped, the others keep their generalized momentum
    (e,) = events
    assert (e.kind, e.link1, e.link2) == ("limit", "elbow2", "upper")
    assert e.energy_after <= e.energy_before
    assert ("limit", j, 1) in law.active  # clamped: may not accelerate further up
    # the joint leaves its stop: the stop lets go after the next accepted step
    y_away = y_new.copy()
    y_away[j] -= 1e-3
    assert law.after_step(0.01, y_away) is None
    assert events[-1].kind == "release" and ("limit", j, 1) not in law.active


def _crossing(sys, event, y):
    """The crossing the loop handed the law at a logged impact or limit."""
    if event.kind == "limit":
        j = list(sys.names).index(event.relevant_joints[0])
        side = 1 if y[j] > 0.5 * (sys.upper[j] + sys.lower[j]) else -1
        return Crossing("limit", ("limit", j, side), lambda t: 0.0, 0.0, 0.0)
    p = _pair_index(sys.world, event)
    return Crossing(event.kind, ("pair", p), lambda t: 0.0, 0.0, 0.0)


@pytest.mark.parametrize("mode", ["joint_clamp", "normal"])
def test_a_law_alone_reproduces_the_first_event_of_the_collapse_bit_for_bit(robot, mode):
    """joint_clamp: link 3's casing meets the shoulder casing (0.151 s); normal: elbow1 reaches
    its upper stop (0.153 s), a row of the contact problem."""
    cfg = packbot.SimConfig(contact_mode=mode, mu=0.5, locked_joints=WRIST)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 0.2, config=cfg)
    first = res.events[0]
    assert first.kind == ("impact" if mode == "joint_clamp" else "limit")
    law, sys, events = _law(robot, cfg, robot.pose("drive"))
    y, v_after = _state(sys, res, first.t)
    law.start(0.0, np.concatenate([sys.reduce(robot.pose("drive")), np.zeros(sys.nv)]), True)
    y_new = law.handle(first.t, y, [_crossing(sys, first, y)])
    np.testing.assert_array_equal(sys.v_full(y_new[sys.nv :]), v_after)
    e = events[0]
    for field in ("t", "kind", "piece1", "piece2", "relevant_joints", "energy_after"):
        assert getattr(e, field) == getattr(first, field), field
    np.testing.assert_array_equal(e.v_after, first.v_after)
    # The witness distance is the collision query's, warm-started by the queries before it: a
    # world that has not seen the run's history may differ in the last bits (the run itself is
    # bit-identical because the loop and the laws keep the order of every query).
    assert e.distance == pytest.approx(first.distance, rel=1e-9, abs=1e-15)


def test_the_hand_off_law_hands_a_penetrating_clamped_pair_over(robot):
    """At the collapse's first secondary intersection, the law alone: the clamped pair is
    handed to the contact-normal rows (its clamps released), logged as a ``handoff``."""
    cfg = packbot.SimConfig(
        contact_mode="joint_clamp",
        locked_joints=WRIST,
        reset_rule="momentum",
        restitution=0.5,
        mu=0.5,
        handoff=True,
    )
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 0.8, config=cfg)
    (h, *_) = res.events_of("handoff")
    law, sys, events = _law(robot, cfg, robot.pose("drive"))
    y, _ = _state(sys, res, h.t)
    p = _pair_index(sys.world, h)
    law.start(0.0, np.concatenate([sys.reduce(robot.pose("drive")), np.zeros(sys.nv)]), True)
    hit = Crossing("impact", ("pair", p), lambda t: 0.0, 0.0, 0.0)
    law.handle(h.t, y, [hit])  # the pair in contact under the report's law: clamped
    assert law.active[("pair", p)].clamps and not law.mixed_on
    deeper = Crossing("secondary_intersection", ("pair", p), lambda t: 0.0, 0.0, 0.0)
    y_new = law.handle(h.t, y, [deeper])
    assert law.mixed_on and law.active[("pair", p)].clamps == []
    (handed,) = [e for e in events if e.kind == "handoff"]  # then the new modes' events
    assert (handed.piece1, handed.piece2) == (h.piece1, h.piece2)
    assert handed.energy_after <= handed.energy_before + 1e-9
    assert law.step_bound(y_new) <= cfg.max_step


# ------------------------------------------------------------------ the loop's pieces
def test_event_log_stops_the_run_only_at_an_event_that_counts():
    """The limit is on the log's length; only a contact or mode event checks it."""
    log = EventLog(2)
    log.log(Event(0.5, "impact"))
    log.log(Event(0.6, "limit"), count=False)
    log.log(Event(0.7, "release"), count=False)  # past the limit: a stop's events never stop
    assert len(log) == 3
    with pytest.raises(packbot.SimulationError, match="max_events=2") as exc:
        log.log(Event(0.8, "impact"))
    assert exc.value.t == 0.8 and len(log) == 4


def test_schedule_orders_failures_then_payload_then_the_tick():
    f1 = packbot.Failure(joint="elbow1", t=0.2, kind="loose")
    f2 = packbot.Failure(joint="shoulder", t=0.1, kind="frozen")
    load = packbot.Payload(mass=1.0, t_pick=0.2, t_drop=0.5)

    class Tick:
        dt = 0.1

    sched = Schedule([f1, f2], load, Tick())  # type: ignore[arg-type]
    assert sched.next_time() == 0.0 and sched.tick_due(0.0) and sched.due(0.0) == []
    sched.ticked()
    assert sched.next_time() == pytest.approx(0.1)
    assert sched.due(0.1) == [f2]
    sched.ticked()
    assert sched.due(0.2) == [f1, "pick"] and sched.tick_due(0.2)
    sched.ticked()
    assert sched.due(0.3) == [] and sched.next_time() == pytest.approx(0.3)
    assert sched.due(math.inf) == ["drop"] and sched.ticks == 3
