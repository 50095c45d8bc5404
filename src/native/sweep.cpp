// The collision world's sweep and its queries in native calls (Pinocchio's headers, Coal's
// library): packbot's only collision sweep.
//
// Python module ``packbot._native_coal`` (nanobind), apart from ``packbot._native`` because it
// links libcoal (the library the coal wheel ships, found at run time beside the pin and coal
// Python modules). It uses Coal's classes inline, so it serves only the Coal version it was
// built against (COAL_VERSION; packbot.native_sweep refuses another).
//
// One object, ``Sweep``, holds:
//   - its own Pinocchio model, rebuilt from the Python model's numbers (joint types, parents,
//     placements; forward kinematics is all it needs),
//   - the world's pieces as Coal shapes built from the Python pieces' numbers (a hull's vertices
//     and triangles, a box's half sides, a halfspace's normal and offset),
//   - the broadphase boxes of packbot.collision_build (one coal::Box per piece in its joint
//     frame, or in the world for static pieces), as Coal CollisionObjects,
//   - the world's pairs (same order) with one coal::ComputeDistance and DistanceRequest each.
//
// ``sweep(q, margin)``:
//   1. forward kinematics; each piece's placement oMg = oMi[joint] * placement;
//   2. each broadphase box's world box: CollisionObject::setTransform, computeAABB, then
//      expand by margin / 2;
//   3. the candidates: the pairs whose two boxes overlap (AABB::overlap), in the pairs' order
//      (a loop over the world's pairs, 204 for the robot and the floor);
//   4. Coal's distance on each candidate (its ComputeDistance and its own copy of the world's
//      DistanceRequest, whose cached GJK guess Coal updates), keeping the first smallest.
// It returns (pairs, distances, closest pair) and keeps each candidate's witness points and
// normal for ``witness``. ``candidates(q, margin)`` is steps 1 to 3 alone.
//
// The queries outside the sweep, each with GJK warm starts of its own (so that none changes
// the sweep's numbers): ``point_distance(q, k)`` one pair's distance, ``distances(q, pairs)``
// the unpruned distances of several pairs; ``patches(q, pairs, tol)`` and ``materials`` the
// contact patches of several pairs at one q (per pair coal::collide with a CollisionRequest
// whose security_margin is tol, then coal::computeContactPatch, both free functions that keep
// no state between calls). They leave the sweep's state (its q, boxes, witness points) as it
// was.

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <coal/BV/AABB.h>
#include <coal/collision.h>
#include <coal/collision_data.h>
#include <coal/collision_object.h>
#include <coal/contact_patch.h>
#include <coal/config.hh>
#include <coal/distance.h>
#include <coal/shape/convex.h>
#include <coal/shape/geometric_shapes.h>

#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/multibody/data.hpp>
#include <pinocchio/multibody/model.hpp>

#include <cstdint>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "joints.hpp"
#include "material.hpp"
#include "sweep_api.hpp"

namespace nb = nanobind;
namespace pin = pinocchio;
namespace material = packbot_native::material;

using Model = pin::ModelTpl<double, 0, packbot_native::PackbotJointsTpl>;
using Data = pin::DataTpl<double, 0, packbot_native::PackbotJointsTpl>;

using F1 = nb::ndarray<const double, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using F2 = nb::ndarray<const double, nb::ndim<2>, nb::c_contig, nb::device::cpu>;
using F3 = nb::ndarray<const double, nb::ndim<3>, nb::c_contig, nb::device::cpu>;
using I1 = nb::ndarray<const int64_t, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using I2 = nb::ndarray<const int64_t, nb::ndim<2>, nb::c_contig, nb::device::cpu>;
using Out2 = nb::ndarray<double, nb::ndim<2>, nb::c_contig, nb::device::cpu>;
using NpI1 = nb::ndarray<nb::numpy, int64_t, nb::ndim<1>>;
using NpF1 = nb::ndarray<nb::numpy, double, nb::ndim<1>>;
using NpI = nb::ndarray<nb::numpy, int64_t>;  // (any number of dimensions)
using NpF = nb::ndarray<nb::numpy, double>;

namespace {

// The piece kinds (packbot.native_sweep's numbering).
constexpr int64_t CONVEX = 0, BOX = 1, HALFSPACE = 2;

pin::SE3 se3_of(const double *H) {
  pin::SE3 M;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) M.rotation()(r, c) = H[4 * r + c];
    M.translation()(r) = H[4 * r + 3];
  }
  return M;
}

coal::Transform3s coal_of(const pin::SE3 &M) {
  return coal::Transform3s(M.rotation(), M.translation());  // Pinocchio's toCoalTransform3s
}

NpF1 new_reals(size_t n, double **data) {
  auto *buf = new double[n > 0 ? n : 1];
  nb::capsule owner(buf, [](void *p) noexcept { delete[] static_cast<double *>(p); });
  *data = buf;
  return NpF1(buf, {n}, owner);
}

// A new C-ordered numpy array of the given shape (any number of dimensions).
template <typename T>
nb::ndarray<nb::numpy, T> new_array(std::initializer_list<size_t> shape, T **data) {
  size_t n = 1;
  for (size_t s : shape) n *= s;
  auto *buf = new T[n > 0 ? n : 1];
  nb::capsule owner(buf, [](void *p) noexcept { delete[] static_cast<T *>(p); });
  *data = buf;
  return nb::ndarray<nb::numpy, T>(buf, shape.size(), shape.begin(), owner);
}

}  // namespace

class Sweep {
 public:
  Sweep(const std::vector<std::string> &types, I1 parents, F3 joint_placements, F2 axes,
        I1 kinds, I1 joints, F3 placements, F2 params, F2 points, I1 point_start, I2 triangles,
        I1 triangle_start, F2 box_half, F2 box_centre, I1 first, I1 second, double gjk_tolerance,
        double epa_tolerance, int64_t gjk_max_iterations, int64_t epa_max_iterations,
        bool absolute_criterion, bool cached_guess) {
    const size_t nj = types.size();
    if (parents.shape(0) != nj || joint_placements.shape(0) != nj || axes.shape(0) != nj)
      throw std::invalid_argument("one entry per joint expected in every joint array");
    for (size_t j = 1; j < nj; ++j) {
      const auto parent = static_cast<pin::JointIndex>(parents.data()[j]);
      model_.addJoint(parent, packbot_native::make_joint(types[j], axes.data() + 3 * j),
                      se3_of(joint_placements.data() + 16 * j), "joint" + std::to_string(j));
    }
    data_ = Data(model_);
    q_.setZero(model_.nq);
    pq_.setZero(model_.nq);

    const size_t G = kinds.shape(0);
    if (joints.shape(0) != G || placements.shape(0) != G || params.shape(0) != G ||
        point_start.shape(0) != G + 1 || triangle_start.shape(0) != G + 1 ||
        box_half.shape(0) != G || box_centre.shape(0) != G)
      throw std::invalid_argument("one entry per piece expected in every piece array");
    halfspace_.assign(G, 0);
    for (size_t g = 0; g < G; ++g) {
      const int64_t j = joints.data()[g];
      if (j < 0 || j >= static_cast<int64_t>(nj))
        throw std::invalid_argument("a piece's joint is out of range");
      joint_.push_back(static_cast<size_t>(j));
      placement_.push_back(se3_of(placements.data() + 16 * g));
      const double *p = params.data() + 4 * g;
      std::shared_ptr<coal::CollisionGeometry> shape;
      if (kinds.data()[g] == CONVEX) {
        const int64_t p0 = point_start.data()[g], p1 = point_start.data()[g + 1];
        const int64_t t0 = triangle_start.data()[g], t1 = triangle_start.data()[g + 1];
        auto pts = std::make_shared<std::vector<coal::Vec3s>>();
        for (int64_t k = p0; k < p1; ++k) {
          const double *v = points.data() + 3 * k;
          pts->emplace_back(v[0], v[1], v[2]);
        }
        auto tris = std::make_shared<std::vector<coal::Triangle>>();
        for (int64_t k = t0; k < t1; ++k) {
          const int64_t *t = triangles.data() + 3 * k;
          for (int c = 0; c < 3; ++c)
            if (t[c] < 0 || t[c] >= p1 - p0)
              throw std::invalid_argument("a hull triangle's vertex is out of range");
          tris->emplace_back(static_cast<coal::Triangle::index_type>(t[0]),
                             static_cast<coal::Triangle::index_type>(t[1]),
                             static_cast<coal::Triangle::index_type>(t[2]));
        }
        if (pts->size() < 4 || tris->empty())
          throw std::invalid_argument("a hull needs >= 4 vertices and its triangles");
        shape = std::make_shared<coal::Convex<coal::Triangle>>(
            pts, static_cast<unsigned int>(pts->size()), tris,
            static_cast<unsigned int>(tris->size()));
      } else if (kinds.data()[g] == BOX) {
        auto box = std::make_shared<coal::Box>();
        box->halfSide = coal::Vec3s(p[0], p[1], p[2]);
        shape = box;
      } else if (kinds.data()[g] == HALFSPACE) {
        halfspace_[g] = 1;
        auto hs = std::make_shared<coal::Halfspace>();
        hs->n = coal::Vec3s(p[0], p[1], p[2]);  // already unit (as the Python shape stores it)
        hs->d = p[3];
        shape = hs;
      } else {
        throw std::invalid_argument("unknown piece kind " + std::to_string(kinds.data()[g]));
      }
      shapes_.push_back(shape);
      // the broadphase box (packbot.collision's _broadphase_model): Box(2 h) has half sides h
      const double *h = box_half.data() + 3 * g;
      const double *c = box_centre.data() + 3 * g;
      auto bbox = std::make_shared<coal::Box>(2 * h[0], 2 * h[1], 2 * h[2]);
      bbox->computeLocalAABB();
      box_placement_.push_back(pin::SE3(Eigen::Matrix3d::Identity(), Eigen::Vector3d(c[0], c[1], c[2])));
      objects_.push_back(std::make_unique<coal::CollisionObject>(bbox, false));
      oMg_.push_back(pin::SE3::Identity());
    }

    const size_t K = first.shape(0);
    if (second.shape(0) != K) throw std::invalid_argument("first and second: one per pair");
    for (size_t k = 0; k < K; ++k) {
      const int64_t a = first.data()[k], b = second.data()[k];
      if (a < 0 || b < 0 || a >= static_cast<int64_t>(G) || b >= static_cast<int64_t>(G))
        throw std::invalid_argument("a pair's piece is out of range");
      first_.push_back(static_cast<size_t>(a));
      second_.push_back(static_cast<size_t>(b));
    }
    request_.gjk_tolerance = gjk_tolerance;
    request_.epa_tolerance = epa_tolerance;
    request_.gjk_max_iterations = static_cast<size_t>(gjk_max_iterations);
    request_.epa_max_iterations = static_cast<size_t>(epa_max_iterations);
    request_.gjk_convergence_criterion_type =
        absolute_criterion ? coal::GJKConvergenceCriterionType::Absolute
                           : coal::GJKConvergenceCriterionType::Relative;
    COAL_COMPILER_DIAGNOSTIC_PUSH
    COAL_COMPILER_DIAGNOSTIC_IGNORED_DEPRECECATED_DECLARATIONS
    request_.enable_cached_gjk_guess = cached_guess;  // as Pinocchio's GeometryData sets it
    COAL_COMPILER_DIAGNOSTIC_POP
    start_pairs();
  }

  Sweep(const Sweep &) = delete;
  Sweep &operator=(const Sweep &) = delete;

  // A new Sweep of the same model, pieces and pairs, as the constructor leaves it (no sweep
  // yet: each pair's request without a GJK guess, no margin), sharing this one's shapes,
  // which nothing changes after they are built (a hull's construction, its neighbours and
  // centre, is most of the constructor's time).
  Sweep *fresh() const { return new Sweep(*this, 0); }

  // (pairs, distances, closest pair index or -1, its distance or inf) of the candidates at q
  // and margin [m].
  std::tuple<NpI1, NpF1, int64_t, double> sweep(F1 q, double margin) {
    if (q.shape(0) != static_cast<size_t>(model_.nq))
      throw std::invalid_argument("q: " + std::to_string(model_.nq) + " entries expected");
    const size_t K = first_.size();
    int64_t *pairs_out = new int64_t[K > 0 ? K : 1];
    nb::capsule pairs_owner(pairs_out,
                            [](void *p) noexcept { delete[] static_cast<int64_t *>(p); });
    std::vector<double> &d = dist_;
    int64_t best = -1;
    double best_d = std::numeric_limits<double>::infinity();
    const size_t T = sweep_into(q.data(), margin, pairs_out, d.data(), &best, &best_d);
    double *dist_out = nullptr;
    NpF1 distances = new_reals(T, &dist_out);
    std::copy(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(T), dist_out);
    return {NpI1(pairs_out, {T}, pairs_owner), distances, best, best_d};
  }

  // The sweep at q (nq entries) and margin [m] into pairs and dist (room for n_pairs each):
  // the candidates' count; best and best_d the first smallest distance's pair (-1) and value.
  size_t sweep_into(const double *q, double margin, int64_t *pairs_out, double *dist_out,
                    int64_t *best_out, double *best_d_out) {
    place_boxes(q, margin);
    collect(cand_);
    const size_t T = cand_.size();
    int64_t best = -1;
    double best_d = std::numeric_limits<double>::infinity();
    for (size_t i = 0; i < T; ++i) {
      const size_t k = cand_[i];
      result_.clear();
      (*functors_[k])(coal_of(oMg_[first_[k]]), coal_of(oMg_[second_[k]]), requests_[k],
                      result_);
      const double d = result_.min_distance;
      pairs_out[i] = static_cast<int64_t>(k);
      dist_out[i] = d;
      p1_[i] = result_.nearest_points[0];
      p2_[i] = result_.nearest_points[1];
      normal_[i] = result_.normal;
      if (d < best_d) {
        best_d = d;
        best = static_cast<int64_t>(k);
      }
    }
    *best_out = best;
    *best_d_out = best_d;
    return T;
  }

  // The broadphase alone: the pairs (ascending) whose world boxes at q, each inflated by
  // margin / 2 [m], overlap (the candidates ``sweep`` would test). The sweep's q and boxes
  // become these (``last_q``, ``boxes``); its witness points stay the last sweep's.
  NpI candidates(F1 q, double margin) {
    check_q(q);
    place_boxes(q.data(), margin);
    std::vector<size_t> found;
    found.reserve(first_.size());
    collect(found);
    int64_t *out = nullptr;
    auto arr = new_array<int64_t>({found.size()}, &out);
    for (size_t i = 0; i < found.size(); ++i) out[i] = static_cast<int64_t>(found[i]);
    return arr;
  }

 private:
  // Forward kinematics at q, the pieces' placements and the broadphase boxes inflated by
  // margin / 2 [m] (the sweep's steps 1 and 2).
  void place_boxes(const double *q, double margin) {
    for (int i = 0; i < model_.nq; ++i) q_[i] = q[i];
    pin::forwardKinematics(model_, data_, q_);
    const size_t G = shapes_.size();
    const double inflation = (0.0 + margin) * 0.5;  // (break_distance + security_margin) / 2
    const bool new_margin = !(margin == margin_);  // (the static pieces' boxes: once a margin)
    margin_ = margin;
    for (size_t g = 0; g < G; ++g) {
      const size_t j = joint_[g];
      coal::CollisionObject &obj = *objects_[g];
      if (j > 0) {
        const pin::SE3 &oMi = data_.oMi[j];
        oMg_[g] = oMi * placement_[g];
        // oMi * box_placement_[g], whose rotation is the identity: Pinocchio's SE3 product
        // (its rotation R * I is R exactly; its translation the same expression as in
        // SE3Tpl::act_impl)
        const Eigen::Vector3d t =
            oMi.translation() + oMi.rotation() * box_placement_[g].translation();
        obj.setTransform(coal::Transform3s(oMi.rotation(), t));
      } else {
        oMg_[g] = placement_[g];
        if (!new_margin) continue;
        obj.setTransform(coal_of(box_placement_[g]));
      }
      obj.computeAABB();
      obj.getAABB().expand(inflation);
    }
  }

  // The pairs whose placed boxes overlap (AABB::overlap), in the pairs' order (step 3).
  void collect(std::vector<size_t> &out) const {
    out.clear();
    const size_t K = first_.size();
    for (size_t k = 0; k < K; ++k)
      if (objects_[first_[k]]->getAABB().overlap(objects_[second_[k]]->getAABB()))
        out.push_back(k);
  }

 public:

  // The C entry point (sweep_api.hpp) in a capsule that keeps this Sweep alive.
  nb::capsule api(nb::handle self) {
    self.inc_ref();
    auto *api = new SweepApi{this, &Sweep::c_sweep, &Sweep::c_materials, &Sweep::c_distance,
                             static_cast<int64_t>(first_.size()), static_cast<int64_t>(model_.nq),
                             self.ptr()};
    return nb::capsule(api, PACKBOT_SWEEP_API, [](void *p) noexcept {
      // (the capsule's destructor: the SweepApi and its reference to the Sweep)
      auto *a = static_cast<SweepApi *>(p);
      PyObject *owner = static_cast<PyObject *>(a->owner);
      delete a;
      Py_XDECREF(owner);
    });
  }

  static int64_t c_sweep(void *self, const double *q, double margin, int64_t *pairs,
                         double *dist, int64_t *best, double *best_d) {
    return static_cast<int64_t>(
        static_cast<Sweep *>(self)->sweep_into(q, margin, pairs, dist, best, best_d));
  }

  // Pair k's signed distance [m] at q, for the screen of contacts between step ends
  // (pair_dips.hpp): with requests and functors of its own (made on first use), so that no
  // other query's GJK warm starts depend on it. Leaves the sweep's state as it was.
  static double c_distance(void *self, const double *q, int64_t k) {
    return static_cast<Sweep *>(self)->dip_distance(q, static_cast<size_t>(k));
  }

  double dip_distance(const double *q, size_t p) {
    for (int i = 0; i < model_.nq; ++i) pq_[i] = q[i];
    pin::forwardKinematics(model_, data_, pq_);
    return query(dip_, p).min_distance;
  }

  // The contact patches of ``pairs`` within ``tol`` [m] at q: (sizes, normals, depths, points1,
  // points2, rotations, translations). sizes (n,): each pair's number of patch points K, -1 for
  // a pair farther apart than tol; normals (n, 3) and depths (n,) the patches' normals (body 1
  // to body 2) and penetration depths (0 and 0 for a far pair); points1 and points2 (sum K, 3)
  // the patches' points on pieces 1 and 2, pair after pair (world frame [m]); rotations (n, 2,
  // 3, 3) the two pieces' world rotations, each stored TRANSPOSED (so that rotations.swapaxes(2,
  // 3)[i, j] is the Fortran-ordered matrix Pinocchio's SE3.rotation is), translations (n, 2, 3).
  std::tuple<NpI, NpF, NpF, NpF, NpF, NpF, NpF> patches(F1 q, I1 pairs, double tol) {
    const size_t n = check_query(q, pairs);
    for (int i = 0; i < model_.nq; ++i) pq_[i] = q.data()[i];
    pin::forwardKinematics(model_, data_, pq_);
    int64_t *sizes = nullptr;
    double *normals = nullptr, *depths = nullptr, *rot = nullptr, *trans = nullptr;
    auto sizes_arr = new_array<int64_t>({n}, &sizes);
    auto normals_arr = new_array<double>({n, 3}, &normals);
    auto depths_arr = new_array<double>({n}, &depths);
    auto rot_arr = new_array<double>({n, 2, 3, 3}, &rot);
    auto trans_arr = new_array<double>({n, 2, 3}, &trans);
    pts1_.clear();
    pts2_.clear();
    for (size_t i = 0; i < n; ++i) {
      const size_t k = static_cast<size_t>(pairs.data()[i]);
      pin::SE3 M[2];
      place_pair(k, M);
      for (int s = 0; s < 2; ++s)
        for (int r = 0; r < 3; ++r) {
          for (int c = 0; c < 3; ++c) rot[18 * i + 9 * s + 3 * c + r] = M[s].rotation()(r, c);
          trans[6 * i + 3 * s + r] = M[s].translation()(r);
        }
      sizes[i] = -1;
      normals[3 * i] = normals[3 * i + 1] = normals[3 * i + 2] = 0.0;
      depths[i] = 0.0;
      const coal::ContactPatch *patch = contact_patch(k, M, tol);
      if (patch == nullptr) continue;
      const coal::Vec3s nrm = patch->getNormal();
      const size_t npts = patch->size();
      sizes[i] = static_cast<int64_t>(npts);
      for (int c = 0; c < 3; ++c) normals[3 * i + c] = nrm[c];
      depths[i] = patch->penetration_depth;
      for (size_t m = 0; m < npts; ++m) {
        pts1_.push_back(patch->getPointShape1(m));
        pts2_.push_back(patch->getPointShape2(m));
      }
    }
    const size_t S = pts1_.size();
    double *p1 = nullptr, *p2 = nullptr;
    auto p1_arr = new_array<double>({S, 3}, &p1);
    auto p2_arr = new_array<double>({S, 3}, &p2);
    for (size_t m = 0; m < S; ++m)
      for (int c = 0; c < 3; ++c) {
        p1[3 * m + c] = pts1_[m][c];
        p2[3 * m + c] = pts2_[m][c];
      }
    return {sizes_arr, normals_arr, depths_arr, p1_arr, p2_arr, rot_arr, trans_arr};
  }

  // The signed distance [m], nearest points on pieces 1 and 2 (world [m]) and normal of pair k
  // at q: CollisionWorld.pair_contact's query (Pinocchio's computeDistance on the world's
  // second GeometryData, made pristine at its first point query), with that data's own request
  // and functor per pair, which no sweep shares: the same GJK warm starts, so the same numbers
  // to the bit. Leaves the sweep's state (its q, boxes, witness points) as it was.
  // q's size and a pair index k checked (point_distance's, dip_distance's).
  void check_pair_query(const F1 &q, int64_t k) const {
    check_q(q);
    if (k < 0 || k >= static_cast<int64_t>(first_.size()))
      throw std::invalid_argument("a pair index is out of range");
  }

  nb::tuple point_distance(F1 q, int64_t k) {
    check_pair_query(q, k);
    for (int i = 0; i < model_.nq; ++i) pq_[i] = q.data()[i];
    pin::forwardKinematics(model_, data_, pq_);
    const coal::DistanceResult &res = query(point_, static_cast<size_t>(k));
    double *a = nullptr, *b = nullptr, *n = nullptr;
    auto a_arr = new_array<double>({3}, &a);
    auto b_arr = new_array<double>({3}, &b);
    auto n_arr = new_array<double>({3}, &n);
    for (int c = 0; c < 3; ++c) {
      a[c] = res.nearest_points[0][c];
      b[c] = res.nearest_points[1][c];
      n[c] = res.normal[c];
    }
    return nb::make_tuple(res.min_distance, a_arr, b_arr, n_arr);
  }

  // The signed distances [m], nearest points on pieces 1 and 2 (world [m]) and normals of
  // ``pairs`` at q, unpruned: (distances (n,), points1 (n, 3), points2 (n, 3), normals (n,
  // 3)). CollisionWorld.all_distances' and closest's query, with requests and functors of
  // its own (made on first use), so that neither the sweep's GJK warm starts nor
  // point_distance's depend on it. Leaves the sweep's state (its q, boxes, witness points)
  // as it was.
  nb::tuple distances(F1 q, I1 pairs) {
    const size_t n = check_query(q, pairs);
    for (int i = 0; i < model_.nq; ++i) pq_[i] = q.data()[i];
    pin::forwardKinematics(model_, data_, pq_);
    double *d = nullptr, *a = nullptr, *b = nullptr, *nrm = nullptr;
    auto d_arr = new_array<double>({n}, &d);
    auto a_arr = new_array<double>({n, 3}, &a);
    auto b_arr = new_array<double>({n, 3}, &b);
    auto n_arr = new_array<double>({n, 3}, &nrm);
    for (size_t i = 0; i < n; ++i) {
      const coal::DistanceResult &res = query(all_, static_cast<size_t>(pairs.data()[i]));
      d[i] = res.min_distance;
      for (int c = 0; c < 3; ++c) {
        a[3 * i + c] = res.nearest_points[0][c];
        b[3 * i + c] = res.nearest_points[1][c];
        nrm[3 * i + c] = res.normal[c];
      }
    }
    return nb::make_tuple(d_arr, a_arr, b_arr, n_arr);
  }

  // The face planes of every piece (the N and o of material.hpp's patch_material), for ``materials``:
  // N (sum F, 3) unit outward normals in the pieces' frames, o (sum F) offsets, start (G + 1)
  // piece g's planes start[g] to start[g + 1] (none: a piece without faces).
  void set_planes(F2 N, F1 o, I1 start) {
    const size_t G = shapes_.size();
    if (start.shape(0) != G + 1 || N.shape(1) != 3 || N.shape(0) != o.shape(0))
      throw std::invalid_argument("set_planes: N (F, 3), o (F,) and start (G + 1,) expected");
    auto planes = std::make_shared<PlaneSet>();
    planes->N.assign(N.data(), N.data() + 3 * N.shape(0));
    planes->o.assign(o.data(), o.data() + o.shape(0));
    planes->start.assign(start.data(), start.data() + G + 1);
    if (planes->start[0] != 0 || planes->start[G] != static_cast<int64_t>(o.shape(0)))
      throw std::invalid_argument("set_planes: start must run from 0 to F");
    for (size_t g = 0; g < G; ++g)
      if (planes->start[g + 1] < planes->start[g])
        throw std::invalid_argument("set_planes: start must not decrease");
    planes_ = std::move(planes);
  }

  bool has_planes() const { return planes_ != nullptr; }

  // The contact set's patches of ``pairs`` at q as material points (ContactSet.add_pairs):
  // ``patches``' Coal calls, then patch_material (check on) in material.hpp, the
  // joints' placements Pinocchio's at q. Returns (sizes, slide_free, normals, depths,
  // rotations, translations, local1, local2, offset0, normal2, frame2, centres): sizes (n,) K,
  // -1 for a pair farther apart than tol, -2 for a patch off the pair's distance (the caller
  // takes the witness points); slide_free (n,) bit 0 the normal is body 1's, bit 1 nothing
  // lags (a one-point patch or a halfspace's, on a face: ContactSet._put's slide_tol inf);
  // normals, depths, rotations, translations as ``patches``; local1 and local2 (sum K, 3) the
  // points in their joints' frames; offset0 (2 sum K): each pair's (2, K) block in turn;
  // normal2 (n, 3), frame2 (n, 3, 3), centres (n, 2, 1, 3) (body 1's, body 2's).
  nb::tuple materials(F1 q, I1 pairs, double tol, double patch_tol, double face_align) {
    if (!planes_) throw std::invalid_argument("materials: set_planes first");
    const size_t n = check_query(q, pairs);
    int64_t *sizes = nullptr, *flags = nullptr;
    double *normals = nullptr, *depths = nullptr, *rot = nullptr, *trans = nullptr;
    double *normal2 = nullptr, *frame2 = nullptr, *centres = nullptr;
    auto sizes_arr = new_array<int64_t>({n}, &sizes);
    auto flags_arr = new_array<int64_t>({n}, &flags);
    auto normals_arr = new_array<double>({n, 3}, &normals);
    auto depths_arr = new_array<double>({n}, &depths);
    auto rot_arr = new_array<double>({n, 2, 3, 3}, &rot);
    auto trans_arr = new_array<double>({n, 2, 3}, &trans);
    auto normal2_arr = new_array<double>({n, 3}, &normal2);
    auto frame2_arr = new_array<double>({n, 3, 3}, &frame2);
    auto centres_arr = new_array<double>({n, 2, 1, 3}, &centres);
    const MatOut out{sizes, flags, normals, depths, rot, trans, normal2, frame2, centres};
    materials_into(q.data(), pairs.data(), n, tol, patch_tol, face_align, out);
    const size_t S = loc1_.size() / 3;
    double *l1 = nullptr, *l2 = nullptr, *o = nullptr;
    auto l1_arr = new_array<double>({S, 3}, &l1);
    auto l2_arr = new_array<double>({S, 3}, &l2);
    auto o_arr = new_array<double>({2 * S}, &o);
    std::copy(loc1_.begin(), loc1_.end(), l1);
    std::copy(loc2_.begin(), loc2_.end(), l2);
    std::copy(off_.begin(), off_.end(), o);
    return nb::make_tuple(sizes_arr, flags_arr, normals_arr, depths_arr, rot_arr, trans_arr,
                          l1_arr, l2_arr, o_arr, normal2_arr, frame2_arr, centres_arr);
  }

  // materials for the C entry point (sweep_api.hpp): the per-pair arrays into the caller's
  // sizes, flags (n), frame2 (n, 9) and centres (n, 6); local1 and local2 (S, 3), offset0
  // (2 S) into the caller's buffers if S <= cap points. Returns S, or -1: no planes set or
  // more than cap points (nothing but the per-pair arrays written).
  static int64_t c_materials(void *self, const double *q, const int64_t *pairs, int64_t n,
                             double tol, double patch_tol, double face_align, int64_t *sizes,
                             int64_t *flags, double *frame2, double *centres, double *local1,
                             double *local2, double *offset0, int64_t cap) {
    Sweep &sw = *static_cast<Sweep *>(self);
    if (!sw.planes_) return -1;
    const MatOut out{sizes, flags, nullptr, nullptr, nullptr, nullptr, nullptr, frame2, centres};
    sw.materials_into(q, pairs, static_cast<size_t>(n), tol, patch_tol, face_align, out);
    const size_t S = sw.loc1_.size() / 3;
    if (static_cast<int64_t>(S) > cap) return -1;
    std::copy(sw.loc1_.begin(), sw.loc1_.end(), local1);
    std::copy(sw.loc2_.begin(), sw.loc2_.end(), local2);
    std::copy(sw.off_.begin(), sw.off_.end(), offset0);
    return static_cast<int64_t>(S);
  }

  // The last sweep's witness points and normals, one row per candidate (its order).
  void witness(Out2 p1, Out2 p2, Out2 normal) const {
    const size_t T = cand_.size();
    if (p1.shape(0) < T || p2.shape(0) < T || normal.shape(0) < T || p1.shape(1) != 3 ||
        p2.shape(1) != 3 || normal.shape(1) != 3)
      throw std::invalid_argument("witness: (>= T, 3) arrays expected");
    for (size_t i = 0; i < T; ++i)
      for (int c = 0; c < 3; ++c) {
        p1.data()[3 * i + c] = p1_[i][c];
        p2.data()[3 * i + c] = p2_[i][c];
        normal.data()[3 * i + c] = normal_[i][c];
      }
  }

  // The world boxes of the last sweep (lower and upper corners, inflated by margin / 2).
  void boxes(Out2 lo, Out2 hi) const {
    const size_t G = objects_.size();
    if (lo.shape(0) != G || hi.shape(0) != G || lo.shape(1) != 3 || hi.shape(1) != 3)
      throw std::invalid_argument("boxes: (G, 3) arrays expected");
    for (size_t g = 0; g < G; ++g) {
      const coal::AABB &b = objects_[g]->getAABB();
      for (int c = 0; c < 3; ++c) {
        lo.data()[3 * g + c] = b.min_[c];
        hi.data()[3 * g + c] = b.max_[c];
      }
    }
  }

  size_t n_pairs() const { return first_.size(); }

  // The configuration of the last sweep [rad] (a copy).
  NpF1 last_q() const {
    double *out = nullptr;
    NpF1 arr = new_reals(static_cast<size_t>(model_.nq), &out);
    for (int i = 0; i < model_.nq; ++i) out[i] = q_[i];
    return arr;
  }

 private:
  // (fresh()'s: the fixed parts shared or copied, the state as after the constructor)
  Sweep(const Sweep &o, int)
      : model_(o.model_),
        data_(o.model_),
        joint_(o.joint_),
        placement_(o.placement_),
        box_placement_(o.box_placement_),
        shapes_(o.shapes_),
        first_(o.first_),
        second_(o.second_),
        request_(o.request_),
        halfspace_(o.halfspace_),
        planes_(o.planes_) {
    q_.setZero(model_.nq);
    pq_.setZero(model_.nq);
    const size_t G = shapes_.size();
    for (size_t g = 0; g < G; ++g) {
      objects_.push_back(
          std::make_unique<coal::CollisionObject>(o.objects_[g]->collisionGeometry(), false));
      oMg_.push_back(pin::SE3::Identity());
    }
    start_pairs();
  }

  // Each pair's distance functor and request (request_'s settings, no GJK guess yet) and the
  // sweep's buffers, from first_, second_ and shapes_. One request per pair, as Pinocchio's
  // GeometryData: with enable_cached_gjk_guess Coal keeps each pair's last GJK guess and
  // support hints in its request (its mutable cached_gjk_guess), where the pair's next query
  // starts.
  void start_pairs() {
    const size_t K = first_.size();
    for (size_t k = 0; k < K; ++k)
      functors_.push_back(std::make_unique<coal::ComputeDistance>(shapes_[first_[k]].get(),
                                                                   shapes_[second_[k]].get()));
    requests_.assign(K, request_);
    cand_.reserve(K);
    dist_.resize(K);
    p1_.resize(K);
    p2_.resize(K);
    normal_.resize(K);
  }

  // Where materials_into writes each pair's results (nullptr: not wanted): sizes, flags (n);
  // normals (n, 3), depths (n), rotations (n, 2, 3, 3, each transposed), translations (n, 2,
  // 3) as ``patches``; normal2 (n, 3), frame2 (n, 9), centres (n, 6).
  struct MatOut {
    int64_t *sizes, *flags;
    double *normals, *depths, *rot, *trans, *normal2, *frame2, *centres;
  };

  // ``materials``' work (checked arguments, planes set): the per-pair results into out, the
  // points and offsets into loc1_, loc2_ and off_.
  void materials_into(const double *q, const int64_t *pairs, size_t n, double tol,
                      double patch_tol, double face_align, const MatOut &out) {
    for (int i = 0; i < model_.nq; ++i) pq_[i] = q[i];
    pin::forwardKinematics(model_, data_, pq_);
    loc1_.clear();
    loc2_.clear();
    off_.clear();
    for (size_t i = 0; i < n; ++i) {
      const size_t k = static_cast<size_t>(pairs[i]);
      pin::SE3 M[2];
      place_pair(k, M);
      double Rg[2][9], tg[2][3], RM[2][9], tM[2][3];
      for (int s = 0; s < 2; ++s) {
        const size_t j = joint_[s == 0 ? first_[k] : second_[k]];
        const pin::SE3 J = j > 0 ? pin::SE3(data_.oMi[j]) : pin::SE3::Identity();
        for (int r = 0; r < 3; ++r) {
          for (int c = 0; c < 3; ++c) {
            if (out.rot) out.rot[18 * i + 9 * s + 3 * c + r] = M[s].rotation()(r, c);
            Rg[s][3 * r + c] = M[s].rotation()(r, c);
            RM[s][3 * r + c] = J.rotation()(r, c);
          }
          tg[s][r] = M[s].translation()(r);
          if (out.trans) out.trans[6 * i + 3 * s + r] = tg[s][r];
          tM[s][r] = J.translation()(r);
        }
      }
      out.sizes[i] = -1;
      out.flags[i] = 0;
      for (int c = 0; c < 3; ++c) {
        if (out.normals) out.normals[3 * i + c] = 0.0;
        if (out.normal2) out.normal2[3 * i + c] = 0.0;
      }
      for (int c = 0; c < 9; ++c) out.frame2[9 * i + c] = 0.0;
      for (int c = 0; c < 6; ++c) out.centres[6 * i + c] = 0.0;
      if (out.depths) out.depths[i] = 0.0;
      const coal::ContactPatch *patch = contact_patch(k, M, tol);
      if (patch == nullptr) continue;
      const coal::Vec3s nrm = patch->getNormal();
      const size_t npts = patch->size();
      double nv[3];
      for (int c = 0; c < 3; ++c) nv[c] = nrm[c];
      if (out.normals)
        for (int c = 0; c < 3; ++c) out.normals[3 * i + c] = nv[c];
      const double d = patch->penetration_depth;
      if (out.depths) out.depths[i] = d;
      raw_.resize(6 * npts);
      for (size_t m = 0; m < npts; ++m) {
        const coal::Vec3s a = patch->getPointShape1(m), b = patch->getPointShape2(m);
        for (int c = 0; c < 3; ++c) {
          raw_[3 * m + c] = a[c];
          raw_[3 * (npts + m) + c] = b[c];
        }
      }
      const size_t s0 = loc1_.size();
      loc1_.resize(s0 + 3 * npts);
      loc2_.resize(s0 + 3 * npts);
      const size_t o0 = off_.size();
      off_.resize(o0 + 2 * npts);
      const material::Planes P1 = planes_of(first_[k]), P2 = planes_of(second_[k]);
      const material::Made made = material::patch_material(
          raw_.data(), raw_.data() + 3 * npts, npts, nv, d, P1, Rg[0], tg[0], P2, Rg[1], tg[1],
          RM[0], tM[0], RM[1], tM[1], patch_tol, loc1_.data() + s0, loc2_.data() + s0,
          off_.data() + o0, scratch_);
      if (!made.ok) {  // (the caller's witness points: nothing of this patch is kept)
        loc1_.resize(s0);
        loc2_.resize(s0);
        off_.resize(o0);
        out.sizes[i] = -2;
        continue;
      }
      out.sizes[i] = static_cast<int64_t>(npts);
      const size_t owner = made.on1 ? first_[k] : second_[k];
      const bool free = (npts == 1 || halfspace_[owner]) &&
                        material::on_a_face(P1, Rg[0], P2, Rg[1], nv, made.on1, face_align);
      out.flags[i] = (made.on1 ? 1 : 0) | (free ? 2 : 0);
      for (int c = 0; c < 3; ++c) {
        if (out.normal2) out.normal2[3 * i + c] = made.normal2[c];
        out.centres[6 * i + c] = made.centre1[c];
        out.centres[6 * i + 3 + c] = made.centre2[c];
      }
      for (int c = 0; c < 9; ++c) out.frame2[9 * i + c] = made.frame2[c];
    }
  }

  void check_q(const F1 &q) const {
    if (q.shape(0) != static_cast<size_t>(model_.nq))
      throw std::invalid_argument("q: " + std::to_string(model_.nq) + " entries expected");
  }

  // A query's q (nq entries) and pair indices (each in range) checked: the number of pairs.
  size_t check_query(const F1 &q, const I1 &pairs) const {
    check_q(q);
    const size_t n = pairs.shape(0), K = first_.size();
    for (size_t i = 0; i < n; ++i)
      if (pairs.data()[i] < 0 || pairs.data()[i] >= static_cast<int64_t>(K))
        throw std::invalid_argument("a pair index is out of range");
    return n;
  }

  // The face planes of every piece (set_planes).
  struct PlaneSet {
    std::vector<double> N, o;
    std::vector<int64_t> start;
  };

  material::Planes planes_of(size_t g) const {
    const int64_t a = planes_->start[g], b = planes_->start[g + 1];
    return {planes_->N.data() + 3 * a, planes_->o.data() + a, static_cast<size_t>(b - a)};
  }

  // The two pieces' world placements of pair k after forward kinematics (Pinocchio's
  // updateGeometryPlacements).
  void place_pair(size_t k, pin::SE3 M[2]) const {
    const size_t g[2] = {first_[k], second_[k]};
    for (int s = 0; s < 2; ++s) {
      const size_t j = joint_[g[s]];
      M[s] = j > 0 ? pin::SE3(data_.oMi[j] * placement_[g[s]]) : placement_[g[s]];
    }
  }

  // Pair k's first contact patch at placements M within tol [m], or nullptr: Coal's collide
  // with a default CollisionRequest whose security_margin is tol, then computeContactPatch
  // with a default ContactPatchRequest (packbot.collision_queries.contact_patch). The patch
  // lives until the next call.
  const coal::ContactPatch *contact_patch(size_t k, const pin::SE3 M[2], double tol) {
    coal::CollisionRequest creq;  // packbot.collision's _patch_requests: Coal's defaults,
    creq.enable_contact = true;   // enable_contact (already the default), the margin tol
    creq.security_margin = tol;
    const coal::ContactPatchRequest preq;
    const coal::Transform3s T1 = coal_of(M[0]), T2 = coal_of(M[1]);
    const coal::CollisionGeometry *s1 = shapes_[first_[k]].get();
    const coal::CollisionGeometry *s2 = shapes_[second_[k]].get();
    coal::CollisionResult cres;
    if (!coal::collide(s1, T1, s2, T2, creq, cres)) return nullptr;
    patch_res_ = coal::ContactPatchResult(preq);
    coal::computeContactPatch(s1, T1, s2, T2, cres, preq, patch_res_);
    if (patch_res_.numContactPatches() == 0) return nullptr;
    return &patch_res_.getContactPatch(0);
  }

  Model model_;
  Data data_;
  Eigen::VectorXd q_, pq_;  // the last sweep's q, the last patches' q
  double margin_ = std::numeric_limits<double>::quiet_NaN();  // the last sweep's
  std::vector<size_t> joint_;
  std::vector<pin::SE3> placement_, box_placement_, oMg_;
  std::vector<std::shared_ptr<coal::CollisionGeometry>> shapes_;
  std::vector<std::unique_ptr<coal::CollisionObject>> objects_;
  std::vector<size_t> first_, second_, cand_;
  std::vector<std::unique_ptr<coal::ComputeDistance>> functors_;
  coal::DistanceRequest request_;
  std::vector<coal::DistanceRequest> requests_;
  coal::DistanceResult result_;
  std::vector<coal::Vec3s> p1_, p2_, normal_;
  std::vector<coal::Vec3s> pts1_, pts2_;  // (patches' scratch)
  std::vector<double> dist_;  // (sweep's scratch: one per pair)
  std::vector<char> halfspace_;  // per piece: a halfspace (its one face has no edge)
  std::shared_ptr<const PlaneSet> planes_;  // (set_planes; shared by fresh() copies)
  coal::ContactPatchResult patch_res_;  // (contact_patch's)
  std::vector<double> loc1_, loc2_, off_, raw_, scratch_;  // (materials' scratch)
  // A query's own GJK requests and distance functors per pair, made on first use: no query's
  // warm starts depend on another's.
  struct QuerySet {
    std::vector<coal::DistanceRequest> requests;
    std::vector<std::unique_ptr<coal::ComputeDistance>> functors;
  };
  // Pair p's distance by the set's request and functor, at the placements of the last
  // forward kinematics into data_ (the result lives until the next query).
  const coal::DistanceResult &query(QuerySet &set, size_t p) {
    if (set.requests.empty()) {
      set.requests.assign(first_.size(), request_);
      set.functors.resize(first_.size());
    }
    if (!set.functors[p])
      set.functors[p] = std::make_unique<coal::ComputeDistance>(shapes_[first_[p]].get(),
                                                                shapes_[second_[p]].get());
    pin::SE3 M[2];
    place_pair(p, M);
    point_result_.clear();
    (*set.functors[p])(coal_of(M[0]), coal_of(M[1]), set.requests[p], point_result_);
    return point_result_;
  }
  // point_distance's (the second GeometryData's requests, as a new copy has them),
  // distances', dip_distance's
  QuerySet point_, all_, dip_;
  coal::DistanceResult point_result_;
};

NB_MODULE(_native_coal, m) {
  m.doc() = "packbot's collision sweep in one native call (Pinocchio's headers, libcoal).";
  m.attr("COAL_VERSION") = COAL_VERSION;
  m.attr("PINOCCHIO_VERSION") = PINOCCHIO_VERSION;
  nb::class_<Sweep>(m, "Sweep")
      .def(nb::init<const std::vector<std::string> &, I1, F3, F2, I1, I1, F3, F2, F2, I1, I2, I1,
                    F2, F2, I1, I1, double, double, int64_t, int64_t, bool, bool>(),
           nb::arg("types"), nb::arg("parents"), nb::arg("joint_placements"), nb::arg("axes"),
           nb::arg("kinds"), nb::arg("joints"), nb::arg("placements"), nb::arg("params"),
           nb::arg("points"), nb::arg("point_start"), nb::arg("triangles"),
           nb::arg("triangle_start"), nb::arg("box_half"), nb::arg("box_centre"),
           nb::arg("first"), nb::arg("second"), nb::arg("gjk_tolerance"),
           nb::arg("epa_tolerance"), nb::arg("gjk_max_iterations"),
           nb::arg("epa_max_iterations"), nb::arg("absolute_criterion"),
           nb::arg("cached_guess"))
      .def("sweep", &Sweep::sweep, nb::arg("q"), nb::arg("margin"))
      .def("patches", &Sweep::patches, nb::arg("q"), nb::arg("pairs"), nb::arg("tol"))
      .def("point_distance", &Sweep::point_distance, nb::arg("q"), nb::arg("k"))
      .def(
          "dip_distance",
          [](Sweep &self, F1 q, int64_t k) {
            self.check_pair_query(q, k);
            return self.dip_distance(q.data(), static_cast<size_t>(k));
          },
          nb::arg("q"), nb::arg("k"))
      .def("candidates", &Sweep::candidates, nb::arg("q"), nb::arg("margin"))
      .def("distances", &Sweep::distances, nb::arg("q"), nb::arg("pairs"))
      .def("set_planes", &Sweep::set_planes, nb::arg("N"), nb::arg("o"), nb::arg("start"))
      .def_prop_ro("has_planes", &Sweep::has_planes)
      .def("materials", &Sweep::materials, nb::arg("q"), nb::arg("pairs"), nb::arg("tol"),
           nb::arg("patch_tol"), nb::arg("face_align"))
      .def("witness", &Sweep::witness, nb::arg("p1"), nb::arg("p2"), nb::arg("normal"))
      .def("boxes", &Sweep::boxes, nb::arg("lo"), nb::arg("hi"))
      .def("last_q", &Sweep::last_q)
      .def("fresh", &Sweep::fresh, nb::rv_policy::take_ownership)
      .def("api", [](nb::handle self) { return nb::cast<Sweep &>(self).api(self); })
      .def_prop_ro("n_pairs", &Sweep::n_pairs);
}
