"""The contact-normal mode's batched contact rows and small solvers, against references.

The rows of :class:`packbot.contact.normal.NormalContacts` (one batch of numpy operations over
every patch point) are checked against Pinocchio point Jacobians computed point by point and
against finite differences of the gaps along q(t) = q + v t (q'' = 0); the patch materials
against the patch they are made of; :func:`packbot.contact.lcp.lemke` against analytic and
complementarity conditions; and the collapse past the state where a stick/slip restart once
repeated forever.
"""

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot.contact import native
from packbot.contact.lcp import lemke
from packbot.contact.normal import NormalContacts
from packbot.system import System


@pytest.fixture(scope="module", autouse=True)
def _steps_one_by_one(step_by_step: None) -> None:
    """This module watches the steps the loop takes one by one (conftest.step_by_step)."""


WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


@pytest.fixture(scope="module")
def contacts(robot):
    """The arm 0.6 s into the collapse (mu = 0.5): link 2 on the chassis, link 3 on link 1."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 0.6, config=cfg)
    sysm = System(robot, res.q[-1], cfg, None)
    nc = NormalContacts.from_config(sysm.model, sysm.data, sysm.world, cfg)
    q = sysm.reduce(res.q[-1])
    assert sysm.world is not None
    for p in range(len(sysm.world.pairs)):
        nc.add_pair(q, p)
    assert len(nc.pairs) >= 2
    return sysm, nc, q


def _point_jacobian(sysm: System, q: np.ndarray, joint: int, local: np.ndarray) -> np.ndarray:
    """3 x nv Jacobian of a point fixed in a joint's frame, Pinocchio alone."""
    if joint == 0:
        return np.zeros((3, sysm.nv))
    pin.computeJointJacobians(sysm.model, sysm.data, q)
    M = sysm.data.oMi[joint]
    return sysm.point_jacobian(q, joint, M.act(local))


def test_rows_match_pointwise_jacobians_and_gap_derivatives(contacts, rng):
    sysm, nc, q0 = contacts
    for _ in range(3):
        q = q0 + 0.01 * rng.standard_normal(len(q0))
        v = rng.standard_normal(len(q0))
        Jn, _, _, vn, extra = nc._kinematics(q, v)
        k = 0
        for p, ex in zip(nc.pairs.values(), extra, strict=True):
            i1, i2 = p.info.joint1, p.info.joint2
            pin.forwardKinematics(sysm.model, sysm.data, q)
            i_n = i1 if p.on1 else i2  # the joint carrying the normal
            Rn = sysm.data.oMi[i_n].rotation if i_n else np.eye(3)
            n = Rn @ p.normal2
            np.testing.assert_allclose(ex["n"], n, atol=1e-14)
            # the normal turns with its body: the row acts on that body at the other body's
            # point, d/dq [n . (p2 - p1)] = n . (J_p2 - J_p1) + (n x (p2 - p1)) . J_w
            Jw = np.zeros((3, sysm.nv))
            if i_n:
                pin.computeJointJacobians(sysm.model, sysm.data, q)
                Jw = pin.getJointJacobian(sysm.model, sysm.data, i_n, pin.WORLD)[3:]
            M1 = sysm.data.oMi[i1] if i1 else pin.SE3.Identity()
            M2 = sysm.data.oMi[i2] if i2 else pin.SE3.Identity()
            for a, b in zip(p.local1, p.local2, strict=True):
                J = _point_jacobian(sysm, q, i2, b) - _point_jacobian(sysm, q, i1, a)
                J = n @ J + np.cross(n, M2.act(b) - M1.act(a)) @ Jw
                np.testing.assert_allclose(Jn[k], J, atol=1e-13)
                assert vn[k] == pytest.approx(J @ v, abs=1e-12)
                k += 1

    # At the patch's own state (p2 - p1 along n) the gap's derivatives along q + v t
    # (q'' = 0) are g' = J_n v and g'' = drift (central differences).
    v = rng.standard_normal(len(q0))
    _, drift, gap, vn, _ = nc._kinematics(q0, v)
    h = 1e-4
    g_plus = nc._kinematics(q0 + h * v, v)[2]
    g_minus = nc._kinematics(q0 - h * v, v)[2]
    np.testing.assert_allclose((g_plus - g_minus) / (2 * h), vn, rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose((g_plus - 2 * gap + g_minus) / h**2, drift, rtol=1e-5, atol=1e-5)


def test_tangential_rows_span_the_contact_plane(contacts, rng):
    _, nc, q0 = contacts
    v = rng.standard_normal(len(q0))
    _, _, _, _, extra = nc._kinematics(q0, v)
    for ex in extra:
        F = np.vstack([ex["T"], ex["n"]])
        np.testing.assert_allclose(F @ F.T, np.eye(3), atol=1e-14)
        assert np.linalg.det(F) == pytest.approx(1.0)  # (t1, t2, n) right-handed
        # the tangential velocity of the centre is the plane part of its velocity
        np.testing.assert_allclose(ex["T"].T @ ex["vT"], ex["vt"], atol=1e-14)
        np.testing.assert_allclose(ex["JT"] @ v, ex["vT"], atol=1e-12)


def test_tangential_rows_are_the_exact_derivatives_of_the_centres_slides(contacts, rng):
    """The slides s = T (c2 - c1) of the patch centres, T the tangents turning with the body
    carrying the frame (the normal's): along q + v t (q'' = 0) their central differences are
    the rows' v_T = J_T v and their drift b_T; the sliding velocity v_t is the relative
    velocity where the bodies touch (body b's velocity field at the other body's centre),
    not that of b's own material centre, which slides away from it."""
    sysm, nc, q0 = contacts
    model, data = sysm.model, sysm.data

    def slides(q):
        pin.forwardKinematics(model, data, q)
        out = []
        for p in nc.pairs.values():
            i1, i2 = p.info.joint1, p.info.joint2
            M1 = data.oMi[i1] if i1 else pin.SE3.Identity()
            M2 = data.oMi[i2] if i2 else pin.SE3.Identity()
            i_n = i1 if p.on1 else i2
            Rn = data.oMi[i_n].rotation if i_n else np.eye(3)
            T = p.frame2[:2] @ Rn.T  # rows t1, t2 in the world
            out.append(T @ (M2.act(p.centre2[0]) - M1.act(p.centre1[0])))
        return np.array(out)

    moved = 0.0
    for _ in range(3):
        # away from the patches' own state: the centres slid apart by up to a millimetre
        q = q0 + 3e-3 * rng.standard_normal(len(q0))
        v = rng.standard_normal(len(q0))
        _, _, _, _, extra = nc._kinematics(q, v)
        vT = np.array([ex["vT"] for ex in extra])
        bT = np.array([ex["bT"] for ex in extra])
        h = 1e-5
        sp, s0, sm = slides(q + h * v), slides(q), slides(q - h * v)
        np.testing.assert_allclose((sp - sm) / (2 * h), vT, rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose((sp - 2 * s0 + sm) / h**2, bT, rtol=1e-4, atol=1e-4)
        for ex, p in zip(extra, nc.pairs.values(), strict=True):
            np.testing.assert_allclose(ex["JT"] @ v, ex["vT"], atol=1e-12)
            # the relative velocity at the touching centre: body b's field there
            pin.forwardKinematics(model, data, q, v)
            i1, i2 = p.info.joint1, p.info.joint2
            M1 = data.oMi[i1] if i1 else pin.SE3.Identity()
            M2 = data.oMi[i2] if i2 else pin.SE3.Identity()
            c1, c2 = M1.act(p.centre1[0]), M2.act(p.centre2[0])

            def field(joint, x):  # world velocity of the body's material point at x
                if joint == 0:
                    return np.zeros(3)
                Vw = pin.getVelocity(model, data, joint, pin.LOCAL_WORLD_ALIGNED)
                return Vw.linear + np.cross(Vw.angular, x - data.oMi[joint].translation)

            at = c2 if p.on1 else c1  # the other body's centre
            vrel = field(i2, at) - field(i1, at)
            n = ex["n"]
            np.testing.assert_allclose(ex["vt"], vrel - n * (n @ vrel), atol=1e-12)
            moved = max(moved, float(np.linalg.norm(c2 - c1 - n * (n @ (c2 - c1)))))
    assert moved > 1e-4  # the slides were not all zero (the terms in c2 - c1 were tested)


def test_lemke_solves_small_lcps_with_a_solution(rng):
    """Lemke's pivots on the contact problems' sizes (1 to 8 rows): a diagonal problem gets its
    analytic answer z_i = max(0, -q_i / M_ii); a positive definite one (symmetric, or with a
    skew part: a P-matrix, one solution) is solved, z >= 0, w = M z + q >= 0 and z . w = 0 to
    1e-9 of the problem's scale (the rounding of its pivots)."""
    for trial in range(400):
        n = int(rng.integers(1, 9))
        d = rng.uniform(0.5, 2.0, n)
        q = rng.standard_normal(n)
        z = lemke(np.diag(d), q)
        assert z is not None
        np.testing.assert_allclose(z, np.maximum(0.0, -q / d), rtol=1e-12, atol=1e-15)
        A = rng.standard_normal((n, n + 1))
        M = A @ A.T + 0.1 * np.eye(n)
        if trial % 2:
            S = rng.standard_normal((n, n))
            M = M + 0.5 * (S - S.T)
        z = lemke(M, q)
        assert z is not None
        w = M @ z + q
        scale = 1.0 + float(np.abs(q).max()) + float(np.abs(M @ z).max())
        assert float(z.min()) >= 0.0 and float(w.min()) >= -1e-9 * scale
        assert abs(float(z @ w)) <= 1e-9 * scale * scale


def test_collapse_passes_the_stick_slip_restart_that_repeated(robot):
    """A 1e-15 rad change of the initial shoulder angle once led to a stick event at the same
    state after every restart (t = 0.3245 s, max_events reached): it must pass."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST, max_events=300)
    q0 = robot.pose("drive").copy()
    q0[robot.joint_names.index("shoulder")] += 1e-15
    res = packbot.simulate(robot, q0, np.zeros(8), 0.4, config=cfg)
    assert res.t[-1] == pytest.approx(0.4)
    same_time = np.unique([ev.t for ev in res.events_of("stick")], return_counts=True)[1]
    assert same_time.max(initial=0) <= 10  # before: until max_events


@pytest.mark.parametrize("mu", [0.0, 0.5])
def test_the_compiled_dynamics_equal_the_numpy_ones_along_a_collapse(robot, monkeypatch, mu):
    """At every accepted step of a collapse, the compiled constrained dynamics (one kernel:
    rows, slipping columns, sticking rows, Delassus solve) give the numpy path's a, lambda, gaps,
    normal and tangential velocities, over stick, slip and limit rows."""
    from packbot import ode

    seen = {"slip": 0, "stick": 0, "limit": 0, "states": 0}
    worst = 0.0
    step = ode.RK45Stepper.step

    def checked(self, t_end, kernel=None, first=None, stiff=None):
        nonlocal worst
        seg = step(self, t_end, kernel, first, stiff)
        run = self._rhs.__self__
        nc, n = run.law.normal, run.n
        if nc.resting or not nc.engaged:
            return seg
        q, v = seg.y1[:n], seg.y1[n : 2 * n]
        a_free, minv = run.sys.aba(q, v, np.zeros(n)), run.sys.minv(q)
        plan = nc._plan()
        fast = nc._evaluate_compiled(q, v, a_free, minv, plan)
        ref = nc._evaluate_rows(q, v, a_free, minv, plan)
        for x, y in ((fast.a, ref.a), (fast.lam, ref.lam), (fast.gap, ref.gap)):
            scale = 1.0 + np.abs(y).max(initial=0.0)
            worst = max(worst, float(np.abs(x - y).max(initial=0.0)) / scale)
        np.testing.assert_allclose(fast.vn, ref.vn, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(fast.vt, ref.vt, rtol=1e-9, atol=1e-12)
        seen["states"] += 1
        seen["slip"] += len(plan.slips) > 0
        seen["stick"] += len(plan.sticks) > 0
        seen["limit"] += any(r >= sum(len(p.local1) for p in nc.pairs.values()) for r in nc.engaged)
        return seg

    monkeypatch.setattr(ode.RK45Stepper, "step", checked)
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, locked_joints=WRIST)
    packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 1.6, config=cfg)
    assert seen["states"] > 100 and seen["limit"] > 10
    assert worst < 1e-9
    if mu > 0.0:
        assert seen["slip"] > 10 and seen["stick"] > 10


def test_small_solves_in_closed_form_match_lapack(rng):
    """solve_small (Cramer's rule up to 3 x 3, the locks' and the engaged rows' systems)
    agrees with numpy's LU solve, and falls back to least squares on a singular matrix."""
    from packbot.contact.lcp import solve_small

    for n in (1, 2, 3, 4):
        for _ in range(300):
            A = rng.standard_normal((n, n))
            G = A @ A.T + 1e-2 * np.eye(n)  # a Delassus block or a block of M^-1
            r = rng.standard_normal(n)
            ref = np.linalg.solve(G, r)
            np.testing.assert_allclose(
                solve_small(G, r), ref, rtol=1e-9, atol=1e-12 * abs(ref).max()
            )
    G = np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [1.0, 0.0, 1.0]])  # rank 2
    r = np.array([1.0, 2.0, 0.5])
    np.testing.assert_allclose(solve_small(G, r), np.linalg.lstsq(G, r, rcond=None)[0])


def test_step_end_reuses_the_last_stage_and_violated_agrees(robot, monkeypatch):
    """At a step's end the mode conditions reuse the stepper's last-stage evaluation (the
    same inputs by value: the result is what a fresh evaluation gives, bit for bit);
    ``violated`` says exactly whether a condition of ``conditions`` is negative, on the
    run's evaluations (the kernel's smallest condition) and on copies with one row's gap or
    force pushed negative; the patch check from the kernel's slides finds the pairs the
    rows' own slides find."""
    from dataclasses import replace

    from packbot.contact import normal

    seen = {"hits": 0, "states": 0, "flagged": 0, "kernel": 0, "slid": 0}
    again = normal.NormalContacts.evaluate_again

    def checked(self, q, v, a_free, minv):
        ev = again(self, q, v, a_free, minv)
        last = self._last_eval
        hit = last is not None and ev is last[6]
        self._last_eval = None
        fresh = self.evaluate(q, v, a_free, minv)
        for x, y in ((ev.a, fresh.a), (ev.lam, fresh.lam), (ev.gap, fresh.gap)):
            np.testing.assert_array_equal(x, y)
        np.testing.assert_array_equal(ev.vt, fresh.vt)
        seen["hits"] += hit
        seen["states"] += 1
        cond = self.conditions(ev)
        assert self.violated(ev) == any(g < 0.0 for _, g in cond.values())
        if ev.cond is not None:  # the kernel's smallest condition
            values = [g for _, g in cond.values()]
            assert ev.cond == pytest.approx(min(values), rel=1e-12, abs=1e-15)
            seen["kernel"] += 1
        if ev.slide2 is not None:  # the patch check from the kernel's slides, and without
            self._last_eval = (q, v, a_free, minv, None, None, ev)
            distance, k = {}, 0  # the pairs' distances at their patches' gaps: slides decide
            for key, p in self.pairs.items():
                distance[key] = float(ev.gap[k : k + len(p.local1)].min())
                k += len(p.local1)
            fast = self.stale_pairs(q, v, distance)
            self._last_eval = None
            assert fast == self.stale_pairs(q, v, distance)
            seen["slid"] += len(fast)
        if len(ev.gap):  # a row pushed across its condition
            for r in range(len(ev.gap)):
                gap = ev.gap.copy()
                gap[r] = -1.0
                lam = ev.lam.copy()
                if len(lam):
                    lam[:] = -1.0
                bad = replace(ev, gap=gap, lam=lam, cond=None)
                negative = any(g < 0.0 for _, g in self.conditions(bad).values())
                assert self.violated(bad) == negative
                seen["flagged"] += negative
        return ev

    monkeypatch.setattr(normal.NormalContacts, "evaluate_again", checked)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST)
    # a torque function: the stepper's stages call the right-hand side (no native step, whose
    # end reads its own evaluation, not this one)
    zero = lambda t, q, v: np.zeros(8)  # noqa: E731
    packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 1.2, config=cfg, controller=zero)
    assert seen["states"] > 100
    assert seen["hits"] > 0.8 * seen["states"]
    assert seen["flagged"] > 100 and seen["kernel"] > 100 and seen["slid"] > 10


@pytest.mark.parametrize("mu", [0.0, 0.5])
def test_the_pairs_skipped_at_a_step_end_have_no_event(robot, monkeypatch, mu):
    """NormalLaw._pairs_to_check leaves out only swept pairs whose pair events are empty (the
    same crossings as checking every pair), and leaves out most of them."""
    from packbot.contact import normal

    seen = {"skipped": 0, "checked": 0}
    pick = normal.NormalLaw._pairs_to_check

    def checked(self, pairs, distances):
        out = pick(self, pairs, distances)
        for i, (p, d1) in enumerate(zip(pairs, distances, strict=True)):
            if i in out:
                seen["checked"] += 1
                continue
            seen["skipped"] += 1
            d0 = self.last_d.get(p, np.inf)
            assert self._pair_crossings(("pair", p), p, None, d0, d1) == []
        assert list(out) == sorted(out)
        return out

    monkeypatch.setattr(normal.NormalLaw, "_pairs_to_check", checked)
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, locked_joints=WRIST)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 1.0, config=cfg)
    assert res.diagnostics.steps > 100 and len(res.events) > 5
    assert seen["skipped"] > 5 * seen["checked"] > 0


def test_patch_materials_are_the_patch_points_on_the_bodies(contacts, rng):
    """A patch made material points (``packbot._native.patch_material``) at the collapse's
    pairs and at states around them: each body's points are Coal's moved along the normal only
    (onto its face), expressed in the body's joint frame; the smallest gap along the normal is
    the pair's distance (to the patch tolerance); the normal is fixed in the body whose face is
    the better aligned with it; the contact frame is orthonormal and right-handed around it;
    the centres are the points' means and the offsets the points' tangential separations; and
    add_pair stores that patch."""
    from packbot import _native
    from packbot.contact.normal_tolerances import PATCH_TOL

    sysm, nc, q0 = contacts
    world, data = sysm.world, sysm.data
    checked = lifted = 0
    for trial in range(12):
        q = q0 + (0.0 if trial == 0 else 2e-4) * rng.standard_normal(len(q0))
        for k in list(nc.pairs):
            patch = world.contact_patch(q, k, nc.tol)
            if patch is None:
                continue
            pin.forwardKinematics(sysm.model, data, q)
            info = patch.pair
            M1 = data.oMi[info.joint1] if info.joint1 else pin.SE3.Identity()
            M2 = data.oMi[info.joint2] if info.joint2 else pin.SE3.Identity()
            G1, G2 = world.geom_data.oMg[info.geom1], world.geom_data.oMg[info.geom2]
            planes1, planes2 = nc._planes_of(info.geom1), nc._planes_of(info.geom2)
            n, d = patch.normal, float(patch.distance)
            ok, l1, l2, n2, F, c1, c2, off, on1 = _native.patch_material(
                patch.points1, patch.points2, n, d,
                *planes1, G1.rotation, G1.translation, *planes2, G2.rotation, G2.translation,
                M1.rotation, M1.translation, M2.rotation, M2.translation, PATCH_TOL, True,
            )  # fmt: skip
            if not ok:
                continue
            p1 = l1 @ M1.rotation.T + M1.translation  # the points, world
            p2 = l2 @ M2.rotation.T + M2.translation
            for p, c in ((p1, patch.points1), (p2, patch.points2)):
                along = (p - c) @ n
                np.testing.assert_allclose(p - c, along[:, None] * n[None, :], atol=1e-12)
            lifted += bool(np.abs((p1 - patch.points1) @ n).max() > 1e-12)
            gaps = (p2 - p1) @ n
            assert abs(float(gaps.min()) - d) <= PATCH_TOL + 1e-12
            (N1, _), (N2, _) = planes1, planes2
            best1 = float((N1 @ (G1.rotation.T @ n)).max(initial=-np.inf))
            best2 = float((N2 @ (G2.rotation.T @ -n)).max(initial=-np.inf))
            assert on1 == (best1 > best2)
            Rn = (M1 if on1 else M2).rotation
            np.testing.assert_allclose(Rn @ n2, n, atol=1e-14)
            np.testing.assert_allclose(F @ F.T, np.eye(3), atol=1e-14)
            np.testing.assert_allclose(np.cross(F[0], F[1]), F[2], atol=1e-14)
            np.testing.assert_allclose(F[2], n2, atol=0.0)
            np.testing.assert_allclose(c1, l1.mean(axis=0)[None, :], atol=1e-14)
            np.testing.assert_allclose(c2, l2.mean(axis=0)[None, :], atol=1e-14)
            np.testing.assert_allclose(off, F[:2] @ (Rn.T @ (p2 - p1).T), atol=1e-12)
            assert nc.add_pair(q, k)
            stored = nc.pairs[k]
            assert stored.on1 == on1
            np.testing.assert_array_equal(stored.local1, l1)
            np.testing.assert_array_equal(stored.offset0, off)
            checked += 1
    for k in list(nc.pairs):  # the module's contact set back at its state
        nc.add_pair(q0, k)
    assert checked >= 12 and lifted >= 6


def test_a_repatch_of_the_same_shape_reuses_the_layout_and_equals_a_full_build(contacts, rng):
    """A refresh that keeps every pair's patch size keeps the layout's index arrays and
    replaces only the patch points, frames and offsets: the layout and the rows at a state are
    those of a layout built from nothing, bit for bit; a change of shape builds it anew."""
    from dataclasses import fields

    sysm, _, q0 = contacts
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST)
    nc = NormalContacts.from_config(sysm.model, sysm.data, sysm.world, cfg)
    assert sysm.world is not None
    for p in range(len(sysm.world.pairs)):
        nc.add_pair(q0, p)
    first = nc._layout()
    sizes = nc.row_signature()
    q = q0 + 1e-5 * rng.standard_normal(len(q0))
    nc.refresh(q)
    assert nc.row_signature() == sizes  # the same pairs and patch sizes
    v = rng.standard_normal(len(q0))
    lay = nc._layout()
    assert lay is not first and lay.rows is first.rows and lay.body is first.body
    assert not np.array_equal(lay.local, first.local)  # the new patches
    rows = nc._kinematics(q, v)
    nc._lay_prev = None  # forget it: the next layout is built from nothing
    nc._invalidate()
    full = nc._layout()
    assert full.rows is not lay.rows
    for f in fields(full):
        a, b = getattr(full, f.name), getattr(lay, f.name)
        if f.name in ("placements", "fixed", "H"):  # (H: a buffer filled at every call)
            assert len(a) == len(b)
        elif isinstance(a, list):
            assert a == b, f.name
        else:
            assert np.array_equal(a, b) and a.dtype == b.dtype and a.shape == b.shape, f.name
    for x, y in zip(rows[:4], nc._kinematics(q, v)[:4], strict=True):
        assert np.array_equal(x, y)
    # another shape (a pair less): built anew
    nc.remove_pair(next(iter(nc.pairs)))
    smaller = nc._layout()
    assert smaller.rows is not full.rows and len(smaller.pair) < len(full.pair)


def test_the_plans_pairs_decide_sliding_and_staleness_as_the_loop_over_every_pair(
    robot, monkeypatch
):
    """At every step end of the collapse (mu = 0.5) ``sliding`` and ``stale``, which look at
    the modes' plan's pairs only, decide as the rule over every pair of the contact set: a pair
    with engaged rows, not sticking, faster than STICK_SPEED slides; the first pair with
    engaged rows whose patch is stale (``stale_pairs`` over every pair) is the stale one."""
    import math

    from packbot.contact.normal_rows import ContactRows, _same
    from packbot.contact.normal_tolerances import STICK_SPEED

    real_sliding, real_stale = ContactRows.sliding, ContactRows.stale_pairs
    seen = {"sliding": 0, "slides": 0, "stale": 0, "stales": 0}

    def sliding(self, q, v):
        out = real_sliding(self, q, v)
        ref = False
        if self.engaged and self.pairs and not self.resting:
            last = self._last_eval
            if last is not None and _same(last[0], q) and _same(last[1], v):
                vts = last[6].vt
            else:
                vts = [ex["vt"] for ex in self._problem(q, v)[4]]
            ref = any(
                not (self.mu > 0.0 and p.stick)
                and math.sqrt(float(vt @ vt)) > STICK_SPEED
                and self._pair_engaged(p)
                for p, vt in zip(self.pairs.values(), vts, strict=True)
            )
        assert out == ref
        seen["sliding"] += 1
        seen["slides"] += out
        return out

    def stale_pairs(self, q, v, distance, engaged_only=False):
        out = real_stale(self, q, v, distance, engaged_only)
        if engaged_only:
            every = real_stale(self, q, v, distance, False)
            ref = [k for k in every if self._pair_engaged(self.pairs[k])][:1]
            assert out == ref
            seen["stale"] += 1
            seen["stales"] += bool(out)
        return out

    monkeypatch.setattr(ContactRows, "sliding", sliding)
    monkeypatch.setattr(ContactRows, "stale_pairs", stale_pairs)
    # every step end asks (the native step end's screen would skip the clear ones: its own
    # agreement with these checks is tests/test_normal_screen.py's)
    monkeypatch.setattr(native.NativeWatch, "end_check", lambda self, *a: -1)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST)
    packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 5.0, config=cfg)
    # (the collapse's 5 s: 678 step ends with engaged rows, 381 of them sliding, 87 stale; 46
    # stale since a vertex on a face is not re-patched for its slide)
    assert seen["sliding"] > 500 and seen["slides"] > 250, seen
    assert seen["stale"] > 250 and seen["stales"] > 30, seen


def test_the_mode_solve_on_its_hoisted_parts_equals_the_inline_one_to_the_bit(contacts, rng):
    """``_solve_modes`` with a ``_ModeBase`` built once (as the mode loop and the direction
    iteration reuse it, its stick-row blocks cached by the stick flags) gives the bits of a
    fresh construction, for every stick/slip assignment tried, new sliding directions each
    time (cache hits included); ``_norm`` is ``np.linalg.norm`` bit for bit."""
    from packbot.contact.normal_modes import _ModeBase, _norm
    from packbot.contact.normal_tolerances import BAUMGARTE

    sysm, nc, q0 = contacts
    saved = (list(nc.engaged), [(p.stick, p.slip_dir.copy()) for p in nc.pairs.values()])
    try:
        solved = 0
        for _ in range(4):
            q = q0 + 1e-3 * rng.standard_normal(len(q0))
            v = 0.1 * rng.standard_normal(len(q0))
            a_free = sysm.aba(q, v, np.zeros(len(q0)))
            minv = sysm.minv(q)
            Jn, drift, gap, vn, extra = nc._problem(q, v)
            touch = list(range(len(gap)))
            base = _ModeBase(touch, Jn, drift, gap, vn, a_free, minv)
            bN = Jn[touch] @ a_free + drift[touch] + 2.0 * BAUMGARTE * vn[touch]
            bN = bN + BAUMGARTE**2 * gap[touch]
            assert np.array_equal(base.bN, bN)
            assert np.array_equal(base.JnM, Jn[touch] @ minv)
            every = [True] * len(nc.pairs)
            mixed = [i % 2 == 0 for i in range(len(nc.pairs))]
            for sticks in (every, mixed, every, mixed):  # the stick-row cache: miss, miss, hit
                for p, s in zip(nc.pairs.values(), sticks, strict=True):
                    p.stick = s
                    d = rng.standard_normal(3)
                    p.slip_dir = d / np.linalg.norm(d)
                args = (touch, Jn, drift, gap, vn, extra, a_free, minv)
                lam1, ok1 = nc._solve_modes(*args, base)
                engaged1 = list(nc.engaged)
                lam2, ok2 = nc._solve_modes(*args)
                assert ok1 == ok2
                solved += ok1
                assert engaged1 == nc.engaged
                if ok1:
                    assert lam1["lamN"] == lam2["lamN"]
                    assert np.array_equal(lam1["lamT"], lam2["lamT"])
                assert tuple(sticks) in base.stick_rows
            assert len(base.stick_rows) == 2  # one entry per stick assignment, reused
        assert solved >= 8  # most of the 16 problems have a solution to compare
        for _ in range(50):
            x = rng.standard_normal(int(rng.integers(1, 5))) * 10.0 ** rng.uniform(-8, 3)
            assert _norm(x) == float(np.linalg.norm(x))
    finally:
        nc.engaged = saved[0]
        for p, (s, d) in zip(nc.pairs.values(), saved[1], strict=True):
            p.stick, p.slip_dir = s, d


def test_refresh_keeps_a_patch_built_at_the_same_state(contacts):
    """``refresh(q)`` keeps a patch already built at q with the contact tolerance (a pair an
    impact just put in the set, before the restart's refresh) and builds the others again: a
    patch built again there is the same, bit for bit."""
    _, nc, q0 = contacts
    k = next(iter(nc.pairs))
    q = q0 + 1e-6
    assert nc.add_pair(q, k)
    first = nc.pairs[k]
    built = {j: p for j, p in nc.pairs.items() if j != k}
    nc.refresh(q)
    assert nc.pairs[k] is first  # kept
    assert all(nc.pairs[j] is not p for j, p in built.items())  # the others built at q
    again = nc.pairs[k]
    assert nc.add_pair(q, k)  # built again at q: the same patch
    for name in ("local1", "local2", "normal2", "offset0", "frame2"):
        np.testing.assert_array_equal(getattr(nc.pairs[k], name), getattr(again, name))
    assert nc.add_pairs(q, [k], tol=2.0 * nc.tol) == [True]  # another margin: built again
    other = nc.pairs[k]
    nc.refresh(q)
    assert nc.pairs[k] is not other
    for j in list(nc.pairs):  # the module's contact set back at its state
        nc.add_pair(q0, j)
