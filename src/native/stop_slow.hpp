// The restart's stop of the slow slides, ported from packbot/contact/normal_steps.py
// (RestartSteps.stop_slow and _stop): the least (M-weighted) velocity change that zeroes the
// tangential velocity at the patch centre of the touching pairs sliding slower than the stick
// speed and lets no touching row approach (the tangential rows as equalities, the touching
// rows an LCP on their Schur complement), made only where it lifts no resting row of a pair
// it does not stop, adds no energy and needs no joint speed above the capture speed. The
// arithmetic follows the Python step by step (its products summed in index order: the same
// to rounding). Row-major arrays throughout.

#pragma once

#include "lcp.hpp"
#include "rows.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace packbot_native {
namespace stop_slow {

// The law's constants (packbot.contact.normal_tolerances, normal_steps.DEPENDENT_ROW).
struct Consts {
  double touch_gap = 0.0, speed_band = 0.0, stick_speed = 0.0, capture_speed = 0.0,
         residual_tol = 0.0, dependent_row = 0.0;
};

// What stop_slow did: KEPT the velocity (out untouched), STOPPED (out = v + dv), HAND_BACK: the
// caller's own step (a least-squares fallback of the LCP).
enum Status : int { KEPT = 0, STOPPED = 1, HAND_BACK = 2 };

class StopSlow {
 public:
  // RestartSteps.stop_slow on the rows at (q, v) (mu > 0, pairs in contact: the caller's).
  Status run(const Rows &R, const Consts &c, const double *v, const double *Mi, double *out) {
    const int nv = R.nv;
    std::vector<char> resting(R.m);
    for (int r = 0; r < R.m; ++r) resting[r] = R.gap[r] <= c.touch_gap && R.vn[r] <= c.speed_band;
    std::vector<int> slow;
    for (int p = 0; p < R.np; ++p) {
      bool touching = false;
      for (int r = R.first[p]; r < R.first[p] + R.K[p]; ++r)
        touching = touching || R.gap[r] <= c.touch_gap;
      if (touching && dense::norm3(R.vt + 3 * p) <= c.stick_speed) slow.push_back(p);
    }
    std::vector<double> v1(nv);
    while (!slow.empty()) {
      const Status st = stop(R, c, slow, v, Mi);
      if (st == HAND_BACK) return HAND_BACK;
      if (st == KEPT) return KEPT;
      for (int i = 0; i < nv; ++i) v1[i] = v[i] + dv_[i];
      std::vector<int> lifting;
      for (int r = 0; r < R.m; ++r)
        if (resting[r] && dense::dot(R.Jn + static_cast<size_t>(r) * nv, v1.data(), nv) >
                              c.speed_band)
          lifting.push_back(R.pair_of(r));
      if (lifting.empty()) {
        std::copy(v1.begin(), v1.end(), out);
        return STOPPED;
      }
      bool stopped_lifts = false;
      for (int p : lifting)
        stopped_lifts = stopped_lifts || std::find(slow.begin(), slow.end(), p) != slow.end();
      if (!stopped_lifts) return KEPT;  // a row of a pair not stopped (or a limit) lifts
      std::vector<int> rest;
      for (int p : slow)
        if (std::find(lifting.begin(), lifting.end(), p) == lifting.end()) rest.push_back(p);
      slow.swap(rest);
    }
    return KEPT;
  }

 private:
  // _stop: the change dv_ stopping the pairs `slow` (STOPPED), KEPT where it is not made.
  Status stop(const Rows &R, const Consts &c, const std::vector<int> &slow, const double *v,
              const double *Mi) {
    const int nv = R.nv;
    const int nE = 2 * static_cast<int>(slow.size());
    E_.resize(static_cast<size_t>(nE) * nv);
    bE_.resize(nE);
    for (size_t k = 0; k < slow.size(); ++k)
      for (int j = 0; j < 2; ++j) {
        const int p = slow[k], t = 2 * static_cast<int>(k) + j;
        std::copy(R.JT + (2 * p + j) * nv, R.JT + (2 * p + j + 1) * nv, &E_[t * nv]);
        bE_[t] = -R.vT[2 * p + j];
      }
    touch_.clear();
    for (int r = 0; r < R.m; ++r)
      if (R.gap[r] <= c.touch_gap) touch_.push_back(r);
    const int nt = static_cast<int>(touch_.size());
    In_.resize(static_cast<size_t>(nt) * nv);
    for (int a = 0; a < nt; ++a)
      std::copy(R.Jn + static_cast<size_t>(touch_[a]) * nv,
                R.Jn + static_cast<size_t>(touch_[a] + 1) * nv, &In_[a * nv]);
    // E M^-1, G_EE^+ = pinv(E M^-1 E^T), G_EI = E M^-1 I^T
    EM_.resize(static_cast<size_t>(nE) * nv);
    dense::matmul(E_.data(), Mi, nE, nv, nv, EM_.data());
    std::vector<double> GEE(static_cast<size_t>(nE) * nE);
    dense::matmul_t(EM_.data(), E_.data(), nE, nv, nE, GEE.data());
    dense::pinv(GEE.data(), nE, 1e-10, GEEp_);
    GEI_.resize(static_cast<size_t>(nE) * nt);
    dense::matmul_t(EM_.data(), In_.data(), nE, nv, nt, GEI_.data());
    // y0 = G_EE^+ b_E; S = I M^-1 I^T - G_EI^T G_EE^+ G_EI; w0 = v_n[touch] + G_EI^T y0
    y0_.resize(nE);
    for (int t = 0; t < nE; ++t) y0_[t] = dense::dot(&GEEp_[t * nE], bE_.data(), nE);
    std::vector<double> IM(static_cast<size_t>(nt) * nv), S(static_cast<size_t>(nt) * nt);
    dense::matmul(In_.data(), Mi, nt, nv, nv, IM.data());
    dense::matmul_t(IM.data(), In_.data(), nt, nv, nt, S.data());
    std::vector<double> GIP(static_cast<size_t>(nt) * nE);  // G_EI^T G_EE^+
    for (int a = 0; a < nt; ++a)
      for (int t = 0; t < nE; ++t) {
        double s = 0.0;
        for (int u = 0; u < nE; ++u) s += GEI_[u * nt + a] * GEEp_[u * nE + t];
        GIP[a * nE + t] = s;
      }
    dense::matmul_sub(GIP.data(), GEI_.data(), nt, nE, nt, S.data());
    std::vector<double> w0(nt);
    for (int a = 0; a < nt; ++a) {
      double s = 0.0;
      for (int t = 0; t < nE; ++t) s += GEI_[t * nt + a] * y0_[t];
      w0[a] = R.vn[touch_[a]] + s;
    }
    // rows in the span of the tangential rows (a zero Schur complement): out of the LCP
    double scale = 0.0;
    for (int a = 0; a < nt; ++a) scale = std::max(scale, std::abs(S[a * nt + a]));
    std::vector<int> keep;
    double wfix = std::numeric_limits<double>::infinity();
    bool any_fixed = false;
    for (int a = 0; a < nt; ++a) {
      if (S[a * nt + a] <= c.dependent_row * scale) {
        any_fixed = true;
        wfix = std::min(wfix, w0[a]);
      } else {
        keep.push_back(a);
      }
    }
    if (any_fixed && wfix < -c.residual_tol) return KEPT;
    const int nk = static_cast<int>(keep.size());
    std::vector<double> Sk(static_cast<size_t>(nk) * nk), wk(nk), lk(nk, 0.0);
    for (int i = 0; i < nk; ++i) {
      wk[i] = w0[keep[i]];
      for (int j = 0; j < nk; ++j) Sk[i * nk + j] = S[keep[i] * nt + keep[j]];
    }
    // _psd_lcp: Lemke when it solves to RESIDUAL_TOL (else the caller's least squares)
    if (!lcp::lemke_solved(Sk.data(), wk.data(), nk, c.residual_tol, lk.data(), work_))
      return HAND_BACK;
    std::vector<double> lam(nt, 0.0);
    for (int i = 0; i < nk; ++i) lam[keep[i]] = lk[i];
    // y = y0 - G_EE^+ (G_EI lam); the impulse E^T y + I^T lam; dv = M^-1 imp
    std::vector<double> g(nE), y(nE), imp(nv, 0.0);
    for (int t = 0; t < nE; ++t) g[t] = dense::dot(&GEI_[t * nt], lam.data(), nt);
    for (int t = 0; t < nE; ++t) y[t] = y0_[t] - dense::dot(&GEEp_[t * nE], g.data(), nE);
    for (int i = 0; i < nv; ++i) {
      double a = 0.0, b = 0.0;
      for (int t = 0; t < nE; ++t) a += E_[t * nv + i] * y[t];
      for (int s = 0; s < nt; ++s) b += In_[s * nv + i] * lam[s];
      imp[i] = a + b;
    }
    dv_.resize(nv);
    for (int i = 0; i < nv; ++i) dv_[i] = dense::dot(Mi + static_cast<size_t>(i) * nv, imp.data(), nv);
    if (dense::dot(imp.data(), v, nv) + 0.5 * dense::dot(imp.data(), dv_.data(), nv) > 0.0)
      return KEPT;  // an inexact projection adding energy
    double dmax = 0.0;
    for (int i = 0; i < nv; ++i) dmax = std::max(dmax, std::abs(dv_[i]));
    if (dmax > c.capture_speed) return KEPT;  // the slide is driven, not a residual
    return STOPPED;
  }

  std::vector<int> touch_;
  std::vector<double> E_, bE_, In_, EM_, GEEp_, GEI_, y0_, dv_;
  lcp::Work work_;
};

}  // namespace stop_slow
}  // namespace packbot_native
