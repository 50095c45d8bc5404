// ContactRhs: the time-stepping window (packbot.contact.timestep.MoreauJeanStepper): one step
// that keeps its contact set (window_step, window_core: the conic problem on conic.hpp) and the
// window's run of such steps with its sweeps (window_run).

#include "contact_rhs.hpp"
#include "conic.hpp"
#include "np_sum.hpp"
#include "sweep_api.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

using packbot_native::np_sum;

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
// 4: M^-1 has no Cholesky factor; 5: the impulses drive a joint past a stop that is not in the
// set (v1 and q1 written: the caller adds the stops within h |v1| and solves again).
nb::tuple ContactRhs::window_step(F1 y, double h, I1 swept, F1 dist, double sweep_margin, F1 reach,
                                  double active_gap, F1 upper, F1 lower, double limit_gap,
                                  double mu, double restitution, double zeno, double touch_gap,
                                  I1 boxes, F1 bound, F1 guess, double rho0, double tol,
                                  int max_iterations, double ok, Out1 out_vf, Out1 out_v1,
                                  Out1 out_q1, bool checked) {
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

void ContactRhs::check_window() const {
  if (applied_.size() != static_cast<size_t>(nv_) || !conditions_set_ || lock_mode_ >= 0 ||
      keys_.size() != static_cast<size_t>(np_))
    throw std::invalid_argument("window_step: torques, layout, keys and conditions first");
}

// window_step on raw arrays: v_f, v1, q1 into ovf, ov1, oq1 (nv each), the impulses into x.
ContactRhs::WindowOut ContactRhs::window_core(const double *y, double h, const int64_t *swept,
                                              const double *dist, size_t nsw, double sweep_margin,
                                              const WindowArgs &a, const double *bound,
                                              const double *guess, size_t nguess, double rho0,
                                              double *ovf, double *ov1, double *oq1,
                                              std::vector<double> &x) {
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
  aba_world(q_, v_, tau);
  const double hh = 0.5 * h;
  for (int i = 0; i < nv; ++i) {
    qm[i] = q_[i] + hh * v_[i];
    vm[i] = v_[i] + hh * data_.ddq[i];
  }
  for (int i = 0; i < nv; ++i) tau[i] = applied_[i] + (-viscous_[i] * vm[i] - coulomb_dir_[i]);
  aba_world(qm, vm, tau);
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
        if (!has_limit_row(j, side)) return none(1);
        ++near;
      }
    }
    if (near != ml_) return none(1);
  }
  // M^-1 and the rows at (q, v)
  minverse(q_);
  minv_ = data_.Minv;
  for (int i = 1; i < nv; ++i)
    for (int c = 0; c < i; ++c) minv_(i, c) = minv_(c, i);
  if (nb_ > 0) jacobians_time_variation();
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
  // a joint past a stop that is not one of the set's rows (driven there inside the step, by
  // the contact impulses: its reach at the start, h max(|v|, |v_f|), did not take it there)
  if (a.upper != nullptr && a.lower != nullptr &&
      past_a_stop_not_in_rows(oq1, a.upper, a.lower, static_cast<size_t>(nv)))
    return none(5);
  const double kin0 = kinetic(q_, yv), pot0 = potential(q_);
  const double kin1 = kinetic(q1, ov1), pot1 = potential(q1);
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
nb::dict ContactRhs::window_run(nb::capsule api, Out1 y, double t, double t_end, double t_commit,
                                double h_window, double until, int quiet, int quiet_steps,
                                bool last_valid, I1 last_sig, I1 swept, F1 dist,
                                double sweep_margin, int64_t best, double best_d, F1 reach,
                                double active_gap, F1 upper, F1 lower, double limit_gap, double mu,
                                double restitution, double zeno, double touch_gap, I1 boxes,
                                F1 coul, F1 guess, double rho0, double tol, int max_iterations,
                                double ok, F1 applied, bool has_e, double e_last, double step_angle,
                                double sweep_slack, double project_depth, double impulse_band,
                                double min_d, int max_steps) {
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
  std::vector<double> impulses;                // (and their impulses, one row of x each)
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
    impulses.insert(impulses.end(), xn.begin(), xn.end());
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
  // each kept step's impulses (steps, 3 m + boxes), on the run's rows (its set does not change)
  const size_t kept = static_cast<size_t>(steps);
  out["impulses"] = owned_mat(impulses, kept, kept ? impulses.size() / kept : 0);
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
