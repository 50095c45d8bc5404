"""The contact-normal mode's event location and restart solvers, against the ways they replace.

- :func:`packbot.ode.locate_earliest` (the event loop's ``locate``) keeps the crossings that
  locating every crossing on the whole step keeps, at the same time (to the event tolerance:
  a pair's distance is warm-started by Coal from its last query, so its root finder's iterates
  move in the last bits with the order of the queries), on real steps of contact runs.
- The compiled Lemke on the Delassus problems of the projection, the frictionless impact and
  the symmetric mode problems (``normal_modes._psd_lcp``) gives the step (the accelerations)
  of the non-negative least squares it replaces, and at any size the array version's pivots.
- One mode condition read alone equals its entry in the dictionary of all of them.
"""

import numpy as np
import pytest

import packbot
from packbot import integrator
from packbot.contact import normal_steps
from packbot.contact.lcp import lcp_residual, solve_lcp_psd
from packbot.contact.normal_tolerances import RESIDUAL_TOL
from packbot.ode import locate_root

WRIST = ("camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw")


@pytest.mark.parametrize("mu", [0.0, 0.5])
def test_the_located_events_equal_locating_every_crossing_on_real_steps(robot, monkeypatch, mu):
    """At every step of a wrist-free collapse with events, the event time and the crossings at
    it equal those of locating each crossing (the former ``locate``), with fewer evaluations of
    the event functions."""
    xtol = integrator.EVENT_XTOL
    locate = integrator._Run.locate
    seen = {"steps": 0, "several": 0, "new": 0, "old": 0}

    def counted(g, key):
        def h(t: float) -> float:
            seen[key] += 1
            return float(g(t))

        return h

    def checked(self, seg, crossings):
        wrapped = [
            integrator.Crossing(c.kind, c.key, counted(c.g, "new"), c.g0, c.g1) for c in crossings
        ]
        t_star, at = locate(self, seg, wrapped)
        t0, t1 = seg.t0, seg.t1
        times = [
            t0 if c.g0 <= 0.0 else locate_root(counted(c.g, "old"), t0, t1, c.g0, c.g1, xtol=xtol)
            for c in crossings
        ]
        t_old = min(times)
        at_old = [c.key for c, tc in zip(crossings, times, strict=True) if tc <= t_old + 10 * xtol]
        assert [c.key for c in at] == at_old
        assert abs(t_star - t_old) <= xtol
        seen["steps"] += 1
        seen["several"] += len(crossings) > 1
        return t_star, [crossings[[w.key for w in wrapped].index(c.key)] for c in at]

    monkeypatch.setattr(integrator._Run, "locate", checked)
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, restitution=0.0)
    packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 1.5, config=cfg)
    assert seen["steps"] > 20 and seen["several"] > 10
    assert seen["new"] < seen["old"]


def _delassus(rng, m, rank, nv=6):
    J = rng.normal(size=(rank, nv))
    J = rng.normal(size=(m, rank)) @ J  # m rows on `rank` independent ones
    L = rng.normal(size=(nv, nv))
    minv = L @ L.T + 0.1 * np.eye(nv)
    return J, minv, J @ minv @ J.T


@pytest.mark.parametrize("m,rank", [(1, 1), (3, 3), (4, 2), (7, 3), (8, 6)])
def test_the_compiled_lemke_gives_the_least_squares_step(rng, m, rank):
    """On Delassus problems with more rows than freedoms (a patch), the compiled Lemke's answer
    passes the residual and moves the bodies as the least-squares solution does (to 1e-6: on
    nearly dependent rows, cond 1e6, Lemke may take a basis with large cancelling impulses and
    lose digits, 4e-8 of the step measured here, within the residual the solvers must pass)."""
    tried = 0
    for _ in range(40):
        J, minv, G = _delassus(rng, m, rank)
        g = J @ rng.normal(size=J.shape[1])  # in the range of G: a velocity the bodies can have
        if np.all(g >= 0.0):
            continue
        tried += 1
        z = normal_steps._psd_lcp(G, g)
        ref = solve_lcp_psd(G, g)
        assert lcp_residual(G, g, z) <= RESIDUAL_TOL
        step, step_ref = minv @ J.T @ z, minv @ J.T @ ref
        scale = 1.0 + np.abs(step_ref).max()
        assert np.abs(step - step_ref).max() <= 1e-6 * scale
    assert tried > 10


def test_the_impulses_and_projections_of_a_collapse_equal_the_least_squares_ones(
    robot, monkeypatch
):
    """At every projection and frictionless impact of a wrist-free collapse (mu = 0), the
    compiled path's G z (so its step M^-1 J^T z: (z - z') . G (z - z') = 0) equals the
    least-squares solution's."""
    psd = normal_steps._psd_lcp
    seen = {"calls": 0, "rows>1": 0}

    def checked(G, g):
        z = psd(G, g)
        ref = solve_lcp_psd(G, g)
        if lcp_residual(G, g, ref) <= RESIDUAL_TOL:
            d = z - ref
            scale = 1.0 + float(np.abs(G @ ref).max(initial=0.0)) + float(np.abs(g).max())
            assert np.abs(G @ d).max(initial=0.0) <= 1e-9 * scale
            assert float(d @ G @ d) <= 1e-16 * scale**2 * (1.0 + float(ref @ ref))
        seen["calls"] += 1
        seen["rows>1"] += len(g) > 1
        return z

    monkeypatch.setattr(normal_steps, "_psd_lcp", checked)
    # (the Python impulse and projection; the native ones equal them: test_native_restart)
    monkeypatch.setattr(normal_steps, "NATIVE_RESTART", False)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.0, restitution=0.0)
    packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 1.0, config=cfg)
    assert seen["calls"] > 20 and seen["rows>1"] > 5


def test_lcps_of_delassus_sized_problems_are_solved_to_complementarity(rng):
    """Problems of 9 to 16 rows (a patch pair and limits) built from rank 2 to 16 rows: a
    positive definite one (symmetric, or with a skew part: friction's columns) is solved by
    Lemke's pivots, a rank-deficient Delassus matrix with a right-hand side the rows can
    produce (q = J c) by the symmetric problems' solver (Lemke, else least squares); z >= 0,
    w = G z + q >= 0 and z . w = 0 to 1e-9 of the problem's scale (the rounding of a few dozen
    pivots: measured below 1e-11)."""
    from packbot.contact import lcp

    for it in range(300):
        n = int(rng.integers(9, 17))
        r = int(rng.integers(2, n + 1))
        J = rng.normal(size=(n, r)) @ rng.normal(size=(r, 8))
        L = rng.normal(size=(8, 8))
        G = J @ (L @ L.T + 0.1 * np.eye(8)) @ J.T
        kind = it % 3
        if kind == 0:
            G = G + 0.1 * np.eye(n)
        elif kind == 1:
            S = rng.normal(size=(n, n))
            G = G + 0.1 * np.eye(n) + 0.1 * (S - S.T)
        q = rng.normal(size=n) if kind < 2 else J @ rng.normal(size=8)
        z = lcp.lemke(G, q) if kind < 2 else normal_steps._psd_lcp(G, q)
        assert z is not None
        w = G @ z + q
        scale = 1.0 + float(np.abs(q).max()) + float(np.abs(G @ z).max())
        assert float(z.min()) >= 0.0
        assert float(w.min()) >= -1e-9 * scale
        assert abs(float(z @ w)) <= 1e-9 * scale * scale


def test_one_mode_condition_equals_the_dictionarys(robot, monkeypatch):
    """At every step end with a mode event of a collapse (mu = 0.5, wrist free), each condition
    read alone (the event functions' way) equals its entry in the dictionary of all of them."""
    from packbot.contact import patch_events

    crossings = patch_events.PatchEvents._problem_crossings
    seen = {"nrow": 0, "nfric": 0}

    def checked(self, contacts, seg, y1, native=None):
        out = crossings(self, contacts, seg, y1, native)
        for t in (seg.t0, 0.5 * (seg.t0 + seg.t1), seg.t1):
            ev = self._contact_eval(contacts, t, seg(t))
            cond = contacts.conditions(ev)
            for k, (_, g) in cond.items():
                assert contacts.condition(ev, k) == g
                seen[k[0]] = seen.get(k[0], 0) + 1
        return out

    monkeypatch.setattr(patch_events.PatchEvents, "_problem_crossings", checked)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5)
    packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 1.0, config=cfg)
    assert seen["nrow"] > 50 and seen["nfric"] > 5


def test_the_mode_lcps_of_a_collapse_give_the_least_squares_accelerations(robot, monkeypatch):
    """At every symmetric mode problem of a wrist-free collapse (mu = 0), the compiled Lemke's
    forces z give the accelerations of the least-squares solution (G z equal: the engaged rows'
    accelerations and the generalized force are those of every solution) and are basic (the
    Delassus block of their support is non-singular), as the selection needs."""
    from packbot.contact import normal_modes

    psd = normal_modes._psd_lcp
    seen = {"calls": 0, "other_support": 0}

    def checked(G, g):
        z = psd(G, g)
        ref = solve_lcp_psd(G, g)
        if lcp_residual(G, g, ref) <= RESIDUAL_TOL and lcp_residual(G, g, z) <= RESIDUAL_TOL:
            scale = 1.0 + float(np.abs(G @ ref).max(initial=0.0)) + float(np.abs(g).max())
            assert np.abs(G @ (z - ref)).max(initial=0.0) <= 1e-9 * scale
            S = np.flatnonzero(z > 1e-12 * (1.0 + np.abs(z).max(initial=0.0)))
            assert np.linalg.matrix_rank(G[np.ix_(S, S)]) == len(S)
            S_ref = np.flatnonzero(ref > 1e-12 * (1.0 + np.abs(ref).max(initial=0.0)))
            seen["other_support"] += not np.array_equal(S, S_ref)
            seen["calls"] += 1
        return z

    monkeypatch.setattr(normal_modes, "_psd_lcp", checked)
    # (the Python selection's LCPs: the native one takes the same decisions, test_native_modes)
    monkeypatch.setattr(normal_modes, "NATIVE_MODES", False)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.0, restitution=0.0)
    packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 1.0, config=cfg)
    assert seen["calls"] > 20


def test_the_frictional_impacts_iteration_limit_keeps_the_impulse(robot, monkeypatch):
    """At every frictional impact of a wrist-free collapse (mu = 0.5), the ADMM stopped at
    ``IMPACT_ADMM_ITERATIONS`` (``normal_steps._impact_admm``) gives the answer of the former
    5,000-iteration limit: the same to the bit when the solver converges before or when the
    cut answer is not accepted (residual 1e-6); else, when the former was accepted too, the same
    normal velocities after the impact (G x) to 1e-5 of the problem's scale (measured up to
    1.6e-6 on the collapses tried)."""
    from packbot.contact.lcp import solve_ncp_admm

    staged = normal_steps._impact_admm
    accept = normal_steps.IMPACT_ADMM_ACCEPT
    seen = {"calls": 0, "same": 0, "cut": 0}

    def checked(model, data, G3, g3, mus):
        x, res = staged(model, data, G3, g3, mus)
        x0, res0 = solve_ncp_admm(model, data, G3, g3, mus, max_iterations=5000)
        seen["calls"] += 1
        if np.array_equal(x, x0):
            seen["same"] += 1
            assert res == res0
        else:
            seen["cut"] += 1
            assert res <= accept  # a cut answer is used only when accepted
            if res0 <= accept:  # (the ADMM's residual is not monotone: res0 may be above)
                scale = 1.0 + float(np.abs(g3).max()) + float(np.abs(G3 @ x0).max())
                assert np.abs(G3 @ (x - x0)).max() <= 1e-5 * scale
        return x, res

    monkeypatch.setattr(normal_steps, "_impact_admm", checked)
    monkeypatch.setattr(normal_steps, "IMPACT_CONIC", False)  # Pinocchio's ADMM at every impact
    # (the Python impulse and projection; the native ones equal them: test_native_restart)
    monkeypatch.setattr(normal_steps, "NATIVE_RESTART", False)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, restitution=0.0)
    packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 1.0, config=cfg)
    assert seen["same"] > 5 and seen["cut"] > 0, seen
    assert seen["cut"] < seen["calls"] / 2


def test_the_compiled_impact_solver_gives_pinocchios_impulse(robot, monkeypatch):
    """At every frictional impact of a wrist-free collapse (mu = 0.5) and of the collapse with
    the wrist locked, the compiled conic solver's answer (``normal_steps._impact_cones``) is a
    solution of the impact's problem: inside the cones, its true residual within
    ``IMPACT_ADMM_ACCEPT``, no energy gained; where the problem's Delassus matrix has full
    rank, the rows' velocities after the impact (G3 x) are those of Pinocchio's ADMM (5,000
    iterations) to 1e-5 of the problem's scale, and so they are at all but a few of the
    rank-deficient ones (most are: 3 rows a point against 8 joints), which can have several
    solutions: measured once, the camera head on the floor at 0.769 s (3 points, rank
    4 of 9), both answers' residuals below 3e-11, 7.9235 J taken against 7.9175 J, the joint
    velocities 0.017 rad/s apart. Pinocchio's is used only where the compiled one is not
    accepted (rarely)."""
    from packbot.contact.lcp import ncp_residual, solve_ncp_admm

    staged = normal_steps._impact_cones
    accept = normal_steps.IMPACT_ADMM_ACCEPT
    seen = {"calls": 0, "compared": 0, "other": 0}
    fallback = normal_steps._impact_admm

    def pinocchio(model, data, G3, g3, mus):
        seen["fallback"] = seen.get("fallback", 0) + 1
        return fallback(model, data, G3, g3, mus)

    def checked(model, data, J3, minv, G3, g3, mus):
        x, res = staged(model, data, J3, minv, G3, g3, mus)
        seen["calls"] += 1
        if res > accept:
            return x, res
        assert ncp_residual(G3, g3, x, mus) == pytest.approx(res, rel=1e-6, abs=1e-15)
        xs = x.reshape(-1, 3)
        assert np.all(np.hypot(xs[:, 0], xs[:, 1]) <= mus * xs[:, 2] * (1 + 1e-12) + 1e-15)
        assert float(x @ g3) + 0.5 * float(x @ (G3 @ x)) <= 1e-12 * (1.0 + abs(float(x @ g3)))
        x0, res0 = solve_ncp_admm(model, data, G3, g3, mus, max_iterations=5000)
        if res0 <= accept:
            scale = 1.0 + float(np.abs(g3).max()) + float(np.abs(G3 @ x0).max())
            d = float(np.abs(G3 @ (x - x0)).max()) / scale
            seen["compared"] += 1
            if d > 1e-5:  # another solution: only where the solutions are not unique
                assert np.linalg.matrix_rank(G3) < len(g3), d
                seen["other"] += 1
        return x, res

    monkeypatch.setattr(normal_steps, "_impact_cones", checked)
    # (the Python impulse and projection; the native ones equal them: test_native_restart)
    monkeypatch.setattr(normal_steps, "NATIVE_RESTART", False)
    monkeypatch.setattr(normal_steps, "_impact_admm", pinocchio)
    for locked in ((), WRIST):
        cfg = packbot.SimConfig(
            contact_mode="normal", mu=0.5, restitution=0.0, locked_joints=locked
        )
        packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 1.0, config=cfg)
    assert seen["calls"] > 10 and seen["compared"] > 10, seen
    assert seen["other"] <= seen["compared"] / 10, seen
    assert seen.get("fallback", 0) < seen["calls"] / 10, seen
