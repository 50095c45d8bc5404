// Lemke's complementary pivoting for the contact-normal mode's small LCPs, and the residual of
// a solution: for ContactRhs::project_round and ContactRhs::impact, and for the Python side
// (packbot._native.lemke and lcp_residual).
//
// LCP(M, q): find z >= 0 with w = M z + q >= 0 and z . w = 0. Row-major arrays throughout.

#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace packbot_native {
namespace lcp {

// The pivot limit and tolerance of packbot's small LCPs (normal_modes.LEMKE_PIVOTS, LEMKE_TOL).
constexpr int MAX_PIVOTS = 200;
constexpr double PIVOT_TOL = 1e-12;

// Lemke's pivots on LCP(M, q) (n x n) into z (n). False on ray termination or the pivot limit
// (z then zeros). T, z2, basis, Tr and ratios: work arrays (resized here).
struct Work {
  std::vector<double> T, Tr, ratios, z2;
  std::vector<int> basis;
};

inline bool lemke(const double *M, const double *q, int n, int max_iter, double tol, double *z,
                  Work &wk) {
  std::fill(z, z + n, 0.0);
  if (n == 0) return true;
  bool any_negative = false;
  for (int i = 0; i < n; ++i)
    if (!(q[i] >= 0.0)) any_negative = true;
  if (!any_negative) return true;
  const int w = 2 * n + 2;
  wk.T.assign(static_cast<size_t>(n) * w, 0.0);
  double *T = wk.T.data();
  for (int i = 0; i < n; ++i) {
    T[i * w + i] = 1.0;
    for (int j = 0; j < n; ++j) T[i * w + n + j] = -M[i * n + j];
    T[i * w + 2 * n] = -1.0;
    T[i * w + 2 * n + 1] = q[i];
  }
  wk.basis.resize(n);
  for (int i = 0; i < n; ++i) wk.basis[i] = i;
  int r = 0;
  for (int i = 1; i < n; ++i)
    if (q[i] < q[r]) r = i;
  int entering = 2 * n;
  wk.Tr.resize(w);
  wk.ratios.resize(n);
  double *Tr = wk.Tr.data();
  for (int it = 0; it < max_iter; ++it) {
    const double piv = T[r * w + entering];
    for (int j = 0; j < w; ++j) Tr[j] = T[r * w + j] / piv;
    for (int i = 0; i < n; ++i) {
      const double c = i == r ? 0.0 : T[i * w + entering];
      if (i == r) {
        for (int j = 0; j < w; ++j) T[i * w + j] = Tr[j] - c * Tr[j];
      } else {
        for (int j = 0; j < w; ++j) T[i * w + j] = T[i * w + j] - c * Tr[j];
      }
    }
    const int leaving = wk.basis[r];
    wk.basis[r] = entering;
    if (leaving == 2 * n) {
      wk.z2.assign(2 * n + 1, 0.0);
      for (int i = 0; i < n; ++i) wk.z2[wk.basis[i]] = T[i * w + w - 1];
      for (int i = 0; i < n; ++i) z[i] = std::max(wk.z2[n + i], 0.0);
      return true;
    }
    entering = leaving < n ? leaving + n : leaving - n;
    bool blocked = true;
    for (int i = 0; i < n; ++i) {
      if (T[i * w + entering] > tol) {
        wk.ratios[i] = T[i * w + w - 1] / T[i * w + entering];
        blocked = false;
      } else {
        wk.ratios[i] = std::numeric_limits<double>::infinity();
      }
    }
    if (blocked) {
      std::fill(z, z + n, 0.0);
      return false;
    }
    double rmin = wk.ratios[0];
    for (int i = 1; i < n; ++i) rmin = std::min(rmin, wk.ratios[i]);
    const double bound = rmin + 1e-12 * (1.0 + std::abs(rmin));
    int first = -1;
    r = -1;
    for (int i = 0; i < n; ++i) {
      if (wk.ratios[i] <= bound) {
        if (first < 0) first = i;
        if (wk.basis[i] == 2 * n && r < 0) r = i;
      }
    }
    if (r < 0) r = first;
  }
  std::fill(z, z + n, 0.0);
  return false;
}

// The residual of an LCP solution relative to the problem's scale (lcp.lcp_residual's
// definition): max(-min z, -min w, |z . w| / s, 0) / s, s = 1 + |q|_inf + |M z|_inf.
inline double residual(const double *M, const double *q, int n, const double *z) {
  if (n == 0) return 0.0;
  double qmax = 0.0, gzmax = 0.0, zw = 0.0;
  double zmin = std::numeric_limits<double>::infinity(), wmin = zmin;
  for (int i = 0; i < n; ++i) {
    double s = 0.0;
    for (int j = 0; j < n; ++j) s += M[i * n + j] * z[j];
    const double w = s + q[i];
    qmax = std::max(qmax, std::abs(q[i]));
    gzmax = std::max(gzmax, std::abs(s));
    zmin = std::min(zmin, z[i]);
    wmin = std::min(wmin, w);
    zw += z[i] * w;
  }
  const double scale = 1.0 + qmax + gzmax;
  const double res = std::max(std::max(-zmin, -wmin), std::max(std::abs(zw) / scale, 0.0));
  return res / scale;
}

// The symmetric problems' first choice (normal_modes._psd_lcp): Lemke's pivots (zeros when q
// >= 0), true when they solve LCP(M, q) to `tol` (residual), false where the caller takes its
// least squares instead.
inline bool lemke_solved(const double *M, const double *q, int n, double tol, double *z,
                         Work &wk) {
  return lemke(M, q, n, MAX_PIVOTS, PIVOT_TOL, z, wk) && residual(M, q, n, z) <= tol;
}

}  // namespace lcp
}  // namespace packbot_native
