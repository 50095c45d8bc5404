// Contacts between step ends: a pair that passes into contact and out again inside one step.
//
// The event functions read each pair's signed distance at the step's ends; a fast, grazing
// pass (the camera head through a flipper's corner in 3 ms inside a 7 ms step, at 4 rad/s)
// can start and end the step apart. This screen bounds each pair's distance over the whole
// step by conservative advancement on its time derivative:
//
//   |d'(t)| <= L = sum over the joints j that move one piece relative to the other of
//              reach_j max |v_j| over the step,
//
// reach_j the bound on the distance from joint j's axis to the pieces it moves (the step
// bound's; packbot.contact.pairs.reach_bounds) and the joints those between the two pieces'
// chains (the ones both pieces hang from move them rigidly together: d does not change).
// |v_j| over the step is the largest speed of q_j on the step's dense output (the path the
// distance queries follow): the derivative of its polynomial at its largest on the step. With d(a) and d(b) known at the
// ends of an interval of the step, no d inside it is below (d(a) + d(b) - L (b - a)) / 2;
// where that bound is negative the interval is halved at a distance query on the step's
// dense output, level by level in time order, until every piece of the step is proven clear, or the
// halves' bound L (b - a) / 2 is within the screen's resolution (the pass, if any, is
// shallower than it), or a query finds d <= 0: a dip, an impact event to locate before it
// (for a pair of the contact set leaving from contact, d <= -PENETRATION_TOL: a re-patch).
//
// A pair's joints are given per world pair (set: a CSR of velocity indices). A pair absent
// from the step start's sweep is at least the sweep's margin away there when the start's
// sweep is known, and is queried at the start when it is not (a stretch's first step).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <vector>

namespace packbot_native {

// The screen's queries per pair and step at most (a pair whose screen needs more is counted
// in PairDips::unresolved and left to the step's end).
constexpr int64_t DIP_QUERIES = 64;

struct Dip {
  int64_t pair;  // the world pair
  double s;      // where a query found it at the level, as a fraction of the step (0, 1]
  double d;      // its signed distance there [m] (<= level)
  double level;  // the level looked for [m]: 0 (a touch) or -pen_tol (a re-patch)
};

class PairDips {
 public:
  // pair k's joints: idx[start[k]] ... idx[start[k + 1] - 1] (velocity indices)
  void set(const int64_t *start, size_t n_pairs, const int64_t *idx, size_t n_idx, int nv) {
    if (start[0] != 0 || start[n_pairs] != static_cast<int64_t>(n_idx))
      throw std::invalid_argument("pair_joints: start must rise from 0 to len(idx)");
    for (size_t k = 0; k < n_pairs; ++k)
      if (start[k + 1] < start[k])
        throw std::invalid_argument("pair_joints: start must rise from 0 to len(idx)");
    for (size_t i = 0; i < n_idx; ++i)
      if (idx[i] < 0 || idx[i] >= nv)
        throw std::invalid_argument("pair_joints: a velocity index is out of range");
    start_.assign(start, start + n_pairs + 1);
    idx_.assign(idx, idx + n_idx);
  }
  bool ready() const { return !start_.empty(); }
  size_t pairs() const { return start_.empty() ? 0 : start_.size() - 1; }

  // The largest |dq_j/dt| [rad/s] of each joint's position on the step's dense output, into
  // vmax (nv): Q (5 rows of stride `stride`, the first nv columns the positions) the
  // interpolant's coefficients, q(theta) = Q0 + hz (Q1 theta + Q2 theta^2 + Q3 theta^3 +
  // Q4 theta^4) (packbot.ode.DenseSegment's basis: the quartic of Dormand-Prince, or the
  // cubic Hermite of a Rosenbrock step, Q4 = 0), over theta in [0, theta_max]. The derivative
  // Q1 + 2 Q2 theta + 3 Q3 theta^2 + 4 Q4 theta^3, at its ends and its interior extremes.
  static void speed_bounds(const double *Q, size_t stride, int nv, double theta_max,
                           std::vector<double> &vmax) {
    vmax.resize(static_cast<size_t>(nv));
    for (int j = 0; j < nv; ++j) {
      const double c1 = Q[stride + j], c2 = 2.0 * Q[2 * stride + j], c3 = 3.0 * Q[3 * stride + j],
                   c4 = 4.0 * Q[4 * stride + j];
      auto f = [&](double th) { return ((c4 * th + c3) * th + c2) * th + c1; };
      double m = std::max(std::abs(f(0.0)), std::abs(f(theta_max)));
      // f'(th) = 3 c4 th^2 + 2 c3 th + c2
      const double A = 3.0 * c4, B = 2.0 * c3, C = c2;
      double roots[2];
      int nr = 0;
      if (A == 0.0) {
        if (B != 0.0) roots[nr++] = -C / B;
      } else {
        const double disc = B * B - 4.0 * A * C;
        if (disc >= 0.0) {
          const double sq = std::sqrt(disc);
          roots[nr++] = (-B - sq) / (2.0 * A);
          roots[nr++] = (-B + sq) / (2.0 * A);
        }
      }
      for (int i = 0; i < nr; ++i)
        if (roots[i] > 0.0 && roots[i] < theta_max) m = std::max(m, std::abs(f(roots[i])));
      vmax[static_cast<size_t>(j)] = m;
    }
  }

  // The screen of one step of h [s] (see the header): the end's swept pairs p1 (n1) at
  // distances d1 [m]; the start's p0 (n0), d0, known (start_known) or not; the contact set's
  // active pairs (na); margin [m] the sweeps'; pen_tol [m] the penetration tolerance; vmax
  // (nv) from speed_bounds, reach (nv) [m]. dist(k, s) is pair k's signed distance [m] at the
  // fraction s of the step on its dense output. What is looked for:
  //   a pair outside the contact set, apart at both ends: d <= 0 inside (an impact);
  //   a pair of the set apart by more than pen_tol at both ends: d <= 0 (a touch of other
  //     features than its rows');
  //   a pair of the set within pen_tol at the start and apart by more than pen_tol at the
  //     end (leaving): d <= -pen_tol inside (other features through its rows: a re-patch);
  // a pair of the set within pen_tol at the end is left to its rows (held, released, or
  // re-patched below -pen_tol at the end). The screen's resolution is pen_tol / 20: no part
  // of a step it proves clear goes below the level it looks for by more than that. At most
  // max_evals queries per pair inside the step (and one at its start when it is not known). Appends the dips found to out (all pairs, or the first only);
  // returns the number of queries.
  template <class Dist>
  int64_t screen(const double *vmax, const double *reach, double h, const int64_t *p1,
                 const double *d1, size_t n1, const int64_t *p0, const double *d0, size_t n0,
                 bool start_known, const int64_t *active, size_t na, double margin,
                 double pen_tol, int64_t max_evals, Dist &&dist, std::vector<Dip> &out,
                 bool first_only) {
    const double tol = pen_tol / 20.0;
    int64_t evals = 0;
    for (size_t i = 0; i < n1; ++i) {
      const int64_t k = p1[i];
      const double e = d1[i];
      if (!(e > 0.0)) continue;  // (in contact at the end: the end's impact event)
      const bool in = std::find(active, active + na, k) != active + na;
      if (in && !(e > pen_tol)) continue;
      if (k < 0 || static_cast<size_t>(k) >= pairs()) continue;
      double L = 0.0;
      for (int64_t a = start_[k]; a < start_[k + 1]; ++a) {
        const size_t j = static_cast<size_t>(idx_[a]);
        L += reach[j] * vmax[j];
      }
      const double Ls = L * h;  // [m] per unit of s
      if (e - Ls >= 0.0) continue;  // (clear from the end alone)
      double b = std::numeric_limits<double>::quiet_NaN();
      const int64_t *at = std::find(p0, p0 + n0, k);
      if (at != p0 + n0)
        b = d0[at - p0];
      else if (start_known)
        b = margin;
      if (std::isnan(b)) {
        b = dist(k, 0.0);
        ++evals;
      }
      // the level looked for: 0, or -pen_tol for a pair of the set leaving from contact
      double level = 0.0;
      if (in && !(b > pen_tol)) level = -pen_tol;
      if (!(b > level)) continue;  // (past it at the start: its own events)
      Dip dip{k, 0.0, 0.0, level};
      if (descend(k, b - level, e - level, level, Ls, tol, max_evals, dist, dip, evals)) {
        out.push_back(dip);
        if (first_only) return evals;
      }
    }
    return evals;
  }

 private:
  // Halve [0, 1] level by level (see the header), da and db the heights [m] of the pair's
  // distance above the level looked for at the step's ends: each level queries the middle of
  // every piece not yet proven clear, in time order, so that a capped screen has still
  // looked at the whole step evenly. A query that finds d <= level ends the search after it;
  // the pieces before it are searched on for an earlier one (the event is located between
  // the step's start and the dip: the earliest dip makes it the first touch). True with the
  // earliest query found at the level, in dip.
  template <class Dist>
  bool descend(int64_t k, double da, double db, double level, double Ls, double tol,
               int64_t max_evals, Dist &dist, Dip &dip, int64_t &evals) {
    stack_.clear();
    stack_.push_back({0.0, da, 1.0, db});
    int64_t used = 0;
    bool found = false;
    while (!stack_.empty()) {
      next_.clear();
      for (const Piece &p : stack_) {
        const double w = Ls * (p.b - p.a);
        if (0.5 * (p.da + p.db - w) >= 0.0 || 0.5 * w <= tol) continue;
        if (used >= max_evals) {
          if (!found) ++unresolved;
          return found;
        }
        const double m = 0.5 * (p.a + p.b);
        const double dm = dist(k, m);
        ++used;
        ++evals;
        if (!(dm > level)) {
          found = true;
          dip.s = m;
          dip.d = dm;
          next_.push_back({p.a, p.da, m, 0.0});  // (the piece before it, its end at the level)
          break;
        }
        const double hm = dm - level;
        next_.push_back({p.a, p.da, m, hm});
        next_.push_back({m, hm, p.b, p.db});
      }
      stack_.swap(next_);
    }
    return found;
  }

  struct Piece {  // [a, b] of the step, its ends' heights above the level [m]
    double a, da, b, db;
  };
  std::vector<int64_t> start_, idx_;
  std::vector<Piece> stack_, next_;  // (a level's pieces, the next level's)

 public:
  int64_t unresolved = 0;  // pairs whose screen gave up at max_evals queries (diagnostics)
};

}  // namespace packbot_native
