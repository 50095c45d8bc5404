// The small dense solves of the constrained accelerations (contact_rhs_dynamics.cpp) and of the
// joint locks' unlocked block (contact_rhs_locks.cpp), as packbot's Python path computes them.
#pragma once

#include <algorithm>
#include <cmath>

namespace packbot_native {

// Gaussian elimination with partial pivoting (closed form for 1 x 1 and 2 x 2): G (m x m,
// row-major) is overwritten; false when singular.
inline bool solve_small(int m, double *G, double *y, double *x) {
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
inline bool cramer_small(int m, const double *G, const double *r, double *x) {
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

}  // namespace packbot_native
