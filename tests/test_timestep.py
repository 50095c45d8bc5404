"""Time-stepping windows of the contact-normal mode (packbot.contact.timestep, issue 16).

Where events pile up the law takes fixed Moreau-Jean steps with one complementarity problem
each (contact cones and the joints' Coulomb friction and brakes as boxes), then resumes
event-driven integration. Checked here on real runs: the starts that used to stop at the
``max_events`` guard finish; no event adds energy; nothing penetrates beyond
``PENETRATION_TOL``; a run stepped in windows from start to end never gains energy between its
steps and rests where the event-driven mode rests; joint friction and brakes work in the
contact-normal mode.
"""

import numpy as np
import pinocchio as pin
import pytest
from test_normal_cascade import GAIN_TOL, start_pose

import packbot
from packbot.contact import normal_law, normal_windows
from packbot.contact.lcp import box_residual, solve_mixed_admm
from packbot.contact.normal import PENETRATION_TOL
from packbot.contact.timestep import WINDOW_STEP, MoreauJeanStepper, StepSegment
from packbot.contact.window_impulses import WindowImpulses

LOCKED = ["camera_tilt", "camera_pan", "gripper_roll", "gripper_jaw"]


def _event_gain(res: packbot.SimResult) -> float:
    return max([0.0, *(e.energy_after - e.energy_before for e in res.events)])


# ------------------------------------------------------------------ the combined problem
def test_mixed_problem_cones_and_boxes_solved_together():
    """One cone block and two box rows, coupled: the solution satisfies every condition."""
    model = pin.buildSampleModelManipulator()
    data = model.createData()
    G = np.array(
        [
            [2.0, 1.0, 0.0, 0.0, 0.0],
            [1.0, 2.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.2, 0.0],
            [0.0, 0.0, 0.2, 1.0, 0.5],
            [0.0, 0.0, 0.0, 0.5, 1.0],
        ]
    )
    g = np.array([0.3, 0.0, -1.0, 0.5, -5.0])
    bound = np.array([1.0, 2.0])
    # box rows name model joints 3 and 1 (not in model order: the solver's order is permuted)
    x, res = solve_mixed_admm(model, data, G, g, np.array([0.5]), np.array([3, 1]), bound)
    u = G @ x + g
    assert res < 1e-8
    # the contact: pushing, tangential impulse inside the cone, normal velocity zero
    assert x[2] > 0.0 and np.hypot(x[0], x[1]) <= 0.5 * x[2] + 1e-9
    assert abs(u[2]) < 1e-8
    # the boxes: row 4 slips (at +2, moving negative), row 3 at -1 moving positive
    assert x[4] == pytest.approx(2.0) and u[4] < 0.0
    assert x[3] == pytest.approx(-1.0) and u[3] > 0.0
    assert box_residual(G[3:, 3:], g[3:] + G[3:, :3] @ x[:3], x[3:], bound) < 1e-8


def test_a_warm_start_from_the_answer_needs_no_iterations():
    """The window's steps start the ADMM from the previous step's impulses (same rows): a
    guess is used (one iteration from the answer converges, from zero it does not), in the
    caller's row order (box rows permuted), and a guess of another size is ignored."""
    model = pin.buildSampleModelManipulator()
    data = model.createData()
    rng = np.random.default_rng(3)
    A = rng.standard_normal((9, 6))
    G = A @ A.T + 0.1 * np.eye(9)  # two cone blocks, then three box rows
    g = rng.standard_normal(9) - np.array([0, 0, 2.0, 0, 0, 2.0, 0, 0, 0])
    mus, joints, bound = np.array([0.5, 0.8]), np.array([4, 2, 1]), np.array([0.3, 0.2, 0.1])
    x, res = solve_mixed_admm(model, data, G, g, mus, joints, bound)
    assert res < 1e-8
    x1, res1 = solve_mixed_admm(model, data, G, g, mus, joints, bound, max_iterations=1, guess=x)
    assert res1 < 1e-6
    np.testing.assert_allclose(x1, x, atol=1e-6)
    _, cold = solve_mixed_admm(model, data, G, g, mus, joints, bound, max_iterations=1)
    assert cold > 1e-3
    _, other = solve_mixed_admm(
        model, data, G, g, mus, joints, bound, max_iterations=1, guess=np.ones(4)
    )
    assert other == pytest.approx(cold)


def test_box_residual_flags_a_wrong_solution():
    G, g = np.eye(1), np.array([-5.0])
    assert box_residual(G, g, np.array([2.0]), np.array([2.0])) < 1e-12  # slips at the bound
    assert box_residual(G, g, np.array([1.0]), np.array([2.0])) > 0.1  # inside, still moving
    assert box_residual(G, g, np.array([3.0]), np.array([2.0])) > 0.1  # outside the box


def test_step_segment_interpolates_between_its_ends():
    y0, y1 = np.array([0.0, 1.0]), np.array([1.0, 3.0])
    seg = StepSegment(1.0, 1.5, y0, y1)
    assert np.array_equal(seg(1.0), y0) and np.array_equal(seg(1.5), y1)
    assert np.allclose(seg(1.25), [0.5, 2.0])
    assert np.allclose(seg.derivative(1.2), [2.0, 4.0])


# ------------------------------------------------------------------ hard starts
@pytest.mark.parametrize(("start", "mu"), [(0, 0.5), (5, 0.5)])
def test_a_start_that_stopped_at_max_events_finishes(robot, start, mu):
    """Wrist free, mu 0.5: starts 0 and 5 of the benchmark stopped at 20,000 events."""
    q0 = start_pose(robot, start)
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, restitution=0.0)
    res = packbot.simulate(robot, q0, np.zeros(robot.nq), 1.0, config=cfg)
    d = res.diagnostics
    assert d.windows >= 1 and d.window_steps > 0
    assert len(res.events_of("timestep")) == d.windows
    assert len(res.events_of("resume")) >= d.windows - 1
    assert len(res.events) < 5000
    assert _event_gain(res) <= GAIN_TOL
    assert -d.min_distance <= PENETRATION_TOL
    assert res.energy[-1] < res.energy[0]


def test_a_run_stepped_in_windows_rests_where_the_event_driven_mode_rests(robot, monkeypatch):
    """The collapse in windows from its first event to its end (a cascade threshold of one).

    Sampled at the step ends, its energy never rises from one step to the next (zero torque:
    the steps' contacts and the guard only dissipate), and it rests within 0.03 rad of the
    event-driven run on the joints that fold the arm (time-stepping at 0.5 ms against exact
    events: the same physics). Not on the turret: its yaw ends where a slow sideways slide
    happens to stick, which the last bits decide (measured: 0.001 or 0.059 rad from the
    event-driven run, depending on a 1e-16 J rounding of the energy guard's input).
    """
    q0 = robot.pose("drive")
    base = {"contact_mode": "normal", "mu": 0.5, "restitution": 0.0, "locked_joints": LOCKED}
    exact = packbot.simulate(robot, q0, np.zeros(robot.nq), 2.0, config=packbot.SimConfig(**base))
    # event-driven but for at most a short cascade window (an edge patch's two points taking
    # the load in turn at 0.33 s: 20 ms, 40 steps)
    assert exact.diagnostics.window_steps * WINDOW_STEP <= 0.05
    monkeypatch.setattr(normal_windows, "CASCADE_EVENTS", 1)
    monkeypatch.setattr(normal_windows, "WINDOW_MIN", 10.0)
    cfg = packbot.SimConfig(**base, sample_dt=WINDOW_STEP)
    stepped = packbot.simulate(robot, q0, np.zeros(robot.nq), 2.0, config=cfg)
    d = stepped.diagnostics
    assert d.windows == 1 and d.window_steps > 0.9 * (2.0 - stepped.events[0].t) / WINDOW_STEP
    t_in = stepped.events_of("timestep")[0].t
    after = stepped.t > t_in + 1e-9
    rises = np.diff(stepped.energy[after])
    assert rises.max() <= 1e-9, rises.max()
    assert -d.min_distance <= PENETRATION_TOL
    fold = [robot.joint_names.index(j) for j in ("shoulder", "elbow1", "elbow2")]
    assert np.abs(stepped.q[-1, fold] - exact.q[-1, fold]).max() < 0.03


# ------------------------------------------------------------------ joint friction, brakes
def test_joint_friction_works_in_the_contact_normal_mode(robot):
    """The collapse with the joints' Coulomb friction: holds and contacts solved together."""
    cfg = packbot.SimConfig(
        contact_mode="normal", mu=0.5, joint_friction=True, locked_joints=LOCKED
    )
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 1.5, config=cfg)
    assert res.diagnostics.windows >= 1
    assert _event_gain(res) <= GAIN_TOL
    assert -res.diagnostics.min_distance <= PENETRATION_TOL
    # the Coulomb part of each reported friction torque stays within its bound
    coulomb = np.array(robot.params.coulomb)
    viscous = np.array(robot.params.viscous)
    tau_c = res.tau_friction + viscous * res.v
    assert (np.abs(tau_c) <= coulomb + 1e-5).all()  # a slip fires 1e-6 N*m past its bound


def test_a_brake_holds_its_joint_in_the_contact_normal_mode(robot):
    """elbow2's brake (threshold 200 N*m, far above what gravity needs) holds it.

    Only impulses move it: the shoulder's limit stop at 0.153 s is a rigid impact whose
    impulse no finite brake torque resists (elbow2 jumps to 4.2 rad/s), and the brake then
    stops it within a few hundredths of a radian. Without the brake elbow2 swings through
    more than a radian.
    """
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=LOCKED)
    q0 = robot.pose("drive")
    brake = packbot.Failure(joint="elbow2", kind="brake", t=0.0, threshold=200.0)
    res = packbot.simulate(robot, q0, np.zeros(robot.nq), 1.0, config=cfg, failures=[brake])
    free = packbot.simulate(robot, q0, np.zeros(robot.nq), 1.0, config=cfg)
    j = res.joint_names.index("elbow2")
    assert np.abs(free.q[:, j] - q0[j]).max() > 1.0
    assert np.abs(res.q[:, j] - q0[j]).max() < 0.05
    late = res.t > 0.5  # long after the last impact: held still
    assert np.abs(res.v[late, j]).max() < 1e-6  # the window solver: to 1e-9 rad/s
    assert _event_gain(res) <= GAIN_TOL
    assert -res.diagnostics.min_distance <= PENETRATION_TOL
    s = res.joint_names.index("shoulder")  # the free joints still fall
    assert abs(res.q[-1, s] - res.q[0, s]) > 0.1


@pytest.mark.parametrize(("start", "duration"), [(1, 0.5), (23, 0.62)])
def test_frictionless_windows_stay_out_and_remove_little_energy(robot, start, duration):
    """mu = 0, wrist free: steps that went wrong before their fixes.

    Start 1 at 0.43 s: the wrist spinning at 36 rad/s left
    21 um of penetration after 0.5 ms steps; a step now turns no body more than STEP_ANGLE.
    Start 23 at 0.61 s: Coal's patch of the camera head 24 um into link 1's tube put its points
    33 mm deep and 12 mm out, and the arm sank 1.4 mm; such a patch is now replaced by the
    witness point (NormalContacts.add_pair).
    """
    q0 = start_pose(robot, start)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.0, restitution=0.0)
    res = packbot.simulate(robot, q0, np.zeros(robot.nq), duration, config=cfg)
    d = res.diagnostics
    assert d.windows >= 1
    assert d.window_energy_removed < 0.05
    assert -d.min_distance <= PENETRATION_TOL
    assert _event_gain(res) <= GAIN_TOL


def test_an_unconverged_step_falls_back_to_the_frictionless_rows(robot, monkeypatch):
    """A step whose ADMM answers (the compiled one, then Pinocchio's) have a large residual
    does not use them (measured once, mu = 0: a residual of 5e-3 turned 11 rad/s into
    30 rad/s): the frictionless LCP of its normal rows is used instead, and the run keeps its
    physical properties. (One ADMM iteration allowed: the native steps hand every step back.)"""
    from packbot.contact import conic, window_impulses

    monkeypatch.setattr(window_impulses, "CONIC_ITERATIONS", 1)
    real = window_impulses.solve_mixed_admm
    real_conic = conic.solve_conic

    def bad(*args, **kwargs):
        x, _ = real(*args, **kwargs)
        return x * 3.0, 1.0  # a wrong answer, and its (honest) residual

    def bad_conic(*args):
        x, _, it, rho = real_conic(*args)
        return x * 3.0, 1.0, it, rho

    monkeypatch.setattr(window_impulses, "solve_mixed_admm", bad)
    monkeypatch.setattr(conic, "solve_conic", bad_conic)
    monkeypatch.setattr(normal_windows, "CASCADE_EVENTS", 1)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, restitution=0.0, locked_joints=LOCKED)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 0.4, config=cfg)
    assert res.diagnostics.window_steps > 100
    assert -res.diagnostics.min_distance <= PENETRATION_TOL
    assert _event_gain(res) <= GAIN_TOL
    assert res.diagnostics.window_energy_removed < 1e-3  # the LCP steps gain nothing


def test_the_primal_projection_is_the_nearest_admissible_velocity():
    """The last fallback: min (v - v_f)^T M (v - v_f) / 2 subject to J_n v + b >= 0."""
    rng = np.random.default_rng(3)
    A = rng.normal(size=(4, 4))
    M = A @ A.T + 4.0 * np.eye(4)
    Jn = rng.normal(size=(3, 4))
    b = np.array([0.0, 0.1, 0.0])
    v_f = rng.normal(size=4) * 2.0
    v = WindowImpulses._project(v_f, Jn, b, M)
    assert (Jn @ v + b).min() >= -1e-9
    # KKT: M (v - v_f) = Jn^T lam with lam >= 0, complementary with the rows
    lam, *_ = np.linalg.lstsq(Jn.T, M @ (v - v_f), rcond=None)
    assert np.allclose(Jn.T @ lam, M @ (v - v_f), atol=1e-6)
    assert lam.min() >= -1e-6
    assert abs(lam @ (Jn @ v + b)) < 1e-6


def test_the_slow_slide_of_start_20_does_not_crawl(robot):
    """Start 20, wrist free, mu 0.5: a slow slide near 0.67 s was stiff for the explicit
    stepper (117,824 steps of 7 us in the first 0.8 s, five minutes of wall time); then a
    window opened once 400 steps averaged under 25 us (922 steps, one window). With the
    patch normals on the faces' bodies and the rows' exact terms the slide is not stiff: 704
    steps, no window. (The crawl detector itself: the next test.)"""
    q0 = start_pose(robot, 20)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, restitution=0.0)
    res = packbot.simulate(robot, q0, np.zeros(robot.nq), 0.8, config=cfg)
    d = res.diagnostics
    assert d.steps < 2_000
    assert -d.min_distance <= PENETRATION_TOL
    assert _event_gain(res) <= GAIN_TOL


def test_the_crawl_detector_opens_a_window_after_crawl_steps(robot, monkeypatch):
    """The crawl detector itself, on a run that does not depend on a stiff stretch: with
    CRAWL_STEP raised so that every step counts as a crawl, the collapse from "drive" (wrist
    locked) opens a window (a ``timestep`` event) once CRAWL_STEPS steps are taken, later for
    a larger count, both before any window of the run as it is (a cascade's), and the run
    keeps its guarantees."""
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, restitution=0.0, locked_joints=LOCKED)
    q0, v0 = robot.pose("drive"), np.zeros(robot.nq)
    plain = packbot.simulate(robot, q0, v0, 0.6, config=cfg)
    t_plain = min((e.t for e in plain.events_of("timestep")), default=np.inf)
    monkeypatch.setattr(normal_windows, "CRAWL_STEPS", 50)
    monkeypatch.setattr(normal_windows, "CRAWL_STEP", 1.0)  # [s]: every step is "slow"
    res = packbot.simulate(robot, q0, v0, 0.6, config=cfg)
    d = res.diagnostics
    assert d.windows >= 1
    assert -d.min_distance <= PENETRATION_TOL
    assert _event_gain(res) <= GAIN_TOL
    # the count: with 100 steps to average, the first window opens later, after more steps
    monkeypatch.setattr(normal_windows, "CRAWL_STEPS", 100)
    later = packbot.simulate(robot, q0, v0, 0.6, config=cfg)
    t50 = res.events_of("timestep")[0].t
    t100 = later.events_of("timestep")[0].t
    assert 0.0 < t50 < t100 < t_plain


def test_an_unconverged_compiled_answer_falls_back_to_pinocchios_admm(robot, monkeypatch):
    """The compiled solver's answer above RESIDUAL_OK is not used: Pinocchio's ADMM solves
    the step instead (counted in ``conic_fallbacks``), and the run is the usual one."""
    from packbot.contact import conic
    from packbot.contact.window_impulses import RESIDUAL_OK

    real_conic = conic.solve_conic
    calls = {"pinocchio": 0}

    def unconverged(*args):
        x, _, it, rho = real_conic(*args)
        return x, 10.0 * RESIDUAL_OK, it, rho

    from packbot.contact import window_impulses

    real = window_impulses.solve_mixed_admm

    def counted(*args, **kwargs):
        calls["pinocchio"] += 1
        return real(*args, **kwargs)

    monkeypatch.setattr(conic, "solve_conic", unconverged)
    monkeypatch.setattr(window_impulses, "solve_mixed_admm", counted)
    monkeypatch.setattr(window_impulses, "CONIC_ITERATIONS", 1)  # (the native steps hand back)
    monkeypatch.setattr(normal_windows, "CASCADE_EVENTS", 1)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, restitution=0.0, locked_joints=LOCKED)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 0.3, config=cfg)
    assert res.diagnostics.window_steps > 100
    assert calls["pinocchio"] >= res.diagnostics.window_steps // 2  # every step with contacts
    assert -res.diagnostics.min_distance <= PENETRATION_TOL
    assert _event_gain(res) <= GAIN_TOL


def test_a_relapse_after_a_window_opens_the_next_one_within_a_few_restarts(robot, monkeypatch):
    """Start 3, wrist free, mu 0.5: from 0.72 s each resumed state cascades again at once (it
    was start 4 at mu 0.8 before the slow-slide stop stopped lifting contacts; there, each
    resume was followed by 24 stick/slip restarts within 0.5 ms before the 20th opened the next
    window). Within RELAPSE_SPAN of a window's end, RELAPSE_EVENTS restarts within CASCADE_SPAN
    open the next one, at the restart that completes them and never later. The restarts are
    counted where the law handles them (the events of one restart share its time); the rule is
    checked at CASCADE_SPAN (where these relapses' windows open by CHATTER_EVENTS first) and
    widened to 5 ms, where the relapses' restarts (0.5 to 0.9 ms apart) must open their
    windows by it."""
    q0 = start_pose(robot, 3)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, restitution=0.0)
    n = normal_windows.RELAPSE_EVENTS
    seen: dict[str, list[float]] = {}
    law = normal_law.NormalLaw
    handle, enter, resume = law._handle, law._enter, law._resume

    def handled(self, t, y, crossings):
        seen["restart"].append(t)
        return handle(self, t, y, crossings)

    def entered(self, t, y, why, *span):
        seen["enter"].append(t)
        return enter(self, t, y, why, *span)

    def resumed(self, t, y):
        seen["resume"].append(t)
        return resume(self, t, y)

    monkeypatch.setattr(law, "_handle", handled)
    monkeypatch.setattr(law, "_enter", entered)
    monkeypatch.setattr(law, "_resume", resumed)
    for span in (normal_windows.CASCADE_SPAN, 0.005):
        monkeypatch.setattr(normal_windows, "CASCADE_SPAN", span)
        seen.update(restart=[], enter=[], resume=[])
        res = packbot.simulate(robot, q0, np.zeros(robot.nq), 1.8, config=cfg)
        by_rule = 0
        for t_end in seen["resume"]:
            near = t_end + normal_windows.RELAPSE_SPAN
            ts = [t for t in seen["restart"] if t_end <= t <= near]
            opened = [t for t in seen["enter"] if t_end < t]
            # the restart completing n within the span: the window opens there at the latest
            done = [ts[i] for i in range(n - 1, len(ts)) if ts[i] - ts[i - n + 1] <= span]
            due = done[0] if done else None
            if due is not None:
                assert opened and opened[0] <= due, (span, t_end, ts[:8], opened[:1])
                by_rule += opened[0] == due
        if span > normal_windows.CASCADE_SPAN:  # (at 1 ms the chatter rule opens them first)
            assert by_rule >= 2, (span, seen["resume"], seen["enter"])
        assert _event_gain(res) <= GAIN_TOL
        assert -res.diagnostics.min_distance <= PENETRATION_TOL


def test_frictionless_steps_are_solved_by_the_compiled_solver(robot, monkeypatch):
    """mu = 0: the compiled ADMM on cones of friction 0 solves the steps (the LCP of the
    normal rows, eight times slower, is only its fallback) and the window still stops the
    arm at its contacts."""
    calls = {"lcp": 0}
    real = WindowImpulses._frictionless

    def counted(G, g, m):
        calls["lcp"] += 1
        return real(G, g, m)

    monkeypatch.setattr(WindowImpulses, "_frictionless", staticmethod(counted))
    monkeypatch.setattr(normal_windows, "CASCADE_EVENTS", 1)
    monkeypatch.setattr(normal_windows, "WINDOW_MIN", 10.0)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.0, restitution=0.0, locked_joints=LOCKED)
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 0.4, config=cfg)
    d = res.diagnostics
    assert d.windows == 1 and d.window_steps > 100
    assert calls["lcp"] == 0
    assert -d.min_distance <= PENETRATION_TOL
    assert _event_gain(res) <= GAIN_TOL
    assert d.window_energy_removed < 1e-3


# ------------------------------------------------------------------ the step's own costs
def _spinning_window(robot, monkeypatch, duration=0.3):
    """The collapse from "drive" with the gripper and camera spinning, in one window from its
    first event (sliding patches: many are rebuilt)."""
    monkeypatch.setattr(normal_windows, "CASCADE_EVENTS", 1)
    monkeypatch.setattr(normal_windows, "WINDOW_MIN", 10.0)
    v0 = np.zeros(robot.nq)
    v0[robot.joint_names.index("gripper_roll")] = 80.0
    v0[robot.joint_names.index("camera_pan")] = -40.0
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.8, restitution=0.0)
    return packbot.simulate(robot, robot.pose("drive"), v0, duration, config=cfg)


def test_the_step_signature_sums_each_pairs_points():
    """Pushing: a pair's normal impulses sum above the band; sliding: the sum of its
    tangential impulses on the cone (not inside it, never without friction); limits: their
    own normal impulse."""
    from packbot.contact.conic import step_signature

    mu, band = 0.5, 1e-9
    # pair 0: two points sticking (tangential sum inside the cone); pair 1: one point on the
    # cone; pair 2: no push; then limit 0 pushing, limit 1 not; then a joint box (ignored)
    x = np.concatenate(
        [
            [0.1, 0.0, 1.0, -0.1, 0.05, 1.0],  # pair 0
            [0.3, 0.4, 1.0],  # pair 1: |t| = 0.5 = mu * 1
            [0.0, 0.0, 1e-12],  # pair 2
            [0.0, 0.0, 2.0, 0.0, 0.0, 0.0],  # limits
            [7.0],
        ]
    )
    row_pair = np.array([0, 0, 1, 2])
    push, slide, lim = step_signature(x, row_pair, 3, 2, mu, band)
    assert push.tolist() == [True, True, False]
    assert slide.tolist() == [False, True, False]
    assert lim.tolist() == [True, False]
    push0, slide0, _ = step_signature(x, row_pair, 3, 2, 0.0, band)
    assert push0.tolist() == push.tolist() and not slide0.any()


def test_a_window_at_rest_sweeps_once_a_step(robot, monkeypatch):
    """The sweep at a step's end serves the next step's contact set, also where the arm rests
    in a window (its margin covers the next step's free velocity change; at the speeds alone,
    a resting arm's steps swept twice). The wrist-locked collapse from "drive" with joint
    friction (the joints' boxes: every step through the stepper, none in a native run of
    steps) in one window from its first event: it comes to rest in the window and rests to
    3 s, sweeping once a step (measured: 3,292 sweeps in 3,291 resting steps)."""
    from packbot.collision import CollisionWorld

    calls = {"rest steps": 0, "sweeps": 0, "inside": False}
    sweep, step = CollisionWorld.sweep, MoreauJeanStepper.step

    def counted_sweep(self, *args, **kwargs):
        calls["sweeps"] += calls["inside"]
        return sweep(self, *args, **kwargs)

    def counted_step(self, t, y, *args, **kwargs):
        n = self.n
        at_rest = float(np.abs(y[n : 2 * n]).sum()) < 1e-3  # [rad/s]
        calls["rest steps"] += at_rest
        calls["inside"] = at_rest
        try:
            return step(self, t, y, *args, **kwargs)
        finally:
            calls["inside"] = False

    monkeypatch.setattr(CollisionWorld, "sweep", counted_sweep)
    monkeypatch.setattr(MoreauJeanStepper, "step", counted_step)
    # (joint friction: the joints' boxes, so each step through MoreauJeanStepper.step; a
    # native run of steps sweeps once a step by construction)
    monkeypatch.setattr(normal_windows, "CASCADE_EVENTS", 1)
    monkeypatch.setattr(normal_windows, "WINDOW_MIN", 10.0)
    cfg = packbot.SimConfig(
        contact_mode="normal", mu=0.5, restitution=0.0, joint_friction=True, locked_joints=LOCKED
    )
    res = packbot.simulate(robot, robot.pose("drive"), np.zeros(robot.nq), 3.0, config=cfg)
    assert res.rest_time is not None
    assert calls["rest steps"] >= 500
    assert calls["sweeps"] <= 1.01 * calls["rest steps"]  # (twice a step: 2x)


def test_the_start_energy_is_the_last_steps_end_energy(robot, monkeypatch):
    """The energy at a step's start is the last step's at its end, computed once: the run
    with it recomputed at every step is the same run, bit for bit."""
    res = _spinning_window(robot, monkeypatch)
    assert res.diagnostics.window_steps > 500
    step = MoreauJeanStepper.step

    def fresh(self, *args, **kwargs):
        self._end_energy = None
        return step(self, *args, **kwargs)

    monkeypatch.setattr(MoreauJeanStepper, "step", fresh)
    again = _spinning_window(robot, monkeypatch)
    assert np.array_equal(again.q, res.q) and np.array_equal(again.v, res.v)
    assert np.array_equal(again.energy, res.energy)


def test_the_reach_bounds_bound_every_pieces_distance_to_the_joints_axes(robot, monkeypatch):
    """Each joint's reach bound is at least the distance from its origin (on its axis) to
    every vertex of every piece it moves, in random configurations; the wrist's are a tenth
    of REACH_BOUND; a model with a joint that is not revolute gets REACH_BOUND throughout."""
    from packbot.contact import pairs
    from packbot.contact.pairs import REACH_BOUND, reach_bounds
    from packbot.system import System

    system = System(robot, robot.pose("drive"), packbot.SimConfig(contact_mode="normal"), None)
    model, world = system.model, system.world
    assert world is not None
    r = reach_bounds(model, world)
    data = model.createData()
    gd = pin.GeometryData(world.geom_model)
    rng = np.random.default_rng(5)
    closest = np.inf  # the smallest margin left, over every vertex and joint
    for _ in range(20):
        q = rng.uniform(model.lowerPositionLimit, model.upperPositionLimit)
        pin.updateGeometryPlacements(model, data, world.geom_model, gd, q)
        for g, go in enumerate(world.geom_model.geometryObjects):
            if go.parentJoint == 0:
                continue
            M = gd.oMg[g]
            pts = np.asarray(go.geometry.points()) @ M.rotation.T + M.translation
            for s in list(model.supports[go.parentJoint])[1:]:
                far = np.linalg.norm(pts - data.oMi[s].translation, axis=1).max()
                closest = min(closest, r[model.idx_vs[s]] - far)
    assert closest >= 0.0
    wrist = [robot.joint_names.index(n) for n in LOCKED]
    assert r[wrist].max() < 0.15 * REACH_BOUND
    assert r.max() <= REACH_BOUND
    monkeypatch.setattr(pairs, "REVOLUTE", ("JointModelRX",))  # (the arm's are RZ, RY)
    assert np.array_equal(reach_bounds(model, world), np.full(model.nv, REACH_BOUND))


def test_a_jam_cycling_every_few_milliseconds_opens_a_window(robot):
    """Start 17, wrist free, mu 1.2: elbow1's casing on a flipper and link 3's tube on the
    shoulder casing jam against a joint limit, cycling every ~3 ms through an impact, a
    stick/slip and the limit. With the chatter rule's former span (32 restarts within 32 ms)
    the cycle escaped it: 3,985 events in 3 s. CHATTER_EVENTS within CHATTER_SPAN (250 ms) hand
    it to a window: under 300 events, the window removing little energy. The cycle comes back
    after a window: without the chatter's relapse rule (RELAPSE_EVENTS restarts at the chatter
    rate within CHATTER_SPAN of a window's end open a window twice as long), 2,570 events in 19
    windows after a rounding-level change of the dynamics; with it, 226 in 7 (measured)."""
    q0 = start_pose(robot, 17)
    cfg = packbot.SimConfig(contact_mode="normal", mu=1.2, restitution=0.0)
    res = packbot.simulate(robot, q0, np.zeros(robot.nq), 3.0, config=cfg)
    d = res.diagnostics
    assert d.windows >= 1
    assert len(res.events) < 300, len(res.events)
    assert d.window_energy_removed < 0.01
    assert _event_gain(res) <= GAIN_TOL
    assert -d.min_distance <= PENETRATION_TOL
