// ContactRhs: Pinocchio's passes on its model and data (aba, computeMinverse, crba,
// nonLinearEffects, computeJointJacobiansTimeVariation, the potential energy), the one file
// that instantiates Pinocchio's algorithms: every other file calls these.

#include "contact_rhs.hpp"

#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/energy.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/rnea.hpp>

void ContactRhs::aba_world(const Eigen::VectorXd &q, const Eigen::VectorXd &v,
                           const Eigen::VectorXd &tau) {
  pin::aba(model_, data_, q, v, tau, pin::Convention::WORLD);
}

void ContactRhs::minverse(const Eigen::VectorXd &q) { pin::computeMinverse(model_, data_, q); }

void ContactRhs::minverse_after_aba() { pin::computeMinverse(model_, data_); }

void ContactRhs::jacobians_time_variation() {
  pin::computeJointJacobiansTimeVariation(model_, data_, q_, v_);
}

void ContactRhs::crba_local(const Eigen::VectorXd &q) {
  pin::crba(model_, data_, q, pin::Convention::LOCAL);
}

void ContactRhs::nonlinear_effects() { pin::nonLinearEffects(model_, data_, q_, v_); }

double ContactRhs::potential(const Eigen::VectorXd &q) {
  return pin::computePotentialEnergy(model_, data_, q);
}
