"""A vertex sliding on a face, or a patch on the floor, is kept; others go stale at SLIDE_TOL.

A one-point patch whose normal is a face normal of its body (``FACE_ALIGN``) is a vertex on
that face: its point is the vertex, where the bodies touch however far it slides, so it is not
rebuilt for its slide (``NormalContacts.stale``), only when its gap leaves the pair's distance.
The collapse (mu = 0.5, wrist locked): link 3's tube slides over the shoulder casing on one
vertex; it was re-patched 44 times (every 1 mm), now never for its slide. A patch of any
size whose normal is a halfspace's (the floor: a face without edges) is kept the same way: its
points are the other body's, and its gaps their heights, however far they slide.
"""

import coal
import numpy as np
import pinocchio as pin
import pytest

import packbot
from packbot.contact import normal_law, normal_set, timestep
from packbot.contact.normal_tolerances import FACE_ALIGN, POINT_TOL, SLIDE_TOL
from packbot.mujoco_model import WRIST_JOINTS


@pytest.fixture(scope="module", autouse=True)
def _steps_one_by_one(step_by_step: None) -> None:
    """This module watches the steps the loop takes one by one (conftest.step_by_step)."""


def _world_point(law, joint: int, local: np.ndarray) -> np.ndarray:
    M = law.normal.data.oMi[joint]
    return np.asarray(M.rotation @ local + M.translation)


@pytest.fixture(scope="module")
def collapse(robot):
    """The collapse (2 s): at every accepted step's end, each vertex-on-face patch's vertex,
    the distance from it to Coal's witness point on its body, and its slide since built."""
    seen: list[tuple[int, float, float, float, float]] = []
    after = normal_law.NormalLaw.after_step

    def watched(self, t, y):
        out = after(self, t, y)
        q = y[: self.n] if out is None else out[: self.n]
        pin.forwardKinematics(self.normal.model, self.normal.data, q)
        for key, p in self.normal.pairs.items():
            if np.isfinite(p.slide_tol) or len(p.local1) > 1:
                continue  # (a floor patch's: test_a_patch_on_the_floor_is_kept_while_it_slides)
            info = p.info
            v1 = _world_point(self, info.joint1, p.local1[0])
            v2 = _world_point(self, info.joint2, p.local2[0])
            c = self.world.pair_contact(q, key)
            # the vertex is on the body without the face
            vertex, witness = (v2, c.p2) if p.on1 else (v1, c.p1)
            n = c.normal
            rel = v2 - v1
            # (its p2 - p1 was along n when built: offset0 = 0)
            assert np.abs(p.offset0).max() < 1e-9
            slide = float(np.linalg.norm(rel - (rel @ n) * n))
            gap = float(rel @ n)  # (the patch's gap: the vertex's height over the face)
            seen.append((key, float(np.linalg.norm(vertex - witness)), slide, c.distance, gap))
        return out

    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, locked_joints=WRIST_JOINTS)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(normal_law.NormalLaw, "after_step", watched)
        res = packbot.simulate(robot, robot.pose("drive"), np.zeros(8), 2.0, config=cfg)
    return res, seen


def test_a_vertex_on_a_face_is_kept_while_it_slides(collapse):
    res, seen = collapse
    assert seen, "no vertex-on-face patch in the collapse: the test covers nothing"
    # kept beyond SLIDE_TOL (the rule before re-patched at 1 mm) ...
    assert max(s for _, _, s, _, _ in seen) > 3.0 * SLIDE_TOL
    # ... and still where the bodies touch: the vertex's height over the face is the pair's
    # distance to POINT_TOL (the rule that rebuilds the patch otherwise), and in most samples
    # the vertex is Coal's witness point on its body (not in all: with an edge lying almost
    # flat on the face, a point 2e-5 m along it is as close, to 2.3e-7 m)
    touching = [(w, gap - d) for _, w, _, d, gap in seen if d < 1e-4]
    assert touching
    assert max(abs(off) for _, off in touching) < POINT_TOL
    assert np.median([w for w, _ in touching]) < 1e-6
    assert -res.diagnostics.min_distance <= 1e-5


def test_only_vertices_on_faces_skip_the_slide_rule(robot, monkeypatch):
    """Every patch of wrist-free starts: slide_tol inf exactly when its normal is a face normal
    of its body and it has one point or that body is a halfspace (the palm's edges crossing the
    camera head's keep SLIDE_TOL)."""
    from test_normal_cascade import start_pose

    kinds = {"vertex": 0, "other": 0}
    made = normal_set.ContactSet._add_made

    def recorded(self, q, ks, t):
        out = made(self, q, ks, t)
        gm = self.world.geom_model
        for k, ok in zip(ks, out, strict=True):
            if not ok:
                continue
            p = self.pairs[k]
            info = self.world.pairs[k]
            M1, M2 = self.data.oMi[info.joint1], self.data.oMi[info.joint2]  # (at q)
            n = (M1 if p.on1 else M2).rotation @ p.normal2  # world, body 1 to body 2
            Rg1 = (M1 * gm.geometryObjects[info.geom1].placement).rotation
            Rg2 = (M2 * gm.geometryObjects[info.geom2].placement).rotation
            N1, _ = self._planes_of(info.geom1)
            N2, _ = self._planes_of(info.geom2)
            best = max(
                float((N1 @ (Rg1.T @ n)).max()) if len(N1) else -1.0,
                float((-(N2 @ (Rg2.T @ n))).max()) if len(N2) else -1.0,
            )
            owner = info.geom1 if p.on1 else info.geom2
            halfspace = isinstance(gm.geometryObjects[owner].geometry, coal.Halfspace)
            if (len(p.local1) == 1 or halfspace) and best >= 1.0 - FACE_ALIGN:
                kinds["vertex"] += 1
                assert p.slide_tol == np.inf
            else:
                kinds["other"] += 1
                assert p.slide_tol == SLIDE_TOL
        return out

    cfg = packbot.SimConfig(contact_mode="normal", mu=0.5, restitution=0.0)
    monkeypatch.setattr(normal_set.ContactSet, "_add_made", recorded)
    packbot.simulate(robot, start_pose(robot, 1), np.zeros(robot.model.nv), 0.6, config=cfg)
    assert kinds["vertex"] > 0 and kinds["other"] > 0, kinds


def test_a_patch_on_the_floor_is_kept_while_it_slides(robot, monkeypatch):
    """A frictionless wrist-free start (the fingers and elbow casings slide on the floor): at
    the start of every window step the stepper takes, a several-point floor patch kept beyond
    SLIDE_TOL of slide still has its rows' gaps at its points' heights above the floor, to
    rounding."""
    from test_normal_cascade import start_pose

    slides: list[float] = []
    step = timestep.MoreauJeanStepper.step

    def placements(model, q):  # the joints' placements at q (a Data of its own)
        data = model.createData()
        pin.forwardKinematics(model, data, q)
        return data.oMi

    def watched(self, t, y, *args, **kwargs):
        c, n = self.contacts, self.n
        q, v = y[:n], y[n : 2 * n]
        if c.pairs:  # (the set the last step kept, at this step's start)
            raw = c.rows_raw(q, v)
            lay = self._layout()
            gap, T, dP = raw[2], raw[9], raw[11]
            for i, key in enumerate(lay.keys):
                p = c.pairs[key]
                if len(p.local1) < 2 or np.isfinite(p.slide_tol):
                    continue
                assert c.world.pairs[key].piece2 == "floor"
                rows = np.flatnonzero(lay.row_pair == i)
                M = placements(c.model, q)[p.info.joint1]
                heights = (p.local1 @ M.rotation.T + M.translation)[:, 2]
                np.testing.assert_allclose(gap[rows], heights, rtol=0.0, atol=1e-12)
                k = lay.rows[rows]
                s = dP[k] @ T[i].T - lay.of.offset0[rows]
                slides.append(float(np.sqrt((s**2).sum(axis=1)).max()))
        return step(self, t, y, *args, **kwargs)

    monkeypatch.setattr(timestep.MoreauJeanStepper, "step", watched)
    cfg = packbot.SimConfig(contact_mode="normal", mu=0.0, restitution=0.0)
    res = packbot.simulate(robot, start_pose(robot, 16), np.zeros(robot.model.nv), 2.0, config=cfg)
    assert slides, "no floor patch kept in a window: the test covers nothing"
    assert max(slides) > 3.0 * SLIDE_TOL, max(slides)
    assert -res.diagnostics.min_distance <= 1e-5
