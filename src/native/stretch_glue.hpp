// The native stretch (stretch.hpp's Stretch on ContactRhs) as packbot/contact/stretch.py calls
// it: its construction on the sweep's capsule, the re-patch's constants and modes, a run, the
// run's re-patches (stretch_glue.cpp; bound in bindings.cpp as packbot._native.Stretch).
#pragma once

#include "contact_rhs.hpp"
#include "stretch.hpp"

#include <cstdint>

namespace packbot_native {

using I2 = nb::ndarray<const int64_t, nb::ndim<2>, nb::c_contig, nb::device::cpu>;
using StretchT = Stretch<ContactRhs>;

void stretch_init(StretchT *self, ContactRhs &rhs, nb::capsule api, double margin, F1 atol,
                  double rtol, double h_min, double near,
                  double pen_tol, int crawl_steps, double crawl_step, double sample_dt,
                  double duration, bool stiff_switch);
void stretch_set_repatch(StretchT &st, double tol, double patch_tol, double face_align,
                         double slide_tol2, double touch_gap, double res_tol, double mu,
                         double speed_band, double stick_speed, double force_band,
                         double stick_band, double baumgarte, double mode_res_tol,
                         int hand_back_at);
void stretch_set_modes(StretchT &st, bool on, U1 stick, U1 on1, F2 slip, I1 engaged);
nb::dict stretch_repatched(StretchT &st);
nb::dict stretch_run(StretchT &st, bool f_pending, Out2 Z, Out1 ay, double t, double h,
                     double max_factor, int stiff_run, bool stiff, int64_t next_sample,
                     double min_d, double t_end, double t_last, double t_sched, I1 active,
                     I2 limits, F1 lim_value, F1 crawl, Out1 y_pend, Out1 ay_pend);

}  // namespace packbot_native
