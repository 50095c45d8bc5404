// The Python module packbot._native (nanobind): ContactRhs (contact_rhs.hpp) and the native
// stretch on it, Stretch (stretch_glue.hpp).

#include "contact_rhs.hpp"
#include "stretch_glue.hpp"

#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <stdexcept>
#include <string>
#include <vector>

using packbot_native::StretchT;
using packbot_native::stretch_init;
using packbot_native::stretch_repatched;
using packbot_native::stretch_run;
using packbot_native::stretch_set_modes;
using packbot_native::stretch_set_repatch;

NB_MODULE(_native, m) {
  m.doc() = "packbot's compiled right-hand side of the contact-normal mode (Pinocchio, nanobind).";
  m.attr("PINOCCHIO_VERSION") = PINOCCHIO_VERSION;
  nb::class_<ContactRhs>(m, "ContactRhs")
      .def(nb::init<const std::vector<std::string> &, I1, F3, F2, F1, F2, F3, F1, F1>(),
           nb::arg("types"), nb::arg("parents"), nb::arg("placements"), nb::arg("axes"),
           nb::arg("masses"), nb::arg("levers"), nb::arg("inertias"), nb::arg("armature"),
           nb::arg("gravity"))
      .def_prop_ro("nv", &ContactRhs::nv)
      .def("set_layout", &ContactRhs::set_layout)
      .def("set_patches", &ContactRhs::set_patches, nb::arg("local"), nb::arg("frame2"),
           nb::arg("offset0"), nb::arg("slide_tol2"))
      .def("set_plan", &ContactRhs::set_plan)
      .def("set_slip_dirs", &ContactRhs::set_slip_dirs)
      .def("accel", &ContactRhs::accel, nb::arg("q"), nb::arg("v"), nb::arg("x"),
           nb::arg("from_tau"), nb::arg("out"))
      .def("set_torque", &ContactRhs::set_torque, nb::arg("applied"), nb::arg("viscous"),
           nb::arg("coulomb_dir"))
      .def("first", &ContactRhs::first, nb::arg("Z"))
      .def("dopri", &ContactRhs::dopri, nb::arg("h"), nb::arg("Z"), nb::arg("ay0"),
           nb::arg("atol"), nb::arg("rtol"), nb::arg("y1"), nb::arg("ay1"))
      .def("stiffness", &ContactRhs::stiffness)
      .def("rosenbrock", &ContactRhs::rosenbrock, nb::arg("h"), nb::arg("Z"), nb::arg("ay0"),
           nb::arg("atol"), nb::arg("rtol"), nb::arg("y1"), nb::arg("ay1"))
      .def("jac_radius", &ContactRhs::jac_radius)
      .def("set_conditions", &ContactRhs::set_conditions, nb::arg("offset0"),
           nb::arg("slide_tol2"), nb::arg("force_band"), nb::arg("point_tol"),
           nb::arg("stick_band"))
      .def("end_eval", &ContactRhs::end_eval, nb::arg("y1"))
      .def("eval_at", &ContactRhs::eval_at, nb::arg("y"))
      .def("row_condition_at", &ContactRhs::row_condition_at, nb::arg("y"), nb::arg("r"))
      .def("row_root", &ContactRhs::row_root, nb::arg("Z"), nb::arg("t0"), nb::arg("t1"),
           nb::arg("h"), nb::arg("y1"), nb::arg("hermite"), nb::arg("r"), nb::arg("g0"),
           nb::arg("g1"), nb::arg("xtol"))
      .def("set_keys", &ContactRhs::set_keys, nb::arg("keys"))
      .def("set_limits", &ContactRhs::set_limits, nb::arg("upper"), nb::arg("lower"))
      .def("set_reach", &ContactRhs::set_reach, nb::arg("reach"), nb::arg("margin"),
           nb::arg("max_step"))
      .def("step_bound", &ContactRhs::step_bound, nb::arg("y"))
      .def("end_check", &ContactRhs::end_check, nb::arg("y1"), nb::arg("swept"), nb::arg("dist"),
           nb::arg("active"), nb::arg("near"), nb::arg("pen_tol"))
      .def("set_locks", &ContactRhs::set_locks, nb::arg("locked"))
      .def("energies", &ContactRhs::energies, nb::arg("Q"), nb::arg("V"), nb::arg("out"))
      .def("end_locks", &ContactRhs::end_locks, nb::arg("y1"))
      .def("set_screen", &ContactRhs::set_screen, nb::arg("rows"), nb::arg("torque_band"),
           nb::arg("accel_band"))
      .def("end_screen", &ContactRhs::end_screen, nb::arg("y1"), nb::arg("margin"))
      .def("window_step", &ContactRhs::window_step, nb::arg("y"), nb::arg("h"), nb::arg("swept"),
           nb::arg("dist"), nb::arg("sweep_margin"), nb::arg("reach"), nb::arg("active_gap"),
           nb::arg("upper"), nb::arg("lower"), nb::arg("limit_gap"), nb::arg("mu"),
           nb::arg("restitution"), nb::arg("zeno"), nb::arg("touch_gap"), nb::arg("boxes"),
           nb::arg("bound"), nb::arg("guess"), nb::arg("rho0"), nb::arg("tol"),
           nb::arg("max_iterations"), nb::arg("ok"), nb::arg("out_vf"), nb::arg("out_v1"),
           nb::arg("out_q1"), nb::arg("checked") = true)
      .def("project_round", &ContactRhs::project_round, nb::arg("q"), nb::arg("v"),
           nb::arg("minv"), nb::arg("touch_gap"), nb::arg("pen_tol"), nb::arg("res_tol"),
           nb::arg("out_q"))
      .def("impact", &ContactRhs::impact, nb::arg("q"), nb::arg("v"), nb::arg("minv"),
           nb::arg("mu"), nb::arg("restitution"), nb::arg("zeno"), nb::arg("touch_gap"),
           nb::arg("res_tol"), nb::arg("conic_tol"), nb::arg("max_iterations"),
           nb::arg("accept"), nb::arg("out_v"))
      .def("window_run", &ContactRhs::window_run, nb::arg("api"), nb::arg("y"), nb::arg("t"),
           nb::arg("t_end"), nb::arg("t_commit"), nb::arg("h_window"), nb::arg("until"),
           nb::arg("quiet"), nb::arg("quiet_steps"), nb::arg("last_valid"), nb::arg("last_sig"),
           nb::arg("swept"), nb::arg("dist"), nb::arg("sweep_margin"), nb::arg("best"),
           nb::arg("best_d"), nb::arg("reach"), nb::arg("active_gap"), nb::arg("upper"),
           nb::arg("lower"), nb::arg("limit_gap"), nb::arg("mu"), nb::arg("restitution"),
           nb::arg("zeno"), nb::arg("touch_gap"), nb::arg("boxes"), nb::arg("coul"),
           nb::arg("guess"), nb::arg("rho0"), nb::arg("tol"), nb::arg("max_iterations"),
           nb::arg("ok"), nb::arg("applied"), nb::arg("has_e"), nb::arg("e_last"),
           nb::arg("step_angle"), nb::arg("sweep_slack"), nb::arg("project_depth"),
           nb::arg("impulse_band"), nb::arg("min_d"), nb::arg("max_steps"))
      .def("select_modes", &ContactRhs::select_modes, nb::arg("q"), nb::arg("v"),
           nb::arg("a_free"), nb::arg("minv"), nb::arg("keep"), nb::arg("held"),
           nb::arg("stick_io"), nb::arg("slip_io"), nb::arg("mu"), nb::arg("touch_gap"),
           nb::arg("speed_band"), nb::arg("stick_speed"), nb::arg("force_band"),
           nb::arg("stick_band"), nb::arg("baumgarte"), nb::arg("residual_tol"))
      .def("stop_slow", &ContactRhs::stop_slow, nb::arg("q"), nb::arg("v"), nb::arg("minv"),
           nb::arg("touch_gap"), nb::arg("speed_band"), nb::arg("stick_speed"),
           nb::arg("capture_speed"), nb::arg("residual_tol"), nb::arg("dependent_row"),
           nb::arg("out_v"))
      .def("last", &ContactRhs::last)
      .def("minv_at",
           [](ContactRhs &r, F1 q, Out2 out) {
             if (q.shape(0) != static_cast<size_t>(r.nv()) || out.shape(0) != q.shape(0) ||
                 out.shape(1) != q.shape(0))
               throw std::invalid_argument("q (nv) and out (nv, nv) expected");
             r.minverse_at(q.data(), out.data());
           })
      .def("free_accel_at", [](ContactRhs &r, F1 q, F1 v, Out1 out) {
        if (q.shape(0) != static_cast<size_t>(r.nv()) || v.shape(0) != q.shape(0) ||
            out.shape(0) != q.shape(0))
          throw std::invalid_argument("q, v and out (nv) expected");
        r.free_accel_raw(q.data(), v.data(), out.data());
      });
  nb::class_<StretchT>(m, "Stretch")
      .def("__init__", &stretch_init, nb::arg("rhs"), nb::arg("api"), nb::arg("margin"),
           nb::arg("atol"), nb::arg("rtol"),
           nb::arg("h_min"), nb::arg("near"), nb::arg("pen_tol"), nb::arg("crawl_steps"),
           nb::arg("crawl_step"), nb::arg("sample_dt"), nb::arg("duration"),
           nb::arg("stiff_switch"), nb::keep_alive<1, 2>(), nb::keep_alive<1, 3>())
      .def("run", &stretch_run)
      .def("set_repatch", &stretch_set_repatch, nb::arg("tol"), nb::arg("patch_tol"),
           nb::arg("face_align"), nb::arg("slide_tol2"), nb::arg("touch_gap"),
           nb::arg("res_tol"), nb::arg("mu"), nb::arg("speed_band"), nb::arg("stick_speed"),
           nb::arg("force_band"), nb::arg("stick_band"), nb::arg("baumgarte"),
           nb::arg("mode_res_tol"), nb::arg("hand_back_at") = 0)
      .def("set_modes", &stretch_set_modes, nb::arg("on"), nb::arg("stick"), nb::arg("on1"),
           nb::arg("slip"), nb::arg("engaged"))
      .def("repatched", &stretch_repatched);
}
