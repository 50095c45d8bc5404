// ContactRhs: the hand-off's constraint kinds (packbot.contact.handoff.HandoffContacts): the
// joint clamp rows and the locked joints.
//
// A clamp (joint j, forbidden acceleration direction s) is a one-sided joint row J = -s e_j
// after the limit rows (set_clamps). It constrains accelerations, not positions: its gap and
// drift are 0, and its normal velocity is 0 at acceleration level (no Baumgarte correction:
// an engaged row is a_j = 0) or the row's true velocity -s v_j at velocity level (the impact,
// the stop of the slow slides: set_row_mode). No restitution acts on it: the hand-off stops
// its approaching joints before the impact (HandoffContacts.stop_clamped).
//
// The locked joints S (the bilateral and the held ones) are eliminated exactly: the problems
// are solved with M^-1 and the free accelerations replaced by their constrained versions
// (lock_subspace, the Schur complement M^-1_c = M^-1 - M^-1 S^T (S M^-1 S^T)^-1 S M^-1), and
// a row the locked joints freeze (no entry on the free joints beyond null_row times its
// largest: the two bodies' Jacobians cancel there) is reported apart, gap null_gap and v_n 0,
// while set_row_mode's locked set holds it. A locked joint's holding torque comes from the same
// elimination (lock_torques), and the hand-off's joint stops (stop_joints: a clamped joint
// approaching its contact before the impact, a clamp creeping away after it) are least joint
// impulses on the clamp rows alone.

#include "contact_rhs.hpp"
#include "lcp.hpp"
#include "small_solve.hpp"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace {

void check_joints(const std::vector<int64_t> &joints, int nv, const char *who) {
  for (const int64_t j : joints)
    if (j < 0 || j >= nv) throw std::invalid_argument(std::string(who) + ": joint out of range");
}

}  // namespace

// The clamp rows (joint, s = +1 or -1), after the patch and limit rows in this order; the
// layout's work arrays are made again (set_conditions after it, as after set_layout).
void ContactRhs::set_clamps(I1 joint, F1 side) {
  if (joint.shape(0) != side.shape(0))
    throw std::invalid_argument("set_clamps: one side per joint expected");
  std::vector<int64_t> j = packbot_native::ints(joint);
  check_joints(j, nv_, "set_clamps");
  clamp_joint_ = std::move(j);
  clamp_side_ = packbot_native::reals(side);
  layout_changed();
}

// How the rows are reported: the locked joints whose frozen rows are set apart (empty: none),
// and whether the clamp rows carry their true velocity (velocity level) or 0.
void ContactRhs::set_row_mode(I1 locked, bool velocity_level, double null_row, double null_gap) {
  std::vector<int64_t> s = packbot_native::ints(locked);
  check_joints(s, nv_, "set_row_mode");
  row_locked_ = std::move(s);
  clamp_velocity_ = velocity_level;
  null_row_ = null_row;
  null_gap_ = null_gap;
  end_valid_ = false;
  jac_valid_ = false;
}

// (rows()' last part) the rows the locked joints freeze set apart, then the clamp rows.
void ContactRhs::clamp_rows() {
  const int nv = nv_, base = mp_ + ml_;
  if (!row_locked_.empty()) {
    std::vector<char> free(static_cast<size_t>(nv), 1);
    for (const int64_t j : row_locked_) free[static_cast<size_t>(j)] = 0;
    for (int r = 0; r < base; ++r) {
      const double *J = &Jn_[static_cast<size_t>(r) * nv];
      double scale = 0.0, on_free = 0.0;
      for (int c = 0; c < nv; ++c) {
        scale = std::max(scale, std::abs(J[c]));
        if (free[static_cast<size_t>(c)]) on_free = std::max(on_free, std::abs(J[c]));
      }
      if (on_free <= null_row_ * scale) {
        gap_[r] = null_gap_;
        vn_[r] = 0.0;
      }
    }
  }
  for (int i = 0; i < mc_; ++i) {
    const int r = base + i;
    const int j = static_cast<int>(clamp_joint_[i]);
    const double s = clamp_side_[i];
    Jn_[static_cast<size_t>(r) * nv + j] = -s;
    gap_[r] = 0.0;
    vn_[r] = clamp_velocity_ ? -s * v_[j] : 0.0;
  }
}

// The free accelerations a_free [rad/s^2] and M^-1 (nv x nv) with the joints `locked` fixed
// (a_j = 0): a_c = a_free - K W^-1 a_free[S], M^-1_c = M^-1 - K W^-1 K^T, K = M^-1[:, S],
// W = M^-1[S, S] (LU with partial pivoting), their rows and columns of S set to 0.
nb::tuple ContactRhs::lock_subspace(F1 a_free, F2 minv, I1 locked) const {
  const int n = nv_;
  const size_t N = static_cast<size_t>(n);
  if (a_free.shape(0) != N || minv.shape(0) != N || minv.shape(1) != N)
    throw std::invalid_argument("lock_subspace: a_free (nv) and minv (nv, nv) expected");
  const std::vector<int64_t> S = packbot_native::ints(locked);
  check_joints(S, n, "lock_subspace");
  const int k = static_cast<int>(S.size());
  const double *Mi = minv.data(), *af = a_free.data();
  Eigen::MatrixXd K(n, k), W(k, k);
  Eigen::VectorXd aS(k);
  for (int a = 0; a < k; ++a) {
    for (int i = 0; i < n; ++i) K(i, a) = Mi[i * n + S[a]];
    for (int b = 0; b < k; ++b) W(a, b) = Mi[S[a] * n + S[b]];
    aS[a] = af[S[a]];
  }
  const Eigen::PartialPivLU<Eigen::MatrixXd> lu(W);
  const Eigen::MatrixXd X = lu.solve(K.transpose());  // (k, n) W^-1 K^T
  const Eigen::VectorXd y = lu.solve(aS);
  std::vector<double> mc(N * N), ac(N);
  for (int i = 0; i < n; ++i) {
    ac[i] = af[i] - K.row(i).dot(y);
    for (int c = 0; c < n; ++c) mc[i * N + c] = Mi[i * n + c] - K.row(i).dot(X.col(c));
  }
  for (const int64_t j : S) {
    ac[j] = 0.0;
    for (int c = 0; c < n; ++c) mc[j * N + c] = mc[c * N + j] = 0.0;
  }
  return nb::make_tuple(vec(ac.data(), N), mat(mc.data(), N, N));
}

// The torques [N*m] holding the joints `locked` at a_S = 0 under the rows' generalized force qc
// = C^T lambda [N*m] (ContactRhs.evaluate's with_qc): M a = M a_free + qc + S^T tau with a_S = 0,
// so tau = -(M^-1_SS)^-1 (a_free + M^-1 qc)_S (a_free [rad/s^2] and M^-1 the full arm's).
nb::ndarray<nb::numpy, double, nb::ndim<1>> ContactRhs::lock_torques(F1 a_free, F2 minv, F1 qc,
                                                                   I1 locked) const {
  const int n = nv_;
  const size_t N = static_cast<size_t>(n);
  if (a_free.shape(0) != N || qc.shape(0) != N || minv.shape(0) != N || minv.shape(1) != N)
    throw std::invalid_argument("lock_torques: a_free, qc (nv) and minv (nv, nv) expected");
  const std::vector<int64_t> S = packbot_native::ints(locked);
  check_joints(S, n, "lock_torques");
  const int k = static_cast<int>(S.size());
  const double *Mi = minv.data(), *af = a_free.data(), *f = qc.data();
  std::vector<double> W(static_cast<size_t>(k) * k), r(k), tau(k, 0.0);
  for (int a = 0; a < k; ++a) {
    const int64_t j = S[a];
    double s = 0.0;
    for (int c = 0; c < n; ++c) s += Mi[j * n + c] * f[c];
    r[a] = -(af[j] + s);
    for (int b = 0; b < k; ++b) W[a * k + b] = Mi[j * n + S[b]];
  }
  if (!packbot_native::solve_small(k, W.data(), r.data(), tau.data()))
    throw std::runtime_error("lock_torques: M^-1 singular on the locked joints");
  return vec(tau.data(), static_cast<size_t>(k));
}

// The least (M-weighted) joint impulse P on the clamp rows J = -s e_j of (joint, side) alone,
// v+ = v + M^-1 J^T P [rad/s] (v and M^-1 the full arm's): one_sided, every row's velocity
// J v+ >= 0 (LCP w = G P + J v >= 0, P >= 0, complementary, G = J M^-1 J^T: Lemke, its residual
// at most res_tol; perfectly inelastic, it never adds energy); else J v+ = 0 (the equalities
// G P = -J v), the rows' joints then set exactly at rest. Returns (status, v+): 0 no row
// approaches (one-sided: v kept), 1 v+, 2 unsolved (v kept).
nb::tuple ContactRhs::stop_joints(F1 v, F2 minv, I1 joint, F1 side, bool one_sided,
                                  double res_tol) {
  const int n = nv_;
  const size_t N = static_cast<size_t>(n);
  if (v.shape(0) != N || minv.shape(0) != N || minv.shape(1) != N || joint.shape(0) != side.shape(0))
    throw std::invalid_argument("stop_joints: v (nv), minv (nv, nv), one side per joint expected");
  const std::vector<int64_t> J = packbot_native::ints(joint);
  check_joints(J, n, "stop_joints");
  const int k = static_cast<int>(J.size());
  const double *Mi = minv.data(), *vv = v.data(), *s = side.data();
  std::vector<double> out(vv, vv + n), G(static_cast<size_t>(k) * k), w(k), P(k, 0.0);
  double wmin = std::numeric_limits<double>::infinity();
  for (int a = 0; a < k; ++a) {
    w[a] = -s[a] * vv[J[a]];
    wmin = std::min(wmin, w[a]);
    for (int b = 0; b < k; ++b) G[a * k + b] = s[a] * s[b] * Mi[J[a] * n + J[b]];
  }
  if (k == 0 || (one_sided && wmin >= 0.0)) return nb::make_tuple(0, vec(out.data(), N));
  bool ok;
  if (one_sided) {
    ok = packbot_native::lcp::lemke_solved(G.data(), w.data(), k, res_tol, P.data(), lcp_);
  } else {
    std::vector<double> r(k);
    for (int a = 0; a < k; ++a) r[a] = -w[a];
    ok = packbot_native::solve_small(k, G.data(), r.data(), P.data());
  }
  if (!ok) return nb::make_tuple(2, vec(vv, N));
  for (int i = 0; i < n; ++i) {
    double d = 0.0;
    for (int a = 0; a < k; ++a) d += Mi[i * n + J[a]] * (-s[a] * P[a]);
    out[i] += d;
  }
  if (!one_sided)
    for (int a = 0; a < k; ++a) out[J[a]] = 0.0;
  return nb::make_tuple(1, vec(out.data(), N));
}
