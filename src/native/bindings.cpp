// The Python module packbot._native (nanobind): ContactRhs (contact_rhs.hpp), the native
// stretch on it, Stretch (stretch_glue.hpp), and the small solvers and the patch materials the
// Python side calls alone: lemke and lcp_residual (lcp.hpp), solve_conic and conic_residual
// (conic.hpp), patch_material (material.hpp).

#include "conic.hpp"
#include "contact_rhs.hpp"
#include "lcp.hpp"
#include "material.hpp"
#include "stretch_glue.hpp"

#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <initializer_list>
#include <stdexcept>
#include <string>
#include <vector>

using packbot_native::StretchT;
using packbot_native::stretch_init;
using packbot_native::stretch_repatched;
using packbot_native::stretch_run;
using packbot_native::stretch_set_modes;
using packbot_native::stretch_set_repatch;

namespace {

using Arr = nb::ndarray<nb::numpy, double>;

// A new numpy array of this shape holding the first prod(shape) doubles of p.
Arr owned(const double *p, std::initializer_list<size_t> shape) {
  size_t n = 1;
  for (const size_t s : shape) n *= s;
  auto *buf = new double[n ? n : 1];
  std::copy(p, p + n, buf);
  nb::capsule owner(buf, [](void *d) noexcept { delete[] static_cast<double *>(d); });
  return Arr(buf, shape, owner);
}

void square(const F2 &M, const F1 &q) {
  if (M.shape(0) != q.shape(0) || M.shape(1) != q.shape(0))
    throw std::invalid_argument("M (n, n) and q (n) expected");
}

// LCP(M, q) by Lemke's pivots: (z, ok), ok false on ray termination or the pivot limit.
nb::tuple lemke(F2 M, F1 q, int max_iter, double tol) {
  square(M, q);
  const int n = static_cast<int>(q.shape(0));
  std::vector<double> z(n);
  packbot_native::lcp::Work wk;
  const bool ok = packbot_native::lcp::lemke(M.data(), q.data(), n, max_iter, tol, z.data(), wk);
  return nb::make_tuple(owned(z.data(), {z.size()}), ok);
}

// The scaled residual of z for LCP(M, q).
double lcp_residual(F2 M, F1 q, F1 z) {
  square(M, q);
  if (z.shape(0) != q.shape(0)) throw std::invalid_argument("z (n) expected");
  return packbot_native::lcp::residual(M.data(), q.data(), static_cast<int>(q.shape(0)),
                                       z.data());
}

std::vector<double> values(const F1 &x) {
  return std::vector<double>(x.data(), x.data() + x.shape(0));
}

void conic_shapes(const F2 &A, const F1 &g, const F1 &x, const F1 &mus, const F1 &bound) {
  const size_t m = A.shape(0);
  if (g.shape(0) != m || x.shape(0) != m || 3 * mus.shape(0) + bound.shape(0) != m)
    throw std::invalid_argument("A (m, r), g and x (m), mus (K) and bound (B), m = 3 K + B");
}

// The window step's problem by the low-rank ADMM from `guess`: (x, residual, iterations, rho).
nb::tuple solve_conic(F2 A, F1 g, F1 mus, F1 bound, F1 guess, double tol, int max_iterations,
                      double rho0) {
  conic_shapes(A, g, guess, mus, bound);
  const int m = static_cast<int>(A.shape(0)), r = static_cast<int>(A.shape(1));
  std::vector<double> x = values(guess);
  const auto sol = packbot_native::conic::solve(A.data(), m, r, g.data(), values(mus),
                                                values(bound), x.data(), tol, max_iterations,
                                                rho0);
  return nb::make_tuple(owned(x.data(), {x.size()}), sol.residual, sol.iterations, sol.rho);
}

// The true scaled residual of x for the window step's problem (G = A A^T).
double conic_residual(F2 A, F1 g, F1 x, F1 mus, F1 bound) {
  conic_shapes(A, g, x, mus, bound);
  return packbot_native::conic::residual(A.data(), static_cast<int>(A.shape(0)),
                                         static_cast<int>(A.shape(1)), g.data(), x.data(),
                                         values(mus), values(bound));
}

packbot_native::material::Planes planes(const F2 &N, const F1 &o) {
  if (N.shape(0) != o.shape(0) || (N.shape(0) && N.shape(1) != 3))
    throw std::invalid_argument("face planes: N (F, 3) and o (F) expected");
  return {N.data(), o.data(), N.shape(0)};
}

// A contact patch as material points (material::patch_material): (ok, local1, local2,
// normal2, frame2, centre1, centre2, offset0, on1).
nb::tuple patch_material(F2 p1, F2 p2, F1 n, double distance, F2 N1, F1 o1, F2 Rg1, F1 tg1,
                         F2 N2, F1 o2, F2 Rg2, F1 tg2, F2 RM1, F1 tM1, F2 RM2, F1 tM2,
                         double patch_tol, bool check) {
  const size_t K = p1.shape(0);
  if (K == 0 || p1.shape(1) != 3 || p2.shape(0) != K || p2.shape(1) != 3 || n.shape(0) != 3)
    throw std::invalid_argument("p1, p2 (K, 3), K > 0, and n (3) expected");
  for (const F2 *R : {&Rg1, &Rg2, &RM1, &RM2})
    if (R->shape(0) != 3 || R->shape(1) != 3) throw std::invalid_argument("rotations (3, 3)");
  for (const F1 *t : {&tg1, &tg2, &tM1, &tM2})
    if (t->shape(0) != 3) throw std::invalid_argument("translations (3)");
  std::vector<double> l1(3 * K), l2(3 * K), off(2 * K), scratch;
  const auto made = packbot_native::material::patch_material(
      p1.data(), p2.data(), K, n.data(), distance, planes(N1, o1), Rg1.data(), tg1.data(),
      planes(N2, o2), Rg2.data(), tg2.data(), RM1.data(), tM1.data(), RM2.data(), tM2.data(),
      patch_tol, l1.data(), l2.data(), off.data(), scratch, check);
  return nb::make_tuple(made.ok, owned(l1.data(), {K, 3}), owned(l2.data(), {K, 3}),
                        owned(made.normal2, {3}), owned(made.frame2, {3, 3}),
                        owned(made.centre1, {1, 3}), owned(made.centre2, {1, 3}),
                        owned(off.data(), {2, K}), made.on1);
}

}  // namespace

NB_MODULE(_native, m) {
  m.doc() = "packbot's compiled right-hand side of the contact-normal mode (Pinocchio, nanobind).";
  m.attr("PINOCCHIO_VERSION") = PINOCCHIO_VERSION;
  m.def("lemke", &lemke, nb::arg("M"), nb::arg("q"), nb::arg("max_iter"), nb::arg("tol"));
  m.def("lcp_residual", &lcp_residual, nb::arg("M"), nb::arg("q"), nb::arg("z"));
  // (the solver's stall rule: a residual within this many times the tolerance may stop it)
  m.attr("CONIC_STALL_OK") = packbot_native::conic::STALL_OK;
  m.def("solve_conic", &solve_conic, nb::arg("A"), nb::arg("g"), nb::arg("mus"), nb::arg("bound"),
        nb::arg("guess"), nb::arg("tol"), nb::arg("max_iterations"), nb::arg("rho0"));
  m.def("conic_residual", &conic_residual, nb::arg("A"), nb::arg("g"), nb::arg("x"),
        nb::arg("mus"), nb::arg("bound"));
  m.def("patch_material", &patch_material, nb::arg("p1"), nb::arg("p2"), nb::arg("n"),
        nb::arg("distance"), nb::arg("N1"), nb::arg("o1"), nb::arg("Rg1"), nb::arg("tg1"),
        nb::arg("N2"), nb::arg("o2"), nb::arg("Rg2"), nb::arg("tg2"), nb::arg("RM1"),
        nb::arg("tM1"), nb::arg("RM2"), nb::arg("tM2"), nb::arg("patch_tol"), nb::arg("check"));
  nb::class_<ContactRhs>(m, "ContactRhs")
      .def(nb::init<const std::vector<std::string> &, I1, F3, F2, F1, F2, F3, F1, F1>(),
           nb::arg("types"), nb::arg("parents"), nb::arg("placements"), nb::arg("axes"),
           nb::arg("masses"), nb::arg("levers"), nb::arg("inertias"), nb::arg("armature"),
           nb::arg("gravity"))
      .def_prop_ro("nv", &ContactRhs::nv)
      .def("rows", &ContactRhs::rows_out, nb::arg("q"), nb::arg("v"))
      .def("evaluate", &ContactRhs::evaluate_at, nb::arg("q"), nb::arg("v"), nb::arg("a_free"),
           nb::arg("minv"), nb::arg("with_qc") = false)
      .def("forces", &ContactRhs::forces_out, nb::arg("lam"), nb::arg("on1"))
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
      .def("limit_excursions", &ContactRhs::limit_excursions, nb::arg("y0"), nb::arg("y1"),
           nb::arg("h"), nb::arg("tol"))
      .def("set_pair_joints", &ContactRhs::set_pair_joints, nb::arg("start"), nb::arg("idx"))
      .def("pair_dips", &ContactRhs::pair_dips, nb::arg("Q"), nb::arg("theta_max"), nb::arg("h"),
           nb::arg("pairs0"), nb::arg("dist0"), nb::arg("pairs1"), nb::arg("dist1"),
           nb::arg("start_known"), nb::arg("active"), nb::arg("margin"), nb::arg("pen_tol"),
           nb::arg("distance"))
      .def_prop_ro("unresolved_dips", [](ContactRhs &r) { return r.dips().unresolved; })
      .def("end_check", &ContactRhs::end_check, nb::arg("y1"), nb::arg("swept"), nb::arg("dist"),
           nb::arg("active"), nb::arg("near"), nb::arg("pen_tol"))
      .def("set_locks", &ContactRhs::set_locks, nb::arg("locked"))
      .def("set_clamps", &ContactRhs::set_clamps, nb::arg("joint"), nb::arg("side"))
      .def("set_row_mode", &ContactRhs::set_row_mode, nb::arg("locked"),
           nb::arg("velocity_level"), nb::arg("null_row"), nb::arg("null_gap"))
      .def("lock_subspace", &ContactRhs::lock_subspace, nb::arg("a_free"), nb::arg("minv"),
           nb::arg("locked"))
      .def("lock_torques", &ContactRhs::lock_torques, nb::arg("a_free"), nb::arg("minv"),
           nb::arg("qc"), nb::arg("locked"))
      .def("stop_joints", &ContactRhs::stop_joints, nb::arg("v"), nb::arg("minv"),
           nb::arg("joint"), nb::arg("side"), nb::arg("one_sided"), nb::arg("res_tol"))
      .def("energies", &ContactRhs::energies, nb::arg("Q"), nb::arg("V"), nb::arg("out"))
      .def("neutral_velocity", &ContactRhs::neutral_velocity, nb::arg("q0"), nb::arg("q1"),
           nb::arg("v"))
      .def("end_locks", &ContactRhs::end_locks, nb::arg("y1"))
      .def("lock_torques_at", &ContactRhs::lock_torques_at, nb::arg("q"), nb::arg("v"),
           nb::arg("tau"))
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
