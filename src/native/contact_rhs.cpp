// The contact-normal mode's right-hand side with its modes fixed, in one native call.
//
// Python module ``packbot._native`` (nanobind). One object, ``ContactRhs``, holds its own
// Pinocchio model (rebuilt from the Python model's numbers: joint types, parents, placements,
// inertias, armature, gravity; nothing crosses between this module's Pinocchio and the pin
// wheel's, so the two need not share an ABI), its Data, the contact set's point layout and the
// current modes' plan, and every work array (sized when the layout or the plan change: no
// allocation per call). ``accel`` then does what packbot's Python path does per call:
//
//   aba (unconstrained accelerations, armature included; or a_free given), computeMinverse,
//   computeJointJacobiansTimeVariation, then the contact rows and the constrained
//   accelerations of packbot/contact/kernels.py (contact_rows, constrained_accel), ported loop
//   for loop (same order of operations), so the two agree to rounding.
//
// Conventions as packbot.contact.normal.NormalContacts: world frame, SI units; a row's gap and
// normal velocity are body 2 minus body 1 along the normal carried by body 2.

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "conic.hpp"
#include "lcp.hpp"
#include "joints.hpp"
#include "modes.hpp"
#include "stop_slow.hpp"
#include "stretch.hpp"
#include "sweep_api.hpp"

#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/energy.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody/data.hpp>
#include <pinocchio/multibody/model.hpp>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace nb = nanobind;
namespace pin = pinocchio;

// The joints this module's model may hold: the 1-dof revolute and prismatic ones (joints.hpp,
// shared with sweep.cpp).
using packbot_native::make_joint;
using packbot_native::PackbotJointsTpl;
using Model = pin::ModelTpl<double, 0, PackbotJointsTpl>;
using Data = pin::DataTpl<double, 0, PackbotJointsTpl>;

using F1 = nb::ndarray<const double, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using F2 = nb::ndarray<const double, nb::ndim<2>, nb::c_contig, nb::device::cpu>;
using F3 = nb::ndarray<const double, nb::ndim<3>, nb::c_contig, nb::device::cpu>;
using I1 = nb::ndarray<const int64_t, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using Out1 = nb::ndarray<double, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using Out2 = nb::ndarray<double, nb::ndim<2>, nb::c_contig, nb::device::cpu>;
using U1Out = nb::ndarray<uint8_t, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using U1 = nb::ndarray<const uint8_t, nb::ndim<1>, nb::c_contig, nb::device::cpu>;

namespace {


// Gaussian elimination with partial pivoting (closed form for 1 x 1 and 2 x 2), as
// kernels._solve_small: G (m x m, row-major) is overwritten; false when singular.
bool solve_small(int m, double *G, double *y, double *x) {
  for (int i = 0; i < m; ++i) x[i] = 0.0;
  if (m == 1 && G[0] != 0.0) {
    x[0] = y[0] / G[0];
    return true;
  }
  if (m == 2) {
    const double a = G[0], b = G[1], c = G[2], d = G[3];
    const double det = a * d - b * c;
    if (std::abs(det) > 1e-12 * (std::abs(a * d) + std::abs(b * c))) {
      x[0] = (d * y[0] - b * y[1]) / det;
      x[1] = (a * y[1] - c * y[0]) / det;
      return true;
    }
  }
  for (int k = 0; k < m; ++k) {
    int piv = k;
    double best = std::abs(G[k * m + k]);
    for (int i = k + 1; i < m; ++i) {
      if (std::abs(G[i * m + k]) > best) {
        best = std::abs(G[i * m + k]);
        piv = i;
      }
    }
    if (best == 0.0 || !std::isfinite(best)) return false;
    if (piv != k) {
      for (int c = 0; c < m; ++c) std::swap(G[k * m + c], G[piv * m + c]);
      std::swap(y[k], y[piv]);
    }
    for (int i = k + 1; i < m; ++i) {
      const double f = G[i * m + k] / G[k * m + k];
      if (f != 0.0) {
        for (int c = k; c < m; ++c) G[i * m + c] -= f * G[k * m + c];
        y[i] -= f * y[k];
      }
    }
  }
  for (int k = m - 1; k >= 0; --k) {
    double s = y[k];
    for (int c = k + 1; c < m; ++c) s -= G[k * m + c] * x[c];
    x[k] = s / G[k * m + k];
  }
  return true;
}

// packbot.contact.lcp.solve_small's closed forms (m <= 3, Cramer's rule), in its order of
// operations: false when it would not take them (m > 3, or a determinant lost to rounding: the
// Python path then calls numpy's solver). G (m x m) is row-major; x gets the solution.
bool cramer_small(int m, const double *G, const double *r, double *x) {
  if (m == 0) return true;
  if (m == 1) {
    if (G[0] == 0.0) return false;
    x[0] = r[0] / G[0];
    return true;
  }
  if (m == 2) {
    const double a = G[0], b = G[1], c = G[2], d = G[3];
    const double det = a * d - b * c;
    if (!(std::abs(det) > 1e-12 * (std::abs(a * d) + std::abs(b * c)))) return false;
    x[0] = (d * r[0] - b * r[1]) / det;
    x[1] = (a * r[1] - c * r[0]) / det;
    return true;
  }
  if (m == 3) {
    const double a = G[0], b = G[1], c = G[2], d = G[3], e = G[4], f = G[5], g = G[6], h = G[7],
                 i = G[8];
    const double c0 = e * i - f * h, c1 = f * g - d * i, c2 = d * h - e * g;
    const double det = a * c0 + b * c1 + c * c2;
    const double scale = std::abs(a * c0) + std::abs(b * c1) + std::abs(c * c2);
    if (!(std::abs(det) > 1e-12 * scale)) return false;
    const double r0 = r[0], r1 = r[1], r2 = r[2];
    x[0] = (c0 * r0 + (c * h - b * i) * r1 + (b * f - c * e) * r2) / det;
    x[1] = (c1 * r0 + (a * i - c * g) * r1 + (c * d - a * f) * r2) / det;
    x[2] = (c2 * r0 + (b * g - a * h) * r1 + (a * e - b * d) * r2) / det;
    return true;
  }
  return false;
}

template <class A> std::vector<int64_t> ints(const A &a) {
  return std::vector<int64_t>(a.data(), a.data() + a.size());
}
template <class A> std::vector<double> reals(const A &a) {
  return std::vector<double>(a.data(), a.data() + a.size());
}

}  // namespace

class ContactRhs {
 public:
  ContactRhs(const std::vector<std::string> &types, I1 parents, F3 placements, F2 axes,
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

  int nv() const { return nv_; }

  // The step bound's constants (packbot.contact.pairs.PairLaw.step_bound): each joint's reach
  // [m] (nv), the query margin [m] and the longest step [s].
  void set_reach(F1 reach, double margin, double max_step) {
    if (reach.shape(0) != static_cast<size_t>(nv_))
      throw std::invalid_argument("reach: nv entries expected");
    reach_ = reals(reach);
    margin_ = margin;
    max_step_ = max_step;
  }

  // The longest step [s] from y = (q, v, ...) (2 nv entries or more: a motor lag's torques
  // follow) keeping every point's motion within half the margin:
  // min(max_step, margin / 2 / max(reach . |v|, 1e-9)), the dot product summed in joint order.
  double step_bound(F1 y) const {
    if (y.shape(0) < static_cast<size_t>(2 * nv_) || reach_.size() != static_cast<size_t>(nv_))
      throw std::invalid_argument("y: at least 2 nv entries expected (after set_reach)");
    return step_bound_raw(y.data() + nv_);
  }

  double step_bound_raw(const double *v) const {
    double speed = 0.0;
    for (int j = 0; j < nv_; ++j) speed += reach_[j] * std::abs(v[j]);
    return std::min(max_step_, 0.5 * margin_ / std::max(speed, 1e-9));
  }

  // The joint limits set_limits loaded [rad] (empty: none).
  const std::vector<double> &upper() const { return upper_; }
  const std::vector<double> &lower() const { return lower_; }

  // The contact set's point layout (see packbot.contact.normal._Layout).
  void set_layout(I1 joints, F2 masks, I1 body, F2 local, I1 pair, I1 rows, I1 centre,
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
    layout_changed();
  }

  // After the layout's arrays changed (set_layout, a re-patch's relayout): its sizes checked,
  // the work arrays made again, no plan, no conditions, the contact rows' mode.
  void layout_changed() {
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
    m_ = mp_ + ml_;
    if (static_cast<int>(masks_.size()) != nb_ * nv_ || static_cast<int>(local_.size()) != 4 * n2h_ ||
        static_cast<int>(pair_.size()) != h_ || static_cast<int>(frame2_.size()) != 9 * np_ ||
        static_cast<int>(normal_body_.size()) != np_ || static_cast<int>(lim_side_.size()) != ml_ ||
        static_cast<int>(lim_value_.size()) != ml_)
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
  void set_patches(F2 local, F3 frame2, F2 offset0, F1 slide_tol2) {
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

  // The current modes (see packbot.contact.normal._Plan) and the law's constants.
  void set_plan(I1 engaged, I1 row_slip, I1 sticks, double mu, double stick_speed,
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
  void set_slip_dirs(F2 slip_dir) {
    if (slip_dir.size() != slip_dir_.size())
      throw std::invalid_argument("slip_dir: (pairs, 3) expected");
    std::copy(slip_dir.data(), slip_dir.data() + slip_dir.size(), slip_dir_.begin());
    end_valid_ = false;
    jac_valid_ = false;
  }

  // The mode conditions' constants: each patch row's tangential offset when built (rows, 2)
  // [m], the square of the slide each pair's patch goes stale at (pairs) [m^2] (inf: never by
  // its slide; end_check), the force and stick hysteresis bands, the point tolerance
  // (packbot.contact.normal).
  void set_conditions(F2 offset0, F1 slide_tol2, double force_band, double point_tol,
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

  // The step end's evaluation: when the last call was a dopri whose FSAL stage was at exactly
  // y1 (no call or load since), (cond, a, lam, gap, vn, vt, slide2) there, as
  // kernels.constrained_accel returns them (cond: the smallest mode condition, slide2: each
  // pair's largest squared slide); else None.
  nb::object end_eval(F1 y1) {
    if (!at_end(y1)) return nb::none();
    const double cond = end_conditions();
    return nb::make_tuple(cond, vec(a_.data(), nv_), vec(lam_.data(), n_), vec(gap_.data(), m_),
                          vec(vn_.data(), m_), mat(vt_.data(), np_, 3),
                          vec(slide2_.data(), np_));
  }

  // The evaluation at y with the modes and torques loaded (an event's root finding inside a
  // native step): the right-hand side's stage at y, then end_eval's tuple there (y becomes the
  // state end_eval and end_check answer for). None when the Delassus matrix is singular.
  nb::object eval_at(F1 y) {
    const size_t n = 2 * static_cast<size_t>(nv_);
    if (y.shape(0) != n) throw std::invalid_argument("y: 2 nv entries expected");
    if (applied_.size() != static_cast<size_t>(nv_))
      throw std::invalid_argument("set_torque was not called");
    end_valid_ = false;
    std::vector<double> f(n);
    if (!stage(y.data(), f.data())) return nb::none();
    y_end_.assign(y.data(), y.data() + n);
    end_valid_ = true;
    return end_eval(y);
  }

  // One mode condition of a contact row at y with the modes and torques loaded (an event's root
  // finding inside a native step), as eval_at then NormalContacts.condition(ev, ("nrow", r))
  // compute it: an engaged row's force plus the force band, a free row's gap plus the point
  // tolerance; y becomes the state end_eval and end_check answer for, as with eval_at. NaN when
  // the Delassus matrix is singular or the conditions' constants are not loaded (the caller
  // evaluates in Python).
  double row_condition_at(F1 y, int64_t r) {
    const size_t n = 2 * static_cast<size_t>(nv_);
    if (y.shape(0) != n) throw std::invalid_argument("y: 2 nv entries expected");
    if (applied_.size() != static_cast<size_t>(nv_))
      throw std::invalid_argument("set_torque was not called");
    if (r < 0 || r >= m_) throw std::invalid_argument("r: a contact row expected");
    end_valid_ = false;
    std::vector<double> f(n);
    if (!conditions_set_ || !stage(y.data(), f.data()))
      return std::numeric_limits<double>::quiet_NaN();
    y_end_.assign(y.data(), y.data() + n);
    end_valid_ = true;
    for (int e = 0; e < ne_; ++e)
      if (engaged_[e] == r) return lam_[e] + force_band_;
    return gap_[r] + point_tol_;
  }

  // A contact row's event inside the last native step, located natively: the time tb of
  // packbot.ode.locate_root (SciPy's brentq, ported there, then the final bracket's event side)
  // on g(t) = row_condition_at(y(t), r), y(t) the step's dense output (stages Z (8, 2 nv),
  // [t0, t1] of size h, end y1; hermite: a Rosenbrock step's cubic), from g0 = g(t0) > 0 >=
  // g1 = g(t1), to a final bracket of xtol [s]. NaN where a condition cannot be evaluated (the
  // caller locates it in Python).
  double row_root(F2 Z, double t0, double t1, double h, F1 y1, bool hermite, int64_t r,
                  double g0, double g1, double xtol) {
    const int n = 2 * nv_;
    if (Z.shape(0) != 8 || Z.shape(1) != static_cast<size_t>(n) ||
        y1.shape(0) != static_cast<size_t>(n))
      throw std::invalid_argument("row_root: Z (8, 2 nv) and y1 (2 nv) expected");
    if (applied_.size() != static_cast<size_t>(nv_) || !conditions_set_)
      throw std::invalid_argument("row_root: torques and conditions first");
    if (r < 0 || r >= m_) throw std::invalid_argument("r: a contact row expected");
    if (!(t1 > t0) || !(g0 > 0.0 && g1 <= 0.0) || !(xtol > 0.0))
      throw std::invalid_argument("row_root: g0 > 0 >= g1 on t0 < t1, xtol > 0 expected");
    const double nan = std::numeric_limits<double>::quiet_NaN();
    std::vector<double> y(n), f(n);
    std::vector<double> ts{t0, t1}, gs{g0, g1};
    bool failed = false;
    auto g_rec = [&](double t) -> double {
      double v;
      if (t == t0) return g0;
      if (t == t1) {
        v = g1;
      } else {
        packbot_native::DenseOutput::at(t, t0, t1, h, Z.data(), y1.data(), n, hermite, y.data());
        end_valid_ = false;
        if (!stage(y.data(), f.data())) {
          failed = true;
          return -1e-300;
        }
        v = gap_[r] + point_tol_;
        for (int e = 0; e < ne_; ++e)
          if (engaged_[e] == r) v = lam_[e] + force_band_;
        if (!std::isfinite(v)) {  // (Python's root finding evaluates it there instead)
          failed = true;
          return -1e-300;
        }
        ts.push_back(t);
        gs.push_back(v);
      }
      return v != 0.0 ? v : -1e-300;
    };
    // brentq (packbot.ode.brentq, SciPy's Zeros/brentq.c)
    const double rtol = 4.0 * 2.220446049250313e-16;
    double xpre = t0, xcur = t1, xblk = 0.0, fblk = 0.0, spre = 0.0, scur = 0.0;
    double fpre = g_rec(xpre), fcur = g_rec(xcur);
    double root = nan;
    if (fpre == 0.0) {
      root = xpre;
    } else if (fcur == 0.0) {
      root = xcur;
    } else {
      for (int it = 0; it < 100 && !failed; ++it) {
        if (fpre != 0.0 && fcur != 0.0 && std::copysign(1.0, fpre) != std::copysign(1.0, fcur)) {
          xblk = xpre;
          fblk = fpre;
          spre = scur = xcur - xpre;
        }
        if (std::abs(fblk) < std::abs(fcur)) {
          xpre = xcur;
          xcur = xblk;
          xblk = xpre;
          fpre = fcur;
          fcur = fblk;
          fblk = fpre;
        }
        const double delta = (xtol + rtol * std::abs(xcur)) / 2.0;
        const double sbis = (xblk - xcur) / 2.0;
        if (fcur == 0.0 || std::abs(sbis) < delta) {
          root = xcur;
          break;
        }
        if (std::abs(spre) > delta && std::abs(fcur) < std::abs(fpre)) {
          double stry;
          if (xpre == xblk) {
            stry = -fcur * (xcur - xpre) / (fcur - fpre);
          } else {
            const double dpre = (fpre - fcur) / (xpre - xcur);
            const double dblk = (fblk - fcur) / (xblk - xcur);
            stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre));
          }
          if (2.0 * std::abs(stry) < std::min(std::abs(spre), 3.0 * std::abs(sbis) - delta)) {
            spre = scur;
            scur = stry;
          } else {
            spre = scur = sbis;
          }
        } else {
          spre = scur = sbis;
        }
        xpre = xcur;
        fpre = fcur;
        if (std::abs(scur) > delta)
          xcur += scur;
        else
          xcur += sbis > 0.0 ? delta : -delta;
        fcur = g_rec(xcur);
      }
    }
    end_valid_ = false;
    if (failed || std::isnan(root)) return nan;
    // the final bracket [ta, tb]: the neighbouring evaluated points with a falling sign change
    // nearest the root (locate_root)
    std::vector<size_t> order(ts.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return ts[a] < ts[b]; });
    double best = std::numeric_limits<double>::infinity(), tb = t1;
    for (size_t k = 0; k + 1 < order.size(); ++k) {
      const size_t i = order[k], j = order[k + 1];
      if (gs[i] > 0.0 && 0.0 >= gs[j]) {
        const double dist = std::max(std::max(ts[i] - root, root - ts[j]), 0.0);
        if (dist < best) {
          best = dist;
          tb = ts[j];
        }
      }
    }
    return tb;
  }

  // The contact set's pairs' indices in the collision world, in the layout's order (end_check).
  void set_keys(I1 keys) {
    if (keys.shape(0) != static_cast<size_t>(np_))
      throw std::invalid_argument("keys: one per pair of the layout expected");
    keys_ = ints(keys);
  }

  // The joint limits [rad] end_check compares the step end's positions with (nv each), or none
  // (empty arrays: no limit check).
  void set_limits(F1 upper, F1 lower) {
    if (upper.shape(0) != lower.shape(0) ||
        (upper.shape(0) && upper.shape(0) != static_cast<size_t>(nv_)))
      throw std::invalid_argument("upper, lower: nv entries each (or none) expected");
    upper_ = reals(upper);
    lower_ = reals(lower);
  }

  // The step end's screen of the contact-normal mode (packbot.contact.normal_law.NormalLaw
  // .watch and after_step) at the end of the last dopri, if it ended at exactly y1 (as
  // end_eval): -1 no such step (the caller checks everything); else a bit set, 0 when nothing
  // is to do. 1: a swept pair (its index in `swept`, signed distance `dist` [m]) has an event
  // (PatchEvents._patch_pair_crossings: outside `active`, d <= 0; in it, d > near or
  // d < -pen_tol). 2: the smallest mode condition (end_eval's cond) is negative. 4: a pair with
  // engaged rows slides faster than the stick speed (NormalContacts.sliding) and one such pair's
  // patch is stale (stale_pairs: its distance missing from the sweep, its gaps' minimum off it
  // by more than the point tolerance, or a slide2 above its set_conditions' slide_tol2), or a
  // slide speed is within a relative 1e-9 of the stick speed (numpy's dot may round otherwise:
  // the caller decides).
  // 8: a joint is at or beyond one of its limits (set_limits; JointStops._limit_crossings).
  int end_check(F1 y1, I1 swept, F1 dist, I1 active, double near, double pen_tol) {
    const size_t ns = swept.shape(0);
    if (dist.shape(0) != ns) throw std::invalid_argument("swept, dist: one length expected");
    if (!at_end(y1)) return -1;
    return end_check_raw(y1.data(), swept.data(), dist.data(), ns, active.data(),
                         active.shape(0), near, pen_tol);
  }

  // end_check at the end of the last dopri (the caller knows it ended at y1), on raw arrays:
  // ns swept pairs, na active ones.
  int end_check_raw(const double *y1, const int64_t *sp, const double *dp, size_t ns,
                    const int64_t *ac, size_t na, double near, double pen_tol) {
    if (keys_.size() != static_cast<size_t>(np_)) return -1;
    int out = 0;
    for (size_t k = 0; k < ns; ++k) {
      const double d = dp[k];
      const bool in = std::find(ac, ac + na, sp[k]) != ac + na;
      if (in ? (d > near || d < -pen_tol) : d <= 0.0) {
        out |= 1;
        break;
      }
    }
    if (!(end_conditions() >= 0.0)) out |= 2;
    const double *q1 = y1;
    for (size_t j = 0; j < upper_.size(); ++j)
      if (q1[j] >= upper_[j] || q1[j] <= lower_[j]) {
        out |= 8;
        break;
      }
    // the pairs with engaged rows, their slide speeds and their gaps' minimum
    engaged_pair_.assign(np_, 0);
    gap_min_.assign(np_, std::numeric_limits<double>::infinity());
    for (int r = 0; r < mp_; ++r) {
      const int p = static_cast<int>(pair_[rows_[r]]);
      if (pos_[r] >= 0) engaged_pair_[p] = 1;
      if (!(gap_[r] >= gap_min_[p])) gap_min_[p] = gap_[r];  // (a NaN is kept, as numpy's min)
    }
    bool sliding = false, unsure = false;
    for (int p = 0; p < np_; ++p) {
      // with friction the slipping pairs (the plan's), without it every pair with engaged rows
      if (!(mu_ > 0.0 ? slipping_[p] != 0 : engaged_pair_[p] != 0)) continue;
      const double *vt = &vt_[3 * p];
      const double s = std::sqrt(vt[0] * vt[0] + vt[1] * vt[1] + vt[2] * vt[2]);
      if (std::abs(s - stick_speed_) <= 1e-9 * stick_speed_ || std::isnan(s)) unsure = true;
      if (s > stick_speed_) sliding = true;
    }
    stale_sure_ = false;
    if (unsure) return out | 4;
    if (!sliding) return out;
    for (int p = 0; p < np_; ++p) {
      if (!engaged_pair_[p]) continue;
      const int64_t key = keys_[p];
      size_t k = 0;
      while (k < ns && sp[k] != key) ++k;
      if (k == ns || std::isnan(gap_min_[p]) || std::abs(gap_min_[p] - dp[k]) > point_tol_ ||
          slide2_[p] > slide_tol2_[p]) {
        stale_sure_ = true;
        return out | 4;
      }
    }
    return out;
  }

  // Whether the last end_check_raw's bit 4 was a stale patch of a sliding pair for certain
  // (not a slide speed at the stick speed, which the caller decides).
  bool stale_sure() const { return stale_sure_; }

  // ------------------------------------------------------------------ the stretch's re-patch
  // (packbot.contact.normal_contacts.NormalContacts.repatch's native steps: stretch.hpp)
  int n_pairs() const { return np_; }
  int n_points() const { return h_; }  // the layout's points: each pair's K and its centre
  int n_pair_rows() const { return mp_; }
  const std::vector<int64_t> &keys() const { return keys_; }
  const std::vector<int> &pair_rows() const { return pK_; }  // each pair's K
  bool contact_rows() const { return conditions_set_ && lock_mode_ < 0; }
  const std::vector<int64_t> &engaged() const { return engaged_; }

  // set_patches on raw arrays of the loaded layout's shapes: local (2 h, 4), frame2 (pairs,
  // 9), offset0 (pair rows, 2), slide_tol2 (pairs).
  void set_patches_raw(const double *local, const double *frame2, const double *offset0,
                       const double *slide_tol2) {
    std::copy(local, local + local_.size(), local_.begin());
    std::copy(frame2, frame2 + frame2_.size(), frame2_.begin());
    std::copy(offset0, offset0 + offset0_.size(), offset0_.begin());
    std::copy(slide_tol2, slide_tol2 + slide_tol2_.size(), slide_tol2_.begin());
    lock_mode_ = -1;
    end_valid_ = false;
    jac_valid_ = false;
  }

  // A re-patch whose patches change size (the same pairs, normals on the same bodies and
  // limits: normal_rows.ContactRows._layout's full build): each pair's K (pairs), the new
  // points and centres local (2 h, 4), frame2 (pairs, 9), offset0 (pair rows, 2) and
  // slide_tol2 (pairs); the body, pair, row and centre indices made from the Ks. As after
  // set_layout and set_conditions: no plan, the contact rows' mode.
  void relayout_raw(const std::vector<int> &K, const double *local, const double *frame2,
                    const double *offset0, const double *slide_tol2) {
    const int np = np_, h = h_;
    std::vector<int64_t> b1(np), b2(np);
    for (int p = 0; p < np; ++p) {
      const int64_t first = centre_[p] - pK_[p];  // (the pair's first point)
      b1[p] = body_[first];
      b2[p] = body_[h + first];
    }
    std::vector<int64_t> body2;
    body_.clear();
    pair_.clear();
    rows_.clear();
    centre_.clear();
    int64_t k = 0;
    for (int p = 0; p < np; ++p) {
      for (int j = 0; j <= K[p]; ++j) {
        body_.push_back(b1[p]);
        body2.push_back(b2[p]);
        pair_.push_back(p);
      }
      for (int j = 0; j < K[p]; ++j) rows_.push_back(k + j);
      centre_.push_back(k + K[p]);
      k += K[p] + 1;
    }
    body_.insert(body_.end(), body2.begin(), body2.end());
    local_.assign(local, local + 8 * k);
    frame2_.assign(frame2, frame2 + 9 * np);
    layout_changed();
    offset0_.assign(offset0, offset0 + 2 * mp_);
    slide_tol2_.assign(slide_tol2, slide_tol2 + np_);
    conditions_set_ = true;
    relaid_ = true;
  }

  // The loaded patches and plan, kept (keep_loaded) and put back (restore_loaded): a
  // re-patch that hands back leaves the extension as the caller loaded it.
  void keep_loaded() {
    relaid_ = false;
    kept_body_ = body_;
    kept_pair_ = pair_;
    kept_rows_ = rows_;
    kept_centre_ = centre_;
    kept_local_ = local_;
    kept_frame2_ = frame2_;
    kept_offset0_ = offset0_;
    kept_slide_tol2_ = slide_tol2_;
    kept_engaged_ = engaged_;
    kept_row_slip_ = row_slip_;
    kept_sticks_ = sticks_;
    kept_slip_dir_ = slip_dir_;
    kept_plan_ = {mu_, stick_speed_, baumgarte_};
  }

  void restore_loaded() {
    if (relaid_) {
      relaid_ = false;
      body_ = kept_body_;  // (a relayout: the layout's shapes back too)
      pair_ = kept_pair_;
      rows_ = kept_rows_;
      centre_ = kept_centre_;
      local_ = kept_local_;
      frame2_ = kept_frame2_;
      layout_changed();
      offset0_ = kept_offset0_;
      slide_tol2_ = kept_slide_tol2_;
      conditions_set_ = true;
    } else {
      set_patches_raw(kept_local_.data(), kept_frame2_.data(), kept_offset0_.data(),
                      kept_slide_tol2_.data());
    }
    engaged_ = kept_engaged_;
    row_slip_ = kept_row_slip_;
    sticks_ = kept_sticks_;
    slip_dir_ = kept_slip_dir_;
    mu_ = kept_plan_[0];
    stick_speed_ = kept_plan_[1];
    baumgarte_ = kept_plan_[2];
    set_plan_sizes(static_cast<int>(engaged_.size()), static_cast<int>(sticks_.size()));
  }

  // M(q)^-1 into out (nv x nv, row-major, symmetric): Pinocchio's computeMinverse with q, the
  // strict lower triangle mirrored from the upper one (packbot.system.System.minv).
  void minverse_at(const double *q, double *out) {
    const int nv = nv_;
    end_valid_ = false;
    jac_valid_ = false;
    for (int i = 0; i < nv; ++i) q_[i] = q[i];
    pin::computeMinverse(model_, data_, q_);
    for (int i = 0; i < nv; ++i)
      for (int c = 0; c < nv; ++c) out[i * nv + c] = c >= i ? data_.Minv(i, c) : data_.Minv(c, i);
  }

  // The unconstrained accelerations at (q, v) under the loaded torques into out (nv):
  // ABA(WORLD) on applied + (-viscous * v - coulomb_dir) (packbot.drive.Drive.free_accel).
  void free_accel_raw(const double *q, const double *v, double *out) {
    const int nv = nv_;
    end_valid_ = false;
    jac_valid_ = false;
    for (int i = 0; i < nv; ++i) {
      q_[i] = q[i];
      v_[i] = v[i];
      x_[i] = applied_[i] + (-viscous_[i] * v_[i] - coulomb_dir_[i]);
    }
    pin::aba(model_, data_, q_, v_, x_, pin::Convention::WORLD);
    for (int i = 0; i < nv; ++i) out[i] = data_.ddq[i];
  }

  // The plan of these modes (packbot.contact.normal_rows.ContactRows._plan, as
  // NativeRhs.load sets it): the engaged rows, each row's slipping pair, the sticking pairs
  // with engaged rows; every pair's slip direction. mu, the stick speed and Baumgarte's
  // constant as loaded.
  void load_plan(const std::vector<int> &eng, const uint8_t *stick, const double *slip_dir) {
    end_valid_ = false;
    jac_valid_ = false;
    plan_rows(eng, stick);
    std::copy(slip_dir, slip_dir + 3 * np_, slip_dir_.begin());
    set_plan_sizes(static_cast<int>(engaged_.size()), static_cast<int>(sticks_.size()));
  }

  // The plan's rows of these modes with mu_ loaded: the engaged rows, each one's slipping pair
  // (-1: none), the sticking pairs with engaged rows (ContactRows._plan; stick: a flag per pair).
  template <class Flag>
  void plan_rows(const std::vector<int> &eng, const Flag *stick) {
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

  // The report's law's modes instead of the contact rows (packbot.contact.stops.JointStops
  // .torque_accel): the joints locked (a_j = 0; engaged clamps and held joints, sorted).
  // None: ABA; one: ABA with M^-1's rank-one correction (JointLocks.accelerations); two or
  // more with at most 3 unlocked: the unlocked block M_UU a_U = (tau - h)_U from CRBA and the
  // bias forces (JointLocks.reduced_accelerations). Anything else is refused. set_layout
  // goes back to the contact rows.
  void set_locks(I1 locked) {
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
  nb::object end_locks(F1 y1) {
    const size_t n = 2 * static_cast<size_t>(nv_);
    if (!end_valid_ || lock_mode_ < 0 || y1.shape(0) != n ||
        !std::equal(y_end_.begin(), y_end_.end(), y1.data()))
      return nb::none();
    return nb::make_tuple(vec(a_.data(), nv_), vec(lock_lam_.data(), lock_lam_.size()));
  }

  // The total energies [J] of k states (rows of Q and V, (k, nv)) into out (k,): kinetic
  // 0.5 v^T M(q) v (CRBA, armature included; (v^T M) v as numpy's v @ M @ v) plus the
  // potential energy of gravity (packbot.system.System.energy). The modes, the last step's end
  // and its evaluation are left as they were.
  void energies(F2 Q, F2 V, Out1 out) {
    const size_t k = Q.shape(0);
    if (Q.shape(1) != static_cast<size_t>(nv_) || V.shape(0) != k ||
        V.shape(1) != static_cast<size_t>(nv_) || out.shape(0) != k)
      throw std::invalid_argument("Q, V (k, nv) and out (k,) expected");
    const int nv = nv_;
    Eigen::VectorXd q(nv);
    for (size_t r = 0; r < k; ++r) {
      const double *qr = Q.data() + r * nv, *vr = V.data() + r * nv;
      for (int i = 0; i < nv; ++i) q[i] = qr[i];
      pin::crba(model_, data_, q, pin::Convention::LOCAL);
      double kin = 0.0;
      for (int i = 0; i < nv; ++i) {
        double w = 0.0;
        for (int c = 0; c < nv; ++c) w += vr[c] * (c <= i ? data_.M(c, i) : data_.M(i, c));
        kin += w * vr[i];
      }
      out.data()[r] = 0.5 * kin + pin::computePotentialEnergy(model_, data_, q);
    }
  }

  // The lock conditions of packbot.contact.locks.JointLocks.conditions_of, as rows
  // (kind, index, s, bound): kind 0 a held joint (index: its lock torque's position; s its
  // one-sided clamp's sign or 0; bound F_j [N*m]): g = F_j + torque_band - |lambda| or, with
  // a clamp, at least -s lambda + torque_band; 1 an engaged clamp: g = -s lambda +
  // torque_band; 2 a free clamped joint (index: the joint): g = -s a_j + accel_band; 3 a
  // constant g = bound (a joint held and clamped both ways).
  void set_screen(F2 rows, double torque_band, double accel_band) {
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
  double end_screen(F1 y1, double margin) {
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

  // Accelerations of the current modes at (q, v) into out; x is tau (from_tau) or a_free.
  // False when the Delassus matrix is singular (out then holds a_free: the caller solves).
  bool accel(F1 q, F1 v, F1 x, bool from_tau, Out1 out) {
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
      pin::aba(model_, data_, q_, v_, x_, pin::Convention::WORLD);
      a_free_ = data_.ddq;
    } else {
      a_free_ = x_;
    }
    const bool ok = compute(from_tau);
    double *o = out.data();
    for (int i = 0; i < nv_; ++i) o[i] = a_[i];
    return ok;
  }

  // The joint torques of the steps to come: tau = applied + (-viscous * v - coulomb_dir), as
  // packbot.drive.Drive.torques with a held command and no motor lag (constants in a step).
  void set_torque(F1 applied, F1 viscous, F1 coulomb_dir) {
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

  // The first stage of a step: Z[1] = f(Z[0]) = (v, a) under the loaded modes and torques, the
  // same arithmetic as accel(q, v, applied + (-viscous * v - coulomb_dir), true) (a restarted
  // stepper's derivative, computed with its first native attempt); false when the Delassus
  // matrix is singular (the caller then calls its right-hand side).
  bool first(Out2 Z) {
    const int n = 2 * nv_;
    if (Z.shape(0) != 8 || Z.shape(1) != static_cast<size_t>(n))
      throw std::invalid_argument("Z (8, 2 nv) expected");
    if (lock_mode_ >= 0) throw std::invalid_argument("first: the contact rows' call (set_locks)");
    if (applied_.size() != static_cast<size_t>(nv_))
      throw std::invalid_argument("set_torque was not called");
    return first_raw(Z.data());
  }

  // first on a raw z (8, 2 nv) (checked by the caller).
  bool first_raw(double *z) {
    end_valid_ = false;
    return stage(z, z + 2 * nv_);
  }

  // The arguments of an attempt (dopri, rosenbrock): Z (8, 2 nv), the others (2 nv,), and the
  // torques set.
  void check_attempt(const Out2 &Z, const F1 &ay0, const F1 &atol, const Out1 &y1,
                     const Out1 &ay1) const {
    const size_t n = 2 * static_cast<size_t>(nv_);
    if (Z.shape(0) != 8 || Z.shape(1) != n || ay0.shape(0) != n || atol.shape(0) != n ||
        y1.shape(0) != n || ay1.shape(0) != n)
      throw std::invalid_argument("Z (8, 2 nv); ay0, atol, y1, ay1 (2 nv,) expected");
    if (applied_.size() != static_cast<size_t>(nv_))
      throw std::invalid_argument("set_torque was not called");
  }

  // One Dormand-Prince 5(4) attempt of size h (packbot.ode.RK45Stepper.step's stages and error
  // norm) on y = (q, v) with the modes and torques loaded: Z (8, 2 nv) holds [y0, k0] on entry
  // and [y0, k0, ..., k6] on return (k6 = f(y1), the FSAL stage), y1 the 5th-order solution,
  // ay1 = |y1|. Returns the scaled RMS error norm, or -1 when a stage's Delassus matrix is
  // singular (the caller takes the Python stages).
  double dopri(double h, Out2 Z, F1 ay0, F1 atol, double rtol, Out1 y1, Out1 ay1) {
    check_attempt(Z, ay0, atol, y1, ay1);
    return dopri_raw(h, Z.data(), ay0.data(), atol.data(), rtol, y1.data(), ay1.data());
  }

  // dopri on raw arrays (sizes checked by the caller): z (8, 2 nv), the others (2 nv,).
  double dopri_raw(double h, double *z, const double *a0, const double *at, double rtol,
                   double *yn, double *a1) {
    const int n = 2 * nv_;
    static constexpr double A[7][7] = {
        {0, 0, 0, 0, 0, 0, 0},
        {1.0 / 5, 0, 0, 0, 0, 0, 0},
        {3.0 / 40, 9.0 / 40, 0, 0, 0, 0, 0},
        {44.0 / 45, -56.0 / 15, 32.0 / 9, 0, 0, 0, 0},
        {19372.0 / 6561, -25360.0 / 2187, 64448.0 / 6561, -212.0 / 729, 0, 0, 0},
        {9017.0 / 3168, -355.0 / 33, 46732.0 / 5247, 49.0 / 176, -5103.0 / 18656, 0, 0},
        {35.0 / 384, 0, 500.0 / 1113, 125.0 / 192, -2187.0 / 6784, 11.0 / 84, 0}};
    static constexpr double E[7] = {-71.0 / 57600,    0, 71.0 / 16695, -71.0 / 1920,
                                    17253.0 / 339200, -22.0 / 525, 1.0 / 40};
    end_valid_ = false;
    ys_.resize(n);
    double ah[7];
    for (int s = 1; s < 7; ++s) {
      for (int j = 0; j < s; ++j) ah[j] = A[s][j] * h;
      // the stage's argument y0 + sum_j (h a_sj) k_j (the order of RK45Stepper's np.dot)
      double *arg = s < 6 ? ys_.data() : yn;
      for (int c = 0; c < n; ++c) {
        double acc = z[c];
        for (int j = 0; j < s; ++j) acc += ah[j] * z[(1 + j) * n + c];
        arg[c] = acc;
      }
      if (!stage(arg, z + (1 + s) * n)) return -1.0;
    }
    // the scaled RMS norm of h * sum_j e_j k_j
    double ss = 0.0;
    for (int c = 0; c < n; ++c) {
      double ev = 0.0;
      for (int j = 0; j < 7; ++j) ev += E[j] * z[(1 + j) * n + c];
      a1[c] = std::abs(yn[c]);
      const double sc = std::max(a0[c], a1[c]) * rtol + at[c];
      ev /= sc;
      ss += ev * ev;
    }
    // Hairer's stiffness test (DOPRI5): h |lambda| ~ h ||k6 - k5|| / ||y1 - y_5||, the two
    // stages at t + h (y_5: the 6th stage's argument, still in ys_)
    double num = 0.0, den = 0.0;
    for (int c = 0; c < n; ++c) {
      const double dk = z[7 * n + c] - z[6 * n + c], dy = yn[c] - ys_[c];
      num += dk * dk;
      den += dy * dy;
    }
    hlamb_ = den > 0.0 ? h * std::sqrt(num / den) : 0.0;
    y_end_.assign(yn, yn + n);  // the FSAL stage's state: end_eval's
    end_valid_ = true;
    return h * std::sqrt(ss * (1.0 / n));
  }

  // The last dopri's stiffness estimate h |lambda| (Hairer's DOPRI5 test; Dormand-Prince's
  // stability bound on the negative real axis is about 3.3).
  double stiffness() const { return hlamb_; }

  // One RODAS4 attempt of size h (Hairer and Wanner, Solving ODEs II, sec. IV.7; rodas.f, the
  // coefficients of METH = 1): a stiffly accurate, L-stable Rosenbrock method of order 4 with
  // an embedded order-3 solution, on y = (q, v) under the loaded modes and torques (autonomous:
  // the torques are constants of the step). Z (8, 2 nv) holds [y0, f(y0)] on entry; on return
  // Z[2] = y1 and, when the error norm is < 1 (accepted), Z[7] = f(y1) (the next step's first
  // stage, the dense output's end slope, end_eval's evaluation). The Jacobian df/dy at y0 is
  // taken by forward differences of the stage (2 nv calls; the q rows exact: dq/dt = v), kept
  // while y0, the modes and the torques stay (a retried attempt reuses it). Returns the scaled
  // RMS error norm (as dopri's), or -1 when a stage's Delassus matrix or I/(h gamma) - J is
  // singular.
  double rosenbrock(double h, Out2 Z, F1 ay0, F1 atol, double rtol, Out1 y1, Out1 ay1) {
    check_attempt(Z, ay0, atol, y1, ay1);
    if (!(h > 0.0)) throw std::invalid_argument("h: a step size > 0 expected");
    return rosenbrock_raw(h, Z.data(), ay0.data(), atol.data(), rtol, y1.data(), ay1.data());
  }

  // rosenbrock on raw arrays (sizes and h > 0 checked by the caller), as dopri_raw.
  double rosenbrock_raw(double h, double *z, const double *a0, const double *at, double rtol,
                        double *yn, double *a1) {
    const int n = 2 * nv_;
    static constexpr double gam = 0.25;
    static constexpr double A[6][5] = {
        {0, 0, 0, 0, 0},
        {1.544, 0, 0, 0, 0},
        {0.9466785280815826, 0.2557011698983284, 0, 0, 0},
        {3.314825187068521, 2.896124015972201, 0.9986419139977817, 0, 0},
        {1.221224509226641, 6.019134481288629, 12.53708332932087, -0.6878860361058950, 0},
        {1.221224509226641, 6.019134481288629, 12.53708332932087, -0.6878860361058950, 1.0}};
    static constexpr double C[6][5] = {
        {0, 0, 0, 0, 0},
        {-5.6688, 0, 0, 0, 0},
        {-2.430093356833875, -0.2063599157091915, 0, 0, 0},
        {-0.1073529058151375, -9.594562251023355, -20.47028614809616, 0, 0},
        {7.496443313967647, -10.24680431464352, -33.99990352819905, 11.70890893206160, 0},
        {8.083246795921522, -7.981132988064893, -31.52159432874371, 16.31930543123136,
         -6.058818238834054}};
    end_valid_ = false;
    ys_.resize(n);
    fs_.resize(n);
    if (!jac_valid_ || !std::equal(y_jac_.begin(), y_jac_.end(), z)) {
      if (!jacobian(z, z + n)) return -1.0;
    }
    const double fac = 1.0 / (h * gam);
    Eigen::MatrixXd E = -jac_;
    E.diagonal().array() += fac;
    lu_.compute(E);
    if (!(std::abs(lu_.determinant()) > 0.0) || !std::isfinite(lu_.determinant())) return -1.0;
    K_.resize(n, 6);
    Eigen::VectorXd r(n);
    for (int s = 0; s < 6; ++s) {
      const double *f;
      if (s == 0) {
        f = z + n;
      } else {
        for (int c = 0; c < n; ++c) {
          double acc = z[c];
          for (int j = 0; j < s; ++j) acc += A[s][j] * K_(c, j);
          ys_[c] = acc;
        }
        if (!stage(ys_.data(), fs_.data())) return -1.0;
        f = fs_.data();
      }
      for (int c = 0; c < n; ++c) {
        double acc = f[c];
        for (int j = 0; j < s; ++j) acc += (C[s][j] / h) * K_(c, j);
        r[c] = acc;
      }
      K_.col(s) = lu_.solve(r);
    }
    // y1 = (the 6th stage's argument) + k6; the error estimate is k6
    double ss = 0.0;
    for (int c = 0; c < n; ++c) {
      const double k6 = K_(c, 5);
      yn[c] = ys_[c] + k6;
      z[2 * n + c] = yn[c];
      a1[c] = std::abs(yn[c]);
      const double sc = std::max(a0[c], a1[c]) * rtol + at[c];
      const double ev = k6 / sc;
      ss += ev * ev;
    }
    const double err = std::sqrt(ss * (1.0 / n));
    if (!(err < 1.0)) return std::isnan(err) ? 1e300 : err;
    if (!stage(yn, z + 7 * n)) return -1.0;
    y_end_.assign(yn, yn + n);
    end_valid_ = true;
    return err;
  }

  // The spectral radius [1/s] of the last Rosenbrock attempt's Jacobian df/dy (0 if none).
  double jac_radius() {
    if (!jac_valid_) return 0.0;
    if (radius_ < 0.0) {
      Eigen::EigenSolver<Eigen::MatrixXd> es(jac_, false);
      radius_ = es.info() == Eigen::Success ? es.eigenvalues().cwiseAbs().maxCoeff()
                                            : std::numeric_limits<double>::infinity();
    }
    return radius_;
  }

  // One step of a time-stepping window (packbot.contact.timestep.MoreauJeanStepper.step) from
  // y = (q, v) over h [s], while its contact set stays as it is, under the loaded torques
  // (set_torque: applied + (-viscous v - coulomb_dir)) and the loaded layout, keys and
  // conditions (set_layout, set_keys, set_conditions). The free velocity at the explicit
  // midpoint (two ABA), M^-1 and the rows at (q, v); then the checks that the set is kept: the
  // previous step's end sweep (swept pairs, their distances [m], its margin [m]) holds, within
  // d_act = active_gap + 2 h max(reach . |v|, reach . |v_f|), exactly the layout's pairs; the
  // joints within limit_gap + h max(|v|, |v_f|) of their limits (upper, lower [rad]; empty:
  // no limits) are exactly the layout's limit rows; no pair's patch is stale (conic.stale_pairs:
  // its smallest gap off its distance by more than the point tolerance, or a point slid beyond
  // its slide_tol2); and, with restitution, no touching row (gap <= touch_gap) approaches
  // faster than zeno [m/s]. Then the problem (conic.step_problem: friction mu on the pairs'
  // blocks, the joint boxes at velocity indices `boxes` with bounds `bound` [N*m*s]) and its
  // impulses by the low-rank ADMM from `guess` (rho0 > 0: a warm start) to `tol` within
  // `max_iterations`; v1 = v_f + M^-1 J^T x.
  //
  // Returns (status, x, residual, iterations, rho, energies); v_f, v1 and q1 = q + h v1
  // written into out_vf, out_v1, out_q1; energies (status 0): the total energy [J] at (q, v)
  // and at (q1, v1), and the kinetic one at (q1, v1) (packbot.system.System.energy).
  // status 0: the step's impulses x (3 m + B) with residual <= ok; 1: the contact set changes
  // (the caller updates it); 2: a bounce row; 3: no answer within ok (the caller's fallbacks);
  // 4: M^-1 has no Cholesky factor.
  nb::tuple window_step(F1 y, double h, I1 swept, F1 dist, double sweep_margin, F1 reach,
                        double active_gap, F1 upper, F1 lower, double limit_gap, double mu,
                        double restitution, double zeno, double touch_gap, I1 boxes, F1 bound,
                        F1 guess, double rho0, double tol, int max_iterations, double ok,
                        Out1 out_vf, Out1 out_v1, Out1 out_q1, bool checked) {
    const int nv = nv_;
    if (y.shape(0) < static_cast<size_t>(2 * nv) || reach.shape(0) != static_cast<size_t>(nv) ||
        out_vf.shape(0) != static_cast<size_t>(nv) || out_v1.shape(0) != static_cast<size_t>(nv) ||
        out_q1.shape(0) != static_cast<size_t>(nv))
      throw std::invalid_argument("window_step: y (2 nv), reach, out_vf, out_v1, out_q1 (nv) expected");
    if (swept.shape(0) != dist.shape(0))
      throw std::invalid_argument("window_step: one distance per swept pair expected");
    if (bound.shape(0) != boxes.shape(0))
      throw std::invalid_argument("window_step: one bound per box expected");
    WindowArgs a;
    a.reach = reach.data();
    a.active_gap = active_gap;
    if (upper.shape(0) == static_cast<size_t>(nv) && lower.shape(0) == static_cast<size_t>(nv)) {
      a.upper = upper.data();
      a.lower = lower.data();
    }
    a.limit_gap = limit_gap;
    a.mu = mu;
    a.restitution = restitution;
    a.zeno = zeno;
    a.touch_gap = touch_gap;
    a.boxes = boxes.data();
    a.B = static_cast<int>(boxes.shape(0));
    a.tol = tol;
    a.max_iterations = max_iterations;
    a.ok = ok;
    a.checked = checked;
    check_window();
    std::vector<double> x;
    const WindowOut w = window_core(y.data(), h, swept.data(), dist.data(), swept.shape(0),
                                    sweep_margin, a, bound.data(), guess.data(), guess.shape(0),
                                    rho0, out_vf.data(), out_v1.data(), out_q1.data(), x);
    if (w.status == 0)
      return nb::make_tuple(0, vec(x.data(), x.size()), w.residual, w.iterations, w.rho,
                            nb::make_tuple(w.energies[0], w.energies[1], w.energies[2]));
    if (w.status == 3)
      return nb::make_tuple(3, vec(x.data(), x.size()), w.residual, w.iterations, w.rho,
                            nb::none());
    return nb::make_tuple(w.status, nb::none(), 0.0, 0, 0.0, nb::none());
  }

  // window_step's arguments that stay the same from step to step (see window_step).
  struct WindowArgs {
    const double *reach = nullptr;
    double active_gap = 0.0;
    const double *upper = nullptr, *lower = nullptr;  // (nullptr: no limits)
    double limit_gap = 0.0, mu = 0.0, restitution = 0.0, zeno = 0.0, touch_gap = 0.0;
    const int64_t *boxes = nullptr;
    int B = 0;
    double tol = 0.0;
    int max_iterations = 0;
    double ok = 0.0;
    // false: the set is the caller's, just updated for this step (MoreauJeanStepper's Python
    // step after its set update): the sweep, limit and patch checks are left out
    bool checked = true;
  };

  // What window_core did: its status (window_step's), the solver's residual, iterations and
  // last rho, and (status 0) the energies [J].
  struct WindowOut {
    int status = 0;
    double residual = 0.0;
    int iterations = 0;
    double rho = 0.0;
    double energies[3] = {0.0, 0.0, 0.0};
  };

  void check_window() const {
    if (applied_.size() != static_cast<size_t>(nv_) || !conditions_set_ || lock_mode_ >= 0 ||
        keys_.size() != static_cast<size_t>(np_))
      throw std::invalid_argument("window_step: torques, layout, keys and conditions first");
  }

  // window_step on raw arrays: v_f, v1, q1 into ovf, ov1, oq1 (nv each), the impulses into x.
  WindowOut window_core(const double *y, double h, const int64_t *swept, const double *dist,
                        size_t nsw, double sweep_margin, const WindowArgs &a, const double *bound,
                        const double *guess, size_t nguess, double rho0, double *ovf, double *ov1,
                        double *oq1, std::vector<double> &x) {
    const int nv = nv_;
    const int B = a.B;
    end_valid_ = false;
    jac_valid_ = false;
    WindowOut out;
    auto none = [&](int status) {
      out.status = status;
      return out;
    };
    const double *yq = y, *yv = y + nv;
    // the free velocity at the explicit midpoint: v_f = v + h a_free(q + h/2 v, v + h/2 a0)
    Eigen::VectorXd qm(nv), vm(nv), tau(nv), vf(nv);
    for (int i = 0; i < nv; ++i) {
      q_[i] = yq[i];
      v_[i] = yv[i];
      tau[i] = applied_[i] + (-viscous_[i] * v_[i] - coulomb_dir_[i]);
    }
    pin::aba(model_, data_, q_, v_, tau, pin::Convention::WORLD);
    const double hh = 0.5 * h;
    for (int i = 0; i < nv; ++i) {
      qm[i] = q_[i] + hh * v_[i];
      vm[i] = v_[i] + hh * data_.ddq[i];
    }
    for (int i = 0; i < nv; ++i) tau[i] = applied_[i] + (-viscous_[i] * vm[i] - coulomb_dir_[i]);
    pin::aba(model_, data_, qm, vm, tau, pin::Convention::WORLD);
    for (int i = 0; i < nv; ++i) vf[i] = v_[i] + h * data_.ddq[i];
    for (int i = 0; i < nv; ++i) ovf[i] = vf[i];
    // the set kept: the pairs within reach are the layout's, the limits within reach its limits
    double s0 = 0.0, s1 = 0.0;
    for (int i = 0; i < nv; ++i) {
      s0 += a.reach[i] * std::abs(v_[i]);
      s1 += a.reach[i] * std::abs(vf[i]);
    }
    const double d_act = a.active_gap + 2.0 * h * std::max(s0, s1);
    if (a.checked && sweep_margin < d_act) return none(1);
    std::vector<double> dpair(np_, std::numeric_limits<double>::quiet_NaN());
    int found = 0;
    for (size_t i = 0; i < (a.checked ? nsw : 0); ++i) {
      const double d = dist[i];
      if (!(d <= d_act)) continue;
      const int64_t key = swept[i];
      int p = -1;
      for (int k = 0; k < np_; ++k)
        if (keys_[k] == key) p = k;
      if (p < 0) return none(1);  // a pair joins
      dpair[p] = d;
      ++found;
    }
    if (a.checked && found != np_) return none(1);  // a pair leaves
    if (a.checked && a.upper != nullptr && a.lower != nullptr) {
      int near = 0;
      for (int j = 0; j < nv; ++j) {
        const double lim = a.limit_gap + h * std::max(std::abs(v_[j]), std::abs(vf[j]));
        for (int side = 1; side >= -1; side -= 2) {
          const bool close = side > 0 ? a.upper[j] - q_[j] <= lim : q_[j] - a.lower[j] <= lim;
          if (!close) continue;
          bool held = false;
          for (int l = 0; l < ml_; ++l)
            if (lim_joint_[l] == j && lim_side_[l] == static_cast<double>(side)) held = true;
          if (!held) return none(1);
          ++near;
        }
      }
      if (near != ml_) return none(1);
    }
    // M^-1 and the rows at (q, v)
    pin::computeMinverse(model_, data_, q_);
    minv_ = data_.Minv;
    for (int i = 1; i < nv; ++i)
      for (int c = 0; c < i; ++c) minv_(i, c) = minv_(c, i);
    if (nb_ > 0) pin::computeJointJacobiansTimeVariation(model_, data_, q_, v_);
    rows();
    // the patch rule (conic.stale_pairs)
    gap_min_.assign(np_, std::numeric_limits<double>::infinity());
    slide2_.assign(np_, 0.0);
    for (int r = 0; r < mp_; ++r) {
      const int k = static_cast<int>(rows_[r]);
      const int p = static_cast<int>(pair_[k]);
      if (gap_[r] < gap_min_[p]) gap_min_[p] = gap_[r];
      const double *T = &F_[9 * p];
      const double *d = &dP_[3 * k];
      const double aa = T[0] * d[0] + T[1] * d[1] + T[2] * d[2] - offset0_[2 * r];
      const double b = T[3] * d[0] + T[4] * d[1] + T[5] * d[2] - offset0_[2 * r + 1];
      const double s2 = aa * aa + b * b;
      if (s2 > slide2_[p]) slide2_[p] = s2;
    }
    for (int p = 0; p < (a.checked ? np_ : 0); ++p)
      if (!(std::abs(gap_min_[p] - dpair[p]) <= point_tol_) || slide2_[p] > slide_tol2_[p])
        return none(1);
    if (a.restitution > 0.0)
      for (int r = 0; r < m_; ++r)
        if (gap_[r] <= a.touch_gap && vn_[r] < -a.zeno) return none(2);
    // the problem (conic.step_problem)
    const int m = m_, rt = 3 * m + B;
    std::vector<double> J(static_cast<size_t>(rt) * nv, 0.0);
    for (int r = 0; r < mp_; ++r) {
      const int k = static_cast<int>(rows_[r]);
      const int p = static_cast<int>(pair_[k]);
      const double *T = &F_[9 * p];
      const double *d = &dJp_[k * 3 * nv];
      for (int c2 = 0; c2 < 2; ++c2)
        for (int c = 0; c < nv; ++c)
          J[(3 * r + c2) * nv + c] =
              T[3 * c2] * d[c] + T[3 * c2 + 1] * d[nv + c] + T[3 * c2 + 2] * d[2 * nv + c];
    }
    for (int r = 0; r < m; ++r)
      for (int c = 0; c < nv; ++c) J[(3 * r + 2) * nv + c] = Jn_[r * nv + c];
    for (int i = 0; i < B; ++i) J[(3 * m + i) * nv + a.boxes[i]] = 1.0;
    std::vector<double> mus(m, 0.0);
    for (int r = 0; r < mp_; ++r) mus[r] = a.mu;
    std::vector<double> Mi(static_cast<size_t>(nv) * nv), C;
    for (int i = 0; i < nv; ++i)
      for (int c = 0; c < nv; ++c) Mi[i * nv + c] = minv_(i, c);
    packbot_native::conic::factor(Mi, nv, 0.0, C);
    for (int i = 0; i < nv; ++i)
      if (!(C[i * nv + i] > 1e-150)) return none(4);
    std::vector<double> A(static_cast<size_t>(rt) * nv, 0.0), g(rt, 0.0);
    for (int i = 0; i < rt; ++i) {
      double sv = 0.0;
      for (int k = 0; k < nv; ++k) {
        const double Jik = J[i * nv + k];
        if (Jik != 0.0) {
          sv += Jik * vf[k];
          for (int c = 0; c <= k; ++c) A[i * nv + c] += Jik * C[k * nv + c];
        }
      }
      g[i] = sv;
    }
    for (int r = 0; r < m; ++r) g[3 * r + 2] += std::max(gap_[r], 0.0) / h;
    std::vector<double> bd(bound, bound + B);
    x.assign(rt, 0.0);
    if (nguess == static_cast<size_t>(rt)) std::copy(guess, guess + rt, x.begin());
    const auto sol = packbot_native::conic::solve(A.data(), rt, nv, g.data(), mus, bd, x.data(),
                                                   a.tol, a.max_iterations, rho0);
    out.residual = sol.residual;
    out.iterations = sol.iterations;
    out.rho = sol.rho;
    if (!(sol.residual <= a.ok)) return none(3);
    // v1 = v_f + M^-1 (J^T x)
    std::vector<double> jx(nv, 0.0);
    for (int c = 0; c < nv; ++c) {
      double s = 0.0;
      for (int i = 0; i < rt; ++i) s += J[i * nv + c] * x[i];
      jx[c] = s;
    }
    for (int i = 0; i < nv; ++i) {
      double s = 0.0;
      for (int c = 0; c < nv; ++c) s += minv_(i, c) * jx[c];
      ov1[i] = vf[i] + s;
    }
    // q1 = q (+) h v1 (1-dof joints: q + h v1) and the energies of the guard (energies' sums)
    Eigen::VectorXd q1(nv);
    for (int i = 0; i < nv; ++i) q1[i] = oq1[i] = q_[i] + h * ov1[i];
    const double kin0 = kinetic(q_, yv), pot0 = pin::computePotentialEnergy(model_, data_, q_);
    const double kin1 = kinetic(q1, ov1), pot1 = pin::computePotentialEnergy(model_, data_, q1);
    out.energies[0] = 0.5 * kin0 + pot0;
    out.energies[1] = 0.5 * kin1 + pot1;
    out.energies[2] = 0.5 * kin1;
    return out;
  }

  // A time-stepping window's steps that keep their contact set, one after another
  // (packbot.contact.timestep.MoreauJeanStepper.run_native): window_core's step from the
  // state, then what MoreauJeanStepper.step and NormalLaw.advance do after it (the step's
  // signature and the window's quiet count; the sweep at q1 through the compiled sweep's C
  // entry point `api`, its margin active_gap + 2 h_window sweep_slack max(reach . |v1|,
  // reach . |v1 + v_f - v|); the energy guard). Each step's size is min(h_window, step_angle /
  // sum |v|, t_end - t).
  //
  // A step is kept (committed) when it ends before t_commit, keeps its contact set (status
  // 0), has no pair deeper than project_depth at its end and does not end the window (t1 >=
  // until with quiet_steps quiet steps); the run stops before a step that is not taken here
  // (it ends at or after t_commit, or window_core hands it back: the caller takes it), or
  // after one taken but not kept (pending: the caller finishes it from its sweep), or after
  // max_steps. The sums and dot products are numpy's (np_sum), so the steps are the Python
  // loop's to the bit.
  //
  // y (2 nv) is the state in and the state after the steps kept out; the dict has the steps
  // kept (their end states and times, the energy each removed) and, pending, the step taken
  // (window_step's results and its sweep). The signature's flags
  // (push, slide per pair, lim per limit row, slip per box) of the last step, and the sweep
  // at y (swept pairs, distances [m], margin [m], closest pair and distance), come in and go
  // out in the dict.
  nb::dict window_run(nb::capsule api, Out1 y, double t, double t_end, double t_commit,
                      double h_window, double until, int quiet, int quiet_steps, bool last_valid,
                      I1 last_sig, I1 swept, F1 dist, double sweep_margin, int64_t best,
                      double best_d, F1 reach, double active_gap, F1 upper, F1 lower,
                      double limit_gap, double mu, double restitution, double zeno,
                      double touch_gap, I1 boxes, F1 coul, F1 guess, double rho0, double tol,
                      int max_iterations, double ok, F1 applied, bool has_e, double e_last,
                      double step_angle, double sweep_slack, double project_depth,
                      double impulse_band, double min_d, int max_steps) {
    void *ptr = PyCapsule_GetPointer(api.ptr(), PACKBOT_SWEEP_API);
    if (ptr == nullptr) {
      PyErr_Clear();
      throw std::invalid_argument("api: a capsule of packbot._native_coal's Sweep.api() expected");
    }
    const SweepApi &sw = *static_cast<const SweepApi *>(ptr);
    const int nv = nv_, n2 = 2 * nv_;
    const int B = static_cast<int>(boxes.shape(0));
    if (y.shape(0) != static_cast<size_t>(n2) || reach.shape(0) != static_cast<size_t>(nv) ||
        applied.shape(0) != static_cast<size_t>(nv) || coul.shape(0) != static_cast<size_t>(B) ||
        swept.shape(0) != dist.shape(0) || sw.nq != nv)
      throw std::invalid_argument("window_run: y (2 nv), reach, applied (nv), coul (boxes) expected");
    check_window();
    const int ns = np_ + np_ + ml_ + B;  // the signature's flags
    if (last_sig.shape(0) != static_cast<size_t>(ns))
      throw std::invalid_argument("window_run: last_sig (2 pairs + limits + boxes) expected");
    WindowArgs a;
    a.reach = reach.data();
    a.active_gap = active_gap;
    if (upper.shape(0) == static_cast<size_t>(nv) && lower.shape(0) == static_cast<size_t>(nv)) {
      a.upper = upper.data();
      a.lower = lower.data();
    }
    a.limit_gap = limit_gap;
    a.mu = mu;
    a.restitution = restitution;
    a.zeno = zeno;
    a.touch_gap = touch_gap;
    a.boxes = boxes.data();
    a.B = B;
    a.tol = tol;
    a.max_iterations = max_iterations;
    a.ok = ok;
    double *Y = y.data();
    std::vector<int64_t> spairs(swept.data(), swept.data() + swept.shape(0)), npairs(sw.n_pairs);
    std::vector<double> sdist(dist.data(), dist.data() + dist.shape(0)), ndist(sw.n_pairs);
    std::vector<int64_t> sig(last_sig.data(), last_sig.data() + ns), nsig(ns);
    std::vector<double> x(guess.data(), guess.data() + guess.shape(0)), xn, bound(B), work(nv);
    std::vector<double> vf(nv), v1(nv), q1(nv), y1(n2);
    std::vector<double> removed, states, times;  // (the steps kept: energy removed, states, ends)
    double rho = rho0, margin = sweep_margin, h_kept = 0.0;
    int64_t min_pair = -1;
    int steps = 0, status = 0, handed = 0;
    WindowOut w;
    double h = 0.0, t1 = t, reach_m = 0.0;
    int64_t nbest = -1;
    double nbest_d = std::numeric_limits<double>::infinity();
    while (steps < max_steps) {
      const double *v = Y + nv;
      for (int i = 0; i < nv; ++i) work[i] = std::abs(v[i]);
      h = std::min(std::min(h_window, step_angle / std::max(np_sum(work.data(), nv), 1e-300)),
                   t_end - t);
      t1 = t + h;
      // (the loop's own tests at the step's end: no scheduled action due, the run not over)
      if (!(t1 < t_commit) || !(t1 + 1e-12 < t_end)) break;
      for (int i = 0; i < B; ++i) bound[i] = h * coul.data()[i];
      w = window_core(Y, h, spairs.data(), sdist.data(), spairs.size(), margin, a, bound.data(),
                      x.data(), x.size(), rho, vf.data(), v1.data(), q1.data(), xn);
      if (w.status != 0) {
        handed = w.status;
        break;
      }
      // the signature (conic.step_signature, then the slipping boxes)
      const int mp = mp_, m3 = 3 * m_;
      std::vector<double> xs(np_, 0.0), t1s(np_, 0.0), t2s(np_, 0.0);
      for (int r = 0; r < mp; ++r) {
        const int p = static_cast<int>(pair_[rows_[r]]);
        t1s[p] += xn[3 * r];
        t2s[p] += xn[3 * r + 1];
        xs[p] += xn[3 * r + 2];
      }
      for (int p = 0; p < np_; ++p) {
        const bool push = xs[p] > impulse_band;
        const double ft = std::sqrt(t1s[p] * t1s[p] + t2s[p] * t2s[p]);
        nsig[p] = push;
        nsig[np_ + p] = push && mu > 0.0 && ft >= mu * xs[p] * (1 - 1e-6);
      }
      for (int i = 0; i < ml_; ++i) nsig[2 * np_ + i] = xn[3 * (mp + i) + 2] > impulse_band;
      for (int i = 0; i < B; ++i)
        nsig[2 * np_ + ml_ + i] = std::abs(xn[m3 + i]) >= h_window * coul.data()[i] * (1 - 1e-6);
      const int nquiet = last_valid && nsig == sig ? quiet + 1 : 0;
      // the sweep at q1 (MoreauJeanStepper._finish's first pass)
      for (int i = 0; i < nv; ++i) work[i] = reach.data()[i] * std::abs(v1[i]);
      const double sp1 = np_sum(work.data(), nv);
      for (int i = 0; i < nv; ++i) work[i] = reach.data()[i] * std::abs(v1[i] + (vf[i] - v[i]));
      const double sp2 = np_sum(work.data(), nv);
      reach_m = active_gap + 2.0 * h_window * sweep_slack * std::max(sp1, sp2);
      const int64_t nc = sw.sweep(sw.self, q1.data(), reach_m, npairs.data(), ndist.data(),
                                  &nbest, &nbest_d);
      bool deep = false;
      for (int64_t i = 0; i < nc; ++i)
        if (ndist[i] < -project_depth) deep = true;
      if (deep || (t1 >= until && nquiet >= quiet_steps)) {
        status = 1;  // pending: the caller finishes it
        npairs.resize(nc);
        ndist.resize(nc);
        break;
      }
      // the energy guard
      const double e0 = has_e ? e_last : w.energies[0];
      const double e1 = w.energies[1], kin = w.energies[2];
      for (int i = 0; i < nv; ++i) work[i] = applied.data()[i] * (0.5 * (v[i] + v1[i]));
      const double excess = e1 - e0 - h * np_sum(work.data(), nv);
      if (excess > 0.0) {
        const double s = kin > 0.0 ? std::sqrt(std::max(0.0, kin - excess) / kin) : 0.0;
        for (int i = 0; i < nv; ++i) v1[i] = s * v1[i];
        removed.push_back(kin * (1.0 - s * s));
        has_e = false;
      } else {
        has_e = true;
        e_last = e1;
      }
      for (int i = 0; i < nv; ++i) {
        y1[i] = q1[i];
        y1[nv + i] = v1[i];
      }
      states.insert(states.end(), y1.begin(), y1.end());
      times.push_back(t1);
      // the law's closest distance: the step's start sweep (NormalLaw.advance, note_min)
      if (best >= 0 && best_d < min_d) {
        min_d = best_d;
        min_pair = best;
      }
      std::copy(y1.begin(), y1.end(), Y);
      t = t1;
      quiet = nquiet;
      sig = nsig;
      last_valid = true;
      x = xn;
      rho = w.rho;
      spairs.assign(npairs.begin(), npairs.begin() + nc);
      sdist.assign(ndist.begin(), ndist.begin() + nc);
      margin = reach_m;
      best = nbest;
      best_d = nbest_d;
      h_kept = h;
      ++steps;
    }
    nb::dict out;
    out["steps"] = steps;
    out["status"] = status;
    out["t"] = t;
    out["quiet"] = quiet;
    out["sig"] = owned_vec(sig);
    out["x"] = owned_vec(x);
    out["rho"] = rho;
    out["removed"] = owned_vec(removed);
    out["h_kept"] = h_kept;
    out["has_e"] = has_e;
    out["e_last"] = e_last;
    out["min_d"] = min_d;
    out["min_pair"] = min_pair;
    out["states"] = owned_mat(states, states.size() / n2, n2);
    out["times"] = owned_vec(times);
    out["swept"] = owned_vec(spairs);
    out["dist"] = owned_vec(sdist);
    out["margin"] = margin;
    out["best"] = best;
    out["best_d"] = best_d;
    // the step window_core handed back (its status, size [s] and free velocity [rad/s]; 0:
    // none): the caller's step from the state out, of that size, need not ask again
    out["handed"] = handed;
    if (handed != 0) {
      out["h_handed"] = h;
      out["vf_handed"] = owned_vec(vf);
    }
    if (status == 1) {  // the pending step: MoreauJeanStepper.step's native result, its sweep
      out["h"] = h;
      out["vf"] = owned_vec(vf);
      out["v1"] = owned_vec(v1);
      out["q1"] = owned_vec(q1);
      out["p_x"] = owned_vec(xn);
      out["p_residual"] = w.residual;
      out["p_rho"] = w.rho;
      out["p_energies"] = nb::make_tuple(w.energies[0], w.energies[1], w.energies[2]);
      out["p_swept"] = owned_vec(npairs);
      out["p_dist"] = owned_vec(ndist);
      out["p_margin"] = reach_m;
      out["p_best"] = nbest;
      out["p_best_d"] = nbest_d;
    }
    return out;
  }

  // numpy's sum of n contiguous doubles (its pairwise sum: in order below 8, 8 accumulators
  // from 8 to 128, halves above), to the bit.
  static double np_sum(const double *a, int n) {
    if (n < 8) {
      double s = 0.0;
      for (int i = 0; i < n; ++i) s += a[i];
      return s;
    }
    if (n <= 128) {
      double r[8];
      for (int j = 0; j < 8; ++j) r[j] = a[j];
      int i = 8;
      for (; i < n - (n % 8); i += 8)
        for (int j = 0; j < 8; ++j) r[j] += a[i + j];
      double res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
      for (; i < n; ++i) res += a[i];
      return res;
    }
    int n2 = n / 2;
    n2 -= n2 % 8;
    return np_sum(a, n2) + np_sum(a + n2, n - n2);
  }

  template <class T> static nb::ndarray<nb::numpy, T, nb::ndim<1>> owned_vec(const std::vector<T> &v) {
    T *buf = new T[v.empty() ? 1 : v.size()];
    std::copy(v.begin(), v.end(), buf);
    nb::capsule owner(buf, [](void *p) noexcept { delete[] static_cast<T *>(p); });
    return nb::ndarray<nb::numpy, T, nb::ndim<1>>(buf, {v.size()}, owner);
  }

  static nb::ndarray<nb::numpy, int64_t, nb::ndim<2>> owned_mat_i(const std::vector<int64_t> &v,
                                                                   size_t rows, size_t cols) {
    auto *buf = new int64_t[rows * cols > 0 ? rows * cols : 1];
    std::copy(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(rows * cols), buf);
    nb::capsule owner(buf, [](void *p) noexcept { delete[] static_cast<int64_t *>(p); });
    return nb::ndarray<nb::numpy, int64_t, nb::ndim<2>>(buf, {rows, cols}, owner);
  }

  static nb::ndarray<nb::numpy, double, nb::ndim<2>> owned_mat(const std::vector<double> &v,
                                                                size_t rows, size_t cols) {
    double *buf = new double[rows * cols > 0 ? rows * cols : 1];
    std::copy(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(rows * cols), buf);
    nb::capsule owner(buf, [](void *p) noexcept { delete[] static_cast<double *>(p); });
    return nb::ndarray<nb::numpy, double, nb::ndim<2>>(buf, {rows, cols}, owner);
  }

  // A restart's drift projection, one round (packbot.contact.normal_steps.RestartSteps.project,
  // up to its sweep of the other pairs): the rows at (q, v) with the loaded layout; no gap
  // negative: status 0. A gap below -pen_tol: status 1 (the caller clips the gaps at the pairs'
  // distances: its own round). Else the LCP G mu + g >= 0 _|_ mu >= 0 on the touching rows (gap
  // <= touch_gap), G = J M^-1 J^T with `minv` (nv x nv, symmetric); Lemke's solution with a
  // residual above res_tol: status 2 (the caller's fallbacks); else out_q = q + M^-1 J^T mu
  // [rad], status 3.
  int project_round(F1 q, F1 v, F2 minv, double touch_gap, double pen_tol, double res_tol,
                    Out1 out_q) {
    check_restart("project_round", q, v, minv, out_q);
    return project_round_raw(q.data(), v.data(), minv.data(), touch_gap, pen_tol, res_tol,
                             out_q.data());
  }

  // project_round on raw arrays (sizes checked by the caller; the layout loaded).
  int project_round_raw(const double *q, const double *v, const double *minv, double touch_gap,
                        double pen_tol, double res_tol, double *oq) {
    const int nv = nv_;
    rows_at(q, v);
    if (m_ == 0) return 0;
    double low = gap_[0];
    for (int r = 1; r < m_; ++r) low = std::min(low, gap_[r]);
    for (int r = 0; r < m_; ++r)
      if (std::isnan(gap_[r])) return 2;  // (numpy's min is NaN: the caller's round decides)
    if (!(low < 0.0)) return 0;
    if (low < -pen_tol) return 1;
    touching(touch_gap);
    const int nt = static_cast<int>(touch_.size());
    delassus(minv, nt);
    for (int a = 0; a < nt; ++a) rt_[a] = gap_[touch_[a]];
    zt_.resize(nt);
    if (!packbot_native::lcp::lemke(Gt_.data(), rt_.data(), nt, packbot_native::lcp::MAX_PIVOTS,
                                    packbot_native::lcp::PIVOT_TOL, zt_.data(), lcp_) ||
        !(packbot_native::lcp::residual(Gt_.data(), rt_.data(), nt, zt_.data()) <= res_tol))
      return 2;
    for (int i = 0; i < nv; ++i) {
      double s = 0.0;
      for (int a = 0; a < nt; ++a) s += MJt_[i * nt + a] * zt_[a];
      oq[i] = q[i] + s;
    }
    return 3;
  }

  // A restart's impact (packbot.contact.normal_steps.RestartSteps.impulse): the rows at (q, v)
  // with the loaded layout; no touching row (gap <= touch_gap) approaching: (0, False). Else
  // restitution e applies when a touching row approaches faster than zeno [m/s] (else 0).
  // mu > 0: the frictional impact, blocks (t1, t2, n) per touching row (a limit row: no
  // tangential part, mu 0), on the conic solver (conic::solve, from zeros, to conic_tol within
  // max_iterations): taken when its residual is at most accept and it adds no kinetic energy,
  // else (2, False): the caller's own impulse (its ADMM, its frictionless candidates). mu = 0
  // (or after a frictional answer not taken: never here): Lemke on LCP(G, target), target =
  // v_n + e min(v_n, 0), residual at most res_tol (else (2, False)), taken when e = 0 or it
  // adds no energy, else the inelastic one. out_v = v + M^-1 J^T P [rad/s]: (1, bounced).
  nb::tuple impact(F1 q, F1 v, F2 minv, double mu, double restitution, double zeno,
                   double touch_gap, double res_tol, double conic_tol, int max_iterations,
                   double accept, Out1 out_v) {
    const int nv = nv_;
    check_restart("impact", q, v, minv, out_v);
    rows_at(q.data(), v.data());
    touching(touch_gap);
    const int nt = static_cast<int>(touch_.size());
    double vmin = std::numeric_limits<double>::infinity();
    for (int a = 0; a < nt; ++a) vmin = std::min(vmin, vn_[touch_[a]]);
    for (int r = 0; r < m_; ++r)
      if (std::isnan(gap_[r]) || std::isnan(vn_[r])) return nb::make_tuple(2, false);
    if (nt == 0 || vmin >= 0.0) return nb::make_tuple(0, false);
    const double e = vmin < -zeno ? restitution : 0.0;
    const double *Mi = minv.data();
    const double *vv = v.data();
    double *ov = out_v.data();
    if (mu > 0.0) {
      // J3: (t1, t2, n) per touching row
      const int rt = 3 * nt;
      std::vector<double> J3(static_cast<size_t>(rt) * nv, 0.0), mus(nt, 0.0);
      for (int a = 0; a < nt; ++a) {
        const int r = touch_[a];
        if (r < mp_) {
          const int k = static_cast<int>(rows_[r]);
          const double *T = &F_[9 * pair_[k]];
          const double *d = &dJp_[k * 3 * nv];
          for (int b = 0; b < 2; ++b)
            for (int c = 0; c < nv; ++c)
              J3[(3 * a + b) * nv + c] =
                  T[3 * b] * d[c] + T[3 * b + 1] * d[nv + c] + T[3 * b + 2] * d[2 * nv + c];
          mus[a] = mu;
        }
        for (int c = 0; c < nv; ++c) J3[(3 * a + 2) * nv + c] = Jn_[r * nv + c];
      }
      std::vector<double> Ms(Mi, Mi + static_cast<size_t>(nv) * nv), C;
      packbot_native::conic::factor(Ms, nv, 0.0, C);
      for (int i = 0; i < nv; ++i)
        if (!(C[i * nv + i] > 1e-150)) return nb::make_tuple(2, false);
      std::vector<double> A(static_cast<size_t>(rt) * nv, 0.0), g(rt, 0.0), w(rt, 0.0);
      for (int i = 0; i < rt; ++i) {
        double sv = 0.0;
        for (int k = 0; k < nv; ++k) {
          const double Jik = J3[i * nv + k];
          if (Jik != 0.0) {
            sv += Jik * vv[k];
            for (int c = 0; c <= k; ++c) A[i * nv + c] += Jik * C[k * nv + c];
          }
        }
        w[i] = sv;
        g[i] = sv;
      }
      for (int a = 0; a < nt; ++a) g[3 * a + 2] += e * std::min(g[3 * a + 2], 0.0);
      std::vector<double> x(rt, 0.0);
      const auto sol = packbot_native::conic::solve(A.data(), rt, nv, g.data(), mus, {}, x.data(),
                                                     conic_tol, max_iterations, 0.0);
      if (!(sol.residual <= accept)) return nb::make_tuple(2, false);
      impulse_dv(J3.data(), rt, Mi, x.data());
      if (energy_change(J3.data(), rt, x.data(), w.data()) > 0.0) return nb::make_tuple(2, false);
      for (int i = 0; i < nv; ++i) ov[i] = vv[i] + dv_[i];
      return nb::make_tuple(1, e > 0.0);
    }
    delassus(Mi, nt);
    std::vector<double> Jt(static_cast<size_t>(nt) * nv), vt(nt);
    for (int a = 0; a < nt; ++a) {
      std::copy(&Jn_[touch_[a] * nv], &Jn_[touch_[a] * nv] + nv, &Jt[a * nv]);
      vt[a] = vn_[touch_[a]];
    }
    zt_.resize(nt);
    rt_.resize(nt);
    for (const double ek : {e, 0.0}) {  // (e = 0: the first is taken)
      for (int a = 0; a < nt; ++a) rt_[a] = vt[a] + ek * std::min(vt[a], 0.0);
      if (!packbot_native::lcp::lemke(Gt_.data(), rt_.data(), nt, packbot_native::lcp::MAX_PIVOTS,
                                    packbot_native::lcp::PIVOT_TOL, zt_.data(), lcp_) ||
          !(packbot_native::lcp::residual(Gt_.data(), rt_.data(), nt, zt_.data()) <= res_tol))
        return nb::make_tuple(2, false);
      impulse_dv(Jt.data(), nt, Mi, zt_.data());
      if (ek == 0.0 || energy_change(Jt.data(), nt, zt_.data(), vt.data()) <= 0.0) {
        for (int i = 0; i < nv; ++i) ov[i] = vv[i] + dv_[i];
        return nb::make_tuple(1, ek > 0.0);
      }
    }
    return nb::make_tuple(2, false);  // (not reached: the inelastic candidate is always taken)
  }

  // A restart's or a re-patch's mode selection (packbot.contact.normal_modes.ModeSelection:
  // select_modes(keep), after keep_modes(held) when `held`, the engaged rows before a re-patch,
  // is not empty; modes.hpp) on the rows at (q, v) with the loaded layout, a_free [rad/s^2] and
  // minv (nv x nv, symmetric) given, and the law's constants. The pairs' modes are read from
  // stick_io (one flag per pair) and slip_io ((pairs, 3), world) and, status 0, written back.
  // Returns (status, kept, engaged rows, events, painleve, gave_up): status 0 done, 1 the
  // caller's own selection (nothing written); kept: keep_modes kept `held`; events (k, 2):
  // kind (0 stick, 1 slip, 2 painleve) and pair (-1: none); painleve: the Painleve fallbacks
  // taken; gave_up: friction given up for this restart. The loaded plan is left changed.
  nb::tuple select_modes(F1 q, F1 v, F1 a_free, F2 minv, bool keep, I1 held, U1Out stick_io,
                         Out2 slip_io, double mu, double touch_gap, double speed_band,
                         double stick_speed, double force_band, double stick_band,
                         double baumgarte, double residual_tol) {
    const size_t nv = static_cast<size_t>(nv_);
    if (q.shape(0) != nv || v.shape(0) != nv || a_free.shape(0) != nv || minv.shape(0) != nv ||
        minv.shape(1) != nv)
      throw std::invalid_argument("select_modes: q, v, a_free (nv) and minv (nv, nv) expected");
    if (!conditions_set_) throw std::invalid_argument("select_modes: layout first");
    if (stick_io.shape(0) != static_cast<size_t>(np_) ||
        slip_io.shape(0) != static_cast<size_t>(np_) || slip_io.shape(1) != 3)
      throw std::invalid_argument("select_modes: stick (pairs) and slip_dir (pairs, 3) expected");
    for (size_t e = 0; e < held.shape(0); ++e)
      if (held.data()[e] < 0 || held.data()[e] >= m_)
        throw std::invalid_argument("select_modes: held row out of range");
    ModeConsts c{mu, touch_gap, speed_band, stick_speed, force_band, stick_band, baumgarte,
                 residual_tol};
    ModesOut o;
    if (select_modes_raw(q.data(), v.data(), a_free.data(), minv.data(), keep, held.data(),
                         held.shape(0), stick_io.data(), slip_io.data(), c, o) != 0)
      return nb::make_tuple(1, false, nb::none(), nb::none(), 0, false);
    std::vector<int64_t> eng(o.engaged.begin(), o.engaged.end());
    std::vector<int64_t> ev(o.events.begin(), o.events.end());
    return nb::make_tuple(0, o.kept, owned_vec(eng), owned_mat_i(ev, ev.size() / 2, 2),
                          o.painleve, o.gave_up);
  }

  // The law's constants of a mode selection (select_modes' arguments).
  struct ModeConsts {
    double mu, touch_gap, speed_band, stick_speed, force_band, stick_band, baumgarte,
        residual_tol;
  };

  // What a mode selection decided (select_modes' results).
  struct ModesOut {
    bool kept = false;
    std::vector<int> engaged, events;
    int painleve = 0;
    bool gave_up = false;
  };

  // select_modes on raw arrays (sizes and rows checked by the caller, the layout loaded):
  // 0 done (stick_io, slip_io and out written), 1 the caller's own selection (nothing written).
  int select_modes_raw(const double *q, const double *v, const double *a_free,
                       const double *minv, bool keep, const int64_t *held, size_t nh,
                       uint8_t *stick_io, double *slip_io, const ModeConsts &k, ModesOut &o) {
    const size_t nv = static_cast<size_t>(nv_);
    rows_at(q, v);
    namespace md = packbot_native::modes;
    const packbot_native::Rows R = rows_view();
    if (!R.finite() || !all_finite(a_free, nv) || !all_finite(minv, nv * nv)) return 1;
    md::Consts c;
    c.mu = k.mu;
    c.touch_gap = k.touch_gap;
    c.speed_band = k.speed_band;
    c.stick_speed = k.stick_speed;
    c.force_band = k.force_band;
    c.stick_band = k.stick_band;
    c.baumgarte = k.baumgarte;
    c.residual_tol = k.residual_tol;
    const double *af = a_free, *Mi = minv;
    const double mu = k.mu, stick_speed = k.stick_speed, baumgarte = k.baumgarte;
    const md::Evaluate evaluate = [&](const std::vector<int> &eng, const std::vector<char> &st,
                                      const std::vector<double> &sd, double *a, double *cond,
                                      std::vector<double> &lam) {
      return evaluate_modes(eng, st, sd, af, Mi, mu, stick_speed, baumgarte, a, cond, lam);
    };
    md::Selection &S = sel_;
    S.stick.assign(stick_io, stick_io + np_);
    S.slip_dir.assign(slip_io, slip_io + 3 * np_);
    bool kept = false;
    md::Status status = md::DONE;
    if (nh > 0) {
      std::vector<int> h(held, held + nh);
      status = S.keep(R, c, af, Mi, h, evaluate, kept);
    }
    if (status == md::DONE && !kept) status = S.select(R, c, af, Mi, keep, evaluate);
    end_valid_ = false;
    jac_valid_ = false;
    if (status != md::DONE) return 1;
    for (int p = 0; p < np_; ++p) stick_io[p] = S.stick[p] ? 1 : 0;
    std::copy(S.slip_dir.begin(), S.slip_dir.end(), slip_io);
    o.kept = kept;
    o.engaged.assign(S.engaged.begin(), S.engaged.end());
    o.events.assign(S.events.begin(), S.events.end());
    o.painleve = S.painleve;
    o.gave_up = S.gave_up;
    return 0;
  }

  // A restart's stop of the slow slides (packbot.contact.normal_steps.RestartSteps.stop_slow;
  // stop_slow.hpp) on the rows at (q, v) with the loaded layout, minv (nv x nv, symmetric)
  // given, with friction. Returns 0: the velocity kept; 1: out_v = v + dv [rad/s]; 2: the
  // caller's own step (Lemke does not solve its LCP: the least squares).
  int stop_slow(F1 q, F1 v, F2 minv, double touch_gap, double speed_band, double stick_speed,
                double capture_speed, double residual_tol, double dependent_row, Out1 out_v) {
    check_restart("stop_slow", q, v, minv, out_v);
    rows_at(q.data(), v.data());
    namespace ss = packbot_native::stop_slow;
    ss::Consts c;
    c.touch_gap = touch_gap;
    c.speed_band = speed_band;
    c.stick_speed = stick_speed;
    c.capture_speed = capture_speed;
    c.residual_tol = residual_tol;
    c.dependent_row = dependent_row;
    const packbot_native::Rows R = rows_view();
    const size_t nv = static_cast<size_t>(nv_);
    if (!R.finite() || !all_finite(v.data(), nv) || !all_finite(minv.data(), nv * nv)) return 2;
    return static_cast<int>(stopper_.run(R, c, v.data(), minv.data(), out_v.data()));
  }

  static bool all_finite(const double *x, size_t n) {
    for (size_t i = 0; i < n; ++i)
      if (!std::isfinite(x[i])) return false;
    return true;
  }

  // The rows computed (rows_at) as the restart's native steps read them.
  packbot_native::Rows rows_view() const {
    packbot_native::Rows R;
    R.nv = nv_;
    R.m = m_;
    R.mp = mp_;
    R.np = np_;
    R.Jn = Jn_.data();
    R.drift = drift_.data();
    R.gap = gap_.data();
    R.vn = vn_.data();
    R.JT = JT_.data();
    R.bT = bT_.data();
    R.vT = vT_.data();
    R.vt = vt_.data();
    R.F = F_.data();
    R.dJp = dJp_.data();
    R.rows = rows_.data();
    R.first = pfirst_.data();
    R.K = pK_.data();
    return R;
  }

  // The constrained accelerations at the rows computed (rows_at) with the modes (the engaged
  // rows, the pairs' stick flags and slip directions: the plan of ContactRows._plan), a_free
  // and Mi given: a (nv), the smallest mode condition and the forces (kernels.constrained_accel,
  // as ConstrainedDynamics.evaluate); false when the Delassus matrix is singular. The plan is
  // loaded (set_plan's).
  bool evaluate_modes(const std::vector<int> &eng, const std::vector<char> &stick,
                      const std::vector<double> &slip_dir, const double *a_free, const double *Mi,
                      double mu, double stick_speed, double baumgarte, double *a, double *cond,
                      std::vector<double> &lam) {
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

  // v^T M(q) v [kg m^2/s^2] (CRBA, armature included; the sums of energies).
  double kinetic(const Eigen::VectorXd &q, const double *v) {
    pin::crba(model_, data_, q, pin::Convention::LOCAL);
    const int nv = nv_;
    double kin = 0.0;
    for (int i = 0; i < nv; ++i) {
      double w = 0.0;
      for (int c = 0; c < nv; ++c) w += v[c] * (c <= i ? data_.M(c, i) : data_.M(i, c));
      kin += w * v[i];
    }
    return kin;
  }

  // The last call's unconstrained accelerations, M^-1, forces, gaps, normal velocities,
  // centre tangential velocities, Delassus matrix and right-hand side (copies).
  nb::tuple last() const {
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> Mi = minv_;
    return nb::make_tuple(vec(a_free_.data(), nv_), mat(Mi.data(), nv_, nv_),
                          vec(lam_.data(), n_), vec(gap_.data(), m_), vec(vn_.data(), m_),
                          mat(vt_.data(), np_, 3), mat(G0_.data(), n_, n_),
                          vec(rhs0_.data(), n_));
  }

 private:
  // numpy copies of n (r x c) doubles
  static nb::ndarray<nb::numpy, double, nb::ndim<1>> vec(const double *p, size_t n) {
    auto *buf = new double[n];
    std::copy(p, p + n, buf);
    nb::capsule owner(buf, [](void *d) noexcept { delete[] static_cast<double *>(d); });
    return nb::ndarray<nb::numpy, double, nb::ndim<1>>(buf, {n}, owner);
  }
  static nb::ndarray<nb::numpy, double, nb::ndim<2>> mat(const double *p, size_t r, size_t c) {
    auto *buf = new double[r * c];
    std::copy(p, p + r * c, buf);
    nb::capsule owner(buf, [](void *d) noexcept { delete[] static_cast<double *>(d); });
    return nb::ndarray<nb::numpy, double, nb::ndim<2>>(buf, {r, c}, owner);
  }

  void set_plan_sizes(int ne, int ns) {
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

  // One right-hand side dy/dt = (v, a) at y = (q, v) under the loaded torques; false when the
  // Delassus matrix is singular.
  bool stage(const double *y, double *f) {
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
    pin::aba(model_, data_, q_, v_, x_, pin::Convention::WORLD);
    a_free_ = data_.ddq;
    if (!compute(true)) return false;
    for (int i = 0; i < nv; ++i) {
      f[i] = y[nv + i];
      f[nv + i] = a_[i];
    }
    return true;
  }

  // df/dy at y0 (f0 = f(y0)) into jac_ by forward differences of the stage (Hairer's
  // increments sqrt(eps max(1e-5, |y_c|))); the q rows exact (dq/dt = v).
  bool jacobian(const double *y0, const double *f0) {
    const int nv = nv_, n = 2 * nv_;
    jac_valid_ = false;
    jac_.setZero(n, n);
    yp_.assign(y0, y0 + n);
    fp_.resize(n);
    for (int c = 0; c < n; ++c) {
      const double d = std::sqrt(2.220446049250313e-16 * std::max(1e-5, std::abs(y0[c])));
      yp_[c] = y0[c] + d;
      const double dd = yp_[c] - y0[c];
      const bool ok = stage(yp_.data(), fp_.data());
      yp_[c] = y0[c];
      if (!ok) return false;
      for (int i = nv; i < n; ++i) jac_(i, c) = (fp_[i] - f0[i]) / dd;
    }
    for (int i = 0; i < nv; ++i) jac_(i, nv + i) = 1.0;
    y_jac_.assign(y0, y0 + n);
    jac_valid_ = true;
    radius_ = -1.0;
    return true;
  }

  // The accelerations of the lock mode at (q_, v_) under x_ (tau) into a_, the lock torques
  // into lock_lam_ (set_locks); false where the Python path would not take the closed form.
  bool lock_accel() {
    const int nv = nv_;
    if (lock_mode_ <= 1) {
      pin::aba(model_, data_, q_, v_, x_, pin::Convention::WORLD);
      a_free_ = data_.ddq;
      if (lock_mode_ == 0) {
        a_ = a_free_;
        return true;
      }
      // a_free - minv[:, j] * (a_free[j] / minv[j, j]), minv mirrored from the upper triangle
      pin::computeMinverse(model_, data_, q_);
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
    pin::crba(model_, data_, q_, pin::Convention::LOCAL);
    pin::nonLinearEffects(model_, data_, q_, v_);
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

  // M^-1, the rows and the plan's accelerations at (q_, v_) with a_free_. after_aba: data_
  // holds aba(WORLD)'s pass at (q_, v_), whose factors give M^-1 (Pinocchio's computeMinverse
  // without q: the same numbers as with q) and whose J and oMi are the rows' (dJ by
  // time_variation()); else the full passes.
  bool compute(bool after_aba) {
    const int nv = nv_;
    if (after_aba) {
      pin::computeMinverse(model_, data_);
      if (nb_ > 0) time_variation();
    } else {
      pin::computeMinverse(model_, data_, q_);
      if (nb_ > 0) pin::computeJointJacobiansTimeVariation(model_, data_, q_, v_);
    }
    minv_ = data_.Minv;  // the upper triangle; the lower one mirrored
    for (int i = 1; i < nv; ++i)
      for (int c = 0; c < i; ++c) minv_(i, c) = minv_(c, i);
    rows();
    return solve_plan();
  }

  // data_.dJ (and data_.v, data_.ov) after aba(WORLD) at (q_, v_), whose joint placements
  // (liMi, oMi), joint motions and J they reuse: computeJointJacobiansTimeVariation's own
  // arithmetic (vJ = v_J + liMi^-1 v_parent, ov = oMi vJ, dJ = ov x J), so the same numbers,
  // without its second pass of joint transforms and Jacobian columns.
  void time_variation() {
    for (pin::JointIndex i = 1; i < static_cast<pin::JointIndex>(model_.njoints); ++i) {
      const pin::JointIndex parent = model_.parents[i];
      Data::Motion &vJ = data_.v[i];
      vJ = data_.joints[i].v();
      if (parent > 0) vJ += data_.liMi[i].actInv(data_.v[parent]);
      data_.ov[i] = data_.oMi[i].act(vJ);
      const int c0 = model_.joints[i].idx_v(), n = model_.joints[i].nv();
      pin::motionSet::motionAction(data_.ov[i], data_.J.middleCols(c0, n),
                                   data_.dJ.middleCols(c0, n));
    }
  }

  // kernels.constrained_accel on the rows computed, with minv_, a_free_ and the plan loaded:
  // a_ and the forces lam_; false when the Delassus matrix is singular.
  bool solve_plan() {
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
        const double *sd = &slip_dir_[3 * p];
        const double w0 = vt_[3 * p] + stick_speed_ * sd[0];
        const double w1 = vt_[3 * p + 1] + stick_speed_ * sd[1];
        const double w2 = vt_[3 * p + 2] + stick_speed_ * sd[2];
        const double nrm = std::sqrt(w0 * w0 + w1 * w1 + w2 * w2);
        double s0, s1, s2;
        if (nrm > 0.0) {
          s0 = w0 / nrm;
          s1 = w1 / nrm;
          s2 = w2 / nrm;
        } else {
          s0 = sd[0];
          s1 = sd[1];
          s2 = sd[2];
        }
        const int k = static_cast<int>(rows_[r]);
        const double *d = &dJp_[k * 3 * nv];
        for (int c = 0; c < nv; ++c)
          C_[e * nv + c] -= mu_ * (s0 * d[c] + s1 * d[nv + c] + s2 * d[2 * nv + c]);
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

  // The restart steps' argument checks.
  void check_restart(const char *who, F1 q, F1 v, F2 minv, Out1 out) const {
    const size_t nv = static_cast<size_t>(nv_);
    if (q.shape(0) != nv || v.shape(0) != nv || minv.shape(0) != nv || minv.shape(1) != nv ||
        out.shape(0) != nv)
      throw std::invalid_argument(std::string(who) + ": q, v, out (nv) and minv (nv, nv) expected");
    if (!conditions_set_) throw std::invalid_argument(std::string(who) + ": layout first");
  }

  // The rows at (q, v) with the loaded layout (rows()); the cached evaluations are forgotten.
  void rows_at(const double *q, const double *v) {
    end_valid_ = false;
    jac_valid_ = false;
    for (int i = 0; i < nv_; ++i) {
      q_[i] = q[i];
      v_[i] = v[i];
    }
    if (nb_ > 0) pin::computeJointJacobiansTimeVariation(model_, data_, q_, v_);
    rows();
  }

  // touch_: the rows with gap <= touch_gap, in row order.
  void touching(double touch_gap) {
    touch_.clear();
    for (int r = 0; r < m_; ++r)
      if (gap_[r] <= touch_gap) touch_.push_back(r);
  }

  // Gt_ (nt x nt) = J M^-1 J^T of the touching rows J = Jn[touch_], as numpy's (J M^-1) J^T;
  // MJt_ (nv x nt) = M^-1 J^T.
  void delassus(const double *Mi, int nt) {
    const int nv = nv_;
    JM_.assign(static_cast<size_t>(nt) * nv, 0.0);
    for (int a = 0; a < nt; ++a) {
      const double *J = &Jn_[touch_[a] * nv];
      for (int c = 0; c < nv; ++c) {
        double s = 0.0;
        for (int k = 0; k < nv; ++k) s += J[k] * Mi[k * nv + c];
        JM_[a * nv + c] = s;
      }
    }
    Gt_.assign(static_cast<size_t>(nt) * nt, 0.0);
    MJt_.assign(static_cast<size_t>(nv) * nt, 0.0);
    for (int a = 0; a < nt; ++a) {
      for (int b = 0; b < nt; ++b) {
        const double *J = &Jn_[touch_[b] * nv];
        double s = 0.0;
        for (int c = 0; c < nv; ++c) s += JM_[a * nv + c] * J[c];
        Gt_[a * nt + b] = s;
      }
      for (int i = 0; i < nv; ++i) MJt_[i * nt + a] = JM_[a * nv + i];  // (M^-1 symmetric)
    }
    rt_.resize(nt);
  }

  // dv_ = M^-1 (J^T x) for rows J (n x nv) [rad/s].
  void impulse_dv(const double *J, int n, const double *Mi, const double *x) {
    const int nv = nv_;
    jx_.assign(nv, 0.0);
    for (int c = 0; c < nv; ++c) {
      double s = 0.0;
      for (int i = 0; i < n; ++i) s += J[i * nv + c] * x[i];
      jx_[c] = s;
    }
    dv_.assign(nv, 0.0);
    for (int i = 0; i < nv; ++i) {
      double s = 0.0;
      for (int c = 0; c < nv; ++c) s += Mi[i * nv + c] * jx_[c];
      dv_[i] = s;
    }
  }

  // The kinetic energy change [J] of impulses x on rows J (n x nv), w = J v before, dv_ their
  // velocity change (normal_steps._energy_change: rounding below 1e-12 of the scale is none).
  double energy_change(const double *J, int n, const double *x, const double *w) const {
    const int nv = nv_;
    double pw = 0.0, pdw = 0.0;
    for (int i = 0; i < n; ++i) {
      double dw = 0.0;
      for (int c = 0; c < nv; ++c) dw += J[i * nv + c] * dv_[c];
      pw += x[i] * w[i];
      pdw += x[i] * dw;
    }
    return pw + 0.5 * pdw - 1e-12 * (std::abs(pw) + std::abs(pdw));
  }

  // kernels.contact_rows, with H, J, dJ from data_.
  void rows() {
    const int nv = nv_;
    for (int b = 0; b < nb_; ++b) {
      const auto &M = data_.oMi[static_cast<size_t>(joints_[b])];
      double *H = &H_[16 * b];
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) H[4 * r + c] = M.rotation()(r, c);
        H[4 * r + 3] = M.translation()(r);
      }
      H[12] = H[13] = H[14] = 0.0;
      H[15] = 1.0;
      const double *mk = &masks_[b * nv];
      for (int r = 0; r < 6; ++r) {
        double sv = 0.0, sa = 0.0;
        for (int c = 0; c < nv; ++c) {
          if (mk[c] != 0.0) {
            sv += data_.J(r, c) * v_[c];
            sa += data_.dJ(r, c) * v_[c];
          }
        }
        Vb_[6 * b + r] = sv;
        Ab_[6 * b + r] = sa;
      }
    }
    for (int i = 0; i < n2h_; ++i) {
      const int b = static_cast<int>(body_[i]);
      const double *H = &H_[16 * b];
      const double *l = &local_[4 * i];
      double *P = &P_[3 * i];
      for (int r = 0; r < 3; ++r)
        P[r] = H[4 * r] * l[0] + H[4 * r + 1] * l[1] + H[4 * r + 2] * l[2] + H[4 * r + 3];
      const double px = P[0], py = P[1], pz = P[2];
      double *Jp = &Jp_[i * 3 * nv];
      const double *mk = &masks_[b * nv];
      for (int c = 0; c < nv; ++c) {
        const double m = mk[c];
        const double wx = data_.J(3, c) * m, wy = data_.J(4, c) * m, wz = data_.J(5, c) * m;
        Jp[c] = data_.J(0, c) * m - (py * wz - pz * wy);
        Jp[nv + c] = data_.J(1, c) * m - (pz * wx - px * wz);
        Jp[2 * nv + c] = data_.J(2, c) * m - (px * wy - py * wx);
      }
      double *vp = &vp_[3 * i];
      for (int r = 0; r < 3; ++r) {
        double s = 0.0;
        for (int c = 0; c < nv; ++c) s += Jp[r * nv + c] * v_[c];
        vp[r] = s;
      }
      const double *al = &Ab_[6 * b + 3];
      const double *w = &Vb_[6 * b + 3];
      // pa = P x al, wv = w x vp
      const double pa0 = P[1] * al[2] - P[2] * al[1];
      const double pa1 = P[2] * al[0] - P[0] * al[2];
      const double pa2 = P[0] * al[1] - P[1] * al[0];
      const double wv0 = w[1] * vp[2] - w[2] * vp[1];
      const double wv1 = w[2] * vp[0] - w[0] * vp[2];
      const double wv2 = w[0] * vp[1] - w[1] * vp[0];
      double *ap = &ap_[3 * i];
      ap[0] = Ab_[6 * b] - pa0 + wv0;
      ap[1] = Ab_[6 * b + 1] - pa1 + wv1;
      ap[2] = Ab_[6 * b + 2] - pa2 + wv2;
    }
    const int h = h_;
    for (int k = 0; k < h; ++k)
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < nv; ++c)
          dJp_[(k * 3 + r) * nv + c] = Jp_[((h + k) * 3 + r) * nv + c] - Jp_[(k * 3 + r) * nv + c];
        vrel_[3 * k + r] = vp_[3 * (h + k) + r] - vp_[3 * k + r];
        arel_[3 * k + r] = ap_[3 * (h + k) + r] - ap_[3 * k + r];
        dP_[3 * k + r] = P_[3 * (h + k) + r] - P_[3 * k + r];
      }
    for (int p = 0; p < np_; ++p) {
      const double *H = &H_[16 * normal_body_[p]];
      const double *f2 = &frame2_[9 * p];
      double *F = &F_[9 * p];
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
          F[3 * r + c] = f2[3 * r] * H[4 * c] + f2[3 * r + 1] * H[4 * c + 1] +
                         f2[3 * r + 2] * H[4 * c + 2];
    }
    std::fill(Jn_.begin(), Jn_.end(), 0.0);
    std::fill(drift_.begin(), drift_.end(), 0.0);
    for (int r = 0; r < mp_; ++r) {
      const int k = static_cast<int>(rows_[r]);
      const int p = static_cast<int>(pair_[k]);
      const double *n = &F_[9 * p + 6];
      // n turns with the body b carrying it: the exact derivatives of the gap n . (p2 - p1)
      // (kernels.contact_rows: the terms in dP = p2 - p1, zero when b is the world)
      const int b = static_cast<int>(normal_body_[p]);
      const double *w = &Vb_[6 * b + 3];
      const double *al = &Ab_[6 * b + 3];
      const double *dPk = &dP_[3 * k];
      const double wxn0 = w[1] * n[2] - w[2] * n[1];
      const double wxn1 = w[2] * n[0] - w[0] * n[2];
      const double wxn2 = w[0] * n[1] - w[1] * n[0];
      const double wxn[3] = {wxn0, wxn1, wxn2};
      const double wwxn[3] = {w[1] * wxn2 - w[2] * wxn1, w[2] * wxn0 - w[0] * wxn2,
                              w[0] * wxn1 - w[1] * wxn0};
      const double nxd[3] = {n[1] * dPk[2] - n[2] * dPk[1], n[2] * dPk[0] - n[0] * dPk[2],
                             n[0] * dPk[1] - n[1] * dPk[0]};
      const double *d = &dJp_[k * 3 * nv];
      const double *mk = &masks_[b * nv];
      for (int c = 0; c < nv; ++c) {
        Jn_[r * nv + c] = n[0] * d[c] + n[1] * d[nv + c] + n[2] * d[2 * nv + c];
        if (mk[c] != 0.0)
          Jn_[r * nv + c] +=
              nxd[0] * data_.J(3, c) + nxd[1] * data_.J(4, c) + nxd[2] * data_.J(5, c);
      }
      double g = 0.0, vv = 0.0, dd = 0.0;
      for (int i = 0; i < 3; ++i) {
        g += dP_[3 * k + i] * n[i];
        vv += vrel_[3 * k + i] * n[i];
        dd += arel_[3 * k + i] * n[i] + 2.0 * vrel_[3 * k + i] * wxn[i];
      }
      for (int i = 0; i < 3; ++i) {
        vv += wxn[i] * dPk[i];
        dd += nxd[i] * al[i] + wwxn[i] * dPk[i];
      }
      gap_[r] = g;
      vn_[r] = vv;
      drift_[r] = dd;
    }
    for (int i = 0; i < ml_; ++i) {
      const int j = static_cast<int>(lim_joint_[i]);
      const double s = lim_side_[i];
      Jn_[(mp_ + i) * nv + j] = -s;
      gap_[mp_ + i] = s * (lim_value_[i] - q_[j]);
      vn_[mp_ + i] = -s * v_[j];
    }
    for (int p = 0; p < np_; ++p) {
      // the centres' tangential slides t . (c2 - c1), the tangents turning with the frame's
      // body b: their exact derivatives (kernels.contact_rows, as the normal rows above); the
      // sliding velocity where the bodies touch, v_rel - w x dP
      const int c0 = static_cast<int>(centre_[p]);
      const double *F = &F_[9 * p];
      const double *d = &dJp_[c0 * 3 * nv];
      const double *vr = &vrel_[3 * c0];
      const double *ar = &arel_[3 * c0];
      const int b = static_cast<int>(normal_body_[p]);
      const double *w = &Vb_[6 * b + 3];
      const double *al = &Ab_[6 * b + 3];
      const double *dPk = &dP_[3 * c0];
      const double *mk = &masks_[b * nv];
      const double wxd[3] = {w[1] * dPk[2] - w[2] * dPk[1], w[2] * dPk[0] - w[0] * dPk[2],
                             w[0] * dPk[1] - w[1] * dPk[0]};
      for (int r = 0; r < 2; ++r) {
        const double *t = F + 3 * r;
        const double wxt[3] = {w[1] * t[2] - w[2] * t[1], w[2] * t[0] - w[0] * t[2],
                               w[0] * t[1] - w[1] * t[0]};
        const double wwxt[3] = {w[1] * wxt[2] - w[2] * wxt[1], w[2] * wxt[0] - w[0] * wxt[2],
                                w[0] * wxt[1] - w[1] * wxt[0]};
        const double txd[3] = {t[1] * dPk[2] - t[2] * dPk[1], t[2] * dPk[0] - t[0] * dPk[2],
                               t[0] * dPk[1] - t[1] * dPk[0]};
        for (int c = 0; c < nv; ++c) {
          JT_[(p * 2 + r) * nv + c] = t[0] * d[c] + t[1] * d[nv + c] + t[2] * d[2 * nv + c];
          if (mk[c] != 0.0)
            JT_[(p * 2 + r) * nv + c] +=
                txd[0] * data_.J(3, c) + txd[1] * data_.J(4, c) + txd[2] * data_.J(5, c);
        }
        double bb = 0.0, vv = 0.0;
        for (int i = 0; i < 3; ++i) {
          bb += t[i] * ar[i] + 2.0 * wxt[i] * vr[i];
          vv += t[i] * vr[i];
        }
        for (int i = 0; i < 3; ++i) {
          bb += txd[i] * al[i] + wwxt[i] * dPk[i];
          vv += wxt[i] * dPk[i];
        }
        bT_[2 * p + r] = bb;
        vT_[2 * p + r] = vv;
      }
      const double *n = F + 6;
      double vnc = 0.0;
      for (int i = 0; i < 3; ++i) vnc += n[i] * (vr[i] - wxd[i]);
      for (int i = 0; i < 3; ++i) vt_[3 * p + i] = vr[i] - wxd[i] - n[i] * vnc;
    }
  }

  // Whether the last call was a dopri (contact rows) whose FSAL stage was at exactly y1.
  bool at_end(F1 y1) const {
    const size_t n = 2 * static_cast<size_t>(nv_);
    return end_valid_ && conditions_set_ && y1.shape(0) == n &&
           std::equal(y_end_.begin(), y_end_.end(), y1.data());
  }

  // The smallest mode condition at the last dopri's end (returned; pos_ and, with friction,
  // slipping_ set) and each pair's largest squared slide (slide2_), as
  // kernels.constrained_accel computes them.
  double end_conditions() {
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

  Model model_;
  Data data_;
  int nv_ = 0;
  Eigen::VectorXd q_, v_, x_, a_free_, a_, force_;
  // the report's law's locks (set_locks): -1 the contact rows, 0 none, 1 one, 2 the unlocked block
  int lock_mode_ = -1;
  std::vector<int64_t> locked_;
  std::vector<int> unlocked_;
  std::vector<double> lock_lam_;
  // the lock conditions' screen (set_screen)
  std::vector<double> screen_;
  double torque_band_ = 0.0, accel_band_ = 0.0;
  Eigen::MatrixXd minv_;
  // (the restart steps: project_round, impact)
  std::vector<int> touch_;
  std::vector<double> JM_, Gt_, MJt_, rt_, zt_, jx_, dv_;
  // (the mode selection: select_modes) each pair's first patch row and its number of rows
  std::vector<int> pfirst_, pK_;
  packbot_native::modes::Selection sel_;
  packbot_native::stop_slow::StopSlow stopper_;
  packbot_native::lcp::Work lcp_;
  // layout
  std::vector<int64_t> joints_, body_, pair_, rows_, centre_, normal_body_, lim_joint_;
  std::vector<double> masks_, local_, frame2_, lim_side_, lim_value_;
  int nb_ = 0, n2h_ = 0, h_ = 0, np_ = 0, mp_ = 0, ml_ = 0, m_ = 0;
  // plan
  std::vector<int64_t> engaged_, row_slip_, sticks_;
  double mu_ = 0.0, stick_speed_ = 0.0, baumgarte_ = 0.0;
  int ne_ = 0, ns_ = 0, n_ = 0;
  // work
  std::vector<double> H_, Vb_, Ab_, P_, Jp_, vp_, ap_, dJp_, vrel_, arel_, dP_, F_;
  std::vector<double> Jn_, drift_, gap_, vn_, JT_, bT_, vT_, vt_, slip_dir_;
  std::vector<double> A_, C_, target_, b_, MC_, G_, G0_, rhs_, rhs0_, lam_;
  // the step's torques and its stage argument
  std::vector<double> applied_, viscous_, coulomb_dir_, ys_;
  // the step end's conditions (end_eval)
  std::vector<double> offset0_, y_end_;
  std::vector<int> pos_;
  std::vector<char> slipping_, engaged_pair_;
  std::vector<double> slide2_, gap_min_, slide_tol2_;
  std::vector<int64_t> keys_;  // (set_keys)
  bool stale_sure_ = false;  // (end_check_raw)
  // (keep_loaded's copies)
  std::vector<double> kept_local_, kept_frame2_, kept_offset0_, kept_slide_tol2_, kept_slip_dir_;
  std::vector<int64_t> kept_engaged_, kept_row_slip_, kept_sticks_;
  std::vector<int64_t> kept_body_, kept_pair_, kept_rows_, kept_centre_;
  bool relaid_ = false;  // (relayout_raw since keep_loaded)
  std::array<double, 3> kept_plan_{};
  std::vector<double> upper_, lower_;  // (set_limits)
  std::vector<double> reach_;  // (set_reach)
  double margin_ = 0.0, max_step_ = 0.0;
  double force_band_ = 0.0, point_tol_ = 0.0, stick_band_ = 0.0;
  bool conditions_set_ = false, end_valid_ = false;
  // the stiff steps (stiffness, rosenbrock): the last dopri's h |lambda|, the Jacobian, where
  // it was taken, its spectral radius (-1: not computed), the LU of I/(h gamma) - J, the stages
  double hlamb_ = 0.0, radius_ = -1.0;
  bool jac_valid_ = false;
  Eigen::MatrixXd jac_, K_;
  Eigen::PartialPivLU<Eigen::MatrixXd> lu_;
  std::vector<double> y_jac_, yp_, fp_, fs_;
};


namespace {

using I2 = nb::ndarray<const int64_t, nb::ndim<2>, nb::c_contig, nb::device::cpu>;
using StretchT = packbot_native::Stretch<ContactRhs>;

template <class T>
nb::ndarray<nb::numpy, T, nb::ndim<2>> owned(const std::vector<T> &v, size_t rows, size_t cols) {
  T *buf = new T[rows * cols > 0 ? rows * cols : 1];
  std::copy(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(rows * cols), buf);
  nb::capsule owner(buf, [](void *p) noexcept { delete[] static_cast<T *>(p); });
  return nb::ndarray<nb::numpy, T, nb::ndim<2>>(buf, {rows, cols}, owner);
}

// Stretch(rhs, api, ...): the sweep's capsule (packbot._native_coal's Sweep.api()).
void stretch_init(StretchT *self, ContactRhs &rhs, nb::capsule api, double margin, F1 atol,
                  double rtol, double h_min, double near,
                  double pen_tol, int crawl_steps, double crawl_step, double sample_dt,
                  double duration, bool stiff_switch) {
  void *p = PyCapsule_GetPointer(api.ptr(), PACKBOT_SWEEP_API);
  if (p == nullptr) {
    PyErr_Clear();
    throw std::invalid_argument("api: a capsule of packbot._native_coal's Sweep.api() expected");
  }
  new (self) StretchT(rhs, *static_cast<SweepApi *>(p), margin, reals(atol), rtol, h_min, near,
                      pen_tol, crawl_steps, crawl_step, sample_dt, duration, stiff_switch);
}

// The re-patch's constants (Stretch::Repatch; packbot/contact/stretch.py passes them).
void stretch_set_repatch(StretchT &st, double tol, double patch_tol, double face_align,
                         double slide_tol2, double touch_gap, double res_tol, double mu,
                         double speed_band, double stick_speed, double force_band,
                         double stick_band, double baumgarte, double mode_res_tol,
                         int hand_back_at) {
  auto &rp = st.repatch();
  rp.hand_back_at = hand_back_at;
  rp.tol = tol;
  rp.patch_tol = patch_tol;
  rp.face_align = face_align;
  rp.slide_tol2 = slide_tol2;
  rp.touch_gap = touch_gap;
  rp.res_tol = res_tol;
  rp.modes = ContactRhs::ModeConsts{mu,         touch_gap,  speed_band, stick_speed,
                                    force_band, stick_band, baumgarte,  mode_res_tol};
}

// The next run's re-patches: allowed (on) or not, and the contact set's modes (per pair its
// stick flag, its normal's body, its slip direction (pairs, 3); the engaged rows).
void stretch_set_modes(StretchT &st, bool on, U1 stick, U1 on1, F2 slip, I1 engaged) {
  auto &rp = st.repatch();
  const size_t np = stick.shape(0);
  if (on1.shape(0) != np || slip.shape(0) != np || (np && slip.shape(1) != 3))
    throw std::invalid_argument("stick, on1 (pairs) and slip (pairs, 3) expected");
  rp.on = on;
  rp.stick.assign(stick.data(), stick.data() + np);
  rp.on1.assign(on1.data(), on1.data() + np);
  rp.slip.assign(slip.data(), slip.data() + 3 * np);
  rp.engaged.assign(engaged.data(), engaged.data() + engaged.shape(0));
  rp.painleve = rp.gave_up = rp.relaid = 0;
  rp.proj_valid = rp.spare = false;
  rp.q_patch.clear();
}

// The last run's re-patches as Python takes them over (stretch.py): a dict.
nb::dict stretch_repatched(StretchT &st) {
  auto &rp = st.repatch();
  const size_t np = rp.stick.size();
  nb::dict out;
  out["q_patch"] = owned(rp.q_patch, 1, rp.q_patch.size());
  out["stick"] = owned(rp.stick, 1, np);
  out["slip"] = owned(rp.slip, np, 3);
  out["engaged"] = owned(rp.engaged, 1, rp.engaged.size());
  out["painleve"] = rp.painleve;
  out["gave_up"] = rp.gave_up;
  out["relaid"] = rp.relaid;
  for (int w = 0; w < 2; ++w) {
    const bool on = w == 0 ? rp.proj_valid : rp.spare;
    const char *name = w == 0 ? "proj" : "spare";
    if (!on) {
      out[name] = nb::none();
      continue;
    }
    const auto &q = w == 0 ? rp.q_proj : rp.q_spare;
    const auto &pairs = w == 0 ? rp.proj_pairs : rp.spare_pairs;
    const auto &dist = w == 0 ? rp.proj_dist : rp.spare_dist;
    out[name] = nb::make_tuple(owned(q, 1, q.size()), owned(pairs, 1, pairs.size()),
                               owned(dist, 1, dist.size()), w == 0 ? rp.proj_best : rp.spare_best,
                               w == 0 ? rp.proj_best_d : rp.spare_best_d);
  }
  return out;
}

// run's arguments and results as Python sees them (packbot/contact/stretch.py): a dict.
nb::dict stretch_run(StretchT &st, bool f_pending, Out2 Z, Out1 ay, double t, double h,
                     double max_factor, int stiff_run, bool stiff, int64_t next_sample,
                     double min_d, double t_end, double t_last, double t_sched, I1 active,
                     I2 limits, F1 lim_value, F1 crawl, Out1 y_pend, Out1 ay_pend) {
  const size_t n = static_cast<size_t>(st.n());
  if (Z.shape(0) != 8 || Z.shape(1) != n || ay.shape(0) != n || y_pend.shape(0) != n ||
      ay_pend.shape(0) != n)
    throw std::invalid_argument("Z (8, 2 nv); ay, y_pend, ay_pend (2 nv,) expected");
  const size_t nl = limits.shape(0);
  if ((nl && limits.shape(1) != 3) || lim_value.shape(0) != nl)
    throw std::invalid_argument("limits (k, 3) and lim_value (k,) expected");
  StretchT::State s;
  s.t = t;
  s.h = h;
  s.max_factor = max_factor;
  s.stiff_run = stiff_run;
  s.stiff = stiff;
  s.next_sample = next_sample;
  s.min_d = min_d;
  std::vector<double> ring(crawl.data(), crawl.data() + crawl.shape(0));
  std::vector<double> samples, hs;
  const auto c = st.run(s, f_pending, Z.data(), ay.data(), t_end, t_last, t_sched, active.data(),
                        active.shape(0), limits.data(), lim_value.data(), nl, ring,
                        y_pend.data(), ay_pend.data(), samples, hs);
  nb::dict out;
  out["status"] = c.status;
  out["steps"] = c.steps;
  out["rejected"] = c.rejected;
  out["rhs_calls"] = c.rhs_calls;
  out["stiff_steps"] = c.stiff_steps;
  out["t"] = s.t;
  out["h"] = s.h;
  out["h_max"] = s.h_max;
  out["stiff_run"] = s.stiff_run;
  out["stiff"] = s.stiff;
  out["min_d"] = s.min_d;
  out["min_pair"] = s.min_pair;
  out["samples"] = owned(samples, samples.size() / n, n);
  out["hs"] = owned(hs, 1, hs.size());
  out["last_pairs"] = owned(st.last_pairs(), 1, st.last_n());
  out["last_dist"] = owned(st.last_dist(), 1, st.last_n());
  out["repatches"] = c.repatches;
  out["spare"] = st.repatch().spare;  // (a re-patch handed back after its projection's sweep)
  if (c.status == packbot_native::STRETCH_PENDING) {
    out["t0"] = c.t0;
    out["t1"] = c.t1;
    out["pending_rejected"] = c.pending_rejected;
    out["pending_rhs_calls"] = c.pending_rhs_calls;
    out["pending_implicit"] = c.pending_implicit;
    out["pending_pairs"] = owned(st.pending_pairs(), 1, st.pending_n());
    out["pending_dist"] = owned(st.pending_dist(), 1, st.pending_n());
    out["pending_best"] = st.pending_best();
    out["pending_best_d"] = st.pending_best_d();
  }
  return out;
}

}  // namespace

NB_MODULE(_native, m) {
  m.doc() = "packbot's compiled right-hand side of the contact-normal mode (Pinocchio, nanobind).";
  m.attr("PINOCCHIO_VERSION") = PINOCCHIO_VERSION;
  nb::class_<ContactRhs>(m, "ContactRhs")
      .def(nb::init<const std::vector<std::string> &, I1, F3, F2, F1, F2, F3, F1, F1>(),
           nb::arg("types"), nb::arg("parents"), nb::arg("placements"), nb::arg("axes"),
           nb::arg("masses"), nb::arg("levers"), nb::arg("inertias"), nb::arg("armature"),
           nb::arg("gravity"))
      .def_prop_ro("nv", &ContactRhs::nv)
      .def("set_layout", &ContactRhs::set_layout)
      .def("set_patches", &ContactRhs::set_patches, nb::arg("local"), nb::arg("frame2"),
           nb::arg("offset0"), nb::arg("slide_tol2"))
      .def("set_plan", &ContactRhs::set_plan)
      .def("set_slip_dirs", &ContactRhs::set_slip_dirs)
      .def("accel", &ContactRhs::accel, nb::arg("q"), nb::arg("v"), nb::arg("x"),
           nb::arg("from_tau"), nb::arg("out"))
      .def("set_torque", &ContactRhs::set_torque, nb::arg("applied"), nb::arg("viscous"),
           nb::arg("coulomb_dir"))
      .def("first", &ContactRhs::first, nb::arg("Z"))
      .def("dopri", &ContactRhs::dopri, nb::arg("h"), nb::arg("Z"), nb::arg("ay0"),
           nb::arg("atol"), nb::arg("rtol"), nb::arg("y1"), nb::arg("ay1"))
      .def("stiffness", &ContactRhs::stiffness)
      .def("rosenbrock", &ContactRhs::rosenbrock, nb::arg("h"), nb::arg("Z"), nb::arg("ay0"),
           nb::arg("atol"), nb::arg("rtol"), nb::arg("y1"), nb::arg("ay1"))
      .def("jac_radius", &ContactRhs::jac_radius)
      .def("set_conditions", &ContactRhs::set_conditions, nb::arg("offset0"),
           nb::arg("slide_tol2"), nb::arg("force_band"), nb::arg("point_tol"),
           nb::arg("stick_band"))
      .def("end_eval", &ContactRhs::end_eval, nb::arg("y1"))
      .def("eval_at", &ContactRhs::eval_at, nb::arg("y"))
      .def("row_condition_at", &ContactRhs::row_condition_at, nb::arg("y"), nb::arg("r"))
      .def("row_root", &ContactRhs::row_root, nb::arg("Z"), nb::arg("t0"), nb::arg("t1"),
           nb::arg("h"), nb::arg("y1"), nb::arg("hermite"), nb::arg("r"), nb::arg("g0"),
           nb::arg("g1"), nb::arg("xtol"))
      .def("set_keys", &ContactRhs::set_keys, nb::arg("keys"))
      .def("set_limits", &ContactRhs::set_limits, nb::arg("upper"), nb::arg("lower"))
      .def("set_reach", &ContactRhs::set_reach, nb::arg("reach"), nb::arg("margin"),
           nb::arg("max_step"))
      .def("step_bound", &ContactRhs::step_bound, nb::arg("y"))
      .def("end_check", &ContactRhs::end_check, nb::arg("y1"), nb::arg("swept"), nb::arg("dist"),
           nb::arg("active"), nb::arg("near"), nb::arg("pen_tol"))
      .def("set_locks", &ContactRhs::set_locks, nb::arg("locked"))
      .def("energies", &ContactRhs::energies, nb::arg("Q"), nb::arg("V"), nb::arg("out"))
      .def("end_locks", &ContactRhs::end_locks, nb::arg("y1"))
      .def("set_screen", &ContactRhs::set_screen, nb::arg("rows"), nb::arg("torque_band"),
           nb::arg("accel_band"))
      .def("end_screen", &ContactRhs::end_screen, nb::arg("y1"), nb::arg("margin"))
      .def("window_step", &ContactRhs::window_step, nb::arg("y"), nb::arg("h"), nb::arg("swept"),
           nb::arg("dist"), nb::arg("sweep_margin"), nb::arg("reach"), nb::arg("active_gap"),
           nb::arg("upper"), nb::arg("lower"), nb::arg("limit_gap"), nb::arg("mu"),
           nb::arg("restitution"), nb::arg("zeno"), nb::arg("touch_gap"), nb::arg("boxes"),
           nb::arg("bound"), nb::arg("guess"), nb::arg("rho0"), nb::arg("tol"),
           nb::arg("max_iterations"), nb::arg("ok"), nb::arg("out_vf"), nb::arg("out_v1"),
           nb::arg("out_q1"), nb::arg("checked") = true)
      .def("project_round", &ContactRhs::project_round, nb::arg("q"), nb::arg("v"),
           nb::arg("minv"), nb::arg("touch_gap"), nb::arg("pen_tol"), nb::arg("res_tol"),
           nb::arg("out_q"))
      .def("impact", &ContactRhs::impact, nb::arg("q"), nb::arg("v"), nb::arg("minv"),
           nb::arg("mu"), nb::arg("restitution"), nb::arg("zeno"), nb::arg("touch_gap"),
           nb::arg("res_tol"), nb::arg("conic_tol"), nb::arg("max_iterations"),
           nb::arg("accept"), nb::arg("out_v"))
      .def("window_run", &ContactRhs::window_run, nb::arg("api"), nb::arg("y"), nb::arg("t"),
           nb::arg("t_end"), nb::arg("t_commit"), nb::arg("h_window"), nb::arg("until"),
           nb::arg("quiet"), nb::arg("quiet_steps"), nb::arg("last_valid"), nb::arg("last_sig"),
           nb::arg("swept"), nb::arg("dist"), nb::arg("sweep_margin"), nb::arg("best"),
           nb::arg("best_d"), nb::arg("reach"), nb::arg("active_gap"), nb::arg("upper"),
           nb::arg("lower"), nb::arg("limit_gap"), nb::arg("mu"), nb::arg("restitution"),
           nb::arg("zeno"), nb::arg("touch_gap"), nb::arg("boxes"), nb::arg("coul"),
           nb::arg("guess"), nb::arg("rho0"), nb::arg("tol"), nb::arg("max_iterations"),
           nb::arg("ok"), nb::arg("applied"), nb::arg("has_e"), nb::arg("e_last"),
           nb::arg("step_angle"), nb::arg("sweep_slack"), nb::arg("project_depth"),
           nb::arg("impulse_band"), nb::arg("min_d"), nb::arg("max_steps"))
      .def("select_modes", &ContactRhs::select_modes, nb::arg("q"), nb::arg("v"),
           nb::arg("a_free"), nb::arg("minv"), nb::arg("keep"), nb::arg("held"),
           nb::arg("stick_io"), nb::arg("slip_io"), nb::arg("mu"), nb::arg("touch_gap"),
           nb::arg("speed_band"), nb::arg("stick_speed"), nb::arg("force_band"),
           nb::arg("stick_band"), nb::arg("baumgarte"), nb::arg("residual_tol"))
      .def("stop_slow", &ContactRhs::stop_slow, nb::arg("q"), nb::arg("v"), nb::arg("minv"),
           nb::arg("touch_gap"), nb::arg("speed_band"), nb::arg("stick_speed"),
           nb::arg("capture_speed"), nb::arg("residual_tol"), nb::arg("dependent_row"),
           nb::arg("out_v"))
      .def("last", &ContactRhs::last)
      .def("minv_at",
           [](ContactRhs &r, F1 q, Out2 out) {
             if (q.shape(0) != static_cast<size_t>(r.nv()) || out.shape(0) != q.shape(0) ||
                 out.shape(1) != q.shape(0))
               throw std::invalid_argument("q (nv) and out (nv, nv) expected");
             r.minverse_at(q.data(), out.data());
           })
      .def("free_accel_at", [](ContactRhs &r, F1 q, F1 v, Out1 out) {
        if (q.shape(0) != static_cast<size_t>(r.nv()) || v.shape(0) != q.shape(0) ||
            out.shape(0) != q.shape(0))
          throw std::invalid_argument("q, v and out (nv) expected");
        r.free_accel_raw(q.data(), v.data(), out.data());
      });
  nb::class_<StretchT>(m, "Stretch")
      .def("__init__", &stretch_init, nb::arg("rhs"), nb::arg("api"), nb::arg("margin"),
           nb::arg("atol"), nb::arg("rtol"),
           nb::arg("h_min"), nb::arg("near"), nb::arg("pen_tol"), nb::arg("crawl_steps"),
           nb::arg("crawl_step"), nb::arg("sample_dt"), nb::arg("duration"),
           nb::arg("stiff_switch"), nb::keep_alive<1, 2>(), nb::keep_alive<1, 3>())
      .def("run", &stretch_run)
      .def("set_repatch", &stretch_set_repatch, nb::arg("tol"), nb::arg("patch_tol"),
           nb::arg("face_align"), nb::arg("slide_tol2"), nb::arg("touch_gap"),
           nb::arg("res_tol"), nb::arg("mu"), nb::arg("speed_band"), nb::arg("stick_speed"),
           nb::arg("force_band"), nb::arg("stick_band"), nb::arg("baumgarte"),
           nb::arg("mode_res_tol"), nb::arg("hand_back_at") = 0)
      .def("set_modes", &stretch_set_modes, nb::arg("on"), nb::arg("stick"), nb::arg("on1"),
           nb::arg("slip"), nb::arg("engaged"))
      .def("repatched", &stretch_repatched);
}
