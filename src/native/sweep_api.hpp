// The collision sweep's C entry point, shared by packbot._native_coal (which exports it) and
// packbot._native (whose stretch of steps calls it): a plain function pointer in a capsule, so
// that the two modules need no link between them (packbot._native does not link libcoal).
//
// ``Sweep.api()`` (packbot._native_coal) returns a capsule named PACKBOT_SWEEP_API holding a
// SweepApi; the capsule keeps the Sweep alive. ``sweep`` does what ``Sweep.sweep(q, margin)``
// does (forward kinematics, the broadphase boxes, Coal's distance on every candidate; the
// witness points kept), writing the candidates' pair indices and signed distances [m] into
// ``pairs`` and ``dist`` (room for ``cap`` each), the closest pair's index (-1: none) into
// ``best`` and its distance (inf: none) into ``best_d``. Returns the number of candidates.
// ``materials`` does what ``Sweep.materials`` does (the contact patches as material points).
#pragma once

#include <cstdint>

#define PACKBOT_SWEEP_API "packbot.sweep_api.2"  // (its version: the struct below)

struct SweepApi {
  void *self;
  int64_t (*sweep)(void *self, const double *q, double margin, int64_t *pairs, double *dist,
                   int64_t *best, double *best_d);
  // Sweep.materials of n pairs (their indices) at q, as the contact-normal mode's re-patch
  // needs them: sizes, flags (n), frame2 (n, 9) and centres (n, 6: body 1's, body 2's) per
  // pair; the points in the joints' frames local1, local2 (S, 3) and the tangential offsets
  // offset0 (each pair's (2, K) block in turn: 2 S) if S <= cap. Returns S, or -1 (no face
  // planes set, or more than cap points).
  int64_t (*materials)(void *self, const double *q, const int64_t *pairs, int64_t n, double tol,
                       double patch_tol, double face_align, int64_t *sizes, int64_t *flags,
                       double *frame2, double *centres, double *local1, double *local2,
                       double *offset0, int64_t cap);
  // Sweep's distance of pair k at q [m] (requests of its own: no other query's warm start
  // moves), for the screen of contacts between step ends (pair_dips.hpp).
  double (*distance)(void *self, const double *q, int64_t k);
  int64_t n_pairs;  // the world's pairs: the room ``pairs`` and ``dist`` need at most
  int64_t nq;       // the configuration's size
  void *owner;      // the Python Sweep (a reference the capsule holds)
};
