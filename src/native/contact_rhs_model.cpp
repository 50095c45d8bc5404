// ContactRhs: its Pinocchio model (the constructor), the model's own quantities (M^-1, the
// unconstrained accelerations, the energies, the step bound), the loaded layout, conditions,
// keys, limits and torques, the plan's work arrays, and the numpy copies of the results.

#include "contact_rhs.hpp"
#include "modes.hpp"  // (sel_'s and stopper_'s types: the constructor may throw)
#include "stop_slow.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

using packbot_native::ints;
using packbot_native::reals;

ContactRhs::ContactRhs(const std::vector<std::string> &types, I1 parents, F3 placements, F2 axes,
                       F1 masses, F2 levers, F3 inertias, F1 armature, F1 gravity) {
  const size_t nj = types.size();
  if (parents.shape(0) != nj || placements.shape(0) != nj || axes.shape(0) != nj ||
      masses.shape(0) != nj || levers.shape(0) != nj || inertias.shape(0) != nj)
    throw std::invalid_argument("one entry per joint expected in every array");
  for (size_t j = 1; j < nj; ++j) {
    const double *H = placements.data() + 16 * j;
    pin::SE3 M;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) M.rotation()(r, c) = H[4 * r + c];
      M.translation()(r) = H[4 * r + 3];
    }
    const auto parent = static_cast<pin::JointIndex>(parents.data()[j]);
    const auto id = model_.addJoint(parent, make_joint(types[j], axes.data() + 3 * j), M,
                                    "joint" + std::to_string(j));
    const double *I = inertias.data() + 9 * j;
    Eigen::Matrix3d Im;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) Im(r, c) = I[3 * r + c];
    const double *l = levers.data() + 3 * j;
    model_.inertias[id] =
        pin::Inertia(masses.data()[j], Eigen::Vector3d(l[0], l[1], l[2]), pin::Symmetric3(Im));
  }
  nv_ = model_.nv;
  if (armature.shape(0) != static_cast<size_t>(nv_) || model_.nq != nv_)
    throw std::invalid_argument("armature: nv entries expected (1-dof joints only)");
  for (int i = 0; i < nv_; ++i) model_.armature[i] = armature.data()[i];
  model_.gravity.linear(Eigen::Vector3d(gravity.data()[0], gravity.data()[1], gravity.data()[2]));
  model_.gravity.angular().setZero();
  data_ = Data(model_);
  q_.setZero(nv_);
  v_.setZero(nv_);
  x_.setZero(nv_);
  a_free_.setZero(nv_);
  a_.setZero(nv_);
  force_.setZero(nv_);
  minv_.setZero(nv_, nv_);
}

// The step bound's constants (packbot.contact.pairs.PairLaw.step_bound): each joint's reach
// [m] (nv), the query margin [m] and the longest step [s].
void ContactRhs::set_reach(F1 reach, double margin, double max_step) {
  if (reach.shape(0) != static_cast<size_t>(nv_))
    throw std::invalid_argument("reach: nv entries expected");
  reach_ = reals(reach);
  margin_ = margin;
  max_step_ = max_step;
}

// The longest step [s] from y = (q, v, ...) (2 nv entries or more: a motor lag's torques
// follow) keeping every point's motion within half the margin:
// min(max_step, margin / 2 / max(reach . |v|, 1e-9)), the dot product summed in joint order.
double ContactRhs::step_bound(F1 y) const {
  if (y.shape(0) < static_cast<size_t>(2 * nv_) || reach_.size() != static_cast<size_t>(nv_))
    throw std::invalid_argument("y: at least 2 nv entries expected (after set_reach)");
  return step_bound_raw(y.data() + nv_);
}

double ContactRhs::step_bound_raw(const double *v) const {
  double speed = 0.0;
  for (int j = 0; j < nv_; ++j) speed += reach_[j] * std::abs(v[j]);
  return std::min(max_step_, 0.5 * margin_ / std::max(speed, 1e-9));
}

// The contact set's point layout (see packbot.contact.normal._Layout).
void ContactRhs::set_layout(I1 joints, F2 masks, I1 body, F2 local, I1 pair, I1 rows, I1 centre,
                            I1 normal_body, F3 frame2, I1 lim_joint, F1 lim_side, F1 lim_value) {
  joints_ = ints(joints);
  masks_ = reals(masks);
  body_ = ints(body);
  local_ = reals(local);
  pair_ = ints(pair);
  rows_ = ints(rows);
  centre_ = ints(centre);
  normal_body_ = ints(normal_body);
  frame2_ = reals(frame2);
  lim_joint_ = ints(lim_joint);
  lim_side_ = reals(lim_side);
  lim_value_ = reals(lim_value);
  clamp_joint_.clear();  // (set_clamps after it: a new layout has none)
  clamp_side_.clear();
  layout_changed();
}

// After the layout's arrays changed (set_layout, a re-patch's relayout): its sizes checked,
// the work arrays made again, no plan, no conditions, the contact rows' mode.
void ContactRhs::layout_changed() {
  lock_mode_ = -1;
  end_valid_ = false;
  conditions_set_ = false;
  jac_valid_ = false;
  nb_ = static_cast<int>(joints_.size());
  n2h_ = static_cast<int>(body_.size());
  h_ = n2h_ / 2;
  np_ = static_cast<int>(centre_.size());
  mp_ = static_cast<int>(rows_.size());
  ml_ = static_cast<int>(lim_joint_.size());
  mc_ = static_cast<int>(clamp_joint_.size());
  m_ = mp_ + ml_ + mc_;
  if (static_cast<int>(masks_.size()) != nb_ * nv_ || static_cast<int>(local_.size()) != 4 * n2h_ ||
      static_cast<int>(pair_.size()) != h_ || static_cast<int>(frame2_.size()) != 9 * np_ ||
      static_cast<int>(normal_body_.size()) != np_ || static_cast<int>(lim_side_.size()) != ml_ ||
      static_cast<int>(lim_value_.size()) != ml_ || static_cast<int>(clamp_side_.size()) != mc_)
    throw std::invalid_argument("inconsistent layout shapes");
  for (auto j : joints_)
    if (j < 0 || j >= static_cast<int64_t>(model_.njoints))
      throw std::invalid_argument("layout joint out of range");
  const int nv = nv_;
  H_.assign(nb_ * 16, 0.0);
  Vb_.assign(nb_ * 6, 0.0);
  Ab_.assign(nb_ * 6, 0.0);
  P_.assign(n2h_ * 3, 0.0);
  Jp_.assign(n2h_ * 3 * nv, 0.0);
  vp_.assign(n2h_ * 3, 0.0);
  ap_.assign(n2h_ * 3, 0.0);
  dJp_.assign(h_ * 3 * nv, 0.0);
  vrel_.assign(h_ * 3, 0.0);
  arel_.assign(h_ * 3, 0.0);
  dP_.assign(h_ * 3, 0.0);
  F_.assign(np_ * 9, 0.0);
  Jn_.assign(m_ * nv, 0.0);
  drift_.assign(m_, 0.0);
  gap_.assign(m_, 0.0);
  vn_.assign(m_, 0.0);
  JT_.assign(np_ * 2 * nv, 0.0);
  bT_.assign(np_ * 2, 0.0);
  vT_.assign(np_ * 2, 0.0);
  vt_.assign(np_ * 3, 0.0);
  slip_dir_.assign(np_ * 3, 0.0);
  set_plan_sizes(0, 0);
  pfirst_.assign(np_, 0);  // each pair's patch rows: [pfirst_, pfirst_ + pK_)
  pK_.assign(np_, 0);
  for (int r = mp_ - 1; r >= 0; --r) {
    const int p = static_cast<int>(pair_[rows_[r]]);
    pfirst_[p] = r;
    ++pK_[p];
  }
}

// A re-patch that keeps the layout's shape (the same pairs, patch sizes, normals' bodies and
// limits: packbot.contact.normal_rows._replace_patches): the new patches' points, frames,
// tangential offsets and slides allowed (set_layout's local and frame2, set_conditions'
// offset0 and slide_tol2); the rest as loaded. As after set_layout, the contact rows' mode
// (no locks) and no step end kept.
void ContactRhs::set_patches(F2 local, F3 frame2, F2 offset0, F1 slide_tol2) {
  if (local.size() != local_.size() || frame2.size() != frame2_.size() ||
      offset0.size() != offset0_.size() || slide_tol2.size() != slide_tol2_.size() ||
      !conditions_set_)
    throw std::invalid_argument("set_patches: the loaded layout's shapes expected");
  std::copy(local.data(), local.data() + local.size(), local_.begin());
  std::copy(frame2.data(), frame2.data() + frame2.size(), frame2_.begin());
  std::copy(offset0.data(), offset0.data() + offset0.size(), offset0_.begin());
  std::copy(slide_tol2.data(), slide_tol2.data() + slide_tol2.size(), slide_tol2_.begin());
  lock_mode_ = -1;
  end_valid_ = false;
  jac_valid_ = false;
}

// The mode conditions' constants: each patch row's tangential offset when built (rows, 2)
// [m], the square of the slide each pair's patch goes stale at (pairs) [m^2] (inf: never by
// its slide; end_check), the force and stick hysteresis bands, the point tolerance
// (packbot.contact.normal).
void ContactRhs::set_conditions(F2 offset0, F1 slide_tol2, double force_band, double point_tol,
                                double stick_band) {
  if (offset0.size() != static_cast<size_t>(2 * mp_))
    throw std::invalid_argument("offset0: (patch rows, 2) expected");
  if (slide_tol2.shape(0) != static_cast<size_t>(np_))
    throw std::invalid_argument("slide_tol2: one entry per pair expected");
  offset0_ = reals(offset0);
  slide_tol2_ = reals(slide_tol2);
  force_band_ = force_band;
  point_tol_ = point_tol;
  stick_band_ = stick_band;
  conditions_set_ = true;
}

// The contact set's pairs' indices in the collision world, in the layout's order (end_check).
void ContactRhs::set_keys(I1 keys) {
  if (keys.shape(0) != static_cast<size_t>(np_))
    throw std::invalid_argument("keys: one per pair of the layout expected");
  keys_ = ints(keys);
}

// The joint limits [rad] end_check compares the step end's positions with (nv each), or none
// (empty arrays: no limit check).
void ContactRhs::set_limits(F1 upper, F1 lower) {
  if (upper.shape(0) != lower.shape(0) ||
      (upper.shape(0) && upper.shape(0) != static_cast<size_t>(nv_)))
    throw std::invalid_argument("upper, lower: nv entries each (or none) expected");
  upper_ = reals(upper);
  lower_ = reals(lower);
}

// M(q)^-1 into out (nv x nv, row-major, symmetric): Pinocchio's computeMinverse with q, the
// strict lower triangle mirrored from the upper one (packbot.system.System.minv).
void ContactRhs::minverse_at(const double *q, double *out) {
  const int nv = nv_;
  end_valid_ = false;
  jac_valid_ = false;
  for (int i = 0; i < nv; ++i) q_[i] = q[i];
  minverse(q_);
  for (int i = 0; i < nv; ++i)
    for (int c = 0; c < nv; ++c) out[i * nv + c] = c >= i ? data_.Minv(i, c) : data_.Minv(c, i);
}

// The unconstrained accelerations at (q, v) under the loaded torques into out (nv):
// ABA(WORLD) on applied + (-viscous * v - coulomb_dir) (packbot.drive.Drive.free_accel).
void ContactRhs::free_accel_raw(const double *q, const double *v, double *out) {
  const int nv = nv_;
  end_valid_ = false;
  jac_valid_ = false;
  for (int i = 0; i < nv; ++i) {
    q_[i] = q[i];
    v_[i] = v[i];
    x_[i] = applied_[i] + (-viscous_[i] * v_[i] - coulomb_dir_[i]);
  }
  aba_world(q_, v_, x_);
  for (int i = 0; i < nv; ++i) out[i] = data_.ddq[i];
}

// The total energies [J] of k states (rows of Q and V, (k, nv)) into out (k,): kinetic
// 0.5 v^T M(q) v (CRBA, armature included; (v^T M) v as numpy's v @ M @ v) plus the
// potential energy of gravity (packbot.system.System.energy). The modes, the last step's end
// and its evaluation are left as they were.
void ContactRhs::energies(F2 Q, F2 V, Out1 out) {
  const size_t k = Q.shape(0);
  if (Q.shape(1) != static_cast<size_t>(nv_) || V.shape(0) != k ||
      V.shape(1) != static_cast<size_t>(nv_) || out.shape(0) != k)
    throw std::invalid_argument("Q, V (k, nv) and out (k,) expected");
  const int nv = nv_;
  Eigen::VectorXd q(nv);
  for (size_t r = 0; r < k; ++r) {
    const double *qr = Q.data() + r * nv, *vr = V.data() + r * nv;
    for (int i = 0; i < nv; ++i) q[i] = qr[i];
    crba_local(q);
    double kin = 0.0;
    for (int i = 0; i < nv; ++i) {
      double w = 0.0;
      for (int c = 0; c < nv; ++c) w += vr[c] * (c <= i ? data_.M(c, i) : data_.M(i, c));
      kin += w * vr[i];
    }
    out.data()[r] = 0.5 * kin + potential(q);
  }
}

// The joint torques of the steps to come: tau = applied + (-viscous * v - coulomb_dir), as
// packbot.drive.Drive.torques with a held command and no motor lag (constants in a step).
void ContactRhs::set_torque(F1 applied, F1 viscous, F1 coulomb_dir) {
  if (applied.shape(0) != static_cast<size_t>(nv_) ||
      viscous.shape(0) != static_cast<size_t>(nv_) ||
      coulomb_dir.shape(0) != static_cast<size_t>(nv_))
    throw std::invalid_argument("applied, viscous, coulomb_dir: nv entries expected");
  end_valid_ = false;
  jac_valid_ = false;
  applied_ = reals(applied);
  viscous_ = reals(viscous);
  coulomb_dir_ = reals(coulomb_dir);
}

nb::ndarray<nb::numpy, int64_t, nb::ndim<2>> ContactRhs::owned_mat_i(const std::vector<int64_t> &v,
    size_t rows, size_t cols) {
  auto *buf = new int64_t[rows * cols > 0 ? rows * cols : 1];
  std::copy(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(rows * cols), buf);
  nb::capsule owner(buf, [](void *p) noexcept { delete[] static_cast<int64_t *>(p); });
  return nb::ndarray<nb::numpy, int64_t, nb::ndim<2>>(buf, {rows, cols}, owner);
}

nb::ndarray<nb::numpy, double, nb::ndim<2>> ContactRhs::owned_mat(const std::vector<double> &v,
    size_t rows, size_t cols) {
  double *buf = new double[rows * cols > 0 ? rows * cols : 1];
  std::copy(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(rows * cols), buf);
  nb::capsule owner(buf, [](void *p) noexcept { delete[] static_cast<double *>(p); });
  return nb::ndarray<nb::numpy, double, nb::ndim<2>>(buf, {rows, cols}, owner);
}

// v^T M(q) v [kg m^2/s^2] (CRBA, armature included; the sums of energies).
double ContactRhs::kinetic(const Eigen::VectorXd &q, const double *v) {
  crba_local(q);
  const int nv = nv_;
  double kin = 0.0;
  for (int i = 0; i < nv; ++i) {
    double w = 0.0;
    for (int c = 0; c < nv; ++c) w += v[c] * (c <= i ? data_.M(c, i) : data_.M(i, c));
    kin += w * v[i];
  }
  return kin;
}

// numpy copies of n (r x c) doubles
nb::ndarray<nb::numpy, double, nb::ndim<1>> ContactRhs::vec(const double *p, size_t n) {
  auto *buf = new double[n];
  std::copy(p, p + n, buf);
  nb::capsule owner(buf, [](void *d) noexcept { delete[] static_cast<double *>(d); });
  return nb::ndarray<nb::numpy, double, nb::ndim<1>>(buf, {n}, owner);
}

nb::ndarray<nb::numpy, double, nb::ndim<2>> ContactRhs::mat(const double *p, size_t r, size_t c) {
  auto *buf = new double[r * c];
  std::copy(p, p + r * c, buf);
  nb::capsule owner(buf, [](void *d) noexcept { delete[] static_cast<double *>(d); });
  return nb::ndarray<nb::numpy, double, nb::ndim<2>>(buf, {r, c}, owner);
}

void ContactRhs::set_plan_sizes(int ne, int ns) {
  ne_ = ne;
  ns_ = ns;
  n_ = ne + 2 * ns;
  A_.assign(n_ * nv_, 0.0);
  C_.assign(n_ * nv_, 0.0);
  target_.assign(n_, 0.0);
  b_.assign(n_, 0.0);
  MC_.assign(nv_ * n_, 0.0);
  G_.assign(n_ * n_, 0.0);
  G0_.assign(n_ * n_, 0.0);
  rhs_.assign(n_, 0.0);
  rhs0_.assign(n_, 0.0);
  lam_.assign(n_, 0.0);
}
