"""The contact-normal mode on real simulation output: a box on a floor (patches, impacts,
resting contact, Zeno), on a slope (Coulomb stick and slip against the analytic motion), the
complementarity solvers, and the arm."""

from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot.collision import CollisionWorld
from packbot.contact.lcp import lcp_residual, lemke, solve_lcp_psd, solve_ncp_admm
from packbot.contact.normal import (
    CAPTURE_SPEED,
    PENETRATION_TOL,
    POINT_TOL,
    SLIDE_TOL,
    NormalContacts,
)
from packbot.environment import FLOOR, Environment, Obstacle
from packbot.model import JointParams, Robot
from packbot.system import System

SIZE = (0.2, 0.1, 0.05)  # box extents [m]
HALF_Z = SIZE[2] / 2


def box_robot(joints: tuple[str, ...] = ("PX", "PZ", "RY"), mass: float = 2.0) -> Robot:
    """A box on a chain of joints (Pinocchio joint types), one convex piece."""
    model = pin.Model()
    parent = 0
    names = []
    for k, jt in enumerate(joints):
        parent = model.addJoint(
            parent, getattr(pin, f"JointModel{jt}")(), pin.SE3.Identity(), f"j{k}_{jt}"
        )
        names.append(f"j{k}_{jt}")
        if k < len(joints) - 1:
            tiny = pin.Inertia(1e-9, np.zeros(3), 1e-12 * np.eye(3))
            model.appendBodyToJoint(parent, tiny, pin.SE3.Identity())
    model.appendBodyToJoint(parent, pin.Inertia.FromBox(mass, *SIZE), pin.SE3.Identity())
    fid = model.addFrame(pin.Frame("box", parent, 0, pin.SE3.Identity(), pin.FrameType.BODY))
    n = model.nq
    model.lowerPositionLimit = -10 * np.ones(n)
    model.upperPositionLimit = 10 * np.ones(n)
    h = np.array(SIZE) / 2
    corners = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)]) * h
    vec = coal.StdVec_Vec3s()
    vec.extend(corners)
    shape = coal.Convex.convexHull(vec, True, "Qt")
    gm = pin.GeometryModel()
    gm.addGeometryObject(pin.GeometryObject("box/0", parent, fid, pin.SE3.Identity(), shape))
    z = np.zeros(n)
    params = JointParams(
        names=tuple(names),
        lower=model.lowerPositionLimit.copy(),
        upper=model.upperPositionLimit.copy(),
        velocity=np.full(n, 100.0),
        effort=np.full(n, 100.0),
        gear_ratio=np.ones(n),
        rotor_inertia=z.copy(),
        armature=z.copy(),
        viscous=z.copy(),
        coulomb=z.copy(),
        table={},
    )
    return Robot(model, gm, gm.copy(), {}, params, Path("box.urdf"))


def distances(robot: Robot, res: packbot.SimResult) -> np.ndarray:
    """Signed distance box - floor at every sample [m]."""
    world = CollisionWorld(robot, srdf=False)
    return np.array([world.all_distances(q).min() for q in res.q])


# ------------------------------------------------------------------ solvers
def test_lcp_solvers_agree_on_a_rank_deficient_patch():
    """4 coplanar points on a 3-dof body: G (4x4) has rank 3; v+ is unique."""
    rng = np.random.default_rng(1)
    J = rng.normal(size=(3, 3))
    J = np.vstack([J, J[0] + J[1] - J[2]])  # the 4th row depends on the others
    G = J @ J.T
    q = np.array([-1.0, -0.5, 0.2, -0.7])
    q = G @ rng.uniform(0.1, 1.0, size=4) + q - q  # q in range(G): a consistent problem
    q = -np.abs(q)
    z1 = solve_lcp_psd(G, q)
    z2 = lemke(G, q)
    assert z2 is not None
    assert lcp_residual(G, q, z1) < 1e-9 and lcp_residual(G, q, z2) < 1e-9
    np.testing.assert_allclose(J.T @ z1, J.T @ z2, atol=1e-8)
    assert np.count_nonzero(z1 > 1e-12) <= 3  # a basic solution: independent support


def test_admm_fresh_operator_reproduces_slope_forces():
    th = np.deg2rad(20.0)
    g3 = 9.81 * np.array([np.sin(th), 0.0, -np.cos(th)])
    model = pin.Model()
    for _ in range(2):  # a second solve must not see the first one's damping
        x, res = solve_ncp_admm(model, model.createData(), np.eye(3) / 2.0, g3, np.array([0.2]))
        assert res < 1e-9
        assert x[2] == pytest.approx(2.0 * 9.81 * np.cos(th), rel=1e-8)
        assert abs(x[0]) == pytest.approx(0.2 * x[2], rel=1e-6)


# ------------------------------------------------------------------ slope
@pytest.mark.parametrize("mu", [0.5, 0.364, 0.2, 0.0])
def test_block_on_slope_sticks_or_slides_with_the_analytic_acceleration(mu):
    """A slope of 20 deg (gravity tilted): sticks for mu >= tan 20 deg, else
    a = g (sin - mu cos)."""
    th = np.deg2rad(20.0)
    robot = box_robot()
    gravity = (9.81 * np.sin(th), 0.0, -9.81 * np.cos(th))
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, gravity=gravity)
    q0 = np.array([0.0, HALF_Z, 0.0])  # resting on its face
    res = packbot.simulate(robot, q0, np.zeros(3), 0.4, config=cfg)
    x, t = res.q[:, 0], res.t
    expected = 9.81 * (np.sin(th) - mu * np.cos(th))
    if expected <= 0.0:
        assert np.abs(x).max() < 1e-9
        assert not res.events_of("slip")
    else:
        # x = a t^2 / 2 from rest (released at t = 0)
        np.testing.assert_allclose(x, 0.5 * expected * t**2, rtol=1e-6, atol=1e-9)
    assert np.abs(res.q[:, 1] - HALF_Z).max() < 1e-8  # neither sinks nor lifts
    assert distances(robot, res).min() > -1e-7


@pytest.mark.parametrize("ground", ["slab", "floor"])
def test_sliding_patch_is_stale_only_once_slid_or_off_its_distance(ground):
    """The box's face patch on a slab's top face (a box obstacle), its 4 rows engaged: moved
    along x by less than SLIDE_TOL it is still valid (kept while sliding), by more it is
    rebuilt; a Coal distance disagreeing with its smallest gap by more than POINT_TOL makes it
    stale too. On the floor (a halfspace: its face has no edge for a corner to lag at) the
    slide never makes it stale; the distance rule still does."""
    robot = box_robot()
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5)
    env = Environment(obstacles=(FLOOR,))
    if ground == "slab":  # top face at z = 0, 2 m wide: the box stays well inside it
        env = Environment(
            obstacles=(
                Obstacle(name="slab", kind="box", size=(2.0, 2.0, 0.1), xyz=(0.0, 0.0, -0.05)),
            )
        )
    sysm = System(robot, np.array([0.0, HALF_Z, 0.0]), cfg, env)
    assert sysm.world is not None
    nc = NormalContacts.from_config(sysm.model, sysm.data, sysm.world, cfg)
    q0, v = np.array([0.0, HALF_Z, 0.0]), np.array([0.01, 0.0, 0.0])
    assert nc.add_pair(q0, 0)
    nc.engaged = list(range(len(nc.pairs[0].local1)))
    assert len(nc.engaged) == 4

    def dist(q: np.ndarray) -> dict[int, float]:
        return {0: sysm.world.pair_contact(q, 0).distance}

    far = ground == "slab"  # (stale once slid far)
    for dx, stale in ((0.0, False), (0.5 * SLIDE_TOL, False), (2.0 * SLIDE_TOL, far), (0.1, far)):
        q = q0 + np.array([dx, 0.0, 0.0])
        assert nc.stale(q, v, dist(q)) is stale, dx
    q = q0 + np.array([0.5 * SLIDE_TOL, 0.0, 0.0])
    assert nc.stale(q, v, {0: dist(q)[0] - 2.0 * POINT_TOL})
    assert nc.stale(q, v, {})  # no distance for a pair in contact: rebuilt
    nc.engaged = []
    assert not nc.stale(q0 + np.array([2 * SLIDE_TOL, 0.0, 0.0]), v, {})  # no engaged row: no patch


def test_collapse_rebuilds_sliding_patches_far_less_often_than_it_steps(robot, monkeypatch):
    """Arm collapse, mu = 0.5, 0.45 s (link 2 sliding slowly on the chassis from 0.3 s):
    a sliding patch is rebuilt only when stale, so the re-patches are a fraction of the
    steps, and no pair penetrates beyond the re-patch tolerance."""
    calls = []
    repatch = NormalContacts.repatch

    def counted(self, *args):
        calls.append(1)
        return repatch(self, *args)

    monkeypatch.setattr(NormalContacts, "repatch", counted)
    wrist = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=wrist)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 0.45, config=cfg)
    d = res.diagnostics
    assert 0 < len(calls) < 0.3 * d.steps, (len(calls), d.steps)
    assert d.min_distance > -PENETRATION_TOL - 1e-9


# ------------------------------------------------------------------ impacts and resting
def test_box_dropped_flat_rests_still_with_long_steps():
    robot = box_robot(("PX", "PZ", "RY"))
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.0, restitution=0.0)
    q0 = np.array([0.0, HALF_Z + 0.01, 0.0])
    res = packbot.simulate(robot, q0, np.zeros(3), 2.0, config=cfg)
    land = res.events_of("impact")[0].t
    assert land == pytest.approx(np.sqrt(2 * 0.01 / 9.81), abs=1e-8)
    after = res.t > land + 1e-9
    np.testing.assert_allclose(res.q[after, 1], HALF_Z, atol=1e-9)
    assert np.abs(res.q[after][:, [0, 2]]).max() < 1e-12  # no rocking, no creeping
    assert np.abs(res.v[after]).max() < 1e-9
    assert all(e.t <= land + 1e-9 for e in res.events)  # no event after the landing
    assert res.diagnostics.steps < 80  # 2 s at rest: long steps (max_step 50 ms)


def test_tilted_box_lands_without_penetration_or_energy_gain():
    """Dropped on a corner edge: impact, rotation onto the face, rest; e = 0 then e = 0.5."""
    robot = box_robot(("PX", "PZ", "RY"))
    for e in (0.0, 0.5):
        cfg = packbot.SimConfig(contact_mode="normal", mu=0.0, restitution=e)
        q0 = np.array([0.0, 0.08, 0.4])
        res = packbot.simulate(robot, q0, np.zeros(3), 1.5, config=cfg)
        impacts = res.events_of("impact")
        assert impacts
        for ev in impacts:
            assert ev.energy_after <= ev.energy_before + 1e-9
        assert distances(robot, res).min() > -1.01 * PENETRATION_TOL  # re-patch threshold
        assert res.diagnostics.min_distance > -1e-5
        assert res.q[-1][2] == pytest.approx(0.0, abs=1e-6)  # face down at the end
        assert res.rest_time is not None


def test_inelastic_impact_leaves_zero_normal_speed():
    robot = box_robot(("PZ",))
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.0, restitution=0.0)
    res = packbot.simulate(robot, np.array([0.1]), np.array([-1.0]), 0.2, config=cfg)
    (hit,) = res.events_of("impact")[:1]
    assert hit.v_before[0] < -1.0
    assert hit.v_after[0] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("e", [0.5, 1.0])
def test_restitution_reverses_normal_speed_and_zeno_ends_in_rest(e):
    robot = box_robot(("PZ",))
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.0, restitution=e)
    res = packbot.simulate(robot, np.array([HALF_Z + 0.05]), np.zeros(1), 1.0, config=cfg)
    impacts = res.events_of("impact")
    first = impacts[0]
    assert first.v_after[0] == pytest.approx(-e * first.v_before[0], rel=1e-9)
    for ev in impacts:
        assert ev.energy_after <= ev.energy_before + 1e-12
    if e < 1.0:
        # a geometric series of bounces: the last ones, below zeno_speed, are inelastic
        slow = [ev for ev in impacts if abs(ev.v_before[0]) < cfg.zeno_speed]
        assert slow and slow[-1].v_after[0] == pytest.approx(0.0, abs=1e-12)
        assert len(impacts) < 40
        assert res.q[-1][0] == pytest.approx(HALF_Z, abs=1e-9)
    assert res.q[:, 0].min() > HALF_Z - 2 * POINT_TOL


def test_joint_limit_is_a_row_of_the_same_problem():
    """A box falling along z with its lower limit 1 cm above the floor: the limit stops it."""
    robot = box_robot(("PZ",))
    robot.model.lowerPositionLimit[0] = HALF_Z + 0.01
    robot.params.lower[0] = HALF_Z + 0.01
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.0)
    res = packbot.simulate(robot, np.array([HALF_Z + 0.05]), np.zeros(1), 0.5, config=cfg)
    (lim,) = res.events_of("limit")
    assert lim.v_after[0] == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(res.q[res.t > lim.t + 1e-9, 0], HALF_Z + 0.01, atol=1e-9)
    assert not res.events_of("impact")


# ------------------------------------------------------------------ the arm
def test_arm_collapse_normal_mode_keeps_every_distance_above_tolerance(robot):
    wrist = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.0, locked_joints=wrist)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 0.4, config=cfg)
    assert res.events_of("impact")
    assert res.diagnostics.min_distance > -cfg.contact_tolerance
    sysw = CollisionWorld(robot)
    d = [sysw.all_distances(q).min() for q in res.q[::4]]
    assert min(d) > -cfg.contact_tolerance
    for ev in res.events_of("impact", "limit"):
        assert ev.energy_after <= ev.energy_before + 1e-9


def test_arm_collapse_with_friction_comes_to_rest_on_its_contacts(robot):
    """mu = 0.5: the collapse ends captured at rest (v = 0, no event after), without
    penetration, in a bounded number of events, with the arm held by its contacts."""
    wrist = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=wrist)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 2.2, config=cfg)
    assert res.rest_time is not None and res.rest_time < 2.1
    assert len(res.events) < 200
    assert not [ev for ev in res.events if ev.t > res.rest_time + 1e-9]
    np.testing.assert_array_equal(res.v[res.t > res.rest_time], 0.0)
    assert res.diagnostics.min_distance > -2 * PENETRATION_TOL
    # at rest on its contacts: some pair touches (within the touch gap) and the arm did fold
    world = CollisionWorld(robot)
    # every pair over every sample: no penetration beyond the re-patch threshold (the drift
    # projection checks the pairs outside the contact set)
    assert min(world.all_distances(q).min() for q in res.q) > -1.01 * PENETRATION_TOL
    assert abs(world.all_distances(res.q[-1]).min()) < 1e-4
    assert res.q[-1][robot.joint_names.index("elbow2")] > 0.5  # link 3 slid and folded over
    # a stick only removes a residual slide: it never stops the arm (it once zeroed elbow2's
    # 2.9 rad/s at t = 0.508 s, the elbow casing's slide being driven by link 3's)
    for ev in res.events_of("stick"):
        assert np.abs(ev.v_after - ev.v_before).max() <= CAPTURE_SPEED, ev.t


def test_slip_against_a_driven_residual_slide_advances_time(robot):
    # mu = 0.45: at t = 0.3161 s link 2's casing slides on the chassis at 4.6e-4 m/s, driven
    # through the closed chain by link 3 sliding on the shoulder casing; the onset direction
    # from the forces pointed against that residual slide and the stick condition held at once:
    # 100 000 stick/slip events at one instant. Coulomb's direction (along the slide) lets
    # the slide pass through zero first.
    cfg = packbot.SimConfig(
        contact_mode="normal",
        mu=0.45,
        locked_joints=("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw"),
        max_events=400,
    )
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 0.4, config=cfg)
    assert res.t[-1] == pytest.approx(0.4)
    mode = [e for e in res.events if e.kind in ("stick", "slip")]
    assert mode, "the run passes stick/slip transitions"
    times = np.array([e.t for e in mode])
    # no pair flips stick <-> slip more than twice at one instant
    _, counts = np.unique(times, return_counts=True)
    assert counts.max() <= 4
    assert res.diagnostics.min_distance > -1.01 * PENETRATION_TOL


# ------------------------------------------------------------------ drift projection
def _contacts(robot: Robot, q: np.ndarray, env: packbot.Environment | None = None):
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.0)
    sysm = System(robot, q, cfg, env)
    assert sysm.world is not None
    nc = NormalContacts.from_config(sysm.model, sysm.data, sysm.world, cfg)  # mu = 0
    return sysm, nc


def _pair(world: CollisionWorld, name: str) -> int:
    (k,) = [i for i, p in enumerate(world.pairs) if name in (p.link1, p.link2)]
    return k


def test_projection_adds_the_pair_it_would_make_penetrate():
    """A box (x, z) sunk 0.5 mm into the floor, a slope 0.2 mm above its top right corner and
    not in the contact set: raising the box 0.5 mm would sink the corner 0.15 mm into the
    slope. The restart adds the slope (its impulse and modes see it) and leaves no pair
    penetrating."""
    robot = box_robot(("PX", "PZ"))
    depth, gap = 5e-4, 2e-4
    q = np.array([0.0, HALF_Z - depth])
    corner = np.array([SIZE[0] / 2, 2 * HALF_Z - depth])
    n = -np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)  # outward normal of the slope, down-left
    offset = float(n @ np.array([corner[0], 0.0, corner[1]])) - gap  # solid: n.x <= offset
    slope = packbot.Obstacle(name="slope", kind="halfspace", normal=tuple(n), offset=offset)
    env = packbot.Environment().with_obstacles(slope)
    sysm, nc = _contacts(robot, q, env)
    world = sysm.world
    floor, sl = _pair(world, "floor"), _pair(world, "slope")
    assert world.pair_contact(q, sl).distance == pytest.approx(gap, rel=1e-6)
    assert nc.add_pair(q, floor)
    minv = sysm.minv(q)
    q1, _, _ = nc.restart(q, np.zeros(2), lambda qq, vv: np.array([0.0, -9.81]), minv)
    d = world.all_distances(q1)
    assert d.min() > -PENETRATION_TOL, d
    assert sl in nc.pairs  # joined the contact set
    assert q1[0] < 0.0  # slid left along the slope to clear it
    # the same projection without the check leaves the slope penetrated (the test can fail)
    _, nc0 = _contacts(robot, q, env)
    nc0.check_others = False
    assert nc0.add_pair(q, floor)
    q0 = nc0.project(q, np.zeros(2), minv)
    assert world.pair_contact(q0, sl).distance < -1e-4


@pytest.mark.parametrize("depth", [2e-6, -2e-6])
def test_stale_patch_point_moves_q_no_more_than_the_true_penetration(depth):
    """The floor patch of a box sunk by ``depth`` (negative: apart) with its points made stale,
    1 mm deeper than the box: the projection moves the box by the true penetration plus at
    most the drift band PENETRATION_TOL, not by the patch's 1 mm."""
    robot = box_robot()
    q = np.array([0.0, HALF_Z - depth, 0.0])
    sysm, nc = _contacts(robot, q)
    assert sysm.world is not None
    assert nc.add_pair(q, 0)
    p = nc.pairs[0]
    p.local2 = p.local2 - 1e-3 * p.normal2  # every gap n.(p2 - p1) 1 mm smaller
    nc._invalidate()
    q1 = nc.project(q, np.zeros(3), sysm.minv(q))
    moved = float(np.abs(q1 - q).max())
    assert moved == pytest.approx(max(depth, 0.0) + PENETRATION_TOL, rel=1e-6)  # not 1 mm
    d1 = sysm.world.pair_contact(q1, 0).distance
    assert d1 == pytest.approx(moved - depth, rel=1e-4)  # moved straight up


@pytest.mark.parametrize("depth", [5e-6, 2e-5])
def test_projection_sweeps_for_the_clip_only_below_the_drift_band(depth, monkeypatch):
    """A box sunk by ``depth``: within the drift band (gap >= -PENETRATION_TOL) the clip at
    the true distance cannot change a gap, so the projection sweeps once (the check of the
    other pairs after the move); deeper, twice. Either way it closes the gap in full."""
    robot = box_robot()
    q = np.array([0.0, HALF_Z - depth, 0.0])
    sysm, nc = _contacts(robot, q)
    world = sysm.world
    assert world is not None
    assert nc.add_pair(q, 0)
    calls = []
    sweep = world.sweep

    def counted(qq, *args, **kwargs):
        calls.append(np.array(qq))
        return sweep(qq, *args, **kwargs)

    monkeypatch.setattr(world, "sweep", counted)
    q1 = nc.project(q, np.zeros(3), sysm.minv(q))
    assert float(np.abs(q1 - q).max()) == pytest.approx(depth, rel=1e-6)
    assert len(calls) == (1 if depth < PENETRATION_TOL else 2)
    assert np.array_equal(calls[-1], q1)  # the last sweep checks the others at the new q
    assert world.pair_contact(q1, 0).distance == pytest.approx(0.0, abs=1e-9)


def test_arm_collapse_frictionless_penetrates_no_pair(robot):
    """mu = 0, 2 s: over every sample and every pair, no distance below the re-patch
    threshold (the drift projection once sank the camera wrist 0.94 mm into the turret)."""
    wrist = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.0, locked_joints=wrist)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 2.0, config=cfg)
    assert res.events_of("impact")
    world = CollisionWorld(robot)
    assert min(world.all_distances(q).min() for q in res.q) > -1.01 * PENETRATION_TOL


def test_a_slide_re_patched_at_zero_speed_keeps_its_direction():
    """A box at rest on the floor whose pair is marked sliding along +x: the modes selected
    again within the mode (``keep``, as a re-patch does) at zero tangential speed keep the
    slide's direction (it was 0 / 0 = NaN: the extension handed the case to the Python
    selection, which divided)."""
    robot = box_robot()
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5)
    q = np.array([0.0, HALF_Z, 0.0])
    sysm = System(robot, q, cfg, Environment(obstacles=(FLOOR,)))
    nc = NormalContacts.from_config(sysm.model, sysm.data, sysm.world, cfg)
    assert nc.add_pair(q, 0)
    pair = nc.pairs[0]
    pair.stick, pair.slip_dir = False, np.array([1.0, 0.0, 0.0])
    minv = sysm.minv(q)
    a_free = minv @ -pin.computeGeneralizedGravity(sysm.model, sysm.data, q)
    nc.select_modes(q, np.zeros(3), a_free, minv, keep=True)
    assert not pair.stick
    np.testing.assert_array_equal(pair.slip_dir, [1.0, 0.0, 0.0])
