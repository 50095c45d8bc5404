// The joints packbot's native modules rebuild in their own Pinocchio model (shared by
// src/native/contact_rhs.hpp and src/native/sweep.cpp).
//
// Pinocchio's algorithms visit a joint variant; its default collection has 25 types (composite
// and mimic joints among them), each instantiating every algorithm step: this one (the 1-dof
// revolute and prismatic joints, and the mimic joint Pinocchio's model code asks for) compiles
// in a fraction of the time and memory.
#pragma once

#include <pinocchio/multibody/joint/joints.hpp>
#include <pinocchio/multibody/model.hpp>

#include <stdexcept>
#include <string>

namespace packbot_native {

namespace pin = pinocchio;

template <typename _Scalar, int _Options> struct PackbotJointsTpl {
  typedef _Scalar Scalar;
  static constexpr int Options = _Options;
  typedef pin::JointModelRevoluteTpl<Scalar, Options, 0> JointModelRX;
  typedef pin::JointModelRevoluteTpl<Scalar, Options, 1> JointModelRY;
  typedef pin::JointModelRevoluteTpl<Scalar, Options, 2> JointModelRZ;
  typedef pin::JointModelRevoluteUnalignedTpl<Scalar, Options> JointModelRevoluteUnaligned;
  typedef pin::JointModelPrismaticTpl<Scalar, Options, 0> JointModelPX;
  typedef pin::JointModelPrismaticTpl<Scalar, Options, 1> JointModelPY;
  typedef pin::JointModelPrismaticTpl<Scalar, Options, 2> JointModelPZ;
  typedef pin::JointModelPrismaticUnalignedTpl<Scalar, Options> JointModelPrismaticUnaligned;
  // Pinocchio's model and data test for mimic joints (boost::get): the variant must hold them
  typedef pin::JointModelMimicTpl<Scalar, Options, PackbotJointsTpl> JointModelMimic;
  typedef boost::variant<JointModelRX, JointModelRY, JointModelRZ, JointModelRevoluteUnaligned,
                         JointModelPX, JointModelPY, JointModelPZ, JointModelPrismaticUnaligned,
                         boost::recursive_wrapper<JointModelMimic>>
      JointModelVariant;
  typedef pin::JointDataRevoluteTpl<Scalar, Options, 0> JointDataRX;
  typedef pin::JointDataRevoluteTpl<Scalar, Options, 1> JointDataRY;
  typedef pin::JointDataRevoluteTpl<Scalar, Options, 2> JointDataRZ;
  typedef pin::JointDataRevoluteUnalignedTpl<Scalar, Options> JointDataRevoluteUnaligned;
  typedef pin::JointDataPrismaticTpl<Scalar, Options, 0> JointDataPX;
  typedef pin::JointDataPrismaticTpl<Scalar, Options, 1> JointDataPY;
  typedef pin::JointDataPrismaticTpl<Scalar, Options, 2> JointDataPZ;
  typedef pin::JointDataPrismaticUnalignedTpl<Scalar, Options> JointDataPrismaticUnaligned;
  typedef pin::JointDataMimicTpl<Scalar, Options, PackbotJointsTpl> JointDataMimic;
  typedef boost::variant<JointDataRX, JointDataRY, JointDataRZ, JointDataRevoluteUnaligned,
                         JointDataPX, JointDataPY, JointDataPZ, JointDataPrismaticUnaligned,
                         boost::recursive_wrapper<JointDataMimic>>
      JointDataVariant;
};

using JointModel = pin::JointModelTpl<double, 0, PackbotJointsTpl>;
using J = PackbotJointsTpl<double, 0>;

// A joint of the collection by Pinocchio's short name; axis: the unaligned joints' axis.
inline JointModel make_joint(const std::string &type, const double *axis) {
  const Eigen::Vector3d ax(axis[0], axis[1], axis[2]);
  if (type == "JointModelRX") return J::JointModelRX();
  if (type == "JointModelRY") return J::JointModelRY();
  if (type == "JointModelRZ") return J::JointModelRZ();
  if (type == "JointModelRevoluteUnaligned") return J::JointModelRevoluteUnaligned(ax);
  if (type == "JointModelPX") return J::JointModelPX();
  if (type == "JointModelPY") return J::JointModelPY();
  if (type == "JointModelPZ") return J::JointModelPZ();
  if (type == "JointModelPrismaticUnaligned") return J::JointModelPrismaticUnaligned(ax);
  throw std::invalid_argument("unsupported joint type " + type);
}

}  // namespace packbot_native
