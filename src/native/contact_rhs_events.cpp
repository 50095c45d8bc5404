// ContactRhs: the step end of the contact rows' mode: its evaluation (end_eval, eval_at), a
// row's condition and its event located in a step's dense output (row_root: brentq), and the
// step end's screen (end_check).

#include "contact_rhs.hpp"
#include "brentq.hpp"
#include "stretch.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

// The step end's evaluation: when the last call was a dopri whose FSAL stage was at exactly
// y1 (no call or load since), (cond, a, lam, gap, vn, vt, slide2) there, as
// ConstrainedDynamics.evaluate reads them (cond: the smallest mode condition, slide2: each
// pair's largest squared slide); else None.
nb::object ContactRhs::end_eval(F1 y1) {
  if (!at_end(y1)) return nb::none();
  const double cond = end_conditions();
  return nb::make_tuple(cond, vec(a_.data(), nv_), vec(lam_.data(), n_), vec(gap_.data(), m_),
                        vec(vn_.data(), m_), mat(vt_.data(), np_, 3),
                        vec(slide2_.data(), np_));
}

// The evaluation at y with the modes and torques loaded (an event's root finding inside a
// native step): the right-hand side's stage at y, then end_eval's tuple there (y becomes the
// state end_eval and end_check answer for). None when the Delassus matrix is singular.
nb::object ContactRhs::eval_at(F1 y) {
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
double ContactRhs::row_condition_at(F1 y, int64_t r) {
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
double ContactRhs::row_root(F2 Z, double t0, double t1, double h, F1 y1, bool hermite, int64_t r,
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
  // brentq (packbot.ode.brentq, SciPy's Zeros/brentq.c: brentq.hpp)
  const double root = packbot_native::brentq(g_rec, t0, t1, xtol, failed);
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
int ContactRhs::end_check(F1 y1, I1 swept, F1 dist, I1 active, double near, double pen_tol) {
  const size_t ns = swept.shape(0);
  if (dist.shape(0) != ns) throw std::invalid_argument("swept, dist: one length expected");
  if (!at_end(y1)) return -1;
  return end_check_raw(y1.data(), swept.data(), dist.data(), ns, active.data(),
                       active.shape(0), near, pen_tol);
}

// The joints that pass one of their limits (set_limits) inside a step and are within it at
// both ends: the cubic Hermite of (q0, v0) at the step's start y0 and (q1, v1) at its end y1
// over h [s] has an extreme beyond the limit by more than tol [rad]. Appends (joint, side,
// s), s in (0, 1) the extreme's fraction of the step. (A long event-driven step can carry a
// joint past its stop and back: elbow1 5.5e-4 rad past its upper stop for 23 ms inside a
// 35 ms step, no event, start 10 of the wrist-locked grid, mu 0.5, e 0.3.)
void ContactRhs::limit_excursions_raw(const double *y0, const double *y1, double h, double tol,
                                      std::vector<Excursion> &out) const {
  const int nv = nv_;
  for (size_t j = 0; j < upper_.size(); ++j) {
    const double q0 = y0[j], q1 = y1[j], d0 = h * y0[nv + j], d1 = h * y1[nv + j];
    if (!(q0 < upper_[j] && q1 < upper_[j] && q0 > lower_[j] && q1 > lower_[j])) continue;
    // q'(s) = A s^2 + B s + C on s in [0, 1]
    const double A = 6.0 * q0 + 3.0 * d0 - 6.0 * q1 + 3.0 * d1;
    const double B = -6.0 * q0 - 4.0 * d0 + 6.0 * q1 - 2.0 * d1;
    const double C = d0;
    double roots[2];
    int nr = 0;
    if (std::abs(A) < 1e-300) {
      if (B != 0.0) roots[nr++] = -C / B;
    } else {
      const double disc = B * B - 4.0 * A * C;
      if (disc >= 0.0) {
        const double sq = std::sqrt(disc);
        const double qq = -0.5 * (B + std::copysign(sq, B));  // (the stable pair of roots)
        if (qq != 0.0) roots[nr++] = C / qq;
        roots[nr++] = qq / A;
      }
    }
    for (int i = 0; i < nr; ++i) {
      const double s = roots[i];
      if (!(s > 0.0 && s < 1.0)) continue;
      const double s2 = s * s, s3 = s2 * s;
      const double q = (2.0 * s3 - 3.0 * s2 + 1.0) * q0 + (s3 - 2.0 * s2 + s) * d0 +
                       (-2.0 * s3 + 3.0 * s2) * q1 + (s3 - s2) * d1;
      if (q > upper_[j] + tol)
        out.push_back({static_cast<int>(j), 1, s});
      else if (q < lower_[j] - tol)
        out.push_back({static_cast<int>(j), -1, s});
    }
  }
}

nb::list ContactRhs::limit_excursions(F1 y0, F1 y1, double h, double tol) const {
  if (y0.shape(0) < static_cast<size_t>(2 * nv_) || y1.shape(0) < static_cast<size_t>(2 * nv_))
    throw std::invalid_argument("limit_excursions: y0, y1 (2 nv at least) expected");
  std::vector<Excursion> found;
  limit_excursions_raw(y0.data(), y1.data(), h, tol, found);
  nb::list out;
  for (const Excursion &e : found) out.append(nb::make_tuple(e.joint, e.side, e.s));
  return out;
}

// Each world pair's joints, for the screen of contacts between step ends (pair_dips.hpp):
// pair k's velocity indices idx[start[k]] ... idx[start[k + 1] - 1] (start: pairs + 1 entries).
void ContactRhs::set_pair_joints(I1 start, I1 idx) {
  if (start.shape(0) < 1) throw std::invalid_argument("pair_joints: start (pairs + 1) expected");
  dips_.set(start.data(), start.shape(0) - 1, idx.data(), idx.shape(0), nv_);
}

// The screen of contacts between step ends over a step of h [s], for Python's watch: Q (5,
// n >= nv) the step's interpolant coefficients (packbot.ode.DenseSegment._coefficients) over
// theta in [0, theta_max] (h / the interpolant's own step); the start's sweep (pairs0, dist0
// [m]; start_known: a pair absent from it is at least margin [m] away, else it is queried),
// the end's (pairs1, dist1), the contact set's active pairs, pen_tol [m] the penetration
// tolerance (PairDips::screen); distance(k, s) pair k's signed distance [m] at the fraction s
// of the step. Returns ([(pair, s, d, level), ...] the dips found, queries made).
nb::tuple ContactRhs::pair_dips(F2 Q, double theta_max, double h, I1 pairs0, F1 dist0,
                                I1 pairs1, F1 dist1, bool start_known, I1 active, double margin,
                                double pen_tol, nb::callable distance) {
  if (Q.shape(0) != 5 || Q.shape(1) < static_cast<size_t>(nv_))
    throw std::invalid_argument("pair_dips: Q (5, nv at least) expected");
  if (pairs0.shape(0) != dist0.shape(0) || pairs1.shape(0) != dist1.shape(0))
    throw std::invalid_argument("pair_dips: one distance per pair expected");
  if (!(h > 0.0) || !(theta_max > 0.0) || !(pen_tol > 0.0) || !(margin > 0.0))
    throw std::invalid_argument("pair_dips: h, theta_max, pen_tol and margin must be > 0");
  if (!dips_.ready() || reach_.size() != static_cast<size_t>(nv_))
    throw std::invalid_argument("pair_dips: set_pair_joints and set_reach first");
  packbot_native::PairDips::speed_bounds(Q.data(), Q.shape(1), nv_, theta_max, vmax_);
  std::vector<packbot_native::Dip> found;
  auto dist = [&](int64_t k, double s) { return nb::cast<double>(distance(k, s)); };
  const int64_t evals = dips_.screen(vmax_.data(), reach_.data(), h, pairs1.data(),
                                     dist1.data(), pairs1.shape(0), pairs0.data(), dist0.data(),
                                     pairs0.shape(0), start_known, active.data(),
                                     active.shape(0), margin, pen_tol,
                                     packbot_native::DIP_QUERIES, dist, found, false);
  nb::list out;
  for (const auto &d : found) out.append(nb::make_tuple(d.pair, d.s, d.d, d.level));
  return nb::make_tuple(out, evals);
}

// end_check at the end of the last dopri (the caller knows it ended at y1), on raw arrays:
// ns swept pairs, na active ones.
int ContactRhs::end_check_raw(const double *y1, const int64_t *sp, const double *dp, size_t ns,
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

// Whether the last call was a dopri (contact rows) whose FSAL stage was at exactly y1.
bool ContactRhs::at_end(F1 y1) const {
  const size_t n = 2 * static_cast<size_t>(nv_);
  return end_valid_ && conditions_set_ && y1.shape(0) == n &&
         std::equal(y_end_.begin(), y_end_.end(), y1.data());
}
