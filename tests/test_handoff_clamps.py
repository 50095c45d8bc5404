"""The hand-off's constraint kinds in the extension, checked against the arm's dynamics.

The joints the hand-off locks (bilateral clamps, held joints) are eliminated by the Schur
complement of M^-1 (``ContactRhs.lock_subspace``), their holding torques read from the same
elimination (``ContactRhs.lock_torques``), and a clamped joint approaching its contact is
stopped by the least joint impulse on the clamp rows (``ContactRhs.stop_joints``). Each is
checked here on the physics it stands for, with M from Pinocchio's CRBA: locked joints held by
torques on themselves alone, the stop perfectly inelastic and complementary.
"""

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot.contact import native
from packbot.contact.handoff import HandoffContacts
from packbot.system import System

#: Relative tolerance of a balance computed two ways (M^-1 against M) [-].
REL_TOL = 1e-9


@pytest.fixture(scope="module")
def arm(robot):
    """(system, hand-off contact set, q, M, M^-1) at a perturbed "drive" pose."""
    cfg = packbot.SimConfig(contact_mode="joint_clamp", mu=0.5, handoff=True)
    q0 = robot.pose("drive") + 0.05 * np.random.default_rng(7).standard_normal(robot.nq)
    sysm = System(robot, q0, cfg, None)
    q = sysm.reduce(q0)
    mixed = HandoffContacts.from_config(sysm.model, sysm.data, sysm.world, cfg, check_others=False)
    M = pin.crba(sysm.model, sysm.data, q)
    M = np.triu(M) + np.triu(M, 1).T
    return sysm, mixed, q, M, sysm.minv(q)


@pytest.mark.parametrize("locked", [[1], [0, 2], [1, 2, 3]])
def test_locked_joints_are_held_by_torques_on_themselves_alone(arm, rng, locked):
    """a_S = 0 exactly, and M (a_c - a_free) (the torque holding them) acts on S alone."""
    sysm, mixed, q, M, minv = arm
    v = 0.5 * rng.standard_normal(len(q))
    a_free = sysm.aba(q, v, np.zeros(len(q)))
    a_c, minv_c = native.lock_subspace(mixed._rows_rhs(), a_free, minv, locked)
    free = np.setdiff1d(np.arange(len(q)), locked)
    hold = M @ (a_c - a_free)
    assert np.all(a_c[locked] == 0.0)
    assert np.abs(hold[free]).max() <= REL_TOL * np.abs(hold).max()
    # a generalized force on the locked arm: its accelerations, S at rest, held on S alone
    f = rng.standard_normal(len(q))
    a = minv_c @ f
    assert np.all(a[locked] == 0.0)
    assert np.abs((M @ a - f)[free]).max() <= REL_TOL * np.abs(f).max()
    # the holding torques of the same elimination
    tau = native.lock_torques(mixed._rows_rhs(), a_free, minv, np.zeros(len(q)), locked)
    assert tau == pytest.approx(hold[locked], rel=REL_TOL, abs=REL_TOL * np.abs(hold).max())


def test_the_clamped_joints_stop_is_inelastic_and_complementary(arm, rng):
    """After stop_clamped no clamped joint approaches its contact, only those that approached
    are pushed (complementarity), and the kinetic energy does not rise."""
    _, mixed, q, M, minv = arm
    clamps = [(0, 1), (2, -1), (3, 1)]
    for _ in range(20):
        v = rng.standard_normal(len(q))
        out = mixed.stop_clamped(v, minv, clamps)
        w = np.array([-s * out[j] for j, s in clamps])  # the rows' velocities after
        assert w.min() >= -1e-12
        imp = M @ (out - v)  # the joint impulse J^T P [N*m*s] (through M, not M^-1): clamps only
        others = np.setdiff1d(np.arange(len(q)), [j for j, _ in clamps])
        assert np.abs(imp[others]).max(initial=0.0) <= REL_TOL * (1.0 + np.abs(imp).max())
        lam = np.array([-s * imp[j] for j, s in clamps])  # each row's impulse
        assert lam.min() >= -REL_TOL * (1.0 + np.abs(lam).max())
        assert np.abs(lam * w).max() <= 1e-9 * (1.0 + np.abs(lam).max())
        assert out @ M @ out <= v @ M @ v + 1e-12 * (v @ M @ v)


def test_a_creeping_clamp_is_stopped_exactly(arm, rng):
    """The equality stop (a clamp left receding slower than CLAMP_ZENO) sets its joints at rest
    exactly by a joint impulse on them alone, and takes energy out."""
    _, mixed, q, M, minv = arm
    creep = [(1, 1), (3, -1)]
    v = rng.standard_normal(len(q))
    status, out = native.stop_joints(mixed._rows_rhs(), v, minv, creep, one_sided=False)
    assert status == 1
    assert out[1] == 0.0 and out[3] == 0.0
    imp = M @ (out - v)
    assert np.abs(imp[[0, 2]]).max() <= REL_TOL * np.abs(imp).max()
    assert out @ M @ out <= v @ M @ v


#: A random start (seed 5's eighth of tests' sampler, wrist locked) whose handed-off pair comes
#: to rest with elbow2 clamped both ways: the rest condition is then solved in the locked
#: subspace, whose M^-1 is singular (it raised numpy's LinAlgError before).
REST_LOCKED = [1.2986306016560674, 1.5819228928654157, -0.33307452384163216, 0.30885023080253715,
               -1.6, 0.0, 0.0, 0.0]  # fmt: skip


def test_a_handed_off_pair_comes_to_rest_with_a_joint_locked_both_ways(robot):
    cfg = packbot.SimConfig(
        contact_mode="joint_clamp",
        locked_joints=("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw"),
        mu=0.5,
        restitution=0.3,
        reset_rule="momentum",
        handoff=True,
    )
    res = packbot.simulate(robot, np.array(REST_LOCKED), np.zeros(robot.nq), 3.0, config=cfg)
    (handoff,) = res.events_of("handoff")
    assert res.rest_time is not None and res.rest_time > handoff.t
    for e in res.events:
        assert e.energy_after <= e.energy_before + 1e-9, (e.t, e.kind)
