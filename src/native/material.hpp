// A contact patch as material points (patch_material), for the collision sweep's batch
// (packbot._native_coal's Sweep.materials) and the contact set's pair by pair patches
// (packbot._native.patch_material).
//
// Conventions: a rotation R (3x3) is row-major, R[3 * r + c] = R(r, c), as Pinocchio's
// SE3::rotation(); a face plane j of a piece is N[3 * j + i] (unit outward normal, piece frame)
// and o[j] (offset: inside <=> N x + o <= 0); points are rows of 3 [m], world frame.
#pragma once

#include <cmath>
#include <cstddef>
#include <limits>
#include <vector>

namespace packbot_native {
namespace material {

// The face planes of one piece (none: F = 0).
struct Planes {
  const double *N = nullptr;  // (F, 3)
  const double *o = nullptr;  // (F,)
  size_t F = 0;
};

// The points mid (K, 3) moved along n onto the face most aligned with sign * n (placement
// R, t); false when that face is too oblique (|N_f . n| < 0.5).
inline bool lift_points(const Planes &P, const double *R, const double *t, const double *mid,
                        size_t K, const double *n, double sign, double *out) {
  double nl[3];
  for (int i = 0; i < 3; ++i) nl[i] = R[0 + i] * n[0] + R[3 + i] * n[1] + R[6 + i] * n[2];
  size_t f = 0;
  double best = -std::numeric_limits<double>::infinity();
  for (size_t j = 0; j < P.F; ++j) {
    const double *Nj = P.N + 3 * j;
    const double s = sign * (Nj[0] * nl[0] + Nj[1] * nl[1] + Nj[2] * nl[2]);
    if (s > best) {
      best = s;
      f = j;
    }
  }
  const double *Nf = P.N + 3 * f;
  const double den = Nf[0] * nl[0] + Nf[1] * nl[1] + Nf[2] * nl[2];
  if (std::abs(den) < 0.5) return false;
  for (size_t k = 0; k < K; ++k) {
    const double *m = mid + 3 * k;
    double s = P.o[f];
    for (int i = 0; i < 3; ++i) {
      const double pl =
          (m[0] - t[0]) * R[0 + i] + (m[1] - t[1]) * R[3 + i] + (m[2] - t[2]) * R[6 + i];
      s += pl * Nf[i];
    }
    s = -s / den;
    for (int i = 0; i < 3; ++i) out[3 * k + i] = m[i] + s * n[i];
  }
  return true;
}

// Whether the points' gaps are consistent with the pair's distance: the smallest gap along n within patch_tol of the distance, none
// beyond distance + 1 mm.
inline bool consistent_points(const double *p1, const double *p2, size_t K, const double *n,
                              double distance, double patch_tol) {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();
  for (size_t k = 0; k < K; ++k) {
    const double *a = p1 + 3 * k, *b = p2 + 3 * k;
    double g = (b[0] - a[0]) * n[0] + (b[1] - a[1]) * n[1];
    g += (b[2] - a[2]) * n[2];
    lo = std::min(lo, g);
    hi = std::max(hi, g);
  }
  return std::abs(lo - distance) <= patch_tol && hi <= distance + 1e-3;
}

// Whether n (world, body 1 to body 2) is a face normal of body 1 rather
// than of body 2 (placements Rg1, Rg2 of the pieces).
inline bool normal_owner(const Planes &P1, const double *Rg1, const Planes &P2, const double *Rg2,
                         const double *n) {
  double best1 = -std::numeric_limits<double>::infinity();
  for (size_t j = 0; j < P1.F; ++j) {
    double s = 0.0;
    for (int i = 0; i < 3; ++i)
      s += P1.N[3 * j + i] * (Rg1[0 + i] * n[0] + Rg1[3 + i] * n[1] + Rg1[6 + i] * n[2]);
    best1 = std::max(best1, s);
  }
  double best2 = -std::numeric_limits<double>::infinity();
  for (size_t j = 0; j < P2.F; ++j) {
    double s = 0.0;
    for (int i = 0; i < 3; ++i)
      s -= P2.N[3 * j + i] * (Rg2[0 + i] * n[0] + Rg2[3 + i] * n[1] + Rg2[6 + i] * n[2]);
    best2 = std::max(best2, s);
  }
  return best1 > best2;
}

// What patch_material makes of one patch.
struct Made {
  bool ok = true;
  bool on1 = false;
  double normal2[3];
  double frame2[9];   // rows t1, t2, n2
  double centre1[3];
  double centre2[3];
};

// A contact patch as material points: its points on each body, in the joints' frames. Coal
// puts every patch point at the patch's one depth; with `check`, each body's points are moved
// along the normal onto that body's face most aligned with the normal (none: Coal's points),
// unless a face is too oblique or the lifted points' gaps are off the pair's distance (then
// Coal's points are kept, and ok is false when even they are off it). Without `check` the
// points are taken as they are (the witness pair). local1, local2 (K, 3) and offset0 (2, K,
// row-major) written to the caller's buffers; scratch holds 9 K doubles.
inline Made patch_material(const double *p1, const double *p2, size_t K, const double *n,
                           double distance, const Planes &P1, const double *Rg1,
                           const double *tg1, const Planes &P2, const double *Rg2,
                           const double *tg2, const double *RM1, const double *tM1,
                           const double *RM2, const double *tM2, double patch_tol,
                           double *local1, double *local2, double *offset0,
                           std::vector<double> &scratch, bool check = true) {
  Made out;
  scratch.resize(9 * K);
  double *mid = scratch.data(), *l1 = mid + 3 * K, *l2 = l1 + 3 * K;
  const double *pts1 = p1, *pts2 = p2;
  if (check) {
    for (size_t e = 0; e < 3 * K; ++e) mid[e] = 0.5 * (p1[e] + p2[e]);
    bool lifted = P1.F > 0 && P2.F > 0;
    if (lifted) {
      const bool ok1 = lift_points(P1, Rg1, tg1, mid, K, n, 1.0, l1);
      const bool ok2 = ok1 && lift_points(P2, Rg2, tg2, mid, K, n, -1.0, l2);
      lifted = ok1 && ok2 && consistent_points(l1, l2, K, n, distance, patch_tol);
      if (lifted) {
        pts1 = l1;
        pts2 = l2;
      }
    }
    if (!lifted) out.ok = consistent_points(p1, p2, K, n, distance, patch_tol);
  }
  out.on1 = normal_owner(P1, Rg1, P2, Rg2, n);
  const double *RMn = out.on1 ? RM1 : RM2;
  for (int i = 0; i < 3; ++i) out.centre1[i] = out.centre2[i] = 0.0;
  for (size_t k = 0; k < K; ++k) {
    for (int i = 0; i < 3; ++i) {
      double a = 0.0, b = 0.0;
      for (int j = 0; j < 3; ++j) {
        a += (pts1[3 * k + j] - tM1[j]) * RM1[3 * j + i];
        b += (pts2[3 * k + j] - tM2[j]) * RM2[3 * j + i];
      }
      local1[3 * k + i] = a;
      local2[3 * k + i] = b;
      out.centre1[i] += a;
      out.centre2[i] += b;
    }
  }
  for (int i = 0; i < 3; ++i) {
    out.centre1[i] /= static_cast<double>(K);
    out.centre2[i] /= static_cast<double>(K);
  }
  double *n2 = out.normal2;
  for (int i = 0; i < 3; ++i) n2[i] = RMn[0 + i] * n[0] + RMn[3 + i] * n[1] + RMn[6 + i] * n[2];
  // tangents: t1 = a x n2 / |a x n2|, t2 = n2 x t1 (a: the x axis unless n2 is near it)
  double ax[3] = {0.0, 0.0, 0.0};
  if (std::abs(n2[0]) < 0.9)
    ax[0] = 1.0;
  else
    ax[1] = 1.0;
  double t1[3] = {ax[1] * n2[2] - ax[2] * n2[1], ax[2] * n2[0] - ax[0] * n2[2],
                  ax[0] * n2[1] - ax[1] * n2[0]};
  const double nt = std::sqrt(t1[0] * t1[0] + t1[1] * t1[1] + t1[2] * t1[2]);
  for (int i = 0; i < 3; ++i) t1[i] /= nt;
  const double t2[3] = {n2[1] * t1[2] - n2[2] * t1[1], n2[2] * t1[0] - n2[0] * t1[2],
                        n2[0] * t1[1] - n2[1] * t1[0]};
  for (int i = 0; i < 3; ++i) {
    out.frame2[i] = t1[i];
    out.frame2[3 + i] = t2[i];
    out.frame2[6 + i] = n2[i];
  }
  for (size_t k = 0; k < K; ++k) {
    double d[3];
    const double *a = pts1 + 3 * k, *b = pts2 + 3 * k;
    for (int i = 0; i < 3; ++i)
      d[i] = RMn[0 + i] * (b[0] - a[0]) + RMn[3 + i] * (b[1] - a[1]) + RMn[6 + i] * (b[2] - a[2]);
    for (int r = 0; r < 2; ++r) {
      const double *f = out.frame2 + 3 * r;
      offset0[r * K + k] = f[0] * d[0] + f[1] * d[1] + f[2] * d[2];
    }
  }
  return out;
}

// normal_set._on_a_face: whether n (world, body 1 to body 2) is a face normal of its body
// (body 1's outward normal +n when on1, body 2's -n), to within face_align (1 - cos).
inline bool on_a_face(const Planes &P1, const double *Rg1, const Planes &P2, const double *Rg2,
                      const double *n, bool on1, double face_align) {
  const Planes &P = on1 ? P1 : P2;
  const double *R = on1 ? Rg1 : Rg2;
  if (P.F == 0) return false;
  double m[3];
  for (int i = 0; i < 3; ++i) {
    const double s = R[0 + i] * n[0] + R[3 + i] * n[1] + R[6 + i] * n[2];
    m[i] = on1 ? s : -s;
  }
  double best = -std::numeric_limits<double>::infinity();
  for (size_t j = 0; j < P.F; ++j) {
    const double s = P.N[3 * j] * m[0] + P.N[3 * j + 1] * m[1] + P.N[3 * j + 2] * m[2];
    if (s > best) best = s;
  }
  return best >= 1.0 - face_align;
}

}  // namespace material
}  // namespace packbot_native
