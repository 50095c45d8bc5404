// ContactRhs: the contact rows of the contact-normal mode from the joint placements, Jacobians
// and their time variation: the points, the normal rows (Jn, drift, gap,
// vn), the limit rows, the centres' tangential rows (JT, bT, vT) and sliding velocities.

#include "contact_rhs.hpp"
#include "rows.hpp"

#include <pinocchio/spatial/act-on-set.hpp>

#include <algorithm>
#include <cstddef>
#include <initializer_list>
#include <stdexcept>
#include <vector>

namespace {

// A numpy copy of the first prod(shape) doubles of v.
nb::ndarray<nb::numpy, double> copy_of(const std::vector<double> &v,
                                       std::initializer_list<size_t> shape) {
  size_t n = 1;
  for (const size_t s : shape) n *= s;
  auto *buf = new double[n ? n : 1];
  std::copy(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(n), buf);
  nb::capsule owner(buf, [](void *d) noexcept { delete[] static_cast<double *>(d); });
  return nb::ndarray<nb::numpy, double>(buf, shape, owner);
}

}  // namespace

// The rows at (q, v) with the loaded layout (rows_at), copied out for the contact set's
// Python side (packbot.contact.normal_rows.ContactRows._kinematics): Jn (m, nv), drift, gap,
// vn (m), JT (np, 2, nv), bT, vT (np, 2), vt (np, 3), F (np, 3, 3: rows t1, t2, n of each
// pair's contact frame, world), dJp (h, 3, nv) and dP (h, 3) at every point and centre.
nb::tuple ContactRhs::rows_out(F1 q, F1 v) {
  const size_t nv = static_cast<size_t>(nv_);
  if (q.shape(0) != nv || v.shape(0) != nv)
    throw std::invalid_argument("q and v: nv entries expected");
  if (lock_mode_ >= 0) throw std::invalid_argument("rows_out: the contact rows' call (set_locks)");
  rows_at(q.data(), v.data());
  const size_t m = static_cast<size_t>(m_), np = static_cast<size_t>(np_);
  const size_t h = static_cast<size_t>(h_);
  return nb::make_tuple(copy_of(Jn_, {m, nv}), copy_of(drift_, {m}), copy_of(gap_, {m}),
                        copy_of(vn_, {m}), copy_of(JT_, {np, 2, nv}), copy_of(bT_, {np, 2}),
                        copy_of(vT_, {np, 2}), copy_of(vt_, {np, 3}), copy_of(F_, {np, 3, 3}),
                        copy_of(dJp_, {h, 3, nv}), copy_of(dP_, {h, 3}));
}

// The rows computed (rows_at) as the restart's native steps read them.
packbot_native::Rows ContactRhs::rows_view() const {
  packbot_native::Rows R;
  R.nv = nv_;
  R.m = m_;
  R.mp = mp_;
  R.np = np_;
  R.Jn = Jn_.data();
  R.drift = drift_.data();
  R.gap = gap_.data();
  R.vn = vn_.data();
  R.JT = JT_.data();
  R.bT = bT_.data();
  R.vT = vT_.data();
  R.vt = vt_.data();
  R.F = F_.data();
  R.dJp = dJp_.data();
  R.v = v_.data();
  R.rows = rows_.data();
  R.first = pfirst_.data();
  R.K = pK_.data();
  return R;
}

// data_.dJ (and data_.v, data_.ov) after aba(WORLD) at (q_, v_), whose joint placements
// (liMi, oMi), joint motions and J they reuse: computeJointJacobiansTimeVariation's own
// arithmetic (vJ = v_J + liMi^-1 v_parent, ov = oMi vJ, dJ = ov x J), so the same numbers,
// without its second pass of joint transforms and Jacobian columns.
void ContactRhs::time_variation() {
  for (pin::JointIndex i = 1; i < static_cast<pin::JointIndex>(model_.njoints); ++i) {
    const pin::JointIndex parent = model_.parents[i];
    Data::Motion &vJ = data_.v[i];
    vJ = data_.joints[i].v();
    if (parent > 0) vJ += data_.liMi[i].actInv(data_.v[parent]);
    data_.ov[i] = data_.oMi[i].act(vJ);
    const int c0 = model_.joints[i].idx_v(), n = model_.joints[i].nv();
    pin::motionSet::motionAction(data_.ov[i], data_.J.middleCols(c0, n),
                                 data_.dJ.middleCols(c0, n));
  }
}

// The rows at (q, v) with the loaded layout (rows()); the cached evaluations are forgotten.
void ContactRhs::rows_at(const double *q, const double *v) {
  end_valid_ = false;
  jac_valid_ = false;
  for (int i = 0; i < nv_; ++i) {
    q_[i] = q[i];
    v_[i] = v[i];
  }
  if (nb_ > 0) jacobians_time_variation();
  rows();
}

// Every contact row of the loaded layout, with H, J, dJ from data_ (H: the bodies' world
// placements; J, dJ: Pinocchio's joint Jacobians at the world origin and their time variation).
void ContactRhs::rows() {
  const int nv = nv_;
  for (int b = 0; b < nb_; ++b) {
    const auto &M = data_.oMi[static_cast<size_t>(joints_[b])];
    double *H = &H_[16 * b];
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) H[4 * r + c] = M.rotation()(r, c);
      H[4 * r + 3] = M.translation()(r);
    }
    H[12] = H[13] = H[14] = 0.0;
    H[15] = 1.0;
    const double *mk = &masks_[b * nv];
    for (int r = 0; r < 6; ++r) {
      double sv = 0.0, sa = 0.0;
      for (int c = 0; c < nv; ++c) {
        if (mk[c] != 0.0) {
          sv += data_.J(r, c) * v_[c];
          sa += data_.dJ(r, c) * v_[c];
        }
      }
      Vb_[6 * b + r] = sv;
      Ab_[6 * b + r] = sa;
    }
  }
  for (int i = 0; i < n2h_; ++i) {
    const int b = static_cast<int>(body_[i]);
    const double *H = &H_[16 * b];
    const double *l = &local_[4 * i];
    double *P = &P_[3 * i];
    for (int r = 0; r < 3; ++r)
      P[r] = H[4 * r] * l[0] + H[4 * r + 1] * l[1] + H[4 * r + 2] * l[2] + H[4 * r + 3];
    const double px = P[0], py = P[1], pz = P[2];
    double *Jp = &Jp_[i * 3 * nv];
    const double *mk = &masks_[b * nv];
    for (int c = 0; c < nv; ++c) {
      const double m = mk[c];
      const double wx = data_.J(3, c) * m, wy = data_.J(4, c) * m, wz = data_.J(5, c) * m;
      Jp[c] = data_.J(0, c) * m - (py * wz - pz * wy);
      Jp[nv + c] = data_.J(1, c) * m - (pz * wx - px * wz);
      Jp[2 * nv + c] = data_.J(2, c) * m - (px * wy - py * wx);
    }
    double *vp = &vp_[3 * i];
    for (int r = 0; r < 3; ++r) {
      double s = 0.0;
      for (int c = 0; c < nv; ++c) s += Jp[r * nv + c] * v_[c];
      vp[r] = s;
    }
    const double *al = &Ab_[6 * b + 3];
    const double *w = &Vb_[6 * b + 3];
    // pa = P x al, wv = w x vp
    const double pa0 = P[1] * al[2] - P[2] * al[1];
    const double pa1 = P[2] * al[0] - P[0] * al[2];
    const double pa2 = P[0] * al[1] - P[1] * al[0];
    const double wv0 = w[1] * vp[2] - w[2] * vp[1];
    const double wv1 = w[2] * vp[0] - w[0] * vp[2];
    const double wv2 = w[0] * vp[1] - w[1] * vp[0];
    double *ap = &ap_[3 * i];
    ap[0] = Ab_[6 * b] - pa0 + wv0;
    ap[1] = Ab_[6 * b + 1] - pa1 + wv1;
    ap[2] = Ab_[6 * b + 2] - pa2 + wv2;
  }
  const int h = h_;
  for (int k = 0; k < h; ++k)
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < nv; ++c)
        dJp_[(k * 3 + r) * nv + c] = Jp_[((h + k) * 3 + r) * nv + c] - Jp_[(k * 3 + r) * nv + c];
      vrel_[3 * k + r] = vp_[3 * (h + k) + r] - vp_[3 * k + r];
      arel_[3 * k + r] = ap_[3 * (h + k) + r] - ap_[3 * k + r];
      dP_[3 * k + r] = P_[3 * (h + k) + r] - P_[3 * k + r];
    }
  for (int p = 0; p < np_; ++p) {
    const double *H = &H_[16 * normal_body_[p]];
    const double *f2 = &frame2_[9 * p];
    double *F = &F_[9 * p];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c)
        F[3 * r + c] = f2[3 * r] * H[4 * c] + f2[3 * r + 1] * H[4 * c + 1] +
                       f2[3 * r + 2] * H[4 * c + 2];
  }
  std::fill(Jn_.begin(), Jn_.end(), 0.0);
  std::fill(drift_.begin(), drift_.end(), 0.0);
  for (int r = 0; r < mp_; ++r) {
    const int k = static_cast<int>(rows_[r]);
    const int p = static_cast<int>(pair_[k]);
    const double *n = &F_[9 * p + 6];
    // n turns with the body b carrying it: the exact derivatives of the gap n . (p2 - p1)
    // (the terms in dP = p2 - p1, zero when b is the world)
    const int b = static_cast<int>(normal_body_[p]);
    const double *w = &Vb_[6 * b + 3];
    const double *al = &Ab_[6 * b + 3];
    const double *dPk = &dP_[3 * k];
    const double wxn0 = w[1] * n[2] - w[2] * n[1];
    const double wxn1 = w[2] * n[0] - w[0] * n[2];
    const double wxn2 = w[0] * n[1] - w[1] * n[0];
    const double wxn[3] = {wxn0, wxn1, wxn2};
    const double wwxn[3] = {w[1] * wxn2 - w[2] * wxn1, w[2] * wxn0 - w[0] * wxn2,
                            w[0] * wxn1 - w[1] * wxn0};
    const double nxd[3] = {n[1] * dPk[2] - n[2] * dPk[1], n[2] * dPk[0] - n[0] * dPk[2],
                           n[0] * dPk[1] - n[1] * dPk[0]};
    const double *d = &dJp_[k * 3 * nv];
    const double *mk = &masks_[b * nv];
    for (int c = 0; c < nv; ++c) {
      Jn_[r * nv + c] = n[0] * d[c] + n[1] * d[nv + c] + n[2] * d[2 * nv + c];
      if (mk[c] != 0.0)
        Jn_[r * nv + c] +=
            nxd[0] * data_.J(3, c) + nxd[1] * data_.J(4, c) + nxd[2] * data_.J(5, c);
    }
    double g = 0.0, vv = 0.0, dd = 0.0;
    for (int i = 0; i < 3; ++i) {
      g += dP_[3 * k + i] * n[i];
      vv += vrel_[3 * k + i] * n[i];
      dd += arel_[3 * k + i] * n[i] + 2.0 * vrel_[3 * k + i] * wxn[i];
    }
    for (int i = 0; i < 3; ++i) {
      vv += wxn[i] * dPk[i];
      dd += nxd[i] * al[i] + wwxn[i] * dPk[i];
    }
    gap_[r] = g;
    vn_[r] = vv;
    drift_[r] = dd;
  }
  for (int i = 0; i < ml_; ++i) {
    const int j = static_cast<int>(lim_joint_[i]);
    const double s = lim_side_[i];
    Jn_[(mp_ + i) * nv + j] = -s;
    gap_[mp_ + i] = s * (lim_value_[i] - q_[j]);
    vn_[mp_ + i] = -s * v_[j];
  }
  if (mc_ > 0 || !row_locked_.empty()) clamp_rows();  // (the hand-off's: contact_rhs_clamps.cpp)
  for (int p = 0; p < np_; ++p) {
    // the centres' tangential slides t . (c2 - c1), the tangents turning with the frame's
    // body b: their exact derivatives (as the normal rows above); the
    // sliding velocity where the bodies touch, v_rel - w x dP
    const int c0 = static_cast<int>(centre_[p]);
    const double *F = &F_[9 * p];
    const double *d = &dJp_[c0 * 3 * nv];
    const double *vr = &vrel_[3 * c0];
    const double *ar = &arel_[3 * c0];
    const int b = static_cast<int>(normal_body_[p]);
    const double *w = &Vb_[6 * b + 3];
    const double *al = &Ab_[6 * b + 3];
    const double *dPk = &dP_[3 * c0];
    const double *mk = &masks_[b * nv];
    const double wxd[3] = {w[1] * dPk[2] - w[2] * dPk[1], w[2] * dPk[0] - w[0] * dPk[2],
                           w[0] * dPk[1] - w[1] * dPk[0]};
    for (int r = 0; r < 2; ++r) {
      const double *t = F + 3 * r;
      const double wxt[3] = {w[1] * t[2] - w[2] * t[1], w[2] * t[0] - w[0] * t[2],
                             w[0] * t[1] - w[1] * t[0]};
      const double wwxt[3] = {w[1] * wxt[2] - w[2] * wxt[1], w[2] * wxt[0] - w[0] * wxt[2],
                              w[0] * wxt[1] - w[1] * wxt[0]};
      const double txd[3] = {t[1] * dPk[2] - t[2] * dPk[1], t[2] * dPk[0] - t[0] * dPk[2],
                             t[0] * dPk[1] - t[1] * dPk[0]};
      for (int c = 0; c < nv; ++c) {
        JT_[(p * 2 + r) * nv + c] = t[0] * d[c] + t[1] * d[nv + c] + t[2] * d[2 * nv + c];
        if (mk[c] != 0.0)
          JT_[(p * 2 + r) * nv + c] +=
              txd[0] * data_.J(3, c) + txd[1] * data_.J(4, c) + txd[2] * data_.J(5, c);
      }
      double bb = 0.0, vv = 0.0;
      for (int i = 0; i < 3; ++i) {
        bb += t[i] * ar[i] + 2.0 * wxt[i] * vr[i];
        vv += t[i] * vr[i];
      }
      for (int i = 0; i < 3; ++i) {
        bb += txd[i] * al[i] + wwxt[i] * dPk[i];
        vv += wxt[i] * dPk[i];
      }
      bT_[2 * p + r] = bb;
      vT_[2 * p + r] = vv;
    }
    const double *n = F + 6;
    double vnc = 0.0;
    for (int i = 0; i < 3; ++i) vnc += n[i] * (vr[i] - wxd[i]);
    for (int i = 0; i < 3; ++i) vt_[3 * p + i] = vr[i] - wxd[i] - n[i] * vnc;
  }
}
