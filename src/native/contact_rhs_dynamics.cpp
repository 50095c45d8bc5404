// ContactRhs: the constrained accelerations of the current modes: the plan (engaged rows,
// slipping and sticking pairs), a stage of the right-hand side, M^-1, the Delassus system and
// its solve, the mode conditions.

#include "contact_rhs.hpp"
#include "rows.hpp"
#include "small_solve.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

using packbot_native::ints;
using packbot_native::reals;

using packbot_native::solve_small;

// The current modes (see packbot.contact.normal._Plan) and the law's constants.
void ContactRhs::set_plan(I1 engaged, I1 row_slip, I1 sticks, double mu, double stick_speed,
                          double baumgarte) {
  end_valid_ = false;
  jac_valid_ = false;
  engaged_ = ints(engaged);
  row_slip_ = ints(row_slip);
  sticks_ = ints(sticks);
  if (row_slip_.size() != engaged_.size())
    throw std::invalid_argument("row_slip: one entry per engaged row expected");
  for (auto r : engaged_)
    if (r < 0 || r >= m_) throw std::invalid_argument("engaged row out of range");
  for (auto p : row_slip_)
    if (p >= np_) throw std::invalid_argument("row_slip pair out of range");
  for (auto p : sticks_)
    if (p < 0 || p >= np_) throw std::invalid_argument("sticking pair out of range");
  mu_ = mu;
  stick_speed_ = stick_speed;
  baumgarte_ = baumgarte;
  set_plan_sizes(static_cast<int>(engaged_.size()), static_cast<int>(sticks_.size()));
}

// Each pair's sliding direction at onset (pairs, 3), world.
void ContactRhs::set_slip_dirs(F2 slip_dir) {
  if (slip_dir.size() != slip_dir_.size())
    throw std::invalid_argument("slip_dir: (pairs, 3) expected");
  std::copy(slip_dir.data(), slip_dir.data() + slip_dir.size(), slip_dir_.begin());
  end_valid_ = false;
  jac_valid_ = false;
}

// The plan of these modes (packbot.contact.normal_rows.ContactRows._plan, as
// NativeRhs.load sets it): the engaged rows, each row's slipping pair, the sticking pairs
// with engaged rows; every pair's slip direction. mu, the stick speed and Baumgarte's
// constant as loaded.
void ContactRhs::load_plan(const std::vector<int> &eng, const uint8_t *stick,
                           const double *slip_dir) {
  end_valid_ = false;
  jac_valid_ = false;
  plan_rows(eng, stick);
  std::copy(slip_dir, slip_dir + 3 * np_, slip_dir_.begin());
  set_plan_sizes(static_cast<int>(engaged_.size()), static_cast<int>(sticks_.size()));
}

// The plan's rows of these modes with mu_ loaded: the engaged rows, each one's slipping pair
// (-1: none), the sticking pairs with engaged rows (ContactRows._plan; stick: a flag per pair).
template <class Flag>
void ContactRhs::plan_rows(const std::vector<int> &eng, const Flag *stick) {
  engaged_.assign(eng.begin(), eng.end());
  row_slip_.assign(eng.size(), -1);
  sticks_.clear();
  if (!(mu_ > 0.0)) return;
  for (int p = 0; p < np_; ++p) {
    bool mine = false;
    for (size_t e = 0; e < eng.size(); ++e) {
      if (eng[e] >= pfirst_[p] && eng[e] < pfirst_[p] + pK_[p]) {
        mine = true;
        if (!stick[p]) row_slip_[e] = p;
      }
    }
    if (mine && stick[p]) sticks_.push_back(p);
  }
}

// Accelerations of the current modes at (q, v) into out; x is tau (from_tau) or a_free.
// False when the Delassus matrix is singular (out then holds a_free: the caller solves).
bool ContactRhs::accel(F1 q, F1 v, F1 x, bool from_tau, Out1 out) {
  if (q.shape(0) != static_cast<size_t>(nv_) || v.shape(0) != static_cast<size_t>(nv_) ||
      x.shape(0) != static_cast<size_t>(nv_) || out.shape(0) != static_cast<size_t>(nv_))
    throw std::invalid_argument("q, v, tau and out: nv entries expected");
  if (lock_mode_ >= 0) throw std::invalid_argument("accel: the contact rows' call (set_locks)");
  end_valid_ = false;
  for (int i = 0; i < nv_; ++i) {
    q_[i] = q.data()[i];
    v_[i] = v.data()[i];
    x_[i] = x.data()[i];
  }
  if (from_tau) {
    aba_world(q_, v_, x_);
    a_free_ = data_.ddq;
  } else {
    a_free_ = x_;
  }
  const bool ok = compute(from_tau);
  double *o = out.data();
  for (int i = 0; i < nv_; ++i) o[i] = a_[i];
  return ok;
}

// The constrained accelerations at the rows computed (rows_at) with the modes (the engaged
// rows, the pairs' stick flags and slip directions: the plan of ContactRows._plan), a_free
// and Mi given: a (nv), the smallest mode condition and the forces (as
// ConstrainedDynamics.evaluate); false when the Delassus matrix is singular. The plan is
// loaded (set_plan's).
bool ContactRhs::evaluate_modes(const std::vector<int> &eng, const std::vector<char> &stick,
                                const std::vector<double> &slip_dir, const double *a_free,
                                const double *Mi, double mu, double stick_speed, double baumgarte,
                                double *a, double *cond, std::vector<double> &lam) {
  const int nv = nv_;
  mu_ = mu;
  stick_speed_ = stick_speed;
  baumgarte_ = baumgarte;
  plan_rows(eng, stick.data());
  set_plan_sizes(static_cast<int>(engaged_.size()), static_cast<int>(sticks_.size()));
  std::copy(slip_dir.begin(), slip_dir.end(), slip_dir_.begin());
  for (int i = 0; i < nv; ++i) {
    a_free_[i] = a_free[i];
    for (int c = 0; c < nv; ++c) minv_(i, c) = Mi[i * nv + c];
  }
  if (!solve_plan()) return false;
  for (int i = 0; i < nv; ++i) a[i] = a_[i];
  *cond = end_conditions();
  lam.assign(lam_.begin(), lam_.begin() + n_);
  return true;
}

// The constrained accelerations of the loaded plan at (q, v) with a_free and M^-1 given (the
// contact set's Python side: packbot.contact.normal_dynamics.ConstrainedDynamics.evaluate):
// end_eval's tuple (cond, a, lam, gap, vn, vt, slide2) there; None when the Delassus matrix
// is singular (the caller solves by least squares).
nb::object ContactRhs::evaluate_at(F1 q, F1 v, F1 a_free, F2 minv, bool with_qc) {
  const size_t n = static_cast<size_t>(nv_);
  if (q.shape(0) != n || v.shape(0) != n || a_free.shape(0) != n || minv.shape(0) != n ||
      minv.shape(1) != n)
    throw std::invalid_argument("q, v, a_free (nv) and minv (nv, nv) expected");
  if (lock_mode_ >= 0)
    throw std::invalid_argument("evaluate_at: the contact rows' call (set_locks)");
  if (!conditions_set_) throw std::invalid_argument("evaluate_at: set_conditions first");
  rows_at(q.data(), v.data());
  const double *af = a_free.data(), *Mi = minv.data();
  for (int i = 0; i < nv_; ++i) {
    a_free_[i] = af[i];
    for (int c = 0; c < nv_; ++c) minv_(i, c) = Mi[i * nv_ + c];
  }
  if (!solve_plan()) return nb::none();
  const double cond = end_conditions();
  nb::object qc = nb::none();
  if (with_qc) {  // the rows' generalized force C^T lambda [N*m] (the hand-off's holding torques)
    std::vector<double> f(static_cast<size_t>(nv_), 0.0);
    for (int c = 0; c < nv_; ++c) {
      double s = 0.0;
      for (int e = 0; e < n_; ++e) s += C_[e * nv_ + c] * lam_[e];
      f[c] = s;
    }
    qc = nb::cast(vec(f.data(), n));
  }
  return nb::make_tuple(cond, vec(a_.data(), nv_), vec(lam_.data(), n_), vec(gap_.data(), m_),
                        vec(vn_.data(), m_), mat(vt_.data(), np_, 3),
                        vec(slide2_.data(), np_), qc);
}

// The last call's unconstrained accelerations, M^-1, forces, gaps, normal velocities,
// centre tangential velocities, Delassus matrix and right-hand side (copies).
nb::tuple ContactRhs::last() const {
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> Mi = minv_;
  return nb::make_tuple(vec(a_free_.data(), nv_), mat(Mi.data(), nv_, nv_),
                        vec(lam_.data(), n_), vec(gap_.data(), m_), vec(vn_.data(), m_),
                        mat(vt_.data(), np_, 3), mat(G0_.data(), n_, n_),
                        vec(rhs0_.data(), n_));
}

// One right-hand side dy/dt = (v, a) at y = (q, v) under the loaded torques; false when the
// Delassus matrix is singular.
bool ContactRhs::stage(const double *y, double *f) {
  const int nv = nv_;
  for (int i = 0; i < nv; ++i) {
    q_[i] = y[i];
    v_[i] = y[nv + i];
    x_[i] = applied_[i] + (-viscous_[i] * v_[i] - coulomb_dir_[i]);
  }
  if (lock_mode_ >= 0) {
    if (!lock_accel()) return false;
    for (int i = 0; i < nv; ++i) {
      f[i] = y[nv + i];
      f[nv + i] = a_[i];
    }
    return true;
  }
  aba_world(q_, v_, x_);
  a_free_ = data_.ddq;
  if (!compute(true)) return false;
  for (int i = 0; i < nv; ++i) {
    f[i] = y[nv + i];
    f[nv + i] = a_[i];
  }
  return true;
}

// M^-1, the rows and the plan's accelerations at (q_, v_) with a_free_. after_aba: data_
// holds aba(WORLD)'s pass at (q_, v_), whose factors give M^-1 (Pinocchio's computeMinverse
// without q: the same numbers as with q) and whose J and oMi are the rows' (dJ by
// time_variation()); else the full passes.
bool ContactRhs::compute(bool after_aba) {
  const int nv = nv_;
  if (after_aba) {
    minverse_after_aba();
    if (nb_ > 0) time_variation();
  } else {
    minverse(q_);
    if (nb_ > 0) jacobians_time_variation();
  }
  minv_ = data_.Minv;  // the upper triangle; the lower one mirrored
  for (int i = 1; i < nv; ++i)
    for (int c = 0; c < i; ++c) minv_(i, c) = minv_(c, i);
  rows();
  return solve_plan();
}

// The constrained accelerations on the rows computed, with minv_, a_free_ and the plan loaded:
// a_ and the forces lam_; false when the Delassus matrix is singular.
bool ContactRhs::solve_plan() {
  const int nv = nv_;
  const double B = baumgarte_;
  for (int e = 0; e < ne_; ++e) {
    const int r = static_cast<int>(engaged_[e]);
    for (int c = 0; c < nv; ++c) {
      A_[e * nv + c] = Jn_[r * nv + c];
      C_[e * nv + c] = Jn_[r * nv + c];
    }
    const int p = static_cast<int>(row_slip_[e]);
    if (p >= 0) {
      const int k = static_cast<int>(rows_[r]);
      const double *d = &dJp_[k * 3 * nv];
      double s[3];
      packbot_native::point_slip_direction(d, &F_[9 * p + 6], v_.data(), nv, &slip_dir_[3 * p],
                                           stick_speed_, s);
      for (int c = 0; c < nv; ++c)
        C_[e * nv + c] -= mu_ * (s[0] * d[c] + s[1] * d[nv + c] + s[2] * d[2 * nv + c]);
    }
    target_[e] = -2.0 * B * vn_[r] - B * B * gap_[r];
    b_[e] = drift_[r];
  }
  for (int i = 0; i < ns_; ++i) {
    const int p = static_cast<int>(sticks_[i]);
    for (int j = 0; j < 2; ++j) {
      const int e = ne_ + 2 * i + j;
      for (int c = 0; c < nv; ++c) {
        A_[e * nv + c] = JT_[(p * 2 + j) * nv + c];
        C_[e * nv + c] = JT_[(p * 2 + j) * nv + c];
      }
      target_[e] = -B * vT_[2 * p + j];
      b_[e] = bT_[2 * p + j];
    }
  }
  const int n = n_;
  for (int i = 0; i < nv; ++i)
    for (int e = 0; e < n; ++e) {
      double s = 0.0;
      for (int c = 0; c < nv; ++c) s += minv_(i, c) * C_[e * nv + c];
      MC_[i * n + e] = s;
    }
  for (int e = 0; e < n; ++e) {
    double s = b_[e];
    for (int c = 0; c < nv; ++c) s += A_[e * nv + c] * a_free_[c];
    rhs_[e] = target_[e] - s;
    for (int f = 0; f < n; ++f) {
      double g = 0.0;
      for (int c = 0; c < nv; ++c) g += A_[e * nv + c] * MC_[c * n + f];
      G_[e * n + f] = g;
    }
  }
  G0_ = G_;
  rhs0_ = rhs_;
  const bool ok = solve_small(n, G_.data(), rhs_.data(), lam_.data());
  a_ = a_free_;
  if (ok) {
    for (int i = 0; i < nv; ++i) {
      double s = 0.0;
      for (int e = 0; e < n; ++e) s += MC_[i * n + e] * lam_[e];
      a_[i] += s;
    }
  }
  return ok;
}

// The smallest mode condition at the last dopri's end (returned; pos_ and, with friction,
// slipping_ set) and each pair's largest squared slide (slide2_), as
// ConstrainedDynamics.evaluate reads them.
double ContactRhs::end_conditions() {
  double cond = std::numeric_limits<double>::infinity();
  pos_.assign(m_, -1);
  for (int e = 0; e < ne_; ++e) pos_[engaged_[e]] = e;
  for (int r = 0; r < m_; ++r) {
    const double g = pos_[r] >= 0 ? lam_[pos_[r]] + force_band_ : gap_[r] + point_tol_;
    if (g < cond) cond = g;
  }
  slipping_.assign(np_, 0);
  if (mu_ > 0.0) {
    for (int i = 0; i < ns_; ++i) {
      const int64_t p = sticks_[i];
      double fn = 0.0;
      for (int r = 0; r < mp_; ++r)
        if (pos_[r] >= 0 && pair_[rows_[r]] == p) fn += lam_[pos_[r]];
      const double l0 = lam_[ne_ + 2 * i], l1 = lam_[ne_ + 2 * i + 1];
      const double g = mu_ * fn - std::sqrt(l0 * l0 + l1 * l1) + force_band_;
      if (g < cond) cond = g;
    }
    for (int e = 0; e < ne_; ++e)
      if (row_slip_[e] >= 0) slipping_[row_slip_[e]] = 1;
    for (int p = 0; p < np_; ++p) {
      if (!slipping_[p]) continue;
      const double *vt = &vt_[3 * p], *sd = &slip_dir_[3 * p];
      const double w0 = vt[0] + stick_speed_ * sd[0];
      const double w1 = vt[1] + stick_speed_ * sd[1];
      const double w2 = vt[2] + stick_speed_ * sd[2];
      const double nw = std::max(std::sqrt(w0 * w0 + w1 * w1 + w2 * w2), 1e-300);
      const double g = (vt[0] * w0 + vt[1] * w1 + vt[2] * w2) / nw + stick_band_;
      if (g < cond) cond = g;
    }
  }
  slide2_.assign(np_, 0.0);
  for (int r = 0; r < mp_; ++r) {
    const int k = static_cast<int>(rows_[r]);
    const int p = static_cast<int>(pair_[k]);
    double s2 = 0.0;
    for (int j = 0; j < 2; ++j) {
      const double *T = &F_[9 * p + 3 * j];
      double d = T[0] * dP_[3 * k] + T[1] * dP_[3 * k + 1] + T[2] * dP_[3 * k + 2];
      d -= offset0_[2 * r + j];
      s2 += d * d;
    }
    if (s2 > slide2_[p]) slide2_[p] = s2;
  }
  return cond;
}
