"""The windows' compiled complementarity solver (packbot.contact.conic, issue 17).

Checked against the independent residuals of packbot.contact.lcp and against Pinocchio's ADMM
(which the windows used before) on problems shaped like the windows' own: more rows than the
arm has joints (a rank-deficient Delassus matrix G = A A^T), cones of several frictions and
joint boxes, coupled.
"""

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from packbot.contact.conic import conic_residual, solve_conic
from packbot.contact.lcp import box_residual, ncp_residual, solve_mixed_admm


def _problem(seed: int, blocks: int, boxes: int, rank: int):
    """A window-like problem: G = A A^T of rank ``rank``, box rows, a feasible free velocity.

    g = A nu_f + b as in a window step (J v_f plus open gaps b >= 0 on the normal rows), so
    that stopping the arm (nu = 0) satisfies every row: the problem has a solution.
    """
    rng = np.random.default_rng(seed)
    m = 3 * blocks + boxes
    A = rng.standard_normal((m, rank))
    nu_f = rng.standard_normal(rank)
    g = A @ nu_f
    g[2 : 3 * blocks : 3] += np.where(rng.random(blocks) < 0.5, 0.0, rng.random(blocks))
    mus = rng.choice([0.0, 0.2, 0.5, 0.8, 1.2], size=blocks)
    bound = rng.uniform(0.05, 0.5, size=boxes)
    return A, g, mus, bound


def _true_residual(A, g, x, mus, bound) -> float:
    """The residual as :func:`solve_mixed_admm` reports it (lcp's numpy functions)."""
    G = A @ A.T
    c = slice(0, 3 * len(mus))
    b = slice(3 * len(mus), len(g))
    r = ncp_residual(G[c, c], g[c] + G[c, b] @ x[b], x[c], mus) if len(mus) else 0.0
    if len(bound):
        r = max(r, box_residual(G[b, b], g[b] + G[b, c] @ x[c], x[b], bound))
    return r


WINDOW_PROBLEMS = Path(__file__).parent / "data" / "window_problems.npz"


@pytest.mark.parametrize("name", ["mu08_start5", "mu08_start4"])
def test_a_window_problem_of_a_wrist_free_start_is_solved_cold(name):
    """Two problems recorded in the windows of wrist-free starts 5 and 4 (mu 0.8): 66 and 72
    rows (22 and 24 blocks: the pairs within reach) of rank 7; the hardest of each run for
    this solver from zero (830 and 160 iterations)."""
    data = np.load(WINDOW_PROBLEMS)
    A, g, mus = data[f"{name}_A"], data[f"{name}_g"], data[f"{name}_mus"]
    bound = np.zeros(0)
    x, res, it, _ = solve_conic(A, g, mus, bound, np.zeros(len(g)), 1e-9, 1000)
    assert res <= 1e-9 and it < 1000
    assert _true_residual(A, g, x, mus, bound) == pytest.approx(res, rel=1e-6, abs=1e-15)
    X = x.reshape(-1, 3)
    assert (np.hypot(X[:, 0], X[:, 1]) <= mus * X[:, 2] + 1e-12).all()
    assert X[:, 2].max() > 0.0


@pytest.mark.parametrize(
    ("seed", "blocks", "boxes", "rank"), [(1, 7, 0, 8), (3, 5, 3, 6), (10, 6, 2, 8)]
)
def test_a_rank_deficient_problem_is_solved_to_its_tolerance(seed, blocks, boxes, rank):
    """More rows than joints, cones of several frictions (0 to 1.2), with and without boxes.

    (Random problems of 21 blocks on 8 joints, with unrelated normals, are harder than the
    windows' own: they need more than 5,000 iterations, and the window step then calls
    Pinocchio's ADMM: tests/test_timestep.py.)
    """
    A, g, mus, bound = _problem(seed, blocks, boxes, rank)
    x, res, it, _ = solve_conic(A, g, mus, bound, np.zeros(len(g)), 1e-9, 5000)
    assert 0 < it < 5000
    assert res <= 1e-9
    assert _true_residual(A, g, x, mus, bound) == pytest.approx(res, rel=1e-6, abs=1e-15)
    X = x[: 3 * blocks].reshape(-1, 3)
    assert (np.hypot(X[:, 0], X[:, 1]) <= mus * X[:, 2] + 1e-12).all()  # inside the cones
    assert (np.abs(x[3 * blocks :]) <= bound).all()  # inside the boxes
    assert X[:, 2].max() > 1e-3  # something pushes


def test_the_answer_moves_the_arm_as_pinocchios_does():
    """Same problem, Pinocchio's ADMM: the same velocities after the step, A^T x (the
    impulses themselves are not unique: G is rank-deficient)."""
    A, g, mus, bound = _problem(4, 6, 2, 8)
    mus = np.full(6, 0.3)
    model = pin.buildSampleModelManipulator()
    data = model.createData()
    x, res, _, _ = solve_conic(A, g, mus, bound, np.zeros(len(g)), 1e-10, 20000)
    xp, resp = solve_mixed_admm(
        model, data, A @ A.T, g, mus, np.array([1, 3]), bound, tol=1e-11, max_iterations=20000
    )
    assert res <= 1e-10 and resp <= 1e-8
    np.testing.assert_allclose(A.T @ x, A.T @ xp, atol=1e-5 * np.abs(A.T @ xp).max())


def test_the_residual_matches_the_lcp_modules_definition():
    """conic_residual (compiled) is the residual solve_mixed_admm reports, on any x."""
    A, g, mus, bound = _problem(5, 4, 2, 5)
    rng = np.random.default_rng(6)
    for _ in range(5):
        x = rng.standard_normal(len(g))
        assert conic_residual(A, g, x, mus, bound) == pytest.approx(
            _true_residual(A, g, x, mus, bound), rel=1e-9
        )
    bad = np.full(len(g), np.nan)
    assert conic_residual(A, g, bad, mus, bound) == np.inf


def test_a_warm_start_from_the_answer_needs_no_iteration():
    """The window's steps start from the previous step's impulses on the same rows."""
    A, g, mus, bound = _problem(7, 5, 1, 6)
    x, res, it, _ = solve_conic(A, g, mus, bound, np.zeros(len(g)), 1e-9, 5000)
    assert res <= 1e-9 and it > 0
    x2, res2, it2, _ = solve_conic(A, g, mus, bound, x, 1e-9, 5000)
    # No iteration; the answer comes back as it went in, to the rounding of its projection
    # onto the cones (1 ulp under some OpenBLAS kernels: 2.6e-16 relative)
    assert it2 == 0 and res2 == pytest.approx(res, rel=1e-12, abs=1e-15)
    np.testing.assert_allclose(x2, x, rtol=1e-14, atol=1e-15)


def test_the_previous_rho_warm_starts_the_next_solve():
    """The window's steps pass the last rho on (with the impulses): a nearby problem from the
    previous answer and its rho takes fewer iterations than from the spectral rule's rho."""
    data = np.load(WINDOW_PROBLEMS)
    A, g, mus = data["mu08_start4_A"], data["mu08_start4_g"], data["mu08_start4_mus"]
    bound = np.zeros(0)
    x, res, _, rho = solve_conic(A, g, mus, bound, np.zeros(len(g)), 1e-9, 1000)
    assert res <= 1e-9 and rho > 0.0
    g2 = g + 1e-3 * np.abs(g).max() * np.sin(np.arange(len(g)))  # the next step's problem
    _, res_spec, it_spec, _ = solve_conic(A, g2, mus, bound, x, 1e-9, 1000)
    _, res_warm, it_warm, _ = solve_conic(A, g2, mus, bound, x, 1e-9, 1000, rho)
    assert res_spec <= 1e-9 and res_warm <= 1e-9
    assert it_warm < it_spec


def test_separating_rows_get_no_impulse():
    """Every point leaving and no box row moving: x = 0 at once."""
    A, g, mus, bound = _problem(8, 4, 0, 5)
    g = np.zeros(len(g))
    g[2::3] = 0.1  # every point leaving, no sliding
    x, res, it, _ = solve_conic(A, g, mus, bound, np.zeros(len(g)), 1e-9, 100)
    assert it == 0 and res == 0.0
    assert not x.any()


def test_a_steps_problem_is_its_rows_and_their_delassus_factor():
    """``step_problem``: the tangent rows T dJ and the normal rows of every point, the limits'
    normal rows, the boxes' unit rows; A A^T = J M^-1 J^T; g = J v_f with max(gap, 0) / h on
    the normal rows; the pairs' points get mu, the limits 0."""
    from packbot.contact.conic import step_problem

    rng = np.random.default_rng(11)
    nv, pairs, points = 8, 2, 6  # points: 2 + 3 patch points and a centre (not a row)
    T = rng.standard_normal((pairs, 2, 3))
    dJp = rng.standard_normal((points, 3, nv))
    rows = np.array([0, 1, 3, 4, 5], dtype=np.intp)  # point 2 is pair 0's centre
    row_pair = np.array([0, 0, 1, 1, 1], dtype=np.intp)
    Jn = rng.standard_normal((len(rows) + 1, nv))  # then one limit row
    boxes = np.array([2, 6], dtype=np.intp)
    B = rng.standard_normal((nv, nv))
    minv = B @ B.T + nv * np.eye(nv)
    v_f = rng.standard_normal(nv)
    gap = np.array([-1e-6, 2e-4, 0.0, 1e-3, -3e-5, 5e-4])
    h, mu = 5e-4, 0.7
    J, A, gf, g, mus = step_problem(Jn, T, dJp, rows, row_pair, boxes, minv, v_f, gap, h, mu)
    m = len(Jn)
    assert J.shape == A.shape == (3 * m + 2, nv)
    for r, (k, p) in enumerate(zip(rows, row_pair, strict=True)):
        assert np.allclose(J[3 * r : 3 * r + 2], T[p] @ dJp[k], rtol=1e-14, atol=1e-14)
    assert np.array_equal(J[3 * len(rows) : 3 * m : 3], np.zeros((1, nv)))  # a limit: no tangents
    assert np.array_equal(J[2 : 3 * m : 3], Jn)
    assert np.array_equal(J[3 * m :], np.eye(nv)[boxes])
    assert np.allclose(A @ A.T, J @ minv @ J.T, rtol=1e-12, atol=1e-12)
    assert np.allclose(gf, J @ v_f, rtol=1e-13, atol=1e-13)
    expect = gf.copy()
    expect[2 : 3 * m : 3] += np.maximum(gap, 0.0) / h
    assert np.allclose(g, expect, rtol=1e-13, atol=1e-13)
    assert mus.tolist() == [mu] * len(rows) + [0.0]


def test_a_solve_stuck_just_above_its_tolerance_stops():
    """A residual that no longer drops (the rounding floor of the rows) ends the solve once it
    has held for STALL_CHECKS checks within STALL_OK times the tolerance; far above it, the
    solve goes on to its limit."""
    from packbot.contact import conic

    A, g, mus, bound = _problem(4, blocks=8, boxes=2, rank=6)
    x, res, _, _ = solve_conic(A, g, mus, bound, np.zeros(len(g)), 1e-9, 5000)
    assert res <= 1e-9
    # an unreachable tolerance (far below the floor: no stall stop): the floor
    _, floor, its2, _ = solve_conic(A, g, mus, bound, x, 1e-30, 20_000)
    assert 1e-30 < floor <= res and its2 == 20_000
    tol = floor / (0.8 * conic.STALL_OK)  # the floor: above it, within STALL_OK times it
    _, res3, its3, _ = solve_conic(A, g, mus, bound, x, tol, 20_000)
    assert tol < res3 <= conic.STALL_OK * tol
    assert its3 < 20_000  # (stopped by the stall, not the limit)
    # the floor far above STALL_OK times the tolerance: no early stop
    _, _, its4, _ = solve_conic(A, g, mus, bound, x, floor / (10.0 * conic.STALL_OK), 3000)
    assert its4 == 3000
