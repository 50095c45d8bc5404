// The native stretch's Python face (stretch_glue.hpp): the arguments and results of
// packbot/contact/stretch.py's calls, to and from Stretch<ContactRhs> (stretch.hpp).

#include "stretch_glue.hpp"

#include "sweep_api.hpp"

#include <algorithm>
#include <stdexcept>
#include <vector>

using packbot_native::reals;

namespace {

template <class T>
nb::ndarray<nb::numpy, T, nb::ndim<2>> owned(const std::vector<T> &v, size_t rows, size_t cols) {
  T *buf = new T[rows * cols > 0 ? rows * cols : 1];
  std::copy(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(rows * cols), buf);
  nb::capsule owner(buf, [](void *p) noexcept { delete[] static_cast<T *>(p); });
  return nb::ndarray<nb::numpy, T, nb::ndim<2>>(buf, {rows, cols}, owner);
}

}  // namespace

namespace packbot_native {

// Stretch(rhs, api, ...): the sweep's capsule (packbot._native_coal's Sweep.api()).
void stretch_init(StretchT *self, ContactRhs &rhs, nb::capsule api, double margin, F1 atol,
                  double rtol, double h_min, double near,
                  double pen_tol, int crawl_steps, double crawl_step, double sample_dt,
                  double duration, bool stiff_switch) {
  void *p = PyCapsule_GetPointer(api.ptr(), PACKBOT_SWEEP_API);
  if (p == nullptr) {
    PyErr_Clear();
    throw std::invalid_argument("api: a capsule of packbot._native_coal's Sweep.api() expected");
  }
  new (self) StretchT(rhs, *static_cast<SweepApi *>(p), margin, reals(atol), rtol, h_min, near,
                      pen_tol, crawl_steps, crawl_step, sample_dt, duration, stiff_switch);
}

// The re-patch's constants (Stretch::Repatch; packbot/contact/stretch.py passes them).
void stretch_set_repatch(StretchT &st, double tol, double patch_tol, double face_align,
                         double slide_tol2, double touch_gap, double res_tol, double mu,
                         double speed_band, double stick_speed, double force_band,
                         double stick_band, double baumgarte, double mode_res_tol,
                         int hand_back_at) {
  auto &rp = st.repatch();
  rp.hand_back_at = hand_back_at;
  rp.tol = tol;
  rp.patch_tol = patch_tol;
  rp.face_align = face_align;
  rp.slide_tol2 = slide_tol2;
  rp.touch_gap = touch_gap;
  rp.res_tol = res_tol;
  rp.modes = ContactRhs::ModeConsts{mu,         touch_gap,  speed_band, stick_speed,
                                    force_band, stick_band, baumgarte,  mode_res_tol};
}

// The next run's re-patches: allowed (on) or not, and the contact set's modes (per pair its
// stick flag, its normal's body, its slip direction (pairs, 3); the engaged rows).
void stretch_set_modes(StretchT &st, bool on, U1 stick, U1 on1, F2 slip, I1 engaged) {
  auto &rp = st.repatch();
  const size_t np = stick.shape(0);
  if (on1.shape(0) != np || slip.shape(0) != np || (np && slip.shape(1) != 3))
    throw std::invalid_argument("stick, on1 (pairs) and slip (pairs, 3) expected");
  rp.on = on;
  rp.stick.assign(stick.data(), stick.data() + np);
  rp.on1.assign(on1.data(), on1.data() + np);
  rp.slip.assign(slip.data(), slip.data() + 3 * np);
  rp.engaged.assign(engaged.data(), engaged.data() + engaged.shape(0));
  rp.gave_up = rp.relaid = 0;
  rp.energy_removed = 0.0;
  rp.proj_valid = rp.spare = false;
  rp.q_patch.clear();
}

// The last run's re-patches as Python takes them over (stretch.py): a dict.
nb::dict stretch_repatched(StretchT &st) {
  auto &rp = st.repatch();
  const size_t np = rp.stick.size();
  nb::dict out;
  out["q_patch"] = owned(rp.q_patch, 1, rp.q_patch.size());
  out["stick"] = owned(rp.stick, 1, np);
  out["slip"] = owned(rp.slip, np, 3);
  out["engaged"] = owned(rp.engaged, 1, rp.engaged.size());
  out["gave_up"] = rp.gave_up;
  out["relaid"] = rp.relaid;
  out["energy_removed"] = rp.energy_removed;
  for (int w = 0; w < 2; ++w) {
    const bool on = w == 0 ? rp.proj_valid : rp.spare;
    const char *name = w == 0 ? "proj" : "spare";
    if (!on) {
      out[name] = nb::none();
      continue;
    }
    const auto &q = w == 0 ? rp.q_proj : rp.q_spare;
    const auto &pairs = w == 0 ? rp.proj_pairs : rp.spare_pairs;
    const auto &dist = w == 0 ? rp.proj_dist : rp.spare_dist;
    out[name] = nb::make_tuple(owned(q, 1, q.size()), owned(pairs, 1, pairs.size()),
                               owned(dist, 1, dist.size()), w == 0 ? rp.proj_best : rp.spare_best,
                               w == 0 ? rp.proj_best_d : rp.spare_best_d);
  }
  return out;
}

// run's arguments and results as Python sees them (packbot/contact/stretch.py): a dict.
nb::dict stretch_run(StretchT &st, bool f_pending, Out2 Z, Out1 ay, double t, double h,
                     double max_factor, int stiff_run, bool stiff, int64_t next_sample,
                     double min_d, double t_end, double t_last, double t_sched, I1 active,
                     I2 limits, F1 lim_value, F1 crawl, Out1 y_pend, Out1 ay_pend) {
  const size_t n = static_cast<size_t>(st.n());
  if (Z.shape(0) != 8 || Z.shape(1) != n || ay.shape(0) != n || y_pend.shape(0) != n ||
      ay_pend.shape(0) != n)
    throw std::invalid_argument("Z (8, 2 nv); ay, y_pend, ay_pend (2 nv,) expected");
  const size_t nl = limits.shape(0);
  if ((nl && limits.shape(1) != 3) || lim_value.shape(0) != nl)
    throw std::invalid_argument("limits (k, 3) and lim_value (k,) expected");
  StretchT::State s;
  s.t = t;
  s.h = h;
  s.max_factor = max_factor;
  s.stiff_run = stiff_run;
  s.stiff = stiff;
  s.next_sample = next_sample;
  s.min_d = min_d;
  std::vector<double> ring(crawl.data(), crawl.data() + crawl.shape(0));
  std::vector<double> samples, hs;
  const auto c = st.run(s, f_pending, Z.data(), ay.data(), t_end, t_last, t_sched, active.data(),
                        active.shape(0), limits.data(), lim_value.data(), nl, ring,
                        y_pend.data(), ay_pend.data(), samples, hs);
  nb::dict out;
  out["status"] = c.status;
  out["steps"] = c.steps;
  out["rejected"] = c.rejected;
  out["rhs_calls"] = c.rhs_calls;
  out["stiff_steps"] = c.stiff_steps;
  out["t"] = s.t;
  out["h"] = s.h;
  out["h_max"] = s.h_max;
  out["stiff_run"] = s.stiff_run;
  out["stiff"] = s.stiff;
  out["min_d"] = s.min_d;
  out["min_pair"] = s.min_pair;
  out["samples"] = owned(samples, samples.size() / n, n);
  out["hs"] = owned(hs, 1, hs.size());
  out["last_pairs"] = owned(st.last_pairs(), 1, st.last_n());
  out["last_dist"] = owned(st.last_dist(), 1, st.last_n());
  out["repatches"] = c.repatches;
  out["samples_before"] = c.samples_before;
  out["spare"] = st.repatch().spare;  // (a re-patch handed back after its projection's sweep)
  if (c.status == packbot_native::STRETCH_PENDING) {
    out["t0"] = c.t0;
    out["t1"] = c.t1;
    out["pending_rejected"] = c.pending_rejected;
    out["pending_rhs_calls"] = c.pending_rhs_calls;
    out["pending_implicit"] = c.pending_implicit;
    out["pending_pairs"] = owned(st.pending_pairs(), 1, st.pending_n());
    out["pending_dist"] = owned(st.pending_dist(), 1, st.pending_n());
    out["pending_best"] = st.pending_best();
    out["pending_best_d"] = st.pending_best_d();
  }
  return out;
}

}  // namespace packbot_native
