// ContactRhs: the integrator steps on y = (q, v) under the loaded modes and torques: one
// Dormand-Prince 5(4) attempt (packbot.ode.RK45Stepper) with Hairer's stiffness test, one
// RODAS4 attempt with its finite-difference Jacobian, the Jacobian's spectral radius.

#include "contact_rhs.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

// The first stage of a step: Z[1] = f(Z[0]) = (v, a) under the loaded modes and torques, the
// same arithmetic as accel(q, v, applied + (-viscous * v - coulomb_dir), true) (a restarted
// stepper's derivative, computed with its first native attempt); false when the Delassus
// matrix is singular (the caller then calls its right-hand side).
bool ContactRhs::first(Out2 Z) {
  const int n = 2 * nv_;
  if (Z.shape(0) != 8 || Z.shape(1) != static_cast<size_t>(n))
    throw std::invalid_argument("Z (8, 2 nv) expected");
  if (lock_mode_ >= 0) throw std::invalid_argument("first: the contact rows' call (set_locks)");
  if (applied_.size() != static_cast<size_t>(nv_))
    throw std::invalid_argument("set_torque was not called");
  return first_raw(Z.data());
}

// first on a raw z (8, 2 nv) (checked by the caller).
bool ContactRhs::first_raw(double *z) {
  end_valid_ = false;
  return stage(z, z + 2 * nv_);
}

// The arguments of an attempt (dopri, rosenbrock): Z (8, 2 nv), the others (2 nv,), and the
// torques set.
void ContactRhs::check_attempt(const Out2 &Z, const F1 &ay0, const F1 &atol, const Out1 &y1,
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
double ContactRhs::dopri(double h, Out2 Z, F1 ay0, F1 atol, double rtol, Out1 y1, Out1 ay1) {
  check_attempt(Z, ay0, atol, y1, ay1);
  return dopri_raw(h, Z.data(), ay0.data(), atol.data(), rtol, y1.data(), ay1.data());
}

// dopri on raw arrays (sizes checked by the caller): z (8, 2 nv), the others (2 nv,).
double ContactRhs::dopri_raw(double h, double *z, const double *a0, const double *at, double rtol,
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
double ContactRhs::rosenbrock(double h, Out2 Z, F1 ay0, F1 atol, double rtol, Out1 y1, Out1 ay1) {
  check_attempt(Z, ay0, atol, y1, ay1);
  if (!(h > 0.0)) throw std::invalid_argument("h: a step size > 0 expected");
  return rosenbrock_raw(h, Z.data(), ay0.data(), atol.data(), rtol, y1.data(), ay1.data());
}

// rosenbrock on raw arrays (sizes and h > 0 checked by the caller), as dopri_raw.
double ContactRhs::rosenbrock_raw(double h, double *z, const double *a0, const double *at,
                                  double rtol, double *yn, double *a1) {
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
double ContactRhs::jac_radius() {
  if (!jac_valid_) return 0.0;
  if (radius_ < 0.0) {
    Eigen::EigenSolver<Eigen::MatrixXd> es(jac_, false);
    radius_ = es.info() == Eigen::Success ? es.eigenvalues().cwiseAbs().maxCoeff()
                                          : std::numeric_limits<double>::infinity();
  }
  return radius_;
}

// df/dy at y0 (f0 = f(y0)) into jac_ by forward differences of the stage (Hairer's
// increments sqrt(eps max(1e-5, |y_c|))); the q rows exact (dq/dt = v).
bool ContactRhs::jacobian(const double *y0, const double *f0) {
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
