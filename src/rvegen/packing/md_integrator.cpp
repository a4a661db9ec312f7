#include "rvegen/packing/md_integrator.hpp"

#include <tbb/blocked_range.h>

#include <Eigen/Geometry>
#include <cmath>

#include "rvegen/model/orientation.hpp"
#include "rvegen/model/parallel.hpp"

namespace rvegen::md {

namespace {

// The orientation tensor held by md.rotation keep_tensor is matched to this (entries at most 1).
constexpr double kHeldTensorTolerance = 1e-10;
constexpr double kMomentum = 0.9;  // fraction of the last step's motion kept (damping 0.1)
constexpr double kMaxTurn = 0.2;   // radians per step
}  // namespace

Integrator::Integrator(size_t bodies) : vel_(bodies, Vec3::Zero()), omega_(bodies, Vec3::Zero()) {}

void Integrator::step(const ContactSums& sums, std::vector<Body>* bodies, VerletList* list) {
  // Each body on its own (all cores).
  rvegen::parallel_for_range(tbb::blocked_range<size_t>(0, bodies->size(), 512),
                             [&](const tbb::blocked_range<size_t>& r) {
                               for (size_t i = r.begin(); i != r.end(); ++i)
                                 move_body(sums, i, bodies, list);
                             });
}

void Integrator::move_body(const ContactSums& sums, size_t i, std::vector<Body>* bodies,
                           VerletList* list) {
  Body& b = (*bodies)[i];
  vel_[i] = kMomentum * vel_[i] + sums.move[i];
  b.shape.center += vel_[i];
  if (b.turn != Turn::kNone) {
    omega_[i] = kMomentum * omega_[i] + sums.turn[i];
    double ang = omega_[i].norm();
    if (ang > kMaxTurn) {
      omega_[i] *= kMaxTurn / ang;
      ang = kMaxTurn;
    }
    if (ang > 0.0) {
      b.turn_by(Eigen::AngleAxisd(ang, omega_[i] / ang).toRotationMatrix());
      list->turned(static_cast<int>(i), ang);
    }
  }
}

void hold_tensors(const PackingSpec& spec, const std::map<int, std::vector<int>>& held,
                  std::vector<Body>* bodies, VerletList* list) {
  for (const auto& held_family : held) {
    // Named copies of the binding: lambdas may not capture structured bindings in C++17.
    const int family = held_family.first;
    const std::vector<int>& members = held_family.second;
    std::vector<Vec3> dirs(members.size());
    const tbb::blocked_range<size_t> all(0, members.size(), 1024);
    rvegen::parallel_for_range(all, [&](const tbb::blocked_range<size_t>& r) {
      for (size_t k = r.begin(); k != r.end(); ++k) dirs[k] = law_axis((*bodies)[members[k]].shape);
    });
    if (!match_orientation_tensor(&dirs, spec.families[family].orientation.tensor(),
                                  kHeldTensorTolerance)) {
      continue;
    }
    // Each body turns on its own (members are distinct bodies).
    rvegen::parallel_for_range(all, [&](const tbb::blocked_range<size_t>& r) {
      for (size_t k = r.begin(); k != r.end(); ++k) {
        list->turned(members[k], set_law_axis(&(*bodies)[members[k]].shape, dirs[k]));
      }
    });
  }
}

}  // namespace rvegen::md
