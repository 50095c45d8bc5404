// ContactRhs: the contact forces of the modes at the last rows (rows_at, evaluate_at), read
// off the multipliers of the modes' problem (packbot.contact.normal_forces.mode_forces):
//
//   an engaged patch point's multiplier lambda is its normal force: the force on body 2 is
//   lambda n, less mu lambda s when its pair slips (s the point's sliding direction, as the
//   force columns J_n - mu J_s of solve_plan have it: point_slip_direction, rows.hpp); a
//   sticking pair's two tangential multipliers are its friction force lambda_1 t1 + lambda_2 t2
//   at the patch centre; a limit row's multiplier is its stop's torque -side lambda on its
//   joint (an upper stop pushes toward -q).
//
// World frame, SI units. A point touches at the material point of the body not carrying the
// normal (the rows' exact derivative of the gap n . (p2 - p1), n turning with its body, acts
// there on both).

#include "contact_rhs.hpp"
#include "rows.hpp"

#include <cstddef>
#include <stdexcept>
#include <vector>

// The forces of the plan's modes with the multipliers lam (ne engaged rows, then two per
// sticking pair: evaluate's, or any solver's of the same problem) on the rows last computed.
// on1 (np): whether each pair's normal is carried by its body 1. Returns (who (k, 2): the
// pair and its row, -1 for a sticking pair's centre; touch, point1, point2, normal, force
// (k, 3) [m, m, m, -, N]; the stops' torques (nv) [N*m]), the records pair by pair: its engaged
// points in row order, then its centre.
nb::tuple ContactRhs::forces_out(F1 lam, U1 on1) {
  const int nv = nv_;
  if (lock_mode_ >= 0) throw std::invalid_argument("forces: the contact rows' call (set_locks)");
  if (lam.shape(0) != static_cast<size_t>(n_))
    throw std::invalid_argument("lam: one multiplier per row of the plan expected");
  if (on1.shape(0) != static_cast<size_t>(np_))
    throw std::invalid_argument("on1: one flag per pair expected");
  const double *L = lam.data();
  std::vector<int> pos(static_cast<size_t>(m_), -1);
  for (int e = 0; e < ne_; ++e) pos[static_cast<size_t>(engaged_[e])] = e;
  std::vector<int> stick(static_cast<size_t>(np_), -1);
  for (int i = 0; i < ns_; ++i) stick[static_cast<size_t>(sticks_[i])] = ne_ + 2 * i;
  std::vector<int64_t> who;
  std::vector<double> touch, p1, p2, normal, force;
  const auto put = [](std::vector<double> &out, const double *x) {
    out.insert(out.end(), x, x + 3);
  };
  const int h = h_;
  for (int p = 0; p < np_; ++p) {
    const double *F = &F_[9 * p];
    const double *n = F + 6;
    const bool normal_on1 = on1.data()[p] != 0;
    for (int r = 0; r < mp_; ++r) {
      const int k = static_cast<int>(rows_[r]);
      if (pair_[k] != p || pos[static_cast<size_t>(r)] < 0) continue;
      const int e = pos[static_cast<size_t>(r)];
      double f[3] = {L[e] * n[0], L[e] * n[1], L[e] * n[2]};
      if (row_slip_[e] >= 0) {
        double s[3];
        packbot_native::point_slip_direction(&dJp_[k * 3 * nv], n, v_.data(), nv,
                                             &slip_dir_[3 * p], stick_speed_, s);
        for (int i = 0; i < 3; ++i) f[i] -= mu_ * L[e] * s[i];
      }
      const double *a = &P_[3 * k], *b = &P_[3 * (h + k)];
      who.push_back(p);
      who.push_back(r);
      put(touch, normal_on1 ? b : a);
      put(p1, a);
      put(p2, b);
      put(normal, n);
      put(force, f);
    }
    const int s = stick[static_cast<size_t>(p)];
    if (s >= 0) {  // the sticking pair's friction, at its patch centre
      const int c0 = static_cast<int>(centre_[p]);
      const double *c = normal_on1 ? &P_[3 * (h + c0)] : &P_[3 * c0];
      const double f[3] = {L[s] * F[0] + L[s + 1] * F[3], L[s] * F[1] + L[s + 1] * F[4],
                           L[s] * F[2] + L[s + 1] * F[5]};
      who.push_back(p);
      who.push_back(-1);
      put(touch, c);
      put(p1, c);
      put(p2, c);
      put(normal, n);
      put(force, f);
    }
  }
  std::vector<double> limit(static_cast<size_t>(nv), 0.0);
  for (int l = 0; l < ml_; ++l) {
    const int e = pos[static_cast<size_t>(mp_ + l)];
    if (e >= 0) limit[static_cast<size_t>(lim_joint_[l])] -= lim_side_[l] * L[e];
  }
  const size_t k = who.size() / 2;
  return nb::make_tuple(owned_mat_i(who, k, 2), owned_mat(touch, k, 3), owned_mat(p1, k, 3),
                        owned_mat(p2, k, 3), owned_mat(normal, k, 3), owned_mat(force, k, 3),
                        owned_vec(limit));
}
