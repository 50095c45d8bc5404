// packbot._native's ContactRhs: the contact-normal mode's right-hand side with its modes fixed,
// in one native call, and the native steps built on it.
//
// One object, ``ContactRhs``, holds its own Pinocchio model (rebuilt from the Python model's
// numbers: joint types, parents, placements, inertias, armature, gravity; nothing crosses
// between this module's Pinocchio and the pin wheel's, so the two need not share an ABI), its
// Data, the contact set's point layout and the current modes' plan, and every work array (sized
// when the layout or the plan change: no allocation per call). ``accel`` then does what
// the contact-normal mode needs per call:
//
//   aba (unconstrained accelerations, armature included; or a_free given), computeMinverse,
//   computeJointJacobiansTimeVariation, then the contact rows and the constrained
//   accelerations (their one implementation: the contact set's Python side reads them through
//   rows_out and evaluate_at).
//
// Conventions as packbot.contact.normal.NormalContacts: world frame, SI units; a row's gap and
// normal velocity are body 2 minus body 1 along the normal carried by body 2.
//
// This header declares the class and holds its members; its member functions are defined one
// concept a file:
//   contact_rhs_model.cpp     the model, the layout, the loaded constants, the work arrays
//   contact_rhs_passes.cpp    Pinocchio's passes (aba, M^-1, crba, ...: their one instance)
//   contact_rhs_rows.cpp      the contact rows
//   contact_rhs_dynamics.cpp  the constrained accelerations of the modes
//   contact_rhs_forces.cpp    the contact forces of the modes (their multipliers as forces)
//   contact_rhs_locks.cpp     the joint locks (the report's law instead of the contact rows)
//   contact_rhs_clamps.cpp    the hand-off's joint clamp rows and locked joints
//   contact_rhs_events.cpp    the step end: its evaluation, a row's event, its screen
//   contact_rhs_step.cpp      the integrator steps (Dormand-Prince 5(4), RODAS4)
//   contact_rhs_window.cpp    the time-stepping window (Moreau-Jean)
//   contact_rhs_restart.cpp   a restart's steps (drift projection, impact, modes, slow slides)
//   contact_rhs_repatch.cpp   the native stretch's re-patch (stretch.hpp)
// and the Python module in bindings.cpp (the native stretch's part in stretch_glue.cpp). The
// self-contained numerics they use are free functions: small_solve.hpp (the small dense solves),
// brentq.hpp (SciPy's brentq), np_sum.hpp (numpy's pairwise sum).
#pragma once

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include "joints.hpp"
#include "lcp.hpp"
#include "pair_dips.hpp"

#include <pinocchio/multibody/data.hpp>
#include <pinocchio/multibody/model.hpp>

#include <Eigen/LU>

#include <algorithm>
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace nb = nanobind;
namespace pin = pinocchio;

// The joints this module's model may hold: the 1-dof revolute and prismatic ones (joints.hpp,
// shared with sweep.cpp).
using packbot_native::make_joint;
using packbot_native::PackbotJointsTpl;
using Model = pin::ModelTpl<double, 0, PackbotJointsTpl>;
using Data = pin::DataTpl<double, 0, PackbotJointsTpl>;

using F1 = nb::ndarray<const double, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using F2 = nb::ndarray<const double, nb::ndim<2>, nb::c_contig, nb::device::cpu>;
using F3 = nb::ndarray<const double, nb::ndim<3>, nb::c_contig, nb::device::cpu>;
using I1 = nb::ndarray<const int64_t, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using Out1 = nb::ndarray<double, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using Out2 = nb::ndarray<double, nb::ndim<2>, nb::c_contig, nb::device::cpu>;
using U1Out = nb::ndarray<uint8_t, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using U1 = nb::ndarray<const uint8_t, nb::ndim<1>, nb::c_contig, nb::device::cpu>;

namespace packbot_native {

// (the restart's types: rows.hpp, modes.hpp, stop_slow.hpp, complete in contact_rhs_rows.cpp
// and contact_rhs_restart.cpp)
struct Rows;
namespace modes {
class Selection;
}
namespace stop_slow {
class StopSlow;
}

template <class A> std::vector<int64_t> ints(const A &a) {
  return std::vector<int64_t>(a.data(), a.data() + a.size());
}
template <class A> std::vector<double> reals(const A &a) {
  return std::vector<double>(a.data(), a.data() + a.size());
}

}  // namespace packbot_native

class ContactRhs {
 public:
  // ---- the model, the layout, the loaded constants, the work arrays: contact_rhs_model.cpp
  ContactRhs(const std::vector<std::string> &types, I1 parents, F3 placements, F2 axes,
             F1 masses, F2 levers, F3 inertias, F1 armature, F1 gravity);
  ~ContactRhs();  // (contact_rhs_restart.cpp: sel_'s and stopper_'s types are complete there)
  void set_reach(F1 reach, double margin, double max_step);
  double step_bound(F1 y) const;
  double step_bound_raw(const double *v) const;
  void set_layout(I1 joints, F2 masks, I1 body, F2 local, I1 pair, I1 rows, I1 centre,
                  I1 normal_body, F3 frame2, I1 lim_joint, F1 lim_side, F1 lim_value);
  void layout_changed();
  void set_patches(F2 local, F3 frame2, F2 offset0, F1 slide_tol2);
  void set_conditions(F2 offset0, F1 slide_tol2, double force_band, double point_tol,
                      double stick_band);
  void set_keys(I1 keys);
  void set_limits(F1 upper, F1 lower);
  void minverse_at(const double *q, double *out);
  void free_accel_raw(const double *q, const double *v, double *out);
  void energies(F2 Q, F2 V, Out1 out);
  // A drift projection q0 -> q1's velocity that adds no energy (contact_rhs_restart.cpp): v
  // in/out [rad/s]; the energy removed [J].
  double neutral_velocity_raw(const double *q0, const double *q1, double *v);
  double neutral_velocity(F1 q0, F1 q1, Out1 v);
  void set_torque(F1 applied, F1 viscous, F1 coulomb_dir);
  static nb::ndarray<nb::numpy, int64_t, nb::ndim<2>> owned_mat_i(const std::vector<int64_t> &v,
                                                                   size_t rows, size_t cols);
  static nb::ndarray<nb::numpy, double, nb::ndim<2>> owned_mat(const std::vector<double> &v,
                                                                size_t rows, size_t cols);
  double kinetic(const Eigen::VectorXd &q, const double *v);
  int nv() const { return nv_; }
  // The joint limits set_limits loaded [rad] (empty: none).
  const std::vector<double> &upper() const { return upper_; }
  const std::vector<double> &lower() const { return lower_; }
  template <class T> static nb::ndarray<nb::numpy, T, nb::ndim<1>> owned_vec(const std::vector<T> &v) {
    T *buf = new T[v.empty() ? 1 : v.size()];
    std::copy(v.begin(), v.end(), buf);
    nb::capsule owner(buf, [](void *p) noexcept { delete[] static_cast<T *>(p); });
    return nb::ndarray<nb::numpy, T, nb::ndim<1>>(buf, {v.size()}, owner);
  }

  // ---- the contact rows: contact_rhs_rows.cpp
  packbot_native::Rows rows_view() const;
  nb::tuple rows_out(F1 q, F1 v);

  // ---- the constrained accelerations of the modes: contact_rhs_dynamics.cpp
  void set_plan(I1 engaged, I1 row_slip, I1 sticks, double mu, double stick_speed,
                double baumgarte);
  void set_slip_dirs(F2 slip_dir);
  void load_plan(const std::vector<int> &eng, const uint8_t *stick, const double *slip_dir);
  template <class Flag>
  void plan_rows(const std::vector<int> &eng, const Flag *stick);
  bool accel(F1 q, F1 v, F1 x, bool from_tau, Out1 out);
  bool evaluate_modes(const std::vector<int> &eng, const std::vector<char> &stick,
                      const std::vector<double> &slip_dir, const double *a_free, const double *Mi,
                      double mu, double stick_speed, double baumgarte, double *a, double *cond,
                      std::vector<double> &lam);
  nb::object evaluate_at(F1 q, F1 v, F1 a_free, F2 minv, bool with_qc);
  nb::tuple last() const;

  // ---- the contact forces of the modes: contact_rhs_forces.cpp
  nb::tuple forces_out(F1 lam, U1 on1);

  // ---- the joint locks: contact_rhs_locks.cpp
  void set_locks(I1 locked);
  nb::object end_locks(F1 y1);
  nb::object lock_torques_at(F1 q, F1 v, F1 tau);
  void set_screen(F2 rows, double torque_band, double accel_band);
  double end_screen(F1 y1, double margin);

  // ---- the hand-off's clamp rows and locked joints: contact_rhs_clamps.cpp
  void set_clamps(I1 joint, F1 side);
  void set_row_mode(I1 locked, bool velocity_level, double null_row, double null_gap);
  nb::tuple lock_subspace(F1 a_free, F2 minv, I1 locked) const;
  nb::ndarray<nb::numpy, double, nb::ndim<1>> lock_torques(F1 a_free, F2 minv, F1 qc,
                                                           I1 locked) const;
  nb::tuple stop_joints(F1 v, F2 minv, I1 joint, F1 side, bool one_sided, double res_tol);

  // ---- the step end and its events: contact_rhs_events.cpp
  nb::object end_eval(F1 y1);
  nb::object eval_at(F1 y);
  double row_condition_at(F1 y, int64_t r);
  double row_root(F2 Z, double t0, double t1, double h, F1 y1, bool hermite, int64_t r,
                  double g0, double g1, double xtol);
  int end_check(F1 y1, I1 swept, F1 dist, I1 active, double near, double pen_tol);
  int end_check_raw(const double *y1, const int64_t *sp, const double *dp, size_t ns,
                    const int64_t *ac, size_t na, double near, double pen_tol);
  // Whether the loaded layout has joint j's stop on `side` (+1 upper, -1 lower) as a limit row.
  bool has_limit_row(int64_t j, int side) const {
    for (int l = 0; l < ml_; ++l)
      if (lim_joint_[l] == j && lim_side_[l] == static_cast<double>(side)) return true;
    return false;
  }
  // Whether q (n joints) is past one of the stops (upper, lower [rad]) that is not a limit row.
  bool past_a_stop_not_in_rows(const double *q, const double *upper, const double *lower,
                               size_t n) const {
    for (size_t j = 0; j < n; ++j) {
      if (q[j] > upper[j] && !has_limit_row(static_cast<int64_t>(j), 1)) return true;
      if (q[j] < lower[j] && !has_limit_row(static_cast<int64_t>(j), -1)) return true;
    }
    return false;
  }
  struct Excursion {
    int joint, side;
    double s;  // (the extreme's fraction of the step)
  };
  void limit_excursions_raw(const double *y0, const double *y1, double h, double tol,
                            std::vector<Excursion> &out) const;
  nb::list limit_excursions(F1 y0, F1 y1, double h, double tol) const;
  // The contacts between step ends (pair_dips.hpp): each world pair's joints (set_pair_joints:
  // a CSR of velocity indices), the screen (its raw form the stretch's, pair_dips Python's).
  void set_pair_joints(I1 start, I1 idx);
  packbot_native::PairDips &dips() { return dips_; }
  const std::vector<double> &reach() const { return reach_; }
  nb::tuple pair_dips(F2 Q, double theta_max, double h, I1 pairs0, F1 dist0, I1 pairs1,
                      F1 dist1, bool start_known, I1 active, double margin, double pen_tol,
                      nb::callable distance);
  // Whether the last end_check_raw's bit 4 was a stale patch of a sliding pair for certain
  // (not a slide speed at the stick speed, which the caller decides).
  bool stale_sure() const { return stale_sure_; }

  // ---- the integrator steps: contact_rhs_step.cpp
  bool first(Out2 Z);
  bool first_raw(double *z);
  void check_attempt(const Out2 &Z, const F1 &ay0, const F1 &atol, const Out1 &y1,
                     const Out1 &ay1) const;
  double dopri(double h, Out2 Z, F1 ay0, F1 atol, double rtol, Out1 y1, Out1 ay1);
  double dopri_raw(double h, double *z, const double *a0, const double *at, double rtol,
                   double *yn, double *a1);
  double rosenbrock(double h, Out2 Z, F1 ay0, F1 atol, double rtol, Out1 y1, Out1 ay1);
  double rosenbrock_raw(double h, double *z, const double *a0, const double *at, double rtol,
                        double *yn, double *a1);
  double jac_radius();
  // The last dopri's stiffness estimate h |lambda| (Hairer's DOPRI5 test; Dormand-Prince's
  // stability bound on the negative real axis is about 3.3).
  double stiffness() const { return hlamb_; }

  // ---- the time-stepping window: contact_rhs_window.cpp
  // window_step's arguments that stay the same from step to step (see window_step).
  struct WindowArgs {
    const double *reach = nullptr;
    double active_gap = 0.0;
    const double *upper = nullptr, *lower = nullptr;  // (nullptr: no limits)
    double limit_gap = 0.0, mu = 0.0, restitution = 0.0, zeno = 0.0, touch_gap = 0.0;
    const int64_t *boxes = nullptr;
    int B = 0;
    double tol = 0.0;
    int max_iterations = 0;
    double ok = 0.0;
    // false: the set is the caller's, just updated for this step (MoreauJeanStepper's Python
    // step after its set update): the sweep, limit and patch checks are left out
    bool checked = true;
  };

  // What window_core did: its status (window_step's), the solver's residual, iterations and
  // last rho, and (status 0) the energies [J].
  struct WindowOut {
    int status = 0;
    double residual = 0.0;
    int iterations = 0;
    double rho = 0.0;
    double energies[3] = {0.0, 0.0, 0.0};
  };

  nb::tuple window_step(F1 y, double h, I1 swept, F1 dist, double sweep_margin, F1 reach,
                        double active_gap, F1 upper, F1 lower, double limit_gap, double mu,
                        double restitution, double zeno, double touch_gap, I1 boxes, F1 bound,
                        F1 guess, double rho0, double tol, int max_iterations, double ok,
                        Out1 out_vf, Out1 out_v1, Out1 out_q1, bool checked);
  void check_window() const;
  WindowOut window_core(const double *y, double h, const int64_t *swept, const double *dist,
                        size_t nsw, double sweep_margin, const WindowArgs &a, const double *bound,
                        const double *guess, size_t nguess, double rho0, double *ovf, double *ov1,
                        double *oq1, std::vector<double> &x);
  nb::dict window_run(nb::capsule api, Out1 y, double t, double t_end, double t_commit,
                      double h_window, double until, int quiet, int quiet_steps, bool last_valid,
                      I1 last_sig, I1 swept, F1 dist, double sweep_margin, int64_t best,
                      double best_d, F1 reach, double active_gap, F1 upper, F1 lower,
                      double limit_gap, double mu, double restitution, double zeno,
                      double touch_gap, I1 boxes, F1 coul, F1 guess, double rho0, double tol,
                      int max_iterations, double ok, F1 applied, bool has_e, double e_last,
                      double step_angle, double sweep_slack, double project_depth,
                      double impulse_band, double min_d, int max_steps);

  // ---- a restart's steps: contact_rhs_restart.cpp
  // The law's constants of a mode selection (select_modes' arguments).
  struct ModeConsts {
    double mu, touch_gap, speed_band, stick_speed, force_band, stick_band, baumgarte,
        residual_tol;
  };

  // What a mode selection decided (select_modes' results).
  struct ModesOut {
    bool kept = false;
    std::vector<int> engaged, events;
    int painleve = 0;
    bool gave_up = false;
  };

  int project_round(F1 q, F1 v, F2 minv, double touch_gap, double pen_tol, double res_tol,
                    Out1 out_q);
  int project_round_raw(const double *q, const double *v, const double *minv, double touch_gap,
                        double pen_tol, double res_tol, double *oq);
  nb::tuple impact(F1 q, F1 v, F2 minv, double mu, double restitution, double zeno,
                   double touch_gap, double res_tol, double conic_tol, int max_iterations,
                   double accept, Out1 out_v);
  nb::tuple select_modes(F1 q, F1 v, F1 a_free, F2 minv, bool keep, I1 held, U1Out stick_io,
                         Out2 slip_io, double mu, double touch_gap, double speed_band,
                         double stick_speed, double force_band, double stick_band,
                         double baumgarte, double residual_tol);
  int select_modes_raw(const double *q, const double *v, const double *a_free,
                       const double *minv, bool keep, const int64_t *held, size_t nh,
                       uint8_t *stick_io, double *slip_io, const ModeConsts &k, ModesOut &o);
  int stop_slow(F1 q, F1 v, F2 minv, double touch_gap, double speed_band, double stick_speed,
                double capture_speed, double residual_tol, double dependent_row, Out1 out_v);
  static bool all_finite(const double *x, size_t n);

  // ---- the native stretch's re-patch: contact_rhs_repatch.cpp
  void set_patches_raw(const double *local, const double *frame2, const double *offset0,
                       const double *slide_tol2);
  void relayout_raw(const std::vector<int> &K, const double *local, const double *frame2,
                    const double *offset0, const double *slide_tol2);
  void keep_loaded();
  void restore_loaded();
  // what the re-patch reads (packbot.contact.normal_contacts.NormalContacts.repatch's native
  // steps: stretch.hpp)
  int n_pairs() const { return np_; }
  int n_points() const { return h_; }  // the layout's points: each pair's K and its centre
  int n_pair_rows() const { return mp_; }
  const std::vector<int64_t> &keys() const { return keys_; }
  const std::vector<int> &pair_rows() const { return pK_; }  // each pair's K
  bool contact_rows() const { return conditions_set_ && lock_mode_ < 0; }
  const std::vector<int64_t> &engaged() const { return engaged_; }

 private:
  // (Pinocchio's passes on model_ and data_: contact_rhs_passes.cpp) aba(WORLD) at (q, v)
  // under tau (data_.ddq), computeMinverse at q or after aba (data_.Minv's upper triangle),
  // computeJointJacobiansTimeVariation at (q_, v_), crba(LOCAL) at q (data_.M's upper
  // triangle), nonLinearEffects at (q_, v_) (data_.nle), the potential energy of gravity at q.
  void aba_world(const Eigen::VectorXd &q, const Eigen::VectorXd &v, const Eigen::VectorXd &tau);
  void minverse(const Eigen::VectorXd &q);
  void minverse_after_aba();
  void jacobians_time_variation();
  void crba_local(const Eigen::VectorXd &q);
  void nonlinear_effects();
  double potential(const Eigen::VectorXd &q);

  // (the model, the layout, the loaded constants, the work arrays: contact_rhs_model.cpp)
  static nb::ndarray<nb::numpy, double, nb::ndim<1>> vec(const double *p, size_t n);
  static nb::ndarray<nb::numpy, double, nb::ndim<2>> mat(const double *p, size_t r, size_t c);
  void set_plan_sizes(int ne, int ns);

  // (the contact rows: contact_rhs_rows.cpp)
  void time_variation();
  void rows_at(const double *q, const double *v);
  void rows();

  // (the constrained accelerations of the modes: contact_rhs_dynamics.cpp)
  bool stage(const double *y, double *f);
  bool compute(bool after_aba);
  bool solve_plan();
  double end_conditions();

  // (the joint locks: contact_rhs_locks.cpp)
  bool lock_accel();

  // (the hand-off's rows: contact_rhs_clamps.cpp)
  void clamp_rows();

  // (the step end and its events: contact_rhs_events.cpp)
  bool at_end(F1 y1) const;

  // (the integrator steps: contact_rhs_step.cpp)
  bool jacobian(const double *y0, const double *f0);

  // (a restart's steps: contact_rhs_restart.cpp)
  void check_restart(const char *who, F1 q, F1 v, F2 minv, Out1 out) const;
  void touching(double touch_gap);
  void delassus(const double *Mi, int nt);
  void impulse_dv(const double *J, int n, const double *Mi, const double *x);
  double energy_change(const double *J, int n, const double *x, const double *w) const;

  Model model_;
  Data data_;
  int nv_ = 0;
  Eigen::VectorXd q_, v_, x_, a_free_, a_, force_;
  // the report's law's locks (set_locks): -1 the contact rows, 0 none, 1 one, 2 the unlocked block
  int lock_mode_ = -1;
  std::vector<int64_t> locked_;
  std::vector<int> unlocked_;
  std::vector<double> lock_lam_;
  // the lock conditions' screen (set_screen)
  std::vector<double> screen_;
  double torque_band_ = 0.0, accel_band_ = 0.0;
  Eigen::MatrixXd minv_;
  // (the restart steps: project_round, impact)
  std::vector<int> touch_;
  std::vector<double> JM_, Gt_, MJt_, rt_, zt_, jx_, dv_;
  // (the mode selection: select_modes) each pair's first patch row and its number of rows
  std::vector<int> pfirst_, pK_;
  // (made on first use, in contact_rhs_restart.cpp)
  std::unique_ptr<packbot_native::modes::Selection> sel_;
  std::unique_ptr<packbot_native::stop_slow::StopSlow> stopper_;
  packbot_native::lcp::Work lcp_;
  // layout
  std::vector<int64_t> joints_, body_, pair_, rows_, centre_, normal_body_, lim_joint_;
  std::vector<double> masks_, local_, frame2_, lim_side_, lim_value_;
  int nb_ = 0, n2h_ = 0, h_ = 0, np_ = 0, mp_ = 0, ml_ = 0, mc_ = 0, m_ = 0;
  // the clamp rows (set_clamps: after the limits) and how the rows are reported (set_row_mode)
  std::vector<int64_t> clamp_joint_, row_locked_;
  std::vector<double> clamp_side_;
  bool clamp_velocity_ = false;
  double null_row_ = 0.0, null_gap_ = 0.0;
  // plan
  std::vector<int64_t> engaged_, row_slip_, sticks_;
  double mu_ = 0.0, stick_speed_ = 0.0, baumgarte_ = 0.0;
  int ne_ = 0, ns_ = 0, n_ = 0;
  // work
  std::vector<double> H_, Vb_, Ab_, P_, Jp_, vp_, ap_, dJp_, vrel_, arel_, dP_, F_;
  std::vector<double> Jn_, drift_, gap_, vn_, JT_, bT_, vT_, vt_, slip_dir_;
  std::vector<double> A_, C_, target_, b_, MC_, G_, G0_, rhs_, rhs0_, lam_;
  // the step's torques and its stage argument
  std::vector<double> applied_, viscous_, coulomb_dir_, ys_;
  // the step end's conditions (end_eval)
  std::vector<double> offset0_, y_end_;
  std::vector<int> pos_;
  std::vector<char> slipping_, engaged_pair_;
  std::vector<double> slide2_, gap_min_, slide_tol2_;
  std::vector<int64_t> keys_;  // (set_keys)
  bool stale_sure_ = false;  // (end_check_raw)
  // (keep_loaded's copies)
  std::vector<double> kept_local_, kept_frame2_, kept_offset0_, kept_slide_tol2_, kept_slip_dir_;
  std::vector<int64_t> kept_engaged_, kept_row_slip_, kept_sticks_;
  std::vector<int64_t> kept_body_, kept_pair_, kept_rows_, kept_centre_;
  bool relaid_ = false;  // (relayout_raw since keep_loaded)
  std::array<double, 3> kept_plan_{};
  std::vector<double> upper_, lower_;  // (set_limits)
  std::vector<double> reach_;  // (set_reach)
  packbot_native::PairDips dips_;  // (set_pair_joints)
  std::vector<double> vmax_;  // (pair_dips: each joint's speed bound over the step)
  double margin_ = 0.0, max_step_ = 0.0;
  double force_band_ = 0.0, point_tol_ = 0.0, stick_band_ = 0.0;
  bool conditions_set_ = false, end_valid_ = false;
  // the stiff steps (stiffness, rosenbrock): the last dopri's h |lambda|, the Jacobian, where
  // it was taken, its spectral radius (-1: not computed), the LU of I/(h gamma) - J, the stages
  double hlamb_ = 0.0, radius_ = -1.0;
  bool jac_valid_ = false;
  Eigen::MatrixXd jac_, K_;
  Eigen::PartialPivLU<Eigen::MatrixXd> lu_;
  std::vector<double> y_jac_, yp_, fp_, fs_;
};
