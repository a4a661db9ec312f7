// Molecular-dynamics packing, part 4: the motion. Bodies move in the strongly damped limit of
// the paper's equations of motion: this step's summed contact responses plus a fraction
// kMomentum of the last step's motion; bodies that may turn turn likewise (at most kMaxTurn
// radians a step). Under md.rotation keep_tensor, one linear map per family then restores the
// law's orientation tensor.
#pragma once

#include <map>
#include <vector>

#include "rvegen/packing/md_contacts.hpp"

namespace rvegen::md {

class Integrator {
 public:
  explicit Integrator(size_t bodies);
  /// Moves (and turns) every body by its damped motion; turns are recorded in *list.
  void step(const ContactSums& sums, std::vector<Body>* bodies, VerletList* list);

 private:
  void move_body(const ContactSums& sums, size_t i, std::vector<Body>* bodies, VerletList* list);
  std::vector<Vec3> vel_, omega_;
};

/// md.rotation keep_tensor: for each family in `held` (family -> bodies that turn), one linear
/// map of all the family's axes (match_orientation_tensor) restores the law's A2 exactly; the
/// turns are recorded in *list.
void hold_tensors(const PackingSpec& spec, const std::map<int, std::vector<int>>& held,
                  std::vector<Body>* bodies, VerletList* list);

}  // namespace rvegen::md
