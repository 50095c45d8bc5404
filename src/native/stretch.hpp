// A stretch of quiet steps of the contact-normal mode in one native call.
//
// The event loop (packbot/integrator.py) takes one step at a time in Python: the step-size
// control of packbot.ode.RK45Stepper.step around the native Dormand-Prince attempt, the collision
// sweep at the step's end, the step end's screen (ContactRhs::end_check), the samples due in the
// step, the crawl rule and the limit stops' release (packbot.contact.normal_law.NormalLaw.watch
// and .after_step). Most steps find nothing to do: no event, no stale patch, no mode to change.
// ``Stretch::run`` takes those steps here, one after another, with the same arithmetic, and
// returns at the first step that has something for Python: that step (its stages, its state,
// the stepper's state after it) is handed back *pending*, and the loop goes on with it as if
// Python had taken it (its watch, then the rest). The steps are the stepper's: Dormand-Prince
// attempts, or Rosenbrock attempts where its stiffness test switches (RK45Stepper.step's
// `stiff`), a restart's derivative computed by the first stage. The stretch also ends, with
// every step it took committed, at the run's end, at a scheduled action's time, or before a
// step it cannot take (the kernel refused an attempt: a singular Delassus matrix; or the step
// size underflowed): Python then takes that step from the start.
//
// The collision sweep is packbot._native_coal's, called through its C entry point
// (sweep_api.hpp): this module does not link libcoal.
//
// A step whose only finding is a sliding pair's stale patch is re-patched here (Repatch,
// try_repatch: NormalContacts.repatch's native steps) and the stretch goes on.
//
// packbot/contact/stretch.py is the Python side; docs/performance.md, "The stretch of quiet
// steps", says what it saves.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <vector>

#include "pair_dips.hpp"
#include "sweep_api.hpp"

namespace packbot_native {

// packbot.ode's step-size control constants (the same values).
struct StepControl {
  static constexpr double SAFETY = 0.9;
  static constexpr double MIN_FACTOR = 0.2;
  static constexpr double MAX_FACTOR = 10.0;
  static constexpr double MAX_FACTOR_FIRST = 5.0;
  static constexpr double ERROR_EXPONENT = -1.0 / 5.0;
  static constexpr double STRETCH = 0.01;
  static constexpr double STIFF_RATIO = 3.0;
  static constexpr int STIFF_STEPS = 3;
  static constexpr double NONSTIFF_RATIO = 3.0;
  static constexpr double ROS_ERROR_EXPONENT = -1.0 / 4.0;
  static constexpr double ROS_MAX_FACTOR = 6.0;
};

// The continuous extension of Dormand-Prince 5(4) (packbot.ode._P): y(t0 + theta h) =
// y0 + sum_m Q_m x^m ..., Q = P8^T Z (packbot.ode.DenseSegment).
struct DenseOutput {
  static constexpr double P[7][4] = {
      {1, -8048581381.0 / 2820520608, 8663915743.0 / 2820520608,
       -12715105075.0 / 11282082432},
      {0, 0, 0, 0},
      {0, 131558114200.0 / 32700410799, -68118460800.0 / 10900136933,
       87487479700.0 / 32700410799},
      {0, -1754552775.0 / 470086768, 14199869525.0 / 1410260304, -10690763975.0 / 1880347072},
      {0, 127303824393.0 / 49829197408, -318862633887.0 / 49829197408,
       701980252875.0 / 199316789632},
      {0, -282668133.0 / 205662961, 2019193451.0 / 616988883, -1453857185.0 / 822651844},
      {0, 40617522.0 / 29380423, -110615467.0 / 29380423, 69997945.0 / 29380423}};

  // The interpolant's coefficients of the first m components into Q (5 rows of m):
  // y(theta) = Q0 + h (Q1 theta + Q2 theta^2 + Q3 theta^3 + Q4 theta^4), packbot.ode's
  // DenseSegment._coefficients (HermiteSegment's with hermite).
  static void coefficients(const double *z, double h, int n, int m, bool hermite, double *Q) {
    for (int c = 0; c < m; ++c) {
      Q[c] = z[c];
      if (hermite) {
        const double y0 = z[c], f0 = z[n + c], f1 = z[7 * n + c];
        const double dy = (z[2 * n + c] - y0) / h;
        Q[m + c] = f0;
        Q[2 * m + c] = 3.0 * dy - 2.0 * f0 - f1;
        Q[3 * m + c] = f0 + f1 - 2.0 * dy;
        Q[4 * m + c] = 0.0;
        continue;
      }
      for (int k = 0; k < 4; ++k) {
        double acc = 0.0;
        for (int j = 0; j < 7; ++j) acc += P[j][k] * z[(1 + j) * n + c];
        Q[(k + 1) * m + c] = acc;
      }
    }
  }

  // y(t) into out (n): the step [t0, t1] of size h with stages z (8, n), y1 its end; a
  // Rosenbrock step (hermite) by the cubic Hermite interpolant on y0 = z[0], f0 = z[1],
  // y1 = z[2], f1 = z[7] (packbot.ode.HermiteSegment).
  static void at(double t, double t0, double t1, double h, const double *z, const double *y1,
                 int n, bool hermite, double *out) {
    if (t == t1) {
      std::copy(y1, y1 + n, out);
      return;
    }
    if (t == t0) {
      std::copy(z, z + n, out);
      return;
    }
    const double th = (t - t0) / h;
    const double x = h * th, x2 = x * th, x3 = x2 * th;
    const double w[5] = {1.0, x, x2, x3, x3 * th};
    if (hermite) {
      for (int c = 0; c < n; ++c) {
        const double y0 = z[c], f0 = z[n + c], f1 = z[7 * n + c];
        const double dy = (z[2 * n + c] - y0) / h;
        const double q[4] = {y0, f0, 3.0 * dy - 2.0 * f0 - f1, f0 + f1 - 2.0 * dy};
        double y = 0.0;
        for (int m = 0; m < 4; ++m) y += w[m] * q[m];
        out[c] = y;
      }
      return;
    }
    for (int c = 0; c < n; ++c) {
      double q[5] = {z[c], 0.0, 0.0, 0.0, 0.0};
      for (int m = 0; m < 4; ++m) {
        double acc = 0.0;
        for (int j = 0; j < 7; ++j) acc += P[j][m] * z[(1 + j) * n + c];
        q[m + 1] = acc;
      }
      double y = 0.0;
      for (int m = 0; m < 5; ++m) y += w[m] * q[m];
      out[c] = y;
    }
  }
};

// Why a stretch ended (Stretch::run's status).
enum StretchStatus : int {
  STRETCH_END = 0,      // t reached t_last (the run's end) or t_end
  STRETCH_PENDING = 1,  // a step with something for Python: handed back, not committed
  STRETCH_SCHEDULE = 2, // a scheduled action is due at t
  STRETCH_REFUSED = 4,  // the next step could not be taken here (Python takes it)
  STRETCH_REPATCHED = 8, // ended right after a re-patch: the stepper restarts there (f pending)
};

// The constants of a run's stretches and their work arrays; run() takes the steps.
template <class Rhs>
class Stretch {
 public:
  // rhs: the contact-normal mode's native right-hand side (its modes and torques loaded by
  // the caller before each run, its step bound's constants by set_reach); api: the collision
  // sweep's entry point; margin [m] the sweep's query margin; atol (2 nv), rtol,
  // h_min [s] the stepper's; near [m] the proximity tolerance, pen_tol [m] the penetration
  // tolerance (end_check); crawl_steps, crawl_step [s] (normal_law.CRAWL_STEPS, CRAWL_STEP);
  // sample_dt [s], duration [s] the recorder's; stiff_switch: whether the stepper switches
  // to Rosenbrock steps in stiff stretches (packbot.contact.native.STIFF_ENABLED).
  Stretch(Rhs &rhs, const SweepApi &api, double margin, std::vector<double> atol, double rtol,
          double h_min, double near,
          double pen_tol, int crawl_steps, double crawl_step, double sample_dt, double duration,
          bool stiff_switch)
      : rhs_(rhs),
        api_(api),
        margin_(margin),
        atol_(std::move(atol)),
        rtol_(rtol),
        h_min_(h_min),
        near_(near),
        pen_tol_(pen_tol),
        crawl_steps_(crawl_steps),
        crawl_step_(crawl_step),
        sample_dt_(sample_dt),
        duration_(duration),
        stiff_switch_(stiff_switch) {
    nv_ = rhs.nv();
    n_ = 2 * nv_;
    if (static_cast<int>(atol_.size()) != n_) throw std::invalid_argument("atol (2 nv) expected");
    if (api_.nq != nv_) throw std::invalid_argument("the sweep's nq is not the model's nv");
    const size_t K = static_cast<size_t>(std::max<int64_t>(api_.n_pairs, 1));
    pairs_.resize(K);
    dist_.resize(K);
    last_pairs_.resize(K);
    last_dist_.resize(K);
    y1_.resize(n_);
    ay1_.resize(n_);
    yq_.resize(n_);
  }

  // The stepper's and the law's state a run starts from and ends with (run's in/out).
  struct State {
    double t = 0.0;          // [s]
    double h = 0.0;          // the next step's size [s]
    double max_factor = 0;   // the stepper's growth cap for the next step
    int stiff_run = 0;       // successive stiff Dormand-Prince steps
    bool stiff = false;      // the next steps are Rosenbrock attempts
    int64_t next_sample = 0; // the recorder's next regular sample
    double h_max = 0.0;      // out: the last step's bound [s] (the stepper's h_max)
    double min_d = 0.0;      // the smallest signed distance kept so far [m]
    int64_t min_pair = -1;   // its pair (-1: none lowered it in this run)
  };

  // What a run did (besides State and the arrays).
  struct Counts {
    int status = STRETCH_END;
    int64_t steps = 0;       // committed steps
    int64_t rejected = 0;    // their rejected attempts
    int64_t rhs_calls = 0;   // their right-hand-side calls (RK45Stepper.n_rhs's count)
    int64_t stiff_steps = 0; // of them Rosenbrock steps
    // the pending step (status PENDING): its start, its end, its rejections, calls and kind
    double t0 = 0.0, t1 = 0.0;
    int64_t pending_rejected = 0, pending_rhs_calls = 0;
    bool pending_implicit = false;
    int64_t repatches = 0;  // re-patches taken here (Repatch)
    // the samples recorded before the first re-patch (-1: no re-patch); none lies between
    // two re-patches of one run
    int64_t samples_before = -1;
  };

  // The stretch's re-patches (packbot.contact.normal_contacts.NormalContacts.repatch after a
  // step whose only finding is a sliding pair's stale patch), taken here when the caller
  // allows it (set_repatch's constants, then each run's modes): the patches rebuilt at the
  // step's end (the sweep's materials), the drift projection's round and its sweep's check,
  // the modes kept or selected again (the rows kept, or select_modes), the plan loaded, and the
  // stepper restarted there (RK45Stepper.reset with its step size and a deferred derivative).
  // A patch of another size changes the layout's shape (ContactRhs::relayout_raw). Where
  // Python's re-patch would take a branch not here (a pair out of tolerance or its patch off
  // its distance, a normal on the other body, a gap below the penetration tolerance, Lemke's
  // residual, a new deep pair, the Python mode selection), the step is handed back pending,
  // the extension as loaded.
  struct Repatch {
    bool on = false;  // (this run's)
    // the constants (set_repatch): the contact tolerance, PATCH_TOL, FACE_ALIGN [-],
    // SLIDE_TOL^2 [m^2], TOUCH_GAP [m], the projection's RESIDUAL_TOL, the mode selection's
    double tol = 0, patch_tol = 0, face_align = 0, slide_tol2 = 0, touch_gap = 0, res_tol = 0;
    typename Rhs::ModeConsts modes{};
    // tests: hand every re-patch back at a stage (0 none; 1 with the patches built, nothing
    // loaded; 2 after the projection's round; 3 at the modes, after the projection's sweep)
    int hand_back_at = 0;
    // the modes Python keeps per pair, in and out: stick flags, slip directions (pairs, 3), the
    // engaged rows; the normal's body (on1) per pair, in
    std::vector<uint8_t> stick, on1;
    std::vector<double> slip;
    std::vector<int64_t> engaged;
    // out: the last re-patch's q before its projection [rad] and the friction given up over
    // the run's re-patches (a Painleve fallback is handed back: the loop's window)
    std::vector<double> q_patch;
    int64_t gave_up = 0, relaid = 0;  // (relaid: re-patches of a new shape)
    double energy_removed = 0.0;  // [J] by the projections' velocity (neutral_velocity_raw)
    // the last projection's sweep (valid: one was made in this run) and, after a hand-back
    // that had swept, that sweep (spare) at q_spare
    bool proj_valid = false, spare = false;
    std::vector<double> q_proj, q_spare;
    std::vector<int64_t> proj_pairs, spare_pairs;
    std::vector<double> proj_dist, spare_dist;
    int64_t proj_best = -1, spare_best = -1;
    double proj_best_d = 0.0, spare_best_d = 0.0;
  };
  Repatch &repatch() { return rp_; }

  // Take the quiet steps from s.t: z (8, n) holds [y, f(y)] on entry (Z[0], Z[1]; with
  // f_pending only y: the first stage computes f(y) (ContactRhs::first)) and, on
  // return, [y, f(y)] at the end of the last committed step, or (PENDING) the pending step's
  // stages [y0, k0, ..., k6] with its end in y_pend and |y_end| in ay_pend; ay (n) |y| in/out.
  // t_end [s]: no step beyond (the loop's t_far); t_last [s]: the run ends there; t_sched [s]:
  // the next scheduled action; active (na) the contact set's active pairs; limits (nl x 3):
  // the active limit stops (joint, side, held); lim_value (nl) their positions [rad]. Samples
  // due (the recorder's rule) are appended to samples (rows of n), the committed steps' sizes
  // to hs; the last committed step's sweep is kept (last_pairs, last_dist).
  Counts run(State &s, bool f_pending, double *z, double *ay, double t_end, double t_last,
             double t_sched,
             const int64_t *active, size_t na, const int64_t *limits, const double *lim_value,
             size_t nl, std::vector<double> &crawl, double *y_pend, double *ay_pend,
             std::vector<double> &samples, std::vector<double> &hs) {
    Counts c;
    const int n = n_;
    const double *atol = atol_.data();
    const double crawl_sum_cap = crawl_steps_ * crawl_step_;
    // a restart's derivative left to the first step (RK45Stepper.reset's defer): its first
    // stage (the stepper calls the same function; when it refuses, Python's right-hand side)
    if (f_pending && s.t < t_last && !(t_sched <= s.t + 1e-12) && !rhs_.first_raw(z)) {
      c.status = STRETCH_REFUSED;
      return c;
    }
    // whether the last committed step's sweep (last_pairs_) is this step's start's
    bool start_known = false;
    while (true) {
      const double t = s.t;
      if (!(t < t_last) || !(t < t_end)) return c;  // (status END)
      if (t_sched <= t + 1e-12) {
        c.status = STRETCH_SCHEDULE;
        return c;
      }
      // the step's bound (NormalLaw.step_bound): every point moves at most half the margin
      const double h_max = rhs_.step_bound_raw(z + nv_);
      s.h_max = h_max;
      // RK45Stepper.step with the kernel and its stiff counterpart
      double h = s.h;
      if (h > h_max) h = h_max;
      bool implicit = s.stiff;
      double expo = implicit ? StepControl::ROS_ERROR_EXPONENT : StepControl::ERROR_EXPONENT;
      int stiff_run = s.stiff_run;
      bool rejected = false;
      int64_t rej = 0, calls = 0;
      double t_new = 0.0, err = 0.0, h_wanted = -1.0;
      while (true) {
        t_new = t + h;
        h_wanted = -1.0;
        if (t_new + StepControl::STRETCH * h >= t_end) {
          h_wanted = h;
          t_new = t_end;
          h = t_end - t;
        }
        if (implicit) {
          err = rhs_.rosenbrock_raw(h, z, ay, atol, rtol_, y1_.data(), ay1_.data());
          if (err < 0.0) {  // the kernel could not: back to Dormand-Prince
            implicit = false;
            stiff_run = 0;
            expo = StepControl::ERROR_EXPONENT;
          }
        }
        if (!implicit) {
          err = rhs_.dopri_raw(h, z, ay, atol, rtol_, y1_.data(), ay1_.data());
          if (err < 0.0) {  // (not: Python's stages; nan is a rejection)
            c.status = STRETCH_REFUSED;
            return c;
          }
        }
        calls += implicit ? (rejected ? 5 : 5 + 2 * n) : 6;  // (RK45Stepper.step's count)
        if (err < 1.0) break;
        ++rej;
        rejected = true;
        double fac = StepControl::SAFETY * std::pow(err, expo);
        if (!(fac > StepControl::MIN_FACTOR)) fac = StepControl::MIN_FACTOR;
        h *= fac;
        const double ulp = std::nextafter(t, std::numeric_limits<double>::infinity()) - t;
        if (h < std::max(h_min_, 10.0 * ulp)) {  // (an underflow: Python raises it)
          c.status = STRETCH_REFUSED;
          return c;
        }
      }
      // accepted: the next step's size
      const double max_factor = implicit ? StepControl::ROS_MAX_FACTOR : s.max_factor;
      double fac;
      if (err == 0.0) {
        fac = max_factor;
      } else {
        fac = StepControl::SAFETY * std::pow(err, expo);
        if (fac > max_factor) fac = max_factor;
      }
      if (rejected) {
        if (fac > 1.0) fac = 1.0;
      } else if (h_wanted > h) {
        const double h_next = h * fac;
        h = h_wanted > h_next ? h_wanted : h_next;
        fac = 1.0;
      }
      const double step = t_new - t;
      const double h_after = h * fac;
      bool stiff = s.stiff && implicit;
      if (implicit) {
        ++calls;  // f(y1), the accepted attempt's last stage
        if (h_after * rhs_.jac_radius() < StepControl::NONSTIFF_RATIO) {
          stiff = false;
          stiff_run = 0;
        }
      } else if (stiff_switch_) {
        if (rhs_.stiffness() > StepControl::STIFF_RATIO) {
          ++stiff_run;
          if (stiff_run >= StepControl::STIFF_STEPS) stiff = true;
        } else {
          stiff_run = 0;
        }
      }
      // the step's end: the sweep, the screen (NormalLaw.watch)
      int64_t best = -1;
      double best_d = std::numeric_limits<double>::infinity();
      const int64_t ns =
          api_.sweep(api_.self, y1_.data(), margin_, pairs_.data(), dist_.data(), &best, &best_d);
      int code = rhs_.end_check_raw(y1_.data(), pairs_.data(), dist_.data(),
                                    static_cast<size_t>(ns), active, na, near_, pen_tol_);
      // (a stale patch alone: the re-patch below, when allowed)
      const bool stale = code == 4 && rhs_.stale_sure();
      bool pending = code < 0 || (code & 3) != 0 || ((code & 4) != 0 && !stale);
      if (!pending && (code & 8)) pending = new_limit(y1_.data(), limits, nl);
      // a joint past a stop and back inside the step (not a held stop): Python's watch
      // locates it on the step's dense output (NormalLaw._excursion_crossings)
      if (!pending && !rhs_.upper().empty()) {
        excursions_.clear();
        rhs_.limit_excursions_raw(z, y1_.data(), step, excursion_tol_, excursions_);
        for (const auto &e : excursions_) {
          bool held = false;
          for (size_t i = 0; i < nl; ++i)
            if (limits[3 * i] == e.joint && limits[3 * i + 1] == e.side && limits[3 * i + 2])
              held = true;
          if (!held) pending = true;
        }
      }
      // after_step: the crawl rule, the limit stops' release (JointStops.release_limits)
      if (!pending && static_cast<int>(crawl.size()) + 1 >= crawl_steps_) {
        double sum = 0.0;  // (the deque's sum, oldest first, with this step)
        const size_t skip = crawl.size() + 1 - static_cast<size_t>(crawl_steps_);
        for (size_t i = skip; i < crawl.size(); ++i) sum += crawl[i];
        sum += step;
        if (sum < crawl_sum_cap) pending = true;
      }
      if (!pending) {
        for (size_t i = 0; i < nl; ++i) {
          const int64_t j = limits[3 * i], side = limits[3 * i + 1], held = limits[3 * i + 2];
          if (static_cast<double>(side) * (lim_value[i] - y1_[j]) > 1e-6 && !held) {
            pending = true;
            break;
          }
        }
      }
      // a step ending on a scheduled action's time is Python's (its samples, the action)
      if (!pending && t_new >= t_sched - 1e-12 && t_new < t_last) pending = true;
      // a pair in contact and out again inside the step (pair_dips.hpp): Python's watch
      // locates it on the step's dense output (NormalLaw._dip_crossings)
      if (!pending && rhs_.dips().ready()) {
        if (rhs_.dips().pairs() != static_cast<size_t>(api_.n_pairs) ||
            rhs_.reach().size() != static_cast<size_t>(nv_))
          throw std::invalid_argument("the screen's pairs or reach do not match the sweep's");
        coef_.resize(5 * static_cast<size_t>(nv_));
        DenseOutput::coefficients(z, step, n_, nv_, implicit, coef_.data());
        PairDips::speed_bounds(coef_.data(), static_cast<size_t>(nv_), nv_, 1.0, vmax_);
        auto dist = [&](int64_t k, double f) {
          DenseOutput::at(t + f * step, t, t_new, step, z, y1_.data(), n_, implicit, yq_.data());
          return api_.distance(api_.self, yq_.data(), k);
        };
        dips_.clear();
        rhs_.dips().screen(vmax_.data(), rhs_.reach().data(), step, pairs_.data(), dist_.data(),
                           static_cast<size_t>(ns), last_pairs_.data(), last_dist_.data(),
                           start_known ? last_n_ : 0, start_known, active, na, margin_,
                           pen_tol_, DIP_QUERIES, dist, dips_, true);
        if (!dips_.empty()) pending = true;
      }
      bool repatched = false;
      if (!pending && stale) {
        // A re-patch changes the patches the samples' contact forces are read from: Python
        // reads those of the samples before the first re-patch from its contact set as the
        // stretch found it, the others from the set as the last re-patch leaves it. So a later
        // re-patch is taken here only while no sample lies between it and the first (this
        // step's included); else the step is handed back (the loop records its samples, then
        // re-patches).
        const bool between =
            c.repatches > 0 && (static_cast<int64_t>(samples.size()) != c.samples_before * n ||
                                sample_due(s, t_new));
        if (rp_.on && !between && try_repatch() == 0)
          repatched = true;
        else
          pending = true;
      }
      if (pending) {
        pend_n_ = static_cast<size_t>(ns);  // (its sweep stays in pairs_, dist_)
        pend_best_ = best;
        pend_best_d_ = best_d;
        c.status = STRETCH_PENDING;
        c.t0 = t;
        c.t1 = t_new;
        c.pending_rejected = rej;
        c.pending_rhs_calls = calls;
        c.pending_implicit = implicit;
        std::copy(y1_.begin(), y1_.end(), y_pend);
        std::copy(ay1_.begin(), ay1_.end(), ay_pend);
        s.h = h_after;
        s.max_factor = StepControl::MAX_FACTOR;
        s.stiff_run = stiff_run;
        s.stiff = stiff;
        return c;
      }
      // committed: the samples due (Recorder.record), the law's bookkeeping
      record(s, t, t_new, step, z, implicit, samples);
      if (best >= 0 && best_d < s.min_d) {
        s.min_d = best_d;
        s.min_pair = best;
      }
      // its sweep kept as the last one (the buffers swapped: the next sweep writes the other)
      std::swap(pairs_, last_pairs_);
      std::swap(dist_, last_dist_);
      last_n_ = static_cast<size_t>(ns);
      start_known = !repatched;  // (a re-patch's projection moves the start)
      crawl.push_back(step);
      hs.push_back(step);
      ++c.steps;
      c.rejected += rej;
      c.rhs_calls += calls;
      if (implicit) ++c.stiff_steps;
      s.t = t_new;
      s.h = h_after;
      s.max_factor = StepControl::MAX_FACTOR;
      s.stiff_run = stiff_run;
      s.stiff = stiff;
      std::copy(y1_.begin(), y1_.end(), z);  // Z[0] = y1, Z[1] = f(y1) (the FSAL stage)
      std::copy(z + 7 * n, z + 8 * n, z + n);
      std::copy(ay1_.begin(), ay1_.end(), ay);
      if (repatched) {
        // the integrator's restart: RK45Stepper.reset(t, y, h=max(h, 1e-6), defer=True)
        std::copy(q_new_.begin(), q_new_.end(), z);
        std::copy(v_new_.begin(), v_new_.end(), z + nv_);
        for (int i = 0; i < n; ++i) ay[i] = std::abs(z[i]);
        s.h = std::min(std::max(s.h, 1e-6), s.h_max);
        s.max_factor = StepControl::MAX_FACTOR_FIRST;
        s.stiff = false;
        s.stiff_run = 0;
        ++c.rhs_calls;  // (reset's count)
        if (c.repatches == 0) c.samples_before = static_cast<int64_t>(samples.size()) / n;
        ++c.repatches;
        // the next step's first stage, as run() starts after a restart; the stepper restarts
        // in Python where the native step is not offered there (no engaged row: its own stages)
        if (rp_.engaged.empty() || !(t_new < t_last) || !(t_new < t_end) ||
            t_sched <= t_new + 1e-12 || !rhs_.first_raw(z)) {
          c.status = STRETCH_REPATCHED;
          return c;
        }
      }
    }
  }

  // the pending step's sweep (status PENDING): its candidates (the first pending_n() of the
  // arrays), their distances, the closest pair; the last committed step's sweep (last_n())
  const std::vector<int64_t> &pending_pairs() const { return pairs_; }
  const std::vector<double> &pending_dist() const { return dist_; }
  size_t pending_n() const { return pend_n_; }
  int64_t pending_best() const { return pend_best_; }
  double pending_best_d() const { return pend_best_d_; }
  const std::vector<int64_t> &last_pairs() const { return last_pairs_; }
  const std::vector<double> &last_dist() const { return last_dist_; }
  size_t last_n() const { return last_n_; }
  int n() const { return n_; }

 private:
  // Whether a joint at or beyond a limit has no active stop there (a limit event).
  bool new_limit(const double *y1, const int64_t *limits, size_t nl) const {
    const std::vector<double> &up = rhs_.upper(), &lo = rhs_.lower();
    for (size_t j = 0; j < up.size(); ++j) {
      int side = 0;
      if (y1[j] >= up[j])
        side = 1;
      else if (y1[j] <= lo[j])
        side = -1;
      if (!side) continue;
      bool active = false;
      for (size_t i = 0; i < nl; ++i)
        if (limits[3 * i] == static_cast<int64_t>(j) && limits[3 * i + 1] == side) active = true;
      if (!active) return true;
    }
    return false;
  }

  // The re-patch at the step's end y1_ (see Repatch): 0 done (q_new_ the projected q, the
  // patches and the plan loaded, rp_'s modes updated); 1 not here, nothing changed; 2 not
  // here, the extension's patches and plan put back (its step end's evaluation forgotten);
  // with the projection's sweep made, that sweep kept as rp_'s spare.
  int try_repatch() {
    const int np = rhs_.n_pairs(), nv = nv_;
    const double *q = y1_.data(), *v = y1_.data() + nv;
    if (!rhs_.contact_rows() || static_cast<int>(rp_.stick.size()) != np ||
        static_cast<int>(rp_.on1.size()) != np || rp_.engaged.empty())
      return 1;
    // the patches at q of the set's pairs, in the layout's order (ContactSet.refresh)
    const std::vector<int64_t> &keys = rhs_.keys();
    const int64_t cap = std::max<int64_t>(rhs_.n_pair_rows(), 16 * static_cast<int64_t>(np));
    m_sizes_.resize(np);
    m_flags_.resize(np);
    m_frame2_.resize(9 * static_cast<size_t>(np));
    m_centres_.resize(6 * static_cast<size_t>(np));
    m_l1_.resize(3 * static_cast<size_t>(cap));
    m_l2_.resize(3 * static_cast<size_t>(cap));
    m_off_.resize(2 * static_cast<size_t>(cap));
    const int64_t S = api_.materials(api_.self, q, keys.data(), np, rp_.tol, rp_.patch_tol,
                                     rp_.face_align, m_sizes_.data(), m_flags_.data(),
                                     m_frame2_.data(), m_centres_.data(), m_l1_.data(),
                                     m_l2_.data(), m_off_.data(), cap);
    if (S < 0) return 1;
    // every pair still within tolerance with a patch on its distance, its normal on the same
    // body: the same pairs (else the loop's refresh drops one); a patch of another size
    // changes the layout's shape (normal_rows.ContactRows._layout's full build) and the
    // engaged rows' meaning (repatch_modes then selects from none held)
    const std::vector<int> &K0 = rhs_.pair_rows();
    bool same_shape = true;
    K_.resize(np);
    int h = 0;
    for (int p = 0; p < np; ++p) {
      if (m_sizes_[p] < 1 || ((m_flags_[p] & 1) != 0) != (rp_.on1[p] != 0)) return 1;
      K_[p] = static_cast<int>(m_sizes_[p]);
      same_shape = same_shape && K_[p] == K0[p];
      h += K_[p] + 1;
    }
    if (rp_.hand_back_at == 1) return 1;
    const std::vector<int> &K = K_;
    // the layout's patches (normal_rows._local, _frame2, _offset0, the slides allowed)
    lay_local_.assign(8 * static_cast<size_t>(h), 1.0);
    lay_off_.resize(2 * static_cast<size_t>(cap));
    lay_slide_.resize(np);
    int r = 0, pt = 0;
    for (int p = 0; p < np; ++p) {
      const int Kp = K[p];
      for (int k = 0; k <= Kp; ++k, ++r) {
        const double *a = k < Kp ? &m_l1_[3 * (pt + k)] : &m_centres_[6 * p];
        const double *b = k < Kp ? &m_l2_[3 * (pt + k)] : &m_centres_[6 * p + 3];
        for (int c = 0; c < 3; ++c) {
          lay_local_[4 * r + c] = a[c];
          lay_local_[4 * (h + r) + c] = b[c];
        }
      }
      for (int k = 0; k < Kp; ++k)
        for (int j = 0; j < 2; ++j) lay_off_[2 * (pt + k) + j] = m_off_[2 * pt + j * Kp + k];
      lay_slide_[p] =
          (m_flags_[p] & 2) ? std::numeric_limits<double>::infinity() : rp_.slide_tol2;
      pt += Kp;
    }
    rhs_.keep_loaded();
    if (same_shape)
      rhs_.set_patches_raw(lay_local_.data(), m_frame2_.data(), lay_off_.data(),
                           lay_slide_.data());
    else
      rhs_.relayout_raw(K, lay_local_.data(), m_frame2_.data(), lay_off_.data(),
                        lay_slide_.data());
    // the drift projection (RestartSteps.project): its round with M^-1 at q, then the sweep's
    // check of the pairs outside the set
    minv_.resize(static_cast<size_t>(nv) * nv);
    q_new_.resize(nv);
    rhs_.minverse_at(q, minv_.data());
    const int st = rhs_.project_round_raw(q, v, minv_.data(), rp_.touch_gap, pen_tol_,
                                          rp_.res_tol, q_new_.data());
    if (st == 1 || st == 2 || st == 4 || rp_.hand_back_at == 2) return hand_back(false);
    bool swept = false;
    if (st == 0) {
      std::copy(q, q + nv, q_new_.begin());
    } else {
      swept = true;
      sweep_into(rp_.q_spare, rp_.spare_pairs, rp_.spare_dist, rp_.spare_best, rp_.spare_best_d);
      const int64_t *sp = rp_.spare_pairs.data();
      for (size_t k = 0; k < rp_.spare_pairs.size(); ++k)
        if (rp_.spare_dist[k] < -pen_tol_ &&
            std::find(keys.begin(), keys.end(), sp[k]) == keys.end())
          return hand_back(true);
    }
    if (rp_.hand_back_at == 3) return hand_back(swept);
    // the velocity after the projection (NormalContacts.neutral_velocity: no energy added)
    v_new_.assign(v, v + nv);
    const double removed = st == 0 ? 0.0 : rhs_.neutral_velocity_raw(q, q_new_.data(),
                                                                     v_new_.data());
    v = v_new_.data();
    // the modes (ModeSelection.repatch_modes: the engaged rows kept, else select_modes
    // with keep, natively), a_free at the projected q and M^-1 at q
    afree_.resize(nv);
    rhs_.free_accel_raw(q_new_.data(), v, afree_.data());
    stick_w_ = rp_.stick;
    slip_w_ = rp_.slip;
    typename Rhs::ModesOut o;
    if (rhs_.select_modes_raw(q_new_.data(), v, afree_.data(), minv_.data(), true,
                              rp_.engaged.data(), same_shape ? rp_.engaged.size() : 0,
                              stick_w_.data(), slip_w_.data(), rp_.modes, o) != 0)
      return hand_back(swept);
    // no consistent mode (a Painleve fallback): the loop's re-patch, which starts a window
    if (o.painleve > 0) return hand_back(swept);
    rp_.stick.swap(stick_w_);
    rp_.slip.swap(slip_w_);
    rp_.engaged.assign(o.engaged.begin(), o.engaged.end());
    rp_.gave_up += o.gave_up ? 1 : 0;
    rp_.energy_removed += removed;
    rp_.relaid += same_shape ? 0 : 1;
    rhs_.load_plan(o.engaged, rp_.stick.data(), rp_.slip.data());
    rp_.q_patch.assign(q, q + nv);
    if (swept) {  // (the world's last sweep, as CollisionWorld.sweep(q, reuse=True) keeps it)
      rp_.proj_valid = true;
      rp_.q_proj.swap(rp_.q_spare);
      rp_.proj_pairs.swap(rp_.spare_pairs);
      rp_.proj_dist.swap(rp_.spare_dist);
      rp_.proj_best = rp_.spare_best;
      rp_.proj_best_d = rp_.spare_best_d;
    }
    return 0;
  }

  // A re-patch handed back after the patches were loaded: the extension as loaded; with the
  // projection's sweep made (swept), that sweep kept as the spare one (Python's re-patch then
  // finds it at the same q: Coal's warm-started GJK would not repeat it bit for bit).
  int hand_back(bool swept) {
    rhs_.restore_loaded();
    rp_.spare = swept;
    return 2;
  }

  // The sweep at q_new_ into the given buffers (the sweep's C entry point, the stretch's margin).
  void sweep_into(std::vector<double> &q_at, std::vector<int64_t> &pairs,
                  std::vector<double> &dist, int64_t &best, double &best_d) {
    const size_t cap = static_cast<size_t>(std::max<int64_t>(api_.n_pairs, 1));
    pairs.resize(cap);
    dist.resize(cap);
    const int64_t ns =
        api_.sweep(api_.self, q_new_.data(), margin_, pairs.data(), dist.data(), &best, &best_d);
    pairs.resize(static_cast<size_t>(ns));
    dist.resize(static_cast<size_t>(ns));
    q_at = q_new_;
  }

  // Whether a regular sample is due in a step ending at t1 (record's first test).
  bool sample_due(const State &s, double t1) const {
    return static_cast<double>(s.next_sample) * sample_dt_ <= std::min(t1, duration_) + 1e-12;
  }

  // The regular samples due in the step [t0, t1] (Recorder.record with t_end = t1).
  void record(State &s, double t0, double t1, double h, const double *z, bool hermite,
              std::vector<double> &samples) {
    const double dt = sample_dt_;
    int64_t k = s.next_sample;
    const double lim = std::min(t1, duration_) + 1e-12;
    if (static_cast<double>(k) * dt > lim) return;
    while (true) {
      const double ts = static_cast<double>(k) * dt;
      if (ts > t1 + 1e-12 || ts > duration_ + 1e-12) break;
      const size_t at = samples.size();
      samples.resize(at + static_cast<size_t>(n_));
      DenseOutput::at(std::min(std::max(ts, t0), t1), t0, t1, h, z, y1_.data(), n_, hermite,
                      samples.data() + at);
      ++k;
    }
    s.next_sample = k;
  }

  Rhs &rhs_;
  SweepApi api_;
  double margin_;
  std::vector<double> atol_;
  double rtol_, h_min_, near_, pen_tol_;
  // (the step end's screen of limit excursions: ContactRhs::limit_excursions_raw, its tol [rad])
  std::vector<typename Rhs::Excursion> excursions_;
  static constexpr double excursion_tol_ = 1e-9;
  // (the step end's screen of contacts between its ends: pair_dips.hpp)
  std::vector<Dip> dips_;
  std::vector<double> vmax_, yq_, coef_;
  int crawl_steps_;
  double crawl_step_, sample_dt_, duration_;
  bool stiff_switch_;
  int nv_ = 0, n_ = 0;
  // the sweeps' buffers (room for every pair): the current step's, the last committed one's
  std::vector<int64_t> pairs_, last_pairs_;
  std::vector<double> dist_, last_dist_, y1_, ay1_;
  size_t last_n_ = 0, pend_n_ = 0;
  // the re-patch's state and work arrays (try_repatch)
  Repatch rp_;
  std::vector<int64_t> m_sizes_, m_flags_;
  std::vector<double> m_frame2_, m_centres_, m_l1_, m_l2_, m_off_;
  std::vector<double> lay_local_, lay_off_, lay_slide_, minv_, q_new_, v_new_, afree_, slip_w_;
  std::vector<uint8_t> stick_w_;
  std::vector<int> K_;  // (the new patches' sizes)
  int64_t pend_best_ = -1;
  double pend_best_d_ = 0.0;
};

}  // namespace packbot_native
