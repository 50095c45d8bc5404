"""A window's steps that keep their contact set, in one native call (``window_run``).

``ContactRhs.window_run`` takes the window steps of ``MoreauJeanStepper._native_step`` one
after another, with the signature, the sweep at each step's end (through the compiled sweep's
C entry point), the energy guard and the quiet count; the step it does not take or keep comes
back to the stepper. Checked here: the runs take most of a window's steps (none with joint
boxes), the runs keep their physics, and a chain of steps samples as its steps.
"""

import numpy as np
import pytest
from test_native_window import _window_rise
from test_normal_cascade import GAIN_TOL, start_pose

import packbot
from packbot.contact import native, normal_windows, timestep, window_run
from packbot.contact.normal_tolerances import PENETRATION_TOL
from packbot.contact.timestep import StepSegment

pytestmark = pytest.mark.skipif(not native.available(), reason="packbot._native not built")


def _run(robot, k: int, mu: float, duration: float = 3.0, **cfg_kw):
    taken = {"calls": 0, "steps": 0, "pending": 0}
    real = window_run.run_native

    def counted(*a, **kw):
        out = real(*a, **kw)
        if out is not None:
            taken["calls"] += 1
            taken["steps"] += out.steps
            taken["pending"] += out.pending is not None
        return out

    cfg = packbot.SimConfig(
        contact_mode="normal", mu=mu, sample_dt=timestep.WINDOW_STEP,
        **{"restitution": 0.0, **cfg_kw},
    )  # fmt: skip
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(normal_windows, "run_native", counted)
        res = packbot.simulate(
            robot, start_pose(robot, k), np.zeros(robot.model.nv), duration, config=cfg
        )
    return res, taken


@pytest.mark.parametrize(
    ("k", "mu", "kw"),
    [
        (21, 0.0, {}),
        (16, 0.5, {}),
        (16, 1.2, {}),
        (16, 0.5, {"joint_friction": True}),  # (the joints' boxes: no run)
    ],
    ids=["start21-mu0", "start16-mu0.5", "start16-mu1.2", "joint-friction"],
)
def test_the_native_runs_take_the_windows_steps_and_keep_the_physics(robot, k, mu, kw):
    """Most of a window's steps are taken in native runs (with joint boxes none: each step's box
    torques are its samples' friction torques), some finished by the stepper (pending); no
    penetration beyond PENETRATION_TOL, no energy gained at an event, and with zero torque no
    energy gained from one window sample to the next beyond 1e-5 J (see
    test_native_window.test_native_window_steps_keep_the_physics)."""
    res, taken = _run(robot, k, mu, **kw)
    d = res.diagnostics
    assert d.window_steps > 0
    if kw.get("joint_friction"):
        assert taken["steps"] == 0, taken
    else:
        assert taken["steps"] >= 0.3 * d.window_steps, taken  # most steps in the runs
        assert taken["pending"] > 0, taken  # (steps taken and finished by the stepper)
    assert -d.min_distance <= PENETRATION_TOL
    assert max((e.energy_after - e.energy_before for e in res.events), default=0.0) <= GAIN_TOL
    assert _window_rise(res) <= 1e-5
    assert res.energy[-1] < res.energy[0]


def test_a_step_chain_samples_as_its_steps(rng):
    """StepChain reads a time from the step that would have recorded a sample at it."""
    ts = [0.0, 5e-4, 1e-3, 1.5e-3, 1.5e-3 + 1e-13, 2e-3]
    ys = [rng.normal(size=4) for _ in ts]
    chain = window_run.StepChain(ts, ys)
    steps = [StepSegment(ts[i], ts[i + 1], ys[i], ys[i + 1]) for i in range(len(ts) - 1)]
    for t in [0.0, 2e-4, 5e-4, 5e-4 + 5e-13, 7e-4, 1.5e-3, 1.5e-3 + 5e-14, 1.9e-3, 2e-3]:
        # the first step whose end + 1e-12 reaches t, at t clamped to it
        seg = next(s for s in steps if t <= s.t1 + 1e-12)
        np.testing.assert_array_equal(chain(t), seg(min(max(t, seg.t0), seg.t1)))
    assert chain.t0 == 0.0 and chain.t1 == 2e-3
    np.testing.assert_array_equal(chain.y1, ys[-1])


def test_a_step_the_native_run_handed_back_is_not_asked_again(robot, monkeypatch):
    """The step a native run of window steps stops at because its set changes (or a bounce,
    no converged impulses) is handed to the stepper with its free velocity
    (``MoreauJeanStepper._handed``): its step does not call the native step again. The same
    run to the bit as when it does (the stepper's hand-back cleared), on two wrist-free
    starts, the hand-back used at hundreds of steps."""
    from test_normal_cascade import start_pose

    real = timestep.MoreauJeanStepper._native_step
    used = {"n": 0}

    def cleared(self, t, y, h):
        self._handed = None
        return real(self, t, y, h)

    def counted(self, t, y, h):
        handed = self._handed
        out = real(self, t, y, h)
        if handed is not None and handed[0] == y.tobytes() and handed[1] == h:
            used["n"] += 1
        return out

    for k, mu in ((16, 0.0), (14, 0.5)):
        cfg = packbot.SimConfig(contact_mode="normal", mu=mu, restitution=0.0)
        runs = []
        for step in (cleared, counted):
            monkeypatch.setattr(timestep.MoreauJeanStepper, "_native_step", step)
            runs.append(packbot.simulate(robot, start_pose(robot, k), np.zeros(8), 2.0, config=cfg))
        a, b = runs
        for key in ("t", "q", "v"):
            np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
        assert [e.kind for e in a.events] == [e.kind for e in b.events]
    assert used["n"] > 200, used
