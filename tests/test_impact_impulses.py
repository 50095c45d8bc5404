"""The impacts' contact impulses in the result: they give the impact's velocity jump exactly,
lie in their cones, and survive a save.

At an impact the restart applies one impulse on every touching row (Newton's law with
restitution, Coulomb's cone in the frictional impact, Lemke's LCP in the frictionless one). The
records are checked against the velocity change the impulse made, captured at the impulse
itself: M(q) (v+ - v-) = sum J^T P + the stops' impulses at the impact's configuration q.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from test_contact_forces import older_file
from test_normal_cascade import start_pose

import packbot
from packbot.contact import native
from packbot.contact.normal_steps import RestartSteps
from packbot.contact_forces import joint_torque
from packbot.errors import ConfigurationError
from packbot.result_file import RESULT_FORMAT_3

pytestmark = pytest.mark.skipif(not native.available(), reason="packbot._native not built")


@pytest.fixture(scope="module")
def robot() -> packbot.Robot:
    return packbot.load_robot()


def _run(robot, k: int, mu: float, e: float, duration: float, monkeypatch=None, python=False):
    """A wrist-free random start's run and, with ``monkeypatch``, every impulse applied:
    (q, v before, v after) per impact, in order; ``python``: the extension's impact hands
    every impact to Python's (status 2: Pinocchio's ADMM, the frictionless LCP)."""
    jumps: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    if python:
        assert monkeypatch is not None

        def handed(self, contacts, q, v, minv, **kw):
            return 2, v.copy(), False, np.zeros(0, dtype=np.int64), np.zeros((0, 3))

        monkeypatch.setattr(native.NativeRestart, "impact", handed)
    if monkeypatch is not None:
        real = RestartSteps.impulse

        def impulse(self, q, v, minv):
            v1 = real(self, q, v, minv)
            if self.impact_rows is not None:
                jumps.append((q.copy(), v.copy(), np.array(v1)))
            return v1

        monkeypatch.setattr(RestartSteps, "impulse", impulse)
    cfg = packbot.SimConfig(contact_mode="normal", mu=mu, restitution=e)
    res = packbot.simulate(
        robot, start_pose(robot, k), np.zeros(robot.model.nv), duration, config=cfg
    )
    return res, jumps


@pytest.mark.parametrize(
    ("k", "mu", "e", "python"),
    [(16, 0.5, 0.0, False), (16, 0.0, 0.3, False), (3, 1.2, 0.3, False), (16, 0.5, 0.3, True)],
    ids=["frictional", "frictionless-bounce", "frictional-bounce", "python-impact"],
)
def test_impulses_close_the_velocity_jump(robot, monkeypatch, k, mu, e, python) -> None:
    """Every impact's records give its velocity jump: |M dv - J^T P - stops| <= 1e-9 |M dv| +
    1e-12 N*m*s (rounding: the records are the solver's impulses themselves; measured 2e-13
    relative on the 35 impacts of start 3), normal impulses > 0 and friction within mu of them
    (1e-9 relative: the solvers' cone projection is exact up to rounding). On the extension's
    impact and on Python's."""
    res, jumps = _run(robot, k, mu, e, 1.0, monkeypatch, python)
    imp = res.impacts
    assert len(imp) == len(jumps) > 3, (len(imp), len(jumps))
    model = robot.model
    data = model.createData()
    worst = 0.0
    for i, (q, v0, v1) in enumerate(jumps):
        recs = [
            (
                (c.link1, c.piece1, c.link2, c.piece2), c.point, c.point1, c.point2, c.normal,
                c.impulse,
            )
            for c in imp.of(i)
        ]  # fmt: skip
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        jump = M @ (v1 - v0)
        P = joint_torque(model, model.createData(), q, recs) + imp.limit_impulse[i]
        # (1e-12 N*m*s: an impulse of rounding size, a touching row approaching at 1e-10 m/s)
        excess = float(np.linalg.norm(jump - P)) - 1e-12
        worst = max(worst, excess / max(float(np.linalg.norm(jump)), 1e-300))
        for c in imp.of(i):
            pn = c.normal_impulse
            assert pn > 0.0
            pt = np.linalg.norm(c.impulse - pn * c.normal)
            assert pt <= mu * pn * (1 + 1e-9) + 1e-12 * pn, (res.impacts.t[i], pn, pt)
    assert worst <= 1e-9, worst


def test_impulses_at_an_impact_event(robot) -> None:
    res, _ = _run(robot, 16, 0.5, 0.0, 1.0)
    impact = res.events_of("impact")[0]
    found = res.impulses_at(impact.t)
    assert found and any((c.piece1, c.piece2) == (impact.piece1, impact.piece2) for c in found), (
        impact,
        [c.pair for c in found],
    )
    assert res.impulses_at(res.t[-1] + 1.0) == []
    for bad in (None, "0.1", True, float("nan")):
        with pytest.raises(ConfigurationError, match="invalid t="):
            res.impulses_at(bad)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def bounced(robot) -> packbot.SimResult:
    return _run(robot, 16, 0.5, 0.3, 0.6)[0]


def test_impulses_survive_save_and_load(bounced, tmp_path) -> None:
    res = bounced
    assert len(res.impacts) > 0
    back = packbot.SimResult.load(res.save(tmp_path / "r.npz"))
    np.testing.assert_array_equal(back.impacts.t, res.impacts.t)
    assert back.impacts.rows.pairs == res.impacts.rows.pairs
    for name in ("sample", "pair", "point", "point1", "point2", "normal", "force"):
        np.testing.assert_array_equal(
            getattr(back.impacts.rows, name), getattr(res.impacts.rows, name)
        )
    np.testing.assert_array_equal(back.impacts.limit_impulse, res.impacts.limit_impulse)
    np.testing.assert_array_equal(back.impacts.clamp_impulse, res.impacts.clamp_impulse)


def test_a_file_of_the_format_before_impacts_loads_without_them(bounced, tmp_path) -> None:
    drop = ("impact_", "contact_clamp_torque")
    old = older_file(bounced, tmp_path, RESULT_FORMAT_3, drop, ("impact_pairs",))
    back = packbot.SimResult.load(old)
    assert len(back.impacts) == 0 and back.impulses_at(bounced.impacts.t[0]) == []
    np.testing.assert_array_equal(back.contacts.force, bounced.contacts.force)


def test_impulses_dataframe(bounced) -> None:
    pytest.importorskip("pandas")
    df = bounced.to_dataframe("impulses")
    assert len(df) == len(bounced.impacts.rows)
    assert {"impact", "link1", "piece2", "impulse_z", "normal_impulse"} <= set(df.columns)
    assert (df["normal_impulse"] > 0).all()
    np.testing.assert_allclose(df.index.to_numpy(), bounced.impacts.t[df["impact"].to_numpy()])
