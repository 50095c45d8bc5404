"""A patch's normal turns with the body whose face it is (material.hpp's ``normal_owner``).

The state is from the collapse of a wrist-free random start without friction (benchmarks/
robustness.py, seed 2026, start 1, mu = 0, t = 1.1019 s, just after an impact restart): the
camera head spins at 1.4 rad/s against the palm, one of its vertices on the palm's face. With
the normal fixed in the head, the patch's gap n . (p2 - p1) left the pair's distance by 0.03 um
within 1 ms (now 1e-17 m) and its normal velocity was not the distance's rate: an engaged row
held at gap 0 while the pair opened, the re-patch found it separating, the mode selection
released it and it fell back in: an impact every 2.5 ms (1,045 in 3 s), each taking 1.4e-5 J.
"""

import numpy as np
import pytest
from test_normal_cascade import start_pose

import packbot
from packbot.contact.normal import NormalContacts
from packbot.system import System

Q = np.array([
    1.794974847825979, -0.4995158412458841, 0.4884042913219972, 2.632242452766668,
    -1.7699196143163018, -0.5878933038684554, -0.17090739448653713, 1.2,
])  # fmt: skip
V = np.array([
    2.5015657444427018e-03, 0.0, -2.3219488960630086e-04, 2.7335077934771624e-02,
    2.8775245303373315e-01, -1.4283897044363840e00, -1.2960387195899772e00, 0.0,
])  # fmt: skip


@pytest.fixture(scope="module")
def palm_head(robot):
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.0, restitution=0.0)
    sysm = System(robot, Q, cfg, None)
    assert sysm.world is not None
    nc = NormalContacts.from_config(sysm.model, sysm.data, sysm.world, cfg)
    (k,) = [
        i
        for i, p in enumerate(sysm.world.pairs)
        if (p.piece1, p.piece2) == ("gripper_link/palm", "camera_head/head")
    ]
    q = sysm.reduce(Q)
    assert nc.add_pair(q, k)
    return sysm, nc, k, q


def test_a_head_vertex_on_the_palm_face_has_the_palm_normal(palm_head):
    _, nc, k, _ = palm_head
    assert nc.pairs[k].on1  # the palm (body 1) carries the face


def test_the_patch_gap_follows_the_distance_as_the_head_spins(palm_head):
    """Along q + v t (the head turning 2.9 mrad in 2 ms) the patch's gap stays the pair's
    distance and its normal velocity the distance's rate (central differences)."""
    sysm, nc, k, q0 = palm_head
    v = V
    world = sysm.world
    assert world is not None
    h = 1e-5
    for t in (1e-3, 2e-3):
        q = q0 + t * v
        _, _, gap, vn, _ = nc._kinematics(q, v)
        d = world.pair_contact(q, k).distance
        assert float(gap.min()) == pytest.approx(d, abs=1e-10)
        rate = world.pair_contact(q + h * v, k).distance - world.pair_contact(q - h * v, k).distance
        assert float(vn[int(np.argmin(gap))]) == pytest.approx(rate / (2 * h), abs=1e-8)


def test_the_frictionless_wrist_free_start_does_not_chatter_on_the_palm(robot):
    """The collapse of that start from t = 0 (rest, 2 mm clear of every contact) for 1.2 s:
    the head reaches the palm, and the pair's impacts stay few (measured 15; 130 with the normal
    fixed in the head, in bursts of one every 1 to 3 ms)."""
    q0 = start_pose(robot, 1)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.0, restitution=0.0)
    res = packbot.simulate(robot, q0, np.zeros(8), 1.2, config=cfg)
    palm = [
        e
        for e in res.events
        if e.kind == "impact" and (e.piece1, e.piece2) == ("gripper_link/palm", "camera_head/head")
    ]
    assert palm  # the head does reach the palm
    assert len(palm) <= 30
    assert all(e.energy_after <= e.energy_before + 1e-12 for e in res.events)
    assert res.diagnostics.min_distance >= -1e-5 - 1e-9
