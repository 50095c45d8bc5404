"""The contact-normal mode (``contact_mode="normal"``): patches, complementarity, Coulomb friction.

**Rows.** Each touching pair is represented by its contact patch (Coal's ``computeContactPatch``:
4 points face on face, 2 edge on face, 1 vertex on face), one *normal row* per patch point. A
point is stored as two material points, p1 on body 1 and p2 on body 2 (in their joint frames),
and the normal n fixed in the body whose face it is (body 2's frame, or body 1's: see
``normal_owner`` in ``src/native/material.hpp``); its gap is g = n . (p2 - p1) [m] and its normal
Jacobian J_n = n^T (J_p2 - J_p1) + (n x (p2 - p1))^T J_w (J_w the angular Jacobian of n's body:
the row acts on that body where the other body's point is), so g' = J_n v exactly (n points
from body 1 to body 2: g' > 0 separates). A
joint at a position limit adds a row too: gap s (limit - q_j) [rad], J = -s e_j (s = +1 upper,
-1 lower). The patches are recomputed at every restart.

**Forces.** Contact forces lambda_k >= 0 act along the normals: M a = tau - h + J_n^T lambda (+
friction). Coulomb friction (coefficient mu) acts per pair at the patch centre: a *sticking*
pair has two tangential rows (zero relative tangential acceleration, force lambda_t free,
checked against the cone |lambda_t| <= mu sum(lambda_n)); on a *slipping* pair each point's
friction force is -mu lambda_k s, s the unit sliding direction of body 2 relative to body 1.

**Modes.** Inside an integration step the modes are fixed: which normal rows are engaged
(a_n = 0, lambda free) and which pairs stick or slip; the right-hand side then solves a small
linear system (smooth, so steps stay long). A light Baumgarte term (a_n = -2 w g' - w^2 g with
w = :data:`BAUMGARTE`) holds the engaged gaps at zero against integration drift. At the end of
every step the mode conditions are checked; a violated one is an event located by root finding:

- an engaged row's force would pull (lambda < 0): ``release``;
- a free row of a pair in contact penetrates (g < -:data:`POINT_TOL`): ``impact``;
- a sticking pair's force leaves the cone: ``slip``;
- a slipping pair's sliding velocity comes back through zero by :data:`STICK_BAND` along its
  friction direction: ``stick``;
- a resting arm's accelerations leave the rest band (see below): ``slip``.

**Restart.** After every event the patches are recomputed, then:

1. *impulse*: every row touching (g <= :data:`TOUCH_GAP`) takes part in one impulse problem,
   Newton's law per row with restitution e (0 below the Zeno speed
   :attr:`SimConfig.zeno_speed`: a bounce so slow becomes resting contact); frictionless, an LCP
   on the Delassus matrix G = J M^-1 J^T (compiled Lemke;
   :func:`packbot.contact.lcp.solve_lcp_psd` when its residual fails: every solution gives the
   same velocity change); with friction, Pinocchio's ADMM on point-contact cones
   (:func:`packbot.contact.lcp.solve_ncp_admm`); residuals checked;
2. *modes*: the acceleration-level problem with the touching rows (lambda >= 0, a_n >= 0,
   complementary), sticking pairs' tangential rows eliminated, solved by Lemke (symmetric
   without sliding friction: then non-negative least squares if Lemke's residual fails); a
   sticking pair whose force leaves the cone is switched to slip and
   the problem solved again. No solution (Painleve: friction making the problem inconsistent)
   is logged as an event and handled impulsively: the sliding pairs are stopped by a
   frictional impulse and the problem is solved with them sticking.

The engaged rows are the support of the solution, which both solvers return *basic* (the
engaged rows' Delassus block is non-singular even on a rank-deficient patch).

**Rest.** At a restart where every joint is slower than :data:`CAPTURE_SPEED` (and the impulse
was not a bounce), the frictional problem of every touching row is solved jointly at v = 0
(per-point cones, ADMM); if its joint accelerations are below :data:`CAPTURE_ACCEL` the
velocity is set to zero and the contacts rest (a = 0, one condition: those accelerations below
twice the band). The pair-by-pair cone check above cannot do this on a statically indeterminate
arm: it takes one force distribution of many (see :meth:`NormalContacts.capture`).

**Where** (one module per part; this module is the public entry point):

- :mod:`packbot.contact.normal_tolerances`: the tolerances and gains above;
- :mod:`packbot.contact.normal_patch`: a pair's patch as material points, the face planes;
- :mod:`packbot.contact.normal_set`: the contact set (pairs, limits, engaged rows);
- :mod:`packbot.contact.normal_rows`: the rows (compiled kinematics, point layout, the modes'
  plan) and when a sliding patch is stale;
- :mod:`packbot.contact.normal_dynamics`: the accelerations with the modes fixed and the mode
  conditions;
- :mod:`packbot.contact.normal_modes`: the mode selection (mixed LCP, cone check, Painleve);
- :mod:`packbot.contact.normal_steps`: the restart's projection, impulse, slow stop, capture;
- :mod:`packbot.contact.normal_contacts`: :class:`NormalContacts`, the restart and re-patch;
- :mod:`packbot.contact.patch_events`: the events of a contact-normal problem;
- :mod:`packbot.contact.normal_law`: :class:`NormalLaw` and its time-stepping windows.
"""

from packbot.contact.normal_contacts import NormalContacts
from packbot.contact.normal_law import NormalLaw
from packbot.contact.normal_modes import ModeEvent
from packbot.contact.normal_tolerances import (
    BAUMGARTE,
    CAPTURE_ACCEL,
    CAPTURE_SPEED,
    FORCE_BAND,
    PATCH_TOL,
    PENETRATION_TOL,
    POINT_TOL,
    PROJECT_ROUNDS,
    RESIDUAL_TOL,
    SLIDE_TOL,
    SPEED_BAND,
    STICK_BAND,
    TOUCH_GAP,
)
from packbot.contact.normal_windows import (
    CASCADE_EVENTS,
    CASCADE_SPAN,
    CHATTER_EVENTS,
    CHATTER_SPAN,
    CRAWL_STEP,
    CRAWL_STEPS,
    HOLD_SPEED,
    RELAPSE_EVENTS,
    RELAPSE_SPAN,
    WINDOW_MIN,
)
from packbot.contact.patch_events import PatchEvents

__all__ = [
    "BAUMGARTE",
    "CAPTURE_ACCEL",
    "CAPTURE_SPEED",
    "CASCADE_EVENTS",
    "CASCADE_SPAN",
    "CHATTER_EVENTS",
    "CHATTER_SPAN",
    "CRAWL_STEP",
    "CRAWL_STEPS",
    "FORCE_BAND",
    "HOLD_SPEED",
    "PATCH_TOL",
    "PENETRATION_TOL",
    "POINT_TOL",
    "PROJECT_ROUNDS",
    "RELAPSE_EVENTS",
    "RELAPSE_SPAN",
    "RESIDUAL_TOL",
    "SLIDE_TOL",
    "SPEED_BAND",
    "STICK_BAND",
    "TOUCH_GAP",
    "WINDOW_MIN",
    "ModeEvent",
    "NormalContacts",
    "NormalLaw",
    "PatchEvents",
]
