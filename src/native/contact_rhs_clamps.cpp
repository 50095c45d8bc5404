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
// while set_row_mode's locked set holds it.

#include "contact_rhs.hpp"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
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
