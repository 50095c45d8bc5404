// The contact set's rows at one state, as the restart's native steps read them (a view into
// ContactRhs's arrays, see ContactRhs::rows_at), and the small dense algebra they share.
// Row-major arrays throughout.

#pragma once

#include <Eigen/SVD>

#include <cmath>
#include <cstdint>
#include <vector>

namespace packbot_native {

// The rows of packbot.contact.normal_rows.ContactRows._problem at one state.
struct Rows {
  int nv = 0, m = 0, mp = 0, np = 0;  // velocities, rows, patch rows (then limits), pairs
  const double *Jn = nullptr;         // (m, nv)
  const double *drift = nullptr, *gap = nullptr, *vn = nullptr;  // (m)
  const double *JT = nullptr;         // (np, 2, nv) tangential rows at the patch centres
  const double *bT = nullptr, *vT = nullptr;  // (np, 2) their drift [m/s^2], velocities [m/s]
  const double *vt = nullptr;         // (np, 3) world tangential velocity at the centre [m/s]
  const double *F = nullptr;          // (np, 3, 3) rows t1, t2, n of each pair's frame, world
  const double *dJp = nullptr;        // (h, 3, nv) J_p2 - J_p1 of every point
  const double *v = nullptr;          // (nv) the velocity the rows were computed at [rad/s]
  const int64_t *rows = nullptr;      // (mp) the point of each patch row
  const int *first = nullptr;         // (np) each pair's first row
  const int *K = nullptr;             // (np) each pair's number of rows

  // Whether every row's numbers are finite (a NaN's comparisons differ between numpy's min and
  // max and std::min and std::max: the native steps hand such a state back to Python).
  bool finite() const {
    auto ok = [](const double *x, size_t n) {
      for (size_t i = 0; i < n; ++i)
        if (!std::isfinite(x[i])) return false;
      return true;
    };
    const size_t M = static_cast<size_t>(m), P = static_cast<size_t>(np), V = static_cast<size_t>(nv);
    return ok(Jn, M * V) && ok(drift, M) && ok(gap, M) && ok(vn, M) && ok(JT, 2 * P * V) &&
           ok(bT, 2 * P) && ok(vT, 2 * P) && ok(vt, 3 * P) && ok(F, 9 * P);
  }

  // The pair of a row (-1: a limit row).
  int pair_of(int r) const {
    for (int p = 0; p < np; ++p)
      if (r >= first[p] && r < first[p] + K[p]) return p;
    return -1;
  }
};

namespace dense {

inline double dot(const double *a, const double *b, int n) {
  double s = 0.0;
  for (int i = 0; i < n; ++i) s += a[i] * b[i];
  return s;
}

inline double norm3(const double *x) {  // (normal_modes._norm: sqrt(x . x))
  return std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
}

// out (r x c) = A (r x k) B (k x c).
inline void matmul(const double *A, const double *B, int r, int k, int c, double *out) {
  for (int i = 0; i < r; ++i)
    for (int j = 0; j < c; ++j) {
      double s = 0.0;
      for (int t = 0; t < k; ++t) s += A[i * k + t] * B[t * c + j];
      out[i * c + j] = s;
    }
}

// out (r x c) = A (r x k) B^T, B (c x k).
inline void matmul_t(const double *A, const double *B, int r, int k, int c, double *out) {
  for (int i = 0; i < r; ++i)
    for (int j = 0; j < c; ++j) out[i * c + j] = dot(A + i * k, B + j * k, k);
}

// out (r x c) -= A (r x k) B (k x c), each product summed before it is subtracted (a Schur
// complement's update, as numpy's M - A @ B).
inline void matmul_sub(const double *A, const double *B, int r, int k, int c, double *out) {
  for (int i = 0; i < r; ++i)
    for (int j = 0; j < c; ++j) {
      double s = 0.0;
      for (int t = 0; t < k; ++t) s += A[i * k + t] * B[t * c + j];
      out[i * c + j] -= s;
    }
}

// numpy.linalg.pinv(G, rcond) of an n x n matrix into out: the SVD, the singular values
// below rcond times the largest cut (the same to rounding).
inline void pinv(const double *G, int n, double rcond, std::vector<double> &out) {
  out.assign(static_cast<size_t>(n) * n, 0.0);
  if (n == 0) return;
  Eigen::MatrixXd M(n, n);
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b) M(a, b) = G[a * n + b];
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(M, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::VectorXd &sv = svd.singularValues();
  const double cutoff = rcond * sv.maxCoeff();
  Eigen::VectorXd inv(n);
  for (int i = 0; i < n; ++i) inv[i] = sv[i] > cutoff ? 1.0 / sv[i] : 0.0;
  const Eigen::MatrixXd P = svd.matrixV() * inv.asDiagonal() * svd.matrixU().transpose();
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b) out[a * n + b] = P(a, b);
}

}  // namespace dense

// The sliding direction s (world, unit) of body 2 relative to body 1 at patch point k of pair
// p, for its friction force -mu lambda s (ContactRows.slip_directions): the tangential part
// v_t of the point's relative velocity (J_p2 - J_p1) v, blended with the tangential part s0_t
// of the pair's onset direction s0 below stick_speed, s = (v_t + stick_speed s0_t) / |...|
// (s0 where that is zero). Each point's own slide, not the patch centre's: a patch spinning
// about its normal slides its points in different directions, and one direction for all
// would make friction do positive work on some of them. s0 is fixed in the world at the
// onset and the normal turns with its body: s0 itself would give s a normal part, a force
// along n applied at the material points, which did work (+0.6 W on a slowing slide).
inline void point_slip_direction(const double *dJp_k, const double *n, const double *v, int nv,
                                 const double *s0, double stick_speed, double *s) {
  double vr[3];
  for (int i = 0; i < 3; ++i) vr[i] = dense::dot(dJp_k + i * nv, v, nv);
  const double vn = vr[0] * n[0] + vr[1] * n[1] + vr[2] * n[2];
  const double sn = s0[0] * n[0] + s0[1] * n[1] + s0[2] * n[2];
  double w[3];
  for (int i = 0; i < 3; ++i) w[i] = vr[i] - vn * n[i] + stick_speed * (s0[i] - sn * n[i]);
  const double nw = dense::norm3(w);
  for (int i = 0; i < 3; ++i) s[i] = nw > 0.0 ? w[i] / nw : s0[i];
}

}  // namespace packbot_native
