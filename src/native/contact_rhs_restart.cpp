// ContactRhs: a restart's native steps (packbot.contact.normal_steps.RestartSteps and
// normal_modes.ModeSelection) on the rows at (q, v): the drift projection (Lemke), the impact
// (conic.hpp, Lemke), the mode selection (modes.hpp), the stop of the slow slides
// (stop_slow.hpp).

#include "contact_rhs.hpp"
#include "conic.hpp"
#include "modes.hpp"
#include "rows.hpp"
#include "stop_slow.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

ContactRhs::~ContactRhs() = default;

// A restart's drift projection, one round (packbot.contact.normal_steps.RestartSteps.project,
// up to its sweep of the other pairs): the rows at (q, v) with the loaded layout; no gap
// negative: status 0. A gap below -pen_tol: status 1 (the caller clips the gaps at the pairs'
// distances: its own round). Else the LCP G mu + g >= 0 _|_ mu >= 0 on the touching rows (gap
// <= touch_gap), G = J M^-1 J^T with `minv` (nv x nv, symmetric); Lemke's solution with a
// residual above res_tol: status 2 (the caller's fallbacks); a row the move would take below
// zero joins the touching rows and the LCP is solved again; out_q = q + M^-1 J^T mu
// [rad], status 3, or status 4 where out_q is past a joint limit (set_limits) that is not one
// of the layout's limit rows (the caller adds the stop and projects again).
int ContactRhs::project_round(F1 q, F1 v, F2 minv, double touch_gap, double pen_tol, double res_tol,
                              Out1 out_q) {
  check_restart("project_round", q, v, minv, out_q);
  return project_round_raw(q.data(), v.data(), minv.data(), touch_gap, pen_tol, res_tol,
                           out_q.data());
}

// The velocity after a drift projection q0 -> q1 that adds no energy
// (packbot.contact.normal_contacts.NormalContacts.neutral_velocity, the one implementation;
// the stretch's re-patch calls it too): the projection moves the arm out of the surfaces it
// was carried into, keeping v, so E = 1/2 v^T M(q) v + V(q) changes by E(q1, v) - E(q0, v).
// A rise is taken from the kinetic energy at q1 by scaling v (the least change of v in the
// metric M(q1) that reaches the energy; its direction kept, so the conditions at zero still
// hold), to zero where the kinetic energy is smaller (the rest stays); a fall is left.
// v in/out [rad/s]; returns the energy removed [J] (0 where none).
double ContactRhs::neutral_velocity_raw(const double *q0, const double *q1, double *v) {
  const int nv = nv_;
  Eigen::VectorXd a(nv), b(nv);
  for (int i = 0; i < nv; ++i) {
    a[i] = q0[i];
    b[i] = q1[i];
  }
  const double e0 = 0.5 * kinetic(a, v) + potential(a);
  const double kin = 0.5 * kinetic(b, v);
  const double excess = kin + potential(b) - e0;
  if (!(excess > 0.0)) return 0.0;
  const double s = kin > 0.0 ? std::sqrt(std::max(0.0, kin - excess) / kin) : 0.0;
  for (int i = 0; i < nv; ++i) v[i] *= s;
  return kin * (1.0 - s * s);
}

double ContactRhs::neutral_velocity(F1 q0, F1 q1, Out1 v) {
  const size_t nv = static_cast<size_t>(nv_);
  if (q0.shape(0) != nv || q1.shape(0) != nv || v.shape(0) != nv)
    throw std::invalid_argument("neutral_velocity: q0, q1 and v (nv) expected");
  return neutral_velocity_raw(q0.data(), q1.data(), v.data());
}

// project_round on raw arrays (sizes checked by the caller; the layout loaded).
int ContactRhs::project_round_raw(const double *q, const double *v, const double *minv,
                                  double touch_gap, double pen_tol, double res_tol, double *oq) {
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
  // the LCP on the touching rows, and again with every other row the move takes below zero
  // (a stop 1.5e-5 rad off, above touch_gap, that the jaw would be projected 1.4e-4 past)
  std::vector<char> in(m_, 0);
  for (const int64_t r : touch_) in[r] = 1;
  for (int round = 0; round <= m_; ++round) {
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
    bool more = false;
    for (int r = 0; r < m_; ++r) {
      if (in[r]) continue;
      double g = gap_[r];
      for (int c = 0; c < nv; ++c) g += Jn_[r * nv + c] * (oq[c] - q[c]);
      if (g < 0.0) in[r] = more = true;
    }
    if (!more) break;
    touch_.clear();
    for (int r = 0; r < m_; ++r)
      if (in[r]) touch_.push_back(r);
  }
  // a joint moved past a stop (set_limits) that is not one of the rows: the caller's round
  // puts the stop in the set and projects again
  if (past_a_stop_not_in_rows(oq, upper_.data(), lower_.data(), upper_.size())) return 4;
  return 3;
}

// A restart's impact (packbot.contact.normal_steps.RestartSteps.impulse): the rows at (q, v)
// with the loaded layout; no touching row (gap <= touch_gap) approaching: (0, False). Else
// restitution e applies when a touching row approaches faster than zeno [m/s] (else 0).
// mu > 0: the frictional impact, blocks (t1, t2, n) per touching row (a limit row: no
// tangential part, mu 0), on the conic solver (conic::solve, from zeros, to conic_tol within
// max_iterations; on the factor of M^-1, that of the locked subspace's M^-1_c with the
// hand-off's locked joints): taken when its residual is at most accept and it adds no kinetic
// energy, else (2, False): the caller's own impulse (its ADMM, its frictionless candidates). mu = 0
// (or after a frictional answer not taken: never here): Lemke on LCP(G, target), target =
// v_n + e min(v_n, 0), residual at most res_tol (else (2, False)), taken when e = 0 or it
// adds no energy, else the inelastic one. out_v = v + M^-1 J^T P [rad/s]: (1, bounced, rows,
// P): the touching rows (nt,) and their impulses (nt, 3), blocks (t1, t2, n) [N*s, N*m*s]
// (the frictionless impact's tangential parts 0).
nb::tuple ContactRhs::impact(F1 q, F1 v, F2 minv, double mu, double restitution, double zeno,
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
  // the impact taken: its rows and their blocks (t1, t2, n), normal only when `x3` is false
  auto taken = [&](bool bounced, const double *x, bool x3) {
    std::vector<int64_t> rows(touch_.begin(), touch_.end());
    std::vector<double> P(3 * static_cast<size_t>(nt), 0.0);
    for (int a = 0; a < nt; ++a)
      for (int b = x3 ? 0 : 2; b < 3; ++b) P[3 * a + b] = x3 ? x[3 * a + b] : x[a];
    return nb::make_tuple(1, bounced, owned_vec(rows), owned_mat(P, nt, 3));
  };
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
    for (int i = 0; i < nv; ++i) {
      // a joint of the hand-off's locked subspace (set_row_mode; M^-1_c's row and column 0):
      // its factor's column is 0 (contact_rhs_clamps.cpp)
      if (Ms[i * nv + i] == 0.0 &&
          std::find(row_locked_.begin(), row_locked_.end(), i) != row_locked_.end()) {
        C[i * nv + i] = 0.0;
        continue;
      }
      if (!(C[i * nv + i] > 1e-150)) return nb::make_tuple(2, false);
    }
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
    return taken(e > 0.0, x.data(), true);
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
      return taken(ek > 0.0, zt_.data(), false);
    }
  }
  return nb::make_tuple(2, false);  // (not reached: the inelastic candidate is always taken)
}

// A restart's or a re-patch's mode selection (packbot.contact.normal_modes.ModeSelection:
// select_modes(keep), after keeping the rows `held` when any, the engaged rows before a re-patch,
// is not empty; modes.hpp) on the rows at (q, v) with the loaded layout, a_free [rad/s^2] and
// minv (nv x nv, symmetric) given, and the law's constants. The pairs' modes are read from
// stick_io (one flag per pair) and slip_io ((pairs, 3), world) and, status 0, written back.
// Returns (status, kept, engaged rows, events, painleve, gave_up): status 0 done, 1 the
// caller's own selection (nothing written); kept: `held` was kept; events (k, 2):
// kind (0 stick, 1 slip, 2 painleve) and pair (-1: none); painleve: the Painleve fallbacks
// taken; gave_up: friction given up for this restart. The loaded plan is left changed.
nb::tuple ContactRhs::select_modes(F1 q, F1 v, F1 a_free, F2 minv, bool keep, I1 held,
                                   U1Out stick_io, Out2 slip_io, double mu, double touch_gap,
                                   double speed_band, double stick_speed, double force_band,
                                   double stick_band, double baumgarte, double residual_tol) {
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

// select_modes on raw arrays (sizes and rows checked by the caller, the layout loaded):
// 0 done (stick_io, slip_io and out written), 1 the caller's own selection (nothing written).
int ContactRhs::select_modes_raw(const double *q, const double *v, const double *a_free,
                                 const double *minv, bool keep, const int64_t *held, size_t nh,
                                 uint8_t *stick_io, double *slip_io, const ModeConsts &k,
                                 ModesOut &o) {
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
  if (!sel_) sel_ = std::make_unique<md::Selection>();
  md::Selection &S = *sel_;
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
int ContactRhs::stop_slow(F1 q, F1 v, F2 minv, double touch_gap, double speed_band,
                          double stick_speed, double capture_speed, double residual_tol,
                          double dependent_row, Out1 out_v) {
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
  if (!stopper_) stopper_ = std::make_unique<ss::StopSlow>();
  return static_cast<int>(stopper_->run(R, c, v.data(), minv.data(), out_v.data()));
}

bool ContactRhs::all_finite(const double *x, size_t n) {
  for (size_t i = 0; i < n; ++i)
    if (!std::isfinite(x[i])) return false;
  return true;
}

// The restart steps' argument checks.
void ContactRhs::check_restart(const char *who, F1 q, F1 v, F2 minv, Out1 out) const {
  const size_t nv = static_cast<size_t>(nv_);
  if (q.shape(0) != nv || v.shape(0) != nv || minv.shape(0) != nv || minv.shape(1) != nv ||
      out.shape(0) != nv)
    throw std::invalid_argument(std::string(who) + ": q, v, out (nv) and minv (nv, nv) expected");
  if (!conditions_set_) throw std::invalid_argument(std::string(who) + ": layout first");
}

// touch_: the rows with gap <= touch_gap, in row order.
void ContactRhs::touching(double touch_gap) {
  touch_.clear();
  for (int r = 0; r < m_; ++r)
    if (gap_[r] <= touch_gap) touch_.push_back(r);
}

// Gt_ (nt x nt) = J M^-1 J^T of the touching rows J = Jn[touch_], as numpy's (J M^-1) J^T;
// MJt_ (nv x nt) = M^-1 J^T.
void ContactRhs::delassus(const double *Mi, int nt) {
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
void ContactRhs::impulse_dv(const double *J, int n, const double *Mi, const double *x) {
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
double ContactRhs::energy_change(const double *J, int n, const double *x, const double *w) const {
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
