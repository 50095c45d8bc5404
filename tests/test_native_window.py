"""A window step whose contact set stays as it is, in one native call (``_native_step``).

The native step (``ContactRhs.window_step``) takes the step's free velocity, M^-1, rows, problem
and impulses as the Python step does (``_python_step``: ABA at the explicit midpoint, the contact
set's rows, conic.step_problem and the extension's conic solver) and hands the step back to Python
where the contact set changes, a row bounces or the impulses do not converge. Compared here step by
step, from the same state and warm start, on window steps of wrist-free random starts.
"""

import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot.contact import native, timestep, window_run
from packbot.contact.normal_tolerances import PENETRATION_TOL

pytestmark = pytest.mark.skipif(not native.available(), reason="packbot._native not built")


def _compared(robot, k: int, mu: float, duration: float, **cfg_kw) -> tuple[list[dict], object]:
    """Every native window step of start k, and the Python step from the same state."""
    from test_normal_cascade import start_pose

    seen: list[dict] = []
    real = timestep.MoreauJeanStepper._native_step

    def compared(self, t, y, h):
        before = (self._last_rows, self._last_x, self._last_rho)
        out = real(self, t, y, h)
        if not isinstance(out, tuple):
            return out
        after = (self._last_rows, self._last_x, self._last_rho)
        version = self.contacts._version
        self._last_rows, self._last_x, self._last_rho = before
        v_f, v1, x, residual, _, _, _, _ = self._python_step(t, y, h)
        assert self.contacts._version == version  # (the Python step kept the set too)
        self._last_rows, self._last_x, self._last_rho = after
        n = self.n
        q, v = y[:n], y[n:]
        e = self.sys.energy
        seen.append(
            {
                "v_f": np.abs(out[0] - v_f).max(),
                "v1": np.abs(out[1] - v1).max() / max(1.0, np.abs(v1).max()),
                "q1": np.abs(out[2] - pin.integrate(self.sys.model, q, h * out[1])).max(),
                "kin": abs(out[8][2] - 0.5 * out[1] @ self.sys.mass_matrix(out[2]) @ out[1]),
                "x": np.abs(out[3] - x).max() / max(1e-6, np.abs(x).max()),
                "residual": max(out[4], residual),
                "e0": abs(out[8][0] - e(q, v)),
                "e1": abs(out[8][1] - e(out[2], out[1])),
            }
        )
        return out

    pytest.MonkeyPatch().setattr(timestep.MoreauJeanStepper, "_native_step", compared)
    # (each step through _native_step: the native runs of steps equal them, test_window_run)
    pytest.MonkeyPatch().setattr(window_run, "ENABLED", False)
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, **{"restitution": 0.0, **cfg_kw})
    try:
        res = packbot.simulate(
            robot, start_pose(robot, k), np.zeros(robot.model.nv), duration, config=cfg
        )
    finally:
        pytest.MonkeyPatch().setattr(timestep.MoreauJeanStepper, "_native_step", real)
        pytest.MonkeyPatch().setattr(window_run, "ENABLED", True)
    return seen, res


@pytest.mark.parametrize(
    ("k", "mu", "kw"),
    [
        (16, 0.0, {}),
        (16, 1.2, {}),
        (5, 0.5, {}),
        (16, 0.5, {"joint_friction": True}),  # (the joints' boxes, limit rows)
        (16, 0.5, {"restitution": 0.5}),  # (bouncing rows handed back: status 2)
    ],
    ids=["mu0", "mu1.2", "mu0.5", "joint-friction", "restitution"],
)
def test_a_native_window_step_is_the_python_step(robot, k, mu, kw):
    seen, res = _compared(robot, k, mu, 2.0, **kw)
    assert len(seen) > 100, len(seen)
    worst = {key: max(s[key] for s in seen) for key in seen[0]}
    # the same free velocity, rows and problem; the Python step assembles the problem in numpy
    # (its factor and products summed in BLAS's order, the native step's in index order), so
    # the low-rank ADMM's iterates part at rounding and each solve stops on its own true
    # residual (CONIC_TOL 1e-9): the impulses may differ along G's null space (the rows are
    # redundant: not unique), the velocities they give by the solver's tolerance on these
    # ill-conditioned problems (measured: at most 3.3e-6 of max |v1| over 1,500 to 1,700
    # steps of each start, the median 1e-14)
    assert worst["v_f"] <= 1e-12, worst
    assert worst["v1"] <= 1e-5, worst
    assert float(np.median([s["v1"] for s in seen])) <= 1e-9
    assert worst["q1"] == 0.0, worst  # (pin.integrate: q + h v1 for 1-dof joints)
    assert worst["e0"] <= 1e-9 and worst["e1"] <= 1e-9 and worst["kin"] <= 1e-9, worst
    assert worst["residual"] <= timestep.RESIDUAL_OK
    assert -res.diagnostics.min_distance <= PENETRATION_TOL + 1e-5


def _stepper_counts(
    robot, k: int, mu: float, duration: float
) -> tuple[int, dict[int, int], int, object]:
    """A run's native window steps, those handed back (by why), its conic fallbacks, the run."""
    from test_normal_cascade import start_pose

    steppers: dict[int, timestep.MoreauJeanStepper] = {}
    real = timestep.MoreauJeanStepper.step

    def counted(self, *args, **kwargs):
        steppers[id(self)] = self
        return real(self, *args, **kwargs)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(timestep.MoreauJeanStepper, "step", counted)
        cfg = packbot.SimConfig(contact_mode="normal", mu=mu, restitution=0.0)
        res = packbot.simulate(
            robot, start_pose(robot, k), np.zeros(robot.model.nv), duration, config=cfg
        )
    s = list(steppers.values())
    misses: dict[int, int] = {}
    for x in s:
        for why, count in x.native_misses.items():
            misses[why] = misses.get(why, 0) + count
    return sum(x.native_steps for x in s), misses, sum(x.conic_fallbacks for x in s), res


def test_native_window_steps_hand_back_where_the_set_changes(robot, monkeypatch):
    """Most window steps keep their set and are native; those that change it are Python's;
    switched off (NATIVE_STEPS), none is native."""
    steps, misses, _, res = _stepper_counts(robot, 16, 0.0, 2.0)
    assert steps > 3 * misses.get(1, 0) > 0, (steps, misses)  # (1: the set changes)
    assert res.diagnostics.window_steps >= steps + sum(misses.values())
    assert -res.diagnostics.min_distance <= 1e-5
    assert max((e.energy_change for e in res.events), default=0.0) <= 1e-9
    monkeypatch.setattr(timestep, "NATIVE_STEPS", False)
    steps, misses, _, _ = _stepper_counts(robot, 16, 0.0, 0.5)
    assert steps == 0 and not misses


def test_unconverged_native_impulses_hand_the_step_back(robot, monkeypatch):
    """With one ADMM iteration allowed, the native step's impulses do not converge: it hands
    the step back (status 3), and Python's fallbacks (Pinocchio's ADMM) take it."""
    monkeypatch.setattr(timestep, "CONIC_ITERATIONS", 1)
    steps, misses, fallbacks, res = _stepper_counts(robot, 16, 1.2, 1.0)
    assert misses.get(3, 0) > 0 and fallbacks > 0, (steps, misses, fallbacks)
    assert -res.diagnostics.min_distance <= 1e-5


@pytest.mark.parametrize(
    ("k", "mu", "kw"),
    [(16, 0.0, {}), (14, 0.5, {}), (16, 0.5, {"joint_friction": True})],
    ids=["mu0", "mu0.5", "joint-friction"],
)
def test_a_native_solve_after_a_set_update_is_the_python_one(robot, monkeypatch, k, mu, kw):
    """A step handed back because its contact set changes: once the set is updated, the
    native call takes its impulses (``checked=False``); compared with the Python solve of the
    same step from the same state and warm start."""
    from test_normal_cascade import start_pose

    seen: list[dict] = []
    real = timestep.MoreauJeanStepper._native_call

    def compared(self, y, h, torques, closest, sweep):
        if sweep is not None:
            return real(self, y, h, torques, closest, sweep)
        before = (self._last_rows, self._last_x, self._last_rho)
        out = real(self, y, h, torques, closest, sweep)
        if isinstance(out, np.ndarray):
            return out
        after = (self._last_rows, self._last_x, self._last_rho)
        self._last_rows, self._last_x, self._last_rho = before
        n = self.n
        py = self._python_solve(y[:n], y[n : 2 * n], out[0], h, closest, None)
        self._last_rows, self._last_x, self._last_rho = after
        seen.append(
            {
                "v1": np.abs(out[1] - py.v1).max() / max(1.0, np.abs(py.v1).max()),
                "x": np.abs(out[3] - py.x).max() / max(1e-6, np.abs(py.x).max()),
                "residual": max(out[4], py.residual),
            }
        )
        return out

    monkeypatch.setattr(timestep.MoreauJeanStepper, "_native_call", compared)
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, restitution=0.0, **kw)
    res = packbot.simulate(robot, start_pose(robot, k), np.zeros(robot.model.nv), 2.0, config=cfg)
    assert len(seen) > 50, len(seen)
    worst = {key: max(s[key] for s in seen) for key in seen[0]}
    assert worst["v1"] <= 1e-9, worst
    parted = [s for s in seen if s["x"] > 1e-9]  # (redundant rows: see the test above)
    assert len(parted) <= 0.005 * len(seen), parted
    assert worst["residual"] <= timestep.RESIDUAL_OK
    assert -res.diagnostics.min_distance <= PENETRATION_TOL + 1e-5
