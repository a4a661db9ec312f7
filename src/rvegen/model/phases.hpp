// The phases of an RVE: the matrix, the cores of each family, and the interphase shells and
// debonding voids of the families that have them. Voxel labels, level-set grids, the report and
// the HDF5 file all number phases this way.
#pragma once

#include <string>
#include <vector>

#include "rvegen/model/inclusion_set.hpp"

namespace rvegen {

enum class PhaseKind { kMatrix, kCore, kInterphase, kVoid };

/// The JSON/HDF5 name of a phase kind: "matrix", "core", "interphase", "void".
const char* phase_kind_name(PhaseKind kind);
/// A phase's name as the finite-element decks write it (element set, material): letters and
/// digits kept, every other character '_', "P_" before a name that does not start with a
/// letter. Two phases of one deck name would share a set and a material.
std::string deck_name(const std::string& phase);

/// One label of the phase image.
struct Phase {
  int label = 0;
  std::string name;  // "matrix", "<family>", "<family> interphase", "<family> void"
  PhaseKind kind = PhaseKind::kMatrix;
  int family = -1;  // -1 for the matrix
};

/// Labels of a set: 0 matrix, 1..F the cores of families 0..F-1, then, family by family, an
/// interphase label for each family with coated inclusions and a void label for each family
/// with debonded ones.
std::vector<Phase> phase_table(const InclusionSet& set);

/// Per family (0..F-1, or more if a phase names a later one), the label of its interphase
/// shells in `phases`; -1 for a family without.
std::vector<int> interphase_labels(const std::vector<Phase>& phases, int families);
/// The same for the debonding voids.
std::vector<int> void_labels(const std::vector<Phase>& phases, int families);

/// The label of family f's cores (the numbering above).
constexpr int core_label(int family) {
  return family + 1;
}

}  // namespace rvegen
