// ContactRhs: the report's law's joint locks instead of the contact rows
// (packbot.contact.locks.JointLocks): the locked joints' accelerations and lock torques, and the
// screen of the lock conditions at a step's end.

#include "contact_rhs.hpp"
#include "small_solve.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

using packbot_native::ints;
using packbot_native::reals;

using packbot_native::cramer_small;

// The report's law's modes instead of the contact rows (packbot.contact.stops.JointStops
// .torque_accel): the joints locked (a_j = 0; engaged clamps and held joints, sorted).
// None: ABA; one: ABA with M^-1's rank-one correction (JointLocks.accelerations); two or
// more with at most 3 unlocked: the unlocked block M_UU a_U = (tau - h)_U from CRBA and the
// bias forces (JointLocks.reduced_accelerations). Anything else is refused. set_layout
// goes back to the contact rows.
void ContactRhs::set_locks(I1 locked) {
  const int nl = static_cast<int>(locked.shape(0));
  std::vector<char> is_locked(nv_, 0);
  for (int i = 0; i < nl; ++i) {
    const int64_t j = locked.data()[i];
    if (j < 0 || j >= nv_ || is_locked[j] || (i && j <= locked.data()[i - 1]))
      throw std::invalid_argument("locked: sorted distinct joint indices expected");
    is_locked[j] = 1;
  }
  if (nl >= 2 && nv_ - nl > 3)
    throw std::invalid_argument("locked: none, one, or all but at most 3 joints expected");
  locked_.assign(locked.data(), locked.data() + nl);
  unlocked_.clear();
  for (int j = 0; j < nv_; ++j)
    if (!is_locked[j]) unlocked_.push_back(j);
  lock_mode_ = nl == 0 ? 0 : (nl == 1 ? 1 : 2);
  end_valid_ = false;
  jac_valid_ = false;
  lock_lam_.assign(nl, 0.0);
}

// (a, lambda_L) at the end of the last dopri in a lock mode, if it ended at exactly y1 (no
// call or load since), else None: the FSAL stage's accelerations and lock torques [N*m]
// (M a = tau - h + S_L^T lambda). One lock: -a_free_j / (M^-1)_jj; the unlocked block's
// mode: (M a - (tau - h))_L.
nb::object ContactRhs::end_locks(F1 y1) {
  const size_t n = 2 * static_cast<size_t>(nv_);
  if (!end_valid_ || lock_mode_ < 0 || y1.shape(0) != n ||
      !std::equal(y_end_.begin(), y_end_.end(), y1.data()))
    return nb::none();
  return nb::make_tuple(vec(a_.data(), nv_), vec(lock_lam_.data(), lock_lam_.size()));
}

// The lock torques lambda_L [N*m] of the loaded lock mode at (q, v) under the joint torques
// tau [N*m] (M a = tau - h + S_L^T lambda, in set_locks's order), or None where its closed
// form does not hold (a singular pivot). A sample's question between steps: the step state
// (the accelerations, lock torques and state of the last stage, which end_locks and
// end_screen read) is kept as it was.
nb::object ContactRhs::lock_torques_at(F1 q, F1 v, F1 tau) {
  const size_t n = static_cast<size_t>(nv_);
  if (lock_mode_ < 0) throw std::invalid_argument("lock_torques_at: no lock mode (set_locks)");
  if (q.shape(0) != n || v.shape(0) != n || tau.shape(0) != n)
    throw std::invalid_argument("lock_torques_at: q, v and tau of nv entries expected");
  const Eigen::VectorXd q0 = q_, v0 = v_, x0 = x_, af0 = a_free_, a0 = a_;
  const std::vector<double> lam0 = lock_lam_;
  for (size_t i = 0; i < n; ++i) {
    q_[i] = q.data()[i];
    v_[i] = v.data()[i];
    x_[i] = tau.data()[i];
  }
  jac_valid_ = false;  // (the passes below overwrite data_)
  const bool ok = lock_accel();
  nb::object out = ok ? nb::cast(vec(lock_lam_.data(), lock_lam_.size())) : nb::none();
  q_ = q0;
  v_ = v0;
  x_ = x0;
  a_free_ = af0;
  a_ = a0;
  lock_lam_ = lam0;
  return out;
}

// The lock conditions of packbot.contact.locks.JointLocks.conditions_of, as rows
// (kind, index, s, bound): kind 0 a held joint (index: its lock torque's position; s its
// one-sided clamp's sign or 0; bound F_j [N*m]): g = F_j + torque_band - |lambda| or, with
// a clamp, at least -s lambda + torque_band; 1 an engaged clamp: g = -s lambda +
// torque_band; 2 a free clamped joint (index: the joint): g = -s a_j + accel_band; 3 a
// constant g = bound (a joint held and clamped both ways).
void ContactRhs::set_screen(F2 rows, double torque_band, double accel_band) {
  if (rows.ndim() != 2 || (rows.shape(0) && rows.shape(1) != 4))
    throw std::invalid_argument("rows: (m, 4) expected");
  screen_ = reals(rows);
  torque_band_ = torque_band;
  accel_band_ = accel_band;
}

// The smallest lock condition at the end of the last dopri in a lock mode, less margin
// times its scale (1 + max |a| + max |lambda|), if that step ended at exactly y1; NaN
// otherwise (no such step: the caller evaluates the conditions). Positive: every condition
// is clearly kept.
double ContactRhs::end_screen(F1 y1, double margin) {
  const size_t n = 2 * static_cast<size_t>(nv_);
  if (!end_valid_ || lock_mode_ < 0 || y1.shape(0) != n ||
      !std::equal(y_end_.begin(), y_end_.end(), y1.data()))
    return std::numeric_limits<double>::quiet_NaN();
  double amax = 0.0, lmax = 0.0;
  for (int i = 0; i < nv_; ++i) amax = std::max(amax, std::abs(a_[i]));
  for (double l : lock_lam_) lmax = std::max(lmax, std::abs(l));
  double g_min = std::numeric_limits<double>::infinity();
  const size_t m = screen_.size() / 4;
  for (size_t r = 0; r < m; ++r) {
    const double *row = &screen_[4 * r];
    const int kind = static_cast<int>(row[0]), i = static_cast<int>(row[1]);
    const double s = row[2];
    double g;
    if (kind == 0) {
      const double l = lock_lam_.at(i);
      g = row[3] + torque_band_ - std::abs(l);
      if (s != 0.0) g = std::max(g, -s * l + torque_band_);
    } else if (kind == 1) {
      g = -s * lock_lam_.at(i) + torque_band_;
    } else if (kind == 2) {
      if (i < 0 || i >= nv_) throw std::invalid_argument("screen: joint out of range");
      g = -s * a_[i] + accel_band_;
    } else {
      g = row[3];
    }
    g_min = std::min(g_min, g);
  }
  return g_min - margin * (1.0 + amax + lmax);
}

// The accelerations of the lock mode at (q_, v_) under x_ (tau) into a_, the lock torques
// into lock_lam_ (set_locks); false where the Python path would not take the closed form.
bool ContactRhs::lock_accel() {
  const int nv = nv_;
  if (lock_mode_ <= 1) {
    aba_world(q_, v_, x_);
    a_free_ = data_.ddq;
    if (lock_mode_ == 0) {
      a_ = a_free_;
      return true;
    }
    // a_free - minv[:, j] * (a_free[j] / minv[j, j]), minv mirrored from the upper triangle
    minverse(q_);
    const int j = static_cast<int>(locked_[0]);
    const double mjj = data_.Minv(j, j);
    const double r = a_free_[j] / mjj;
    for (int i = 0; i < nv; ++i) {
      const double mij = i <= j ? data_.Minv(i, j) : data_.Minv(j, i);
      a_[i] = a_free_[i] - mij * r;
    }
    lock_lam_[0] = -a_free_[j] / mjj;
    return std::isfinite(r);
  }
  crba_local(q_);
  nonlinear_effects();
  const int k = static_cast<int>(unlocked_.size());
  double G[9], r[3], x[3];
  for (int i = 0; i < nv; ++i) force_[i] = x_[i] - data_.nle[i];
  for (int a = 0; a < k; ++a) {
    const int ua = unlocked_[a];
    r[a] = force_[ua];
    for (int b = 0; b < k; ++b) {
      const int ub = unlocked_[b];
      G[a * k + b] = ua <= ub ? data_.M(ua, ub) : data_.M(ub, ua);
    }
  }
  if (!cramer_small(k, G, r, x)) return false;
  a_.setZero();
  for (int a = 0; a < k; ++a) a_[unlocked_[a]] = x[a];
  // lambda_L = (M a - f)_L over the unlocked joints' columns (a is zero on the locked ones)
  for (size_t l = 0; l < locked_.size(); ++l) {
    const int jl = static_cast<int>(locked_[l]);
    double s = 0.0;
    for (int a = 0; a < k; ++a) {
      const int ua = unlocked_[a];
      s += (jl <= ua ? data_.M(jl, ua) : data_.M(ua, jl)) * x[a];
    }
    lock_lam_[l] = s - force_[jl];
  }
  return true;
}
