// The contact-normal mode's mode selection at a restart, after
// packbot/contact/normal_modes.py (ModeSelection.select_modes and its helpers; keeping the
// engaged rows at a re-patch, ModeSelection.repatch_modes, exists here only):
// which touching rows are engaged, which pairs stick or slip and the slip directions, from the
// acceleration-level mixed LCP (touching normal rows complementary, sticking pairs' tangential
// rows equalities), the cone check, the slip directions' consistency and the Painleve
// fallback. The arithmetic follows the Python step by step; its matrix products are summed in
// index order (numpy's BLAS may sum in another), so the results agree to rounding.
//
// The rows come from the host (ContactRhs::rows_at) as a Rows view; the constrained
// accelerations of a mode (ConstrainedDynamics.evaluate) from the host's evaluate callback.
// Row-major arrays throughout.

#pragma once

#include "lcp.hpp"
#include "rows.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <vector>

namespace packbot_native {
namespace modes {

using packbot_native::Rows;

// The law's constants (packbot.contact.normal_tolerances).
struct Consts {
  double mu = 0.0, touch_gap = 0.0, speed_band = 0.0, stick_speed = 0.0, force_band = 0.0,
         stick_band = 0.0, baumgarte = 0.0, residual_tol = 0.0;
};

// What a mode change is (ModeEvent.kind).
enum Kind : int { STICK = 0, SLIP = 1, PAINLEVE = 2 };

// Outcome of a selection: DONE, or HAND_BACK where the Python path takes a branch this port
// does not (a least-squares fallback of the symmetric LCP, a singular Delassus matrix in an
// evaluation, a slide of zero speed to normalise).
enum Status : int { DONE = 0, HAND_BACK = 1 };

// The constrained accelerations of a mode (ConstrainedDynamics.evaluate): (engaged rows, stick
// flags, slip directions) -> a (nv) [rad/s^2], the smallest mode condition (cond) and the
// forces lam (the engaged rows', then the sticking pairs' tangential ones); false: the Python
// path's numpy evaluation (a singular Delassus matrix).
using Evaluate =
    std::function<bool(const std::vector<int> &, const std::vector<char> &,
                       const std::vector<double> &, double *, double *, std::vector<double> &)>;

class Selection {
 public:
  // The modes: in, then out (DONE).
  std::vector<char> stick;        // (np)
  std::vector<double> slip_dir;   // (np, 3) world, at onset
  std::vector<int> engaged;       // the engaged rows
  std::vector<int> events;        // (kind, pair) pairs; a Painleve event's pair -1
  int painleve = 0;               // Painleve fallbacks taken
  bool gave_up = false;           // friction given up for this restart (logged by the caller)

  // ModeSelection.select_modes(q, v, a_free, minv, keep) on the rows.
  Status select(const Rows &R, const Consts &c, const double *a_free, const double *Mi,
                bool keep, const Evaluate &evaluate) {
    R_ = &R;
    c_ = c;
    a_free_ = a_free;
    Mi_ = Mi;
    evaluate_ = &evaluate;
    events.clear();
    painleve = 0;
    gave_up = false;
    const int nv = R.nv;
    touch_.clear();
    for (int r = 0; r < R.m; ++r)
      if (R.gap[r] <= c.touch_gap && std::abs(R.vn[r]) <= c.speed_band) touch_.push_back(r);
    engaged = touch_;
    if (c.mu > 0.0) {
      for (int p = 0; p < R.np; ++p) {
        const double *vt = R.vt + 3 * p;
        const double speed = norm3(vt);
        const char was = stick[p];
        if (keep && stick[p]) continue;
        stick[p] = speed <= c.stick_speed && !keep;
        // a sliding pair re-patched at zero tangential speed (keep) keeps its direction
        if (!stick[p] && speed > 0.0)
          for (int i = 0; i < 3; ++i) slip_dir[3 * p + i] = vt[i] / speed;
        if (was != stick[p]) push(stick[p] ? STICK : SLIP, p);
      }
    }
    if (touch_.empty()) {
      engaged.clear();
      return DONE;
    }
    // _ModeBase: b_N = J_n[N] a_free + drift[N] + 2 B v_n[N] + B^2 gap[N]; J_n[N] M^-1
    const int nt = static_cast<int>(touch_.size());
    const double B = c.baumgarte, B2 = B * B, twoB = 2.0 * B;
    bN_.assign(nt, 0.0);
    JnM_.assign(static_cast<size_t>(nt) * nv, 0.0);
    for (int a = 0; a < nt; ++a) {
      const double *J = R.Jn + static_cast<size_t>(touch_[a]) * nv;
      bN_[a] = dot(J, a_free, nv) + R.drift[touch_[a]] + twoB * R.vn[touch_[a]] +
               B2 * R.gap[touch_[a]];
      for (int j = 0; j < nv; ++j) {
        double s = 0.0;
        for (int k = 0; k < nv; ++k) s += J[k] * Mi[k * nv + j];
        JnM_[a * nv + j] = s;
      }
    }
    stick_rows_.clear();
    Status st = DONE;
    if (!mode_loop(st)) return st;
    if (!consistent_directions(st)) return st;
    if (coulomb_residual_directions() && !mode_loop(st)) return st;
    return st;
  }

  // The engaged rows `held` of before a re-patch kept (true) or not (false; the caller then
  // selects with keep), the caller having checked the row signature: kept when every one
  // still touches, no sliding pair is slower than stick_speed, and one solve with them is a
  // solution of the mode problem (positive forces on them, no touching free row accelerating
  // into contact, Baumgarte terms included, to residual_tol scaled; every mode condition
  // satisfied). Sticking pairs stay sticking; sliding pairs take their sliding velocity's
  // direction.
  Status keep(const Rows &R, const Consts &c, const double *a_free, const double *Mi,
              const std::vector<int> &held, const Evaluate &evaluate, bool &kept) {
    kept = false;
    events.clear();
    painleve = 0;
    gave_up = false;
    const int nv = R.nv;
    std::vector<char> touch(R.m, 0), mine(R.m, 0);
    for (int r = 0; r < R.m; ++r)
      touch[r] = R.gap[r] <= c.touch_gap && std::abs(R.vn[r]) <= c.speed_band;
    for (int r : held) {
      if (!touch[r]) return DONE;
      mine[r] = 1;
    }
    if (c.mu > 0.0) {
      for (int p = 0; p < R.np; ++p) {
        bool any_mine = false, touching = false;
        for (int r = R.first[p]; r < R.first[p] + R.K[p]; ++r) {
          any_mine = any_mine || mine[r];
          touching = touching || touch[r];
        }
        if (stick[p]) {
          if (touching && !any_mine) return DONE;
          continue;
        }
        const double *vt = R.vt + 3 * p;
        const double speed = norm3(vt);
        if (speed <= c.stick_speed) return DONE;
        for (int i = 0; i < 3; ++i) slip_dir[3 * p + i] = vt[i] / speed;
      }
    }
    engaged = held;
    a_.resize(nv);
    double cond = 0.0;
    if (!evaluate(engaged, stick, slip_dir, a_.data(), &cond, lam_)) return HAND_BACK;
    if (cond < 0.0) return DONE;  // (violated)
    const int ne = static_cast<int>(held.size());
    double lmin = lam_[0], lmax = 0.0;
    for (int e = 0; e < ne; ++e) {
      lmin = std::min(lmin, lam_[e]);
      lmax = std::max(lmax, std::abs(lam_[e]));
    }
    if (lmin <= 1e-12 * (1.0 + lmax)) return DONE;
    const double B = c.baumgarte;
    double wmin = std::numeric_limits<double>::infinity(), wmax = 0.0;
    bool any = false;
    for (int r = 0; r < R.m; ++r) {
      if (!touch[r] || mine[r]) continue;
      any = true;
      double w = dot(R.Jn + static_cast<size_t>(r) * nv, a_.data(), nv) + R.drift[r];
      w += 2.0 * B * R.vn[r] + B * B * R.gap[r];
      wmin = std::min(wmin, w);
      wmax = std::max(wmax, std::abs(w));
    }
    if (any && wmin < -c.residual_tol * (1.0 + wmax)) return DONE;
    kept = true;
    return DONE;
  }

 private:
  static double dot(const double *a, const double *b, int n) { return dense::dot(a, b, n); }
  static double norm3(const double *x) { return dense::norm3(x); }
  static double norm2(const double *x) { return std::sqrt(x[0] * x[0] + x[1] * x[1]); }

  void push(int kind, int pair) {
    events.push_back(kind);
    events.push_back(pair);
  }

  // _mode_loop: the mode problem with the cone check until no sticking pair leaves its cone.
  bool mode_loop(Status &st) {
    const Rows &R = *R_;
    for (int it = 0; it < R.np + 2; ++it) {
      bool ok = solve_modes(st);
      if (st != DONE) return false;
      if (!ok) {
        push(PAINLEVE, -1);
        ++painleve;
        std::fill(stick.begin(), stick.end(), 1);
        ok = solve_modes(st);
        if (st != DONE) return false;
        if (!ok) {
          gave_up = true;
          engaged = touch_;
          return false;
        }
      }
      cone_check();
      if (moved_.empty()) break;
      for (size_t k = 0; k < moved_.size(); ++k) {
        const int p = moved_[k];
        stick[p] = 0;
        for (int i = 0; i < 3; ++i) slip_dir[3 * p + i] = moved_dir_[3 * k + i];
        push(SLIP, p);
      }
    }
    return true;
  }

  // The sticking rows' blocks of _solve_modes for the current stick flags (cached by them, as
  // _ModeBase.stick_rows): J_T, b_T + J_T a_free + B v_T, J_T M^-1, pinv(J_T M^-1 J_T^T).
  struct StickRows {
    std::vector<char> key;
    std::vector<int> pairs;  // the sticking pairs with touching rows
    std::vector<double> JT, bTt, JTM, GTTi;
  };

  const StickRows &stick_rows() {
    for (const auto &s : stick_rows_)
      if (s.key == stick) return s;
    const Rows &R = *R_;
    const int nv = R.nv;
    StickRows s;
    s.key = stick;
    if (c_.mu > 0.0) {
      for (int p = 0; p < R.np; ++p) {
        if (!stick[p]) continue;
        bool eng = false;  // (_pair_engaged: the engaged rows are the touching ones here)
        for (int r : engaged) eng = eng || (r >= R.first[p] && r < R.first[p] + R.K[p]);
        if (eng) s.pairs.push_back(p);
      }
    }
    const int nT = 2 * static_cast<int>(s.pairs.size());
    s.JT.resize(static_cast<size_t>(nT) * nv);
    s.bTt.resize(nT);
    s.JTM.resize(static_cast<size_t>(nT) * nv);
    for (size_t k = 0; k < s.pairs.size(); ++k) {
      const int p = s.pairs[k];
      for (int j = 0; j < 2; ++j) {
        const int t = 2 * static_cast<int>(k) + j;
        std::copy(R.JT + (2 * p + j) * nv, R.JT + (2 * p + j + 1) * nv, &s.JT[t * nv]);
        s.bTt[t] = dot(&s.JT[t * nv], a_free_, nv) + R.bT[2 * p + j] +
                   c_.baumgarte * R.vT[2 * p + j];
      }
    }
    for (int t = 0; t < nT; ++t)
      for (int j = 0; j < nv; ++j) {
        double v = 0.0;
        for (int k = 0; k < nv; ++k) v += s.JT[t * nv + k] * Mi_[k * nv + j];
        s.JTM[t * nv + j] = v;
      }
    if (nT) {  // numpy.linalg.pinv(G_TT, rcond=1e-10)
      std::vector<double> G(static_cast<size_t>(nT) * nT);
      dense::matmul_t(s.JTM.data(), s.JT.data(), nT, nv, nT, G.data());
      dense::pinv(G.data(), nT, 1e-10, s.GTTi);
    }
    stick_rows_.push_back(std::move(s));
    return stick_rows_.back();
  }

  // _solve_modes: the mixed LCP; false when Lemke fails on the non-symmetric problem (or its
  // residual is above 1e-6); st HAND_BACK where the Python path takes its least squares.
  bool solve_modes(Status &st) {
    const Rows &R = *R_;
    const int nv = R.nv;
    engaged = touch_;
    const int nt = static_cast<int>(touch_.size());
    // C[N]: J_n, less mu s^T (J_p2 - J_p1) on the slipping pairs' rows
    CN_.resize(static_cast<size_t>(nt) * nv);
    for (int a = 0; a < nt; ++a) {
      const int r = touch_[a];
      const double *J = R.Jn + static_cast<size_t>(r) * nv;
      std::copy(J, J + nv, &CN_[a * nv]);
      if (c_.mu == 0.0 || r >= R.mp) continue;
      const int p = R.pair_of(r);
      if (stick[p]) continue;
      const double *d = R.dJp + static_cast<size_t>(R.rows[r]) * 3 * nv;
      double s[3];
      point_slip_direction(d, R.F + 9 * p + 6, R.v, nv, &slip_dir[3 * p], c_.stick_speed, s);
      for (int k = 0; k < nv; ++k)
        CN_[a * nv + k] -= c_.mu * (s[0] * d[k] + s[1] * d[nv + k] + s[2] * d[2 * nv + k]);
    }
    const StickRows &S = stick_rows();
    const int nT = 2 * static_cast<int>(S.pairs.size());
    bool symmetric = c_.mu == 0.0;
    if (!symmetric) {
      symmetric = true;
      for (char s : stick) symmetric = symmetric && s;
    }
    // G_NN = J_n[N] M^-1 C[N]^T
    Ml_.assign(static_cast<size_t>(nt) * nt, 0.0);
    for (int a = 0; a < nt; ++a)
      for (int b = 0; b < nt; ++b) Ml_[a * nt + b] = dot(&JnM_[a * nv], &CN_[b * nv], nv);
    ql_ = bN_;
    GTN_.assign(static_cast<size_t>(nT) * nt, 0.0);
    if (nT) {
      std::vector<double> GNT(static_cast<size_t>(nt) * nT), GNTi(static_cast<size_t>(nt) * nT);
      for (int a = 0; a < nt; ++a)
        for (int t = 0; t < nT; ++t) GNT[a * nT + t] = dot(&JnM_[a * nv], &S.JT[t * nv], nv);
      for (int t = 0; t < nT; ++t)
        for (int b = 0; b < nt; ++b) GTN_[t * nt + b] = dot(&S.JTM[t * nv], &CN_[b * nv], nv);
      for (int a = 0; a < nt; ++a)
        for (int t = 0; t < nT; ++t) {
          double v = 0.0;
          for (int u = 0; u < nT; ++u) v += GNT[a * nT + u] * S.GTTi[u * nT + t];
          GNTi[a * nT + t] = v;
        }
      dense::matmul_sub(GNTi.data(), GTN_.data(), nt, nT, nt, Ml_.data());
      dense::matmul_sub(GNTi.data(), S.bTt.data(), nt, nT, 1, ql_.data());
    }
    z_.assign(nt, 0.0);
    if (symmetric) {  // _psd_lcp: Lemke if it solves to RESIDUAL_TOL, else least squares
      if (!lcp::lemke_solved(Ml_.data(), ql_.data(), nt, c_.residual_tol, z_.data(), work_)) {
        st = HAND_BACK;
        return false;
      }
    } else if (!lcp::lemke(Ml_.data(), ql_.data(), nt, lcp::MAX_PIVOTS, lcp::PIVOT_TOL, z_.data(),
                           work_) ||
               lcp::residual(Ml_.data(), ql_.data(), nt, z_.data()) > 1e-6) {
      return false;
    }
    for (int a = 0; a < nt; ++a)
      if (!std::isfinite(z_[a])) {  // (numpy's max would be NaN: the Python's own branch)
        st = HAND_BACK;
        return false;
      }
    double zmax = 0.0;
    for (int a = 0; a < nt; ++a) zmax = std::max(zmax, std::abs(z_[a]));
    const double scale = 1e-12 * (1.0 + zmax);
    engaged.clear();
    for (int a = 0; a < nt; ++a)
      if (z_[a] > scale) engaged.push_back(touch_[a]);
    // lam_T = -G_TT^+ (G_TN z + b_T)
    lamT_.assign(nT, 0.0);
    if (nT) {
      std::vector<double> g(nT);
      for (int t = 0; t < nT; ++t) g[t] = dot(&GTN_[t * nt], z_.data(), nt) + S.bTt[t];
      for (int t = 0; t < nT; ++t) lamT_[t] = -dot(&S.GTTi[t * nT], g.data(), nT);
    }
    return true;
  }

  // _cone_check: sticking pairs whose tangential force leaves the cone (moved_), with their
  // slip direction -f / |f| (moved_dir_).
  void cone_check() {
    moved_.clear();
    moved_dir_.clear();
    if (c_.mu == 0.0) return;
    const Rows &R = *R_;
    const int nT = static_cast<int>(lamT_.size());
    int k_t = 0;
    for (int p = 0; p < R.np; ++p) {
      double fn = 0.0;
      bool had_rows = false;
      for (size_t a = 0; a < touch_.size(); ++a) {
        const int r = touch_[a];
        if (r >= R.first[p] && r < R.first[p] + R.K[p]) {
          fn += z_[a];
          had_rows = true;
        }
      }
      if (!stick[p] || !had_rows) continue;
      if (k_t + 2 > nT) continue;
      const double *lt = &lamT_[k_t];
      k_t += 2;
      const double nt = norm2(lt);
      if (nt > c_.mu * fn + c_.force_band) {
        const double *T = R.F + 9 * p;  // rows t1, t2
        moved_.push_back(p);
        for (int i = 0; i < 3; ++i) moved_dir_.push_back(-(T[i] * lt[0] + T[3 + i] * lt[1]) / nt);
      }
    }
  }

  // _consistent_directions: a slip onset from rest turned towards its tangential acceleration.
  bool consistent_directions(Status &st) {
    if (c_.mu == 0.0) return true;
    const Rows &R = *R_;
    const int nv = R.nv;
    std::vector<int> starting;
    for (int p = 0; p < R.np; ++p)
      if (!stick[p] && norm3(R.vt + 3 * p) <= c_.stick_speed) starting.push_back(p);
    if (starting.empty() || engaged.empty()) return true;
    a_.resize(nv);
    for (int it = 0; it < 8; ++it) {
      double cond = 0.0;
      if (engaged.empty()) {
        std::copy(a_free_, a_free_ + nv, a_.begin());
      } else if (!(*evaluate_)(engaged, stick, slip_dir, a_.data(), &cond, lam_)) {
        st = HAND_BACK;
        return false;
      }
      bool moved = false;
      for (int p : starting) {
        double j[2], at[3];
        for (int t = 0; t < 2; ++t)
          j[t] = dot(R.JT + (2 * p + t) * nv, a_.data(), nv) + R.bT[2 * p + t];
        const double *T = R.F + 9 * p;
        for (int i = 0; i < 3; ++i) at[i] = T[i] * j[0] + T[3 + i] * j[1];
        const double na = norm3(at);
        double *sd = &slip_dir[3 * p];
        if (na <= 1e-9 || at[0] * sd[0] + at[1] * sd[1] + at[2] * sd[2] > 0.0) continue;
        double s[3];
        for (int i = 0; i < 3; ++i) s[i] = sd[i] + at[i] / na;
        const double ns = norm3(s);
        for (int i = 0; i < 3; ++i) sd[i] = ns > 1e-9 ? s[i] / ns : at[i] / na;
        moved = true;
      }
      if (!moved) return true;
      solve_modes(st);  // (its answer is not checked: the Python ignores it too)
      if (st != DONE) return false;
    }
    return true;
  }

  // _coulomb_residual_directions: a pair slipping against its residual slide slips along it.
  bool coulomb_residual_directions() {
    if (c_.mu == 0.0) return false;
    const Rows &R = *R_;
    bool turned = false;
    for (int p = 0; p < R.np; ++p) {
      if (stick[p]) continue;
      const double *vt = R.vt + 3 * p;
      double *sd = &slip_dir[3 * p];
      const double speed = norm3(vt);
      double w[3];
      for (int i = 0; i < 3; ++i) w[i] = vt[i] + c_.stick_speed * sd[i];
      const double g = (vt[0] * w[0] + vt[1] * w[1] + vt[2] * w[2]) / std::max(norm3(w), 1e-300) +
                       c_.stick_band;
      if (speed > 0.0 && g < 0.5 * c_.stick_band) {
        for (int i = 0; i < 3; ++i) sd[i] = vt[i] / speed;
        turned = true;
      }
    }
    return turned;
  }

  const Rows *R_ = nullptr;
  Consts c_;
  const double *a_free_ = nullptr, *Mi_ = nullptr;
  const Evaluate *evaluate_ = nullptr;
  std::vector<int> touch_, moved_;
  std::vector<double> bN_, JnM_, CN_, Ml_, ql_, GTN_, z_, lamT_, a_, lam_, moved_dir_;
  std::vector<StickRows> stick_rows_;
  lcp::Work work_;
};

}  // namespace modes
}  // namespace packbot_native
