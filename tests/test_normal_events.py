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
    # (coverage floors, not counts: steps with several crossings vary with the machine's
    # rounding, 7 to 11+ measured)
    assert seen["steps"] > 20 and seen["several"] >= 3
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
