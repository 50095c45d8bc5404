// A time-stepping window step's complementarity problem and its low-rank ADMM (the method:
// packbot/contact/conic.py's docstring), for ContactRhs::window_step and for the window's
// Python steps (packbot._native.solve_conic and conic_residual).
//
// Rows come in blocks (t1, t2, n) per contact row, then one unit row per joint box; G = A A^T
// with A = J C, C the lower Cholesky factor of M^-1. Row-major arrays throughout.

#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace packbot_native {
namespace conic {

constexpr int CHECK_EVERY = 10;
constexpr double PROX = 1e-6;
constexpr double RHO_POWER = 0.2;
constexpr double RATIO = 10.0;
constexpr double RHO_MIN = 1e-9;
constexpr double RHO_MAX = 1e3;
constexpr int POWER_ITERATIONS = 20;
constexpr double RELAX = 1.5;
constexpr int STALL_CHECKS = 10;
constexpr double STALL_GAIN = 0.99;
constexpr double STALL_OK = 2.0;

// Lower Cholesky factor of rho I + S (r x r) into L (conic._factor).
inline void factor(const std::vector<double> &S, int r, double rho, std::vector<double> &L) {
  L.assign(static_cast<size_t>(r) * r, 0.0);
  for (int i = 0; i < r; ++i)
    for (int j = 0; j <= i; ++j) {
      double s = S[i * r + j] + (i == j ? rho : 0.0);
      for (int k = 0; k < j; ++k) s -= L[i * r + k] * L[j * r + k];
      if (i == j)
        L[i * r + i] = std::sqrt(std::max(s, 1e-300));
      else
        L[i * r + j] = s / L[j * r + j];
    }
}

// w = A^T b (A m x r).
inline void transposed_apply(const double *A, int m, int r, const double *b, double *w) {
  for (int k = 0; k < r; ++k) {
    double s = 0.0;
    for (int i = 0; i < m; ++i) s += A[i * r + k] * b[i];
    w[k] = s;
  }
}

// out = (A A^T + rho I)^-1 b by the Woodbury identity (L: rho I + A^T A); w: r doubles.
inline void inverse_apply(const double *A, int m, int r, const std::vector<double> &L, double rho,
                          const double *b, double *out, double *w) {
  transposed_apply(A, m, r, b, w);
  for (int i = 0; i < r; ++i) {
    double s = w[i];
    for (int k = 0; k < i; ++k) s -= L[i * r + k] * w[k];
    w[i] = s / L[i * r + i];
  }
  for (int i = r - 1; i >= 0; --i) {
    double s = w[i];
    for (int k = i + 1; k < r; ++k) s -= L[k * r + i] * w[k];
    w[i] = s / L[i * r + i];
  }
  for (int i = 0; i < m; ++i) {
    double s = b[i];
    for (int k = 0; k < r; ++k) s -= A[i * r + k] * w[k];
    out[i] = s / rho;
  }
}

// out = A A^T x + g.
inline void velocity(const double *A, int m, int r, const double *x, const double *g, double *out,
                     double *w) {
  transposed_apply(A, m, r, x, w);
  for (int i = 0; i < m; ++i) {
    double s = g[i];
    for (int k = 0; k < r; ++k) s += A[i * r + k] * w[k];
    out[i] = s;
  }
}

// x onto the cones (blocks t1, t2, n of friction mus[k]), then the boxes |x| <= bound.
inline void project(double *x, const std::vector<double> &mus, const std::vector<double> &bound) {
  const int K = static_cast<int>(mus.size());
  for (int k = 0; k < K; ++k) {
    const double mu = mus[k];
    const double a = x[3 * k], b = x[3 * k + 1], n = x[3 * k + 2];
    const double t = std::sqrt(a * a + b * b);
    if (n >= 0.0 && t <= mu * n) continue;
    if (mu * t <= -n) {
      x[3 * k] = 0.0;
      x[3 * k + 1] = 0.0;
      x[3 * k + 2] = 0.0;
      continue;
    }
    const double al = (mu * t + n) / (mu * mu + 1.0);
    const double f = mu * al / t;
    x[3 * k] = a * f;
    x[3 * k + 1] = b * f;
    x[3 * k + 2] = al;
  }
  for (size_t j = 0; j < bound.size(); ++j) {
    const size_t i = 3 * static_cast<size_t>(K) + j;
    const double bd = bound[j];
    if (x[i] > bd)
      x[i] = bd;
    else if (x[i] < -bd)
      x[i] = -bd;
  }
}

// The true scaled residual of x (conic.conic_residual).
inline double residual(const double *A, int m, int r, const double *g, const double *x,
                       const std::vector<double> &mus, const std::vector<double> &bound) {
  const int K = static_cast<int>(mus.size());
  const int c = 3 * K;
  for (int i = 0; i < m; ++i)
    if (!std::isfinite(x[i])) return std::numeric_limits<double>::infinity();
  std::vector<double> wc(r, 0.0), wb(r, 0.0);
  for (int k = 0; k < r; ++k) {
    double s = 0.0;
    for (int i = 0; i < c; ++i) s += A[i * r + k] * x[i];
    wc[k] = s;
    s = 0.0;
    for (int i = c; i < m; ++i) s += A[i * r + k] * x[i];
    wb[k] = s;
  }
  double res = 0.0;
  if (K) {
    double g3max = 0.0, G3xmax = 0.0;
    std::vector<double> V(c);
    for (int i = 0; i < c; ++i) {
      double sc = 0.0, sb = 0.0;
      for (int k = 0; k < r; ++k) {
        sc += A[i * r + k] * wc[k];
        sb += A[i * r + k] * wb[k];
      }
      const double gc = g[i] + sb;
      V[i] = sc + gc;
      g3max = std::max(g3max, std::abs(gc));
      G3xmax = std::max(G3xmax, std::abs(sc));
    }
    const double scale = 1.0 + g3max + G3xmax;
    double primal = -std::numeric_limits<double>::infinity(), dual = 0.0, compl_ = 0.0;
    bool anymu = false;
    for (int k = 0; k < K; ++k)
      if (mus[k] != 0.0) anymu = true;
    for (int k = 0; k < K; ++k) {
      const double mu = mus[k];
      const double x1 = x[3 * k], x2 = x[3 * k + 1], xn = x[3 * k + 2];
      const double v1 = V[3 * k], v2 = V[3 * k + 1], vn = V[3 * k + 2];
      const double xt = std::sqrt(x1 * x1 + x2 * x2);
      const double vt = std::sqrt(v1 * v1 + v2 * v2);
      const double vs = vn + mu * vt;
      primal = std::max(primal, std::max(xt - mu * xn, -xn));
      dual = std::max(dual, -vs);
      if (anymu) dual = std::max(dual, mu * vt - vs);
      compl_ += x1 * v1 + x2 * v2 + xn * vs;
    }
    res = std::max(std::max(primal, dual), std::max(std::abs(compl_) / scale, 0.0)) / scale;
  }
  const int B = m - c;
  if (B) {
    double gmax = 0.0, Gxmax = 0.0, worst = 0.0;
    for (int j = 0; j < B; ++j) {
      const int i = c + j;
      double sc = 0.0, sb = 0.0;
      for (int k = 0; k < r; ++k) {
        sc += A[i * r + k] * wc[k];
        sb += A[i * r + k] * wb[k];
      }
      const double gb = g[i] + sc;
      const double u = sb + gb;
      gmax = std::max(gmax, std::abs(gb));
      Gxmax = std::max(Gxmax, std::abs(sb));
      const double bd = bound[j];
      double viol;
      if (x[i] >= bd * (1.0 - 1e-9))
        viol = std::max(u, 0.0);
      else if (x[i] <= -bd * (1.0 - 1e-9))
        viol = std::max(-u, 0.0);
      else
        viol = std::abs(u);
      worst = std::max(std::max(worst, viol), std::abs(x[i]) - bd);
    }
    res = std::max(res, worst / (1.0 + gmax + Gxmax));
  }
  return res;
}

struct Solution {
  double residual = 0.0;
  int iterations = 0;
  double rho = 0.0;
};

// conic.solve_conic: x (m) from the guess in x; returns the residual, iterations and last rho.
inline Solution solve(const double *A, int m, int r, const double *g, const std::vector<double> &mus,
                      const std::vector<double> &bound, double *x_out, double tol,
                      int max_iterations, double rho0) {
  const int K = static_cast<int>(mus.size());
  std::vector<double> z(x_out, x_out + m);
  project(z.data(), mus, bound);
  std::vector<double> best = z;
  double best_res = residual(A, m, r, g, z.data(), mus, bound);
  if (best_res <= tol && rho0 > 0.0) {
    std::copy(best.begin(), best.end(), x_out);
    return {best_res, 0, rho0};
  }
  std::vector<double> AtA(static_cast<size_t>(r) * r, 0.0);
  for (int a = 0; a < r; ++a)
    for (int b = 0; b <= a; ++b) {
      double s = 0.0;
      for (int i = 0; i < m; ++i) s += A[i * r + a] * A[i * r + b];
      AtA[a * r + b] = s;
      AtA[b * r + a] = s;
    }
  std::vector<double> w(r, 1.0), w2(r);
  double lam = 0.0;
  for (int it = 0; it < POWER_ITERATIONS; ++it) {
    for (int a = 0; a < r; ++a) {
      double s = 0.0;
      for (int b = 0; b < r; ++b) s += AtA[a * r + b] * w[b];
      w2[a] = s;
    }
    double ss = 0.0;
    for (int a = 0; a < r; ++a) ss += w2[a] * w2[a];
    lam = std::sqrt(ss);
    if (lam <= 0.0) break;
    for (int a = 0; a < r; ++a) w[a] = w2[a] / lam;
  }
  lam = std::max(lam, 1e-300);
  double rho = rho0 <= 0.0 ? PROX * std::pow(lam / PROX, RHO_POWER) : rho0;
  if (best_res <= tol) {
    std::copy(best.begin(), best.end(), x_out);
    return {best_res, 0, rho};
  }
  std::vector<double> L;
  factor(AtA, r, PROX + rho, L);
  std::vector<double> u(m), y(m), xp(m), zp(m), rhs(m), work(r);
  velocity(A, m, r, z.data(), g, u.data(), work.data());
  for (int i = 0; i < m; ++i) y[i] = -u[i];
  for (int k = 0; k < K; ++k)
    y[3 * k + 2] -= mus[k] * std::sqrt(u[3 * k] * u[3 * k] + u[3 * k + 1] * u[3 * k + 1]);
  std::vector<double> x = z;
  int it = 0;
  double stall_ref = best_res;
  int stalled = 0;
  while (it < max_iterations) {
    ++it;
    for (int i = 0; i < m; ++i) {
      xp[i] = x[i];
      zp[i] = z[i];
    }
    for (int i = 0; i < m; ++i) rhs[i] = -g[i] + rho * z[i] - y[i] + PROX * x[i];
    for (int k = 0; k < K; ++k)
      rhs[3 * k + 2] -= mus[k] * std::sqrt(y[3 * k] * y[3 * k] + y[3 * k + 1] * y[3 * k + 1]);
    inverse_apply(A, m, r, L, PROX + rho, rhs.data(), x.data(), work.data());
    for (int i = 0; i < m; ++i) {
      x[i] = RELAX * x[i] + (1.0 - RELAX) * zp[i];
      z[i] = x[i] + y[i] / rho;
    }
    project(z.data(), mus, bound);
    double prim = 0.0, dual = 0.0;
    for (int i = 0; i < m; ++i) {
      const double d = x[i] - z[i];
      y[i] += rho * d;
      prim = std::max(prim, std::abs(d));
      dual = std::max(dual, std::abs(rho * (z[i] - zp[i]) + PROX * (x[i] - xp[i])));
    }
    if (it % CHECK_EVERY == 0) {
      const double res = residual(A, m, r, g, z.data(), mus, bound);
      if (res < best_res) {
        best_res = res;
        best = z;
      }
      if (res <= tol || !std::isfinite(res)) break;
      if (best_res < STALL_GAIN * stall_ref) {
        stall_ref = best_res;
        stalled = 0;
      } else {
        ++stalled;
        if (stalled >= STALL_CHECKS && best_res <= STALL_OK * tol) break;
      }
      if ((prim > RATIO * dual || dual > RATIO * prim) && prim > 0.0 && dual > 0.0) {
        rho = std::min(std::max(rho * std::sqrt(prim / dual), RHO_MIN * lam), RHO_MAX * lam);
        factor(AtA, r, PROX + rho, L);
      }
    }
  }
  std::copy(best.begin(), best.end(), x_out);
  return {best_res, it, rho};
}

}  // namespace conic
}  // namespace packbot_native
