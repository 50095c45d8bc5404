"""The contact-normal mode's tolerances and gains (see :mod:`packbot.contact.normal`).

Modelling tolerances of the patches, the mode conditions and the restart's steps; the law's
own thresholds (cascades, windows) are in :mod:`packbot.contact.normal_law`.
"""

#: A row takes part in the impulse and acceleration problems when its gap is below this [m].
TOUCH_GAP = 1e-5
#: A free row of a pair in contact is an impact when its gap falls below -POINT_TOL [m].
POINT_TOL = 1e-6
#: A pair in contact whose signed distance falls below -PENETRATION_TOL [m] is re-patched (its
#: patch no longer describes the touching features).
PENETRATION_TOL = 1e-5
#: A patch whose smallest point gap is farther than this from the pair's distance [m] is not
#: used (see :meth:`NormalContacts.add_pair`).
PATCH_TOL = 1e-4
#: Hysteresis of the force conditions [N] (release, cone).
FORCE_BAND = 1e-6
#: A touching row whose normal speed is within this of zero takes part in the mode problem
#: [m/s] (rad/s for a stop). One approaching faster is left free: an engaged row's gap keeps
#: the speed it had when engaged (the mode holds its acceleration at zero), so such a row would
#: drift through its surface; free, it is an impact at -POINT_TOL. (After a restart's impulse
#: no touching row approaches; a re-patch, which applies none, can find one.)
SPEED_BAND = 1e-6
#: Hysteresis of the stick condition [m/s]: a slipping pair sticks once its sliding velocity
#: has come back through zero by this much along its friction direction. Smaller bands let
#: a pair sliding at the cone's edge with almost no acceleration (the arm's elbow casing on the
#: chassis while link 3 slides) fire a stick event every few milliseconds, each followed by an
#: immediate slip: the restarts then keep resetting the other pair's slide (measured: a
#: stick/slip pair of events every 3.35 ms with 1e-6 m/s).
STICK_BAND = 1e-4
#: A pair may start sticking when its sliding speed is below this [m/s] (the stick mode's
#: velocity term removes the rest).
STICK_SPEED = 1e-3
#: Rest capture (:meth:`NormalContacts.capture`): at a restart, an arm slower than this
#: [rad/s] whose contacts can all stick at v = 0 with accelerations below CAPTURE_ACCEL
#: [rad/s^2] is brought to rest.
CAPTURE_SPEED = 1e-2
CAPTURE_ACCEL = 1e-2
#: A sliding pair's patch is rebuilt once its material points have slid this far apart
#: tangentially since it was built [m] (see :meth:`NormalContacts.stale`). The rows are the
#: exact derivatives of the patch's gaps and of its centres' slides, the frame turning with
#: the body whose face it is (the extension's rows): a kept patch's forces act where the
#: bodies touch, and its gaps stay the distances while a vertex slides on a face (the gap
#: condition of ``stale``, POINT_TOL, catches a curved body's next facet or a point sliding
#: off its face). What a slide leaves behind is the shape of a face-on-face patch: its corners
#: on the other face's edges lag by up to this, small against the pieces' faces (tens of mm).
#: It was 0.1 mm while the rows were those of the material points (the forces' points of
#: application lagged by the slide). The collapse (5 s, mu 0.2, 0.5, 0.8): 317, 274, 260
#: re-patches at 0.1 mm, 155, 87, 61 at 1 mm; shoulder, elbows at rest within 1.1e-3 rad.
SLIDE_TOL = 1e-3
#: A one-point patch whose normal is a face normal of its body to within this (1 - cos) is a
#: vertex on that face [-]: its point is the vertex, a material point of the other body, where
#: the bodies touch however far it slides, and its gap is the vertex's height above the face's
#: plane; nothing lags, so SLIDE_TOL does not apply (the gap condition of ``stale`` still
#: catches the vertex leaving its face). Measured: the vertex-on-face patches of the collapse and
#: of wrist-free starts within 2e-13 of a face normal, the edge-on-edge ones (whose points are
#: material points sliding along both edges: SLIDE_TOL applies) 3e-3 or more away. The
#: collapse's re-patches (mu 0.5): 90 -> 46 (link 3's tube on the shoulder casing: 44 -> 0).
#: A patch of any size whose normal is a halfspace's (the floor) is kept the same way: that
#: face has no edge for a corner to lag at, its points are the other body's, and its gaps are
#: their heights above the plane however far they slide. Measured: the collapse's restarts
#: (mu 0.5) 80 -> 68; on two frictionless wrist-free starts, most of the windows' re-patches
#: for a slide were the fingers' and elbow casings' on the floor.
FACE_ALIGN = 1e-9
#: Stiffness of the drift correction [rad/s] (a_n = -2 w g' - w^2 g on engaged rows).
BAUMGARTE = 20.0
#: Largest acceptable scaled residual of a complementarity solution [-].
RESIDUAL_TOL = 1e-7
#: Rounds of the drift projection (:meth:`NormalContacts.project`): each adds to the contact set
#: the pairs that the previous one made penetrate.
PROJECT_ROUNDS = 3

#: A row is frozen by the locked joints (the hand-off's bilateral and held joints) when its
#: largest entry on the other joints is below NULL_ROW times its largest entry [-] (rounding:
#: the two bodies' Jacobians cancel there).
NULL_ROW = 1e-9
#: The gap reported for such a row [m]: far from touching.
NULL_GAP = 1.0
