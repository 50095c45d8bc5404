"""Golden results that reproduce: sensitivity, horizon, bands and checkpoints (packbot.regress)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from packbot.batch import RunRecord
from packbot.contact.joint_clamp import impact_reset
from packbot.regress import (
    NOISE_FACTOR,
    Sensitivity,
    Tolerances,
    checkpoints,
    compare,
    measure_sensitivity,
)

JOINTS = ("a", "b")


def record(q=(0.0, 1.0), kinds=("impact", "limit"), times=(0.1, 0.5), energy=-1.0, rest=0.8):
    return RunRecord(
        id="r",
        index=0,
        params={},
        digest="d",
        status="ok",
        joint_names=JOINTS,
        final_q=tuple(q),
        rest_time=rest,
        n_impacts=kinds.count("impact"),
        n_limits=kinds.count("limit"),
        n_events=len(kinds),
        event_times=tuple(times),
        event_kinds=tuple(kinds),
        min_distance=0.002,
        energy_change=energy,
        t_end=1.0,
    )


def trajectory(offset=0.0, jump_at=None, jump=0.0):
    t = np.round(np.arange(0, 101) * 0.01, 12)
    q = np.stack([np.sin(t), np.cos(t)], axis=1) + offset
    if jump_at is not None:
        q[t >= jump_at] += jump
    return t, q


def golden_entry(rec, traj, sens):
    t, q = checkpoints(traj, rec.t_end)
    return {**rec.quantities(), "checkpoints": {"t": t, "q": q}, "sensitivity": sens.to_json()}


def test_checkpoints_every_quarter_second() -> None:
    t, q = checkpoints(trajectory(), 1.0)
    assert t == [0.0, 0.25, 0.5, 0.75, 1.0]
    assert q[2] == pytest.approx([math.sin(0.5), math.cos(0.5)])


def test_a_quiet_run_has_no_horizon_and_its_noise() -> None:
    nominal = record()
    member = record(q=(3e-9, 1.0), times=(0.1 + 2e-10, 0.5), energy=-1.0 + 4e-9)
    sens = measure_sensitivity(
        nominal, trajectory(), [(member, trajectory(offset=3e-9))], Tolerances()
    )
    assert sens.horizon is None and sens.band == {}
    assert sens.q == pytest.approx(3e-9)
    assert sens.time == pytest.approx(2e-10, rel=1e-3)
    assert sens.energy == pytest.approx(4e-9)


def test_a_branching_run_gets_a_horizon_and_a_band() -> None:
    nominal = record()
    # The copy takes another event at 0.5 s and its trajectory jumps there.
    member = record(q=(0.2, 0.9), kinds=("impact", "release"), energy=-1.3)
    sens = measure_sensitivity(
        nominal, trajectory(), [(member, trajectory(jump_at=0.5, jump=0.1))], Tolerances()
    )
    assert sens.horizon == pytest.approx(0.5)
    assert sens.band["q.a"] == (0.0, 0.2) and sens.band["energy_change"] == (-1.3, -1.0)
    assert Sensitivity.from_json(sens.to_json()) == sens


def test_compare_widens_each_tolerance_to_the_measured_noise() -> None:
    g = record()
    sens = Sensitivity(q=1e-6)
    golden = {"r": golden_entry(g, trajectory(), sens)}
    near = record(q=(5e-6, 1.0))  # beyond the absolute 1e-6, within 10 x the noise
    assert compare(golden, {"r": near}, Tolerances(), {"r": trajectory()}) == []
    far = record(q=(2e-5, 1.0))
    drifts = compare(golden, {"r": far}, Tolerances(), {"r": trajectory()})
    assert [d.quantity for d in drifts] == ["q.a"]
    assert drifts[0].tolerance == pytest.approx(NOISE_FACTOR * 1e-6)


def test_checkpoints_catch_a_trajectory_that_moved_and_came_back() -> None:
    g = record()
    golden = {"r": golden_entry(g, trajectory(), Sensitivity())}
    t, q = trajectory()
    q[50, 1] += 1e-3  # at t = 0.5 s only: the final quantities are untouched
    drifts = compare(golden, {"r": record()}, Tolerances(), {"r": (t, q)})
    assert [d.quantity for d in drifts] == ["q(t=0.5).b"]
    assert compare(golden, {"r": record()}, Tolerances(), None) == []  # no trajectories given


def test_a_chaotic_run_is_compared_before_its_horizon_and_on_its_band() -> None:
    g = record()
    sens = Sensitivity(
        horizon=0.5,
        band={
            "q.a": (0.0, 0.2),
            "q.b": (0.9, 1.0),
            "rest_time": (0.8, 0.8),
            "n_events": (2.0, 2.0),
            "min_distance": (0.002, 0.002),
            "energy_change": (-1.3, -1.0),
        },
    )
    golden = {"r": golden_entry(g, trajectory(), sens)}
    # Another branch after the horizon, inside the band: no drift.
    other = record(q=(0.3, 0.95), kinds=("impact", "release"), energy=-1.5)
    assert compare(golden, {"r": other}, Tolerances(), {"r": trajectory(jump_at=0.6, jump=1)}) == []
    # Outside the band (widened by its width): a drift.
    wild = record(q=(0.7, 0.95), kinds=("impact", "release"))
    assert [d.quantity for d in compare(golden, {"r": wild})] == ["q.a (band)"]
    # The copies' branching event moved just before the horizon: not a drift; two more are.
    moved = record(q=(0.1, 0.95), kinds=("impact", "stick"), times=(0.1, 0.49))
    assert compare(golden, {"r": moved}) == []
    more = record(q=(0.1, 0.95), kinds=("impact", "stick", "slip"), times=(0.1, 0.2, 0.3))
    assert "events before the horizon" in [d.quantity for d in compare(golden, {"r": more})]
    # Before the horizon everything is strict: an event moved at 0.1 s, the trajectory at 0.25 s.
    early = record(times=(0.1 + 1e-3, 0.5))
    assert [d.quantity for d in compare(golden, {"r": early})] == ["event[0].t (impact)"]
    drifts = compare(golden, {"r": g}, Tolerances(), {"r": trajectory(jump_at=0.2, jump=1e-4)})
    assert [d.quantity for d in drifts] == ["q(t=0.25).a"]


def test_momentum_reset_stops_the_joints_exactly() -> None:
    # The roundoff of the impulse solve used to leave +-1e-16 rad/s on a stopped joint, whose
    # sign decided whether a limit stop held it: two machines took two branches.
    rng = np.random.default_rng(3)
    for _ in range(50):
        a = rng.normal(size=(4, 4))
        minv = np.linalg.inv(a @ a.T + 4 * np.eye(4))
        v = rng.normal(size=4)
        rel = np.array([1, 3])
        for e in (0.0, 0.5):
            out = impact_reset(v, rel, e, "momentum", minv)
            assert np.array_equal(out[rel], -e * v[rel])


def _rtol_runner(run, progress):
    """A toy run whose final pose a change of config.rtol moves (chaotic for x = 1 only)."""
    import io

    x = float(run.scenario["x"])
    dr = float(run.scenario.get("config", {}).get("rtol", 1e-8)) / 1e-8 - 1.0
    qa = x + (dr * 1e6 if x == 1.0 else 0.0)  # +-1e-3 rad per 1e-9 for x = 1
    t, q = trajectory()
    q[t >= 0.5, 0] += qa - q[-1, 0]
    rec = record(q=(qa, q[-1, 1]))
    buf = io.BytesIO()
    np.savez(buf, t=t, q=q)
    skip = ("id", "index", "params", "digest", "status", "error", "seconds", "files")
    quantities = {k: v for k, v in rec.quantities().items() if k not in skip}
    return quantities, {"trajectory": (f"{run.id}.npz", buf.getvalue())}


def test_a_chaotic_run_is_sampled_by_more_copies(tmp_path) -> None:
    """A run its three copies find chaotic is made again with CHAOTIC_PERTURBATIONS, and its
    band spans them all; a quiet run is not; the pose's band is widened by chaotic_q."""
    from packbot.matrix import Matrix, expand
    from packbot.regress import CHAOTIC_PERTURBATIONS, PERTURBATIONS, read_golden, run_regression

    made: list[str] = []

    def runner(run, progress):
        made.append(run.id)
        return _rtol_runner(run, progress)

    m = Matrix(name="toy", base="toy", axes={"x": [1.0, 2.0]})
    m.validate()
    runs = expand(m, {"x": 0.0, "config": {"rtol": 1e-8}})
    run_regression(m, tmp_path, update=True, runs=runs, workers=0, runner=runner)
    chaotic, quiet = runs
    assert sum(r.startswith(chaotic.id) for r in made) == 1 + len(PERTURBATIONS) + len(
        CHAOTIC_PERTURBATIONS
    )
    assert sum(r.startswith(quiet.id) for r in made) == 1 + len(PERTURBATIONS)
    golden = read_golden(tmp_path / "toy")[1]
    band = golden[chaotic.id]["sensitivity"]["band"]["q.a"]
    assert band == pytest.approx([1.0 - 6e-3, 1.0 + 6e-3], abs=1e-9)  # the extra copies' +-6e-9
    assert golden[quiet.id]["sensitivity"].get("horizon") is None
    # Compared: the band widened by its width and chaotic_q (0.05 rad).
    rec = {chaotic.id: record(q=(1.0 + 6e-3 + 0.012 + 0.049, 1.0)), quiet.id: record(q=(2.0, 1.0))}
    rec = {k: RunRecord(**{**v.__dict__, "id": k}) for k, v in rec.items()}
    drifts = compare(golden, rec, Tolerances())
    assert "q.a (band)" not in {d.quantity for d in drifts if d.run == chaotic.id}
    rec[chaotic.id] = RunRecord(**{**rec[chaotic.id].__dict__, "final_q": (1.0 + 0.07, 1.0)})
    drifts = compare(golden, rec, Tolerances())
    assert "q.a (band)" in {d.quantity for d in drifts if d.run == chaotic.id}
