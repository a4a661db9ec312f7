#include "rvegen/model/phases.hpp"

#include <algorithm>
#include <cctype>

namespace rvegen {

std::string deck_name(const std::string& phase) {
  std::string s;
  for (char c : phase) s += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
  if (s.empty() || !std::isalpha(static_cast<unsigned char>(s[0]))) s = "P_" + s;
  return s;
}

const char* phase_kind_name(PhaseKind kind) {
  switch (kind) {
    case PhaseKind::kMatrix:
      return "matrix";
    case PhaseKind::kCore:
      return "core";
    case PhaseKind::kInterphase:
      return "interphase";
    case PhaseKind::kVoid:
      return "void";
  }
  return "matrix";
}

std::vector<Phase> phase_table(const InclusionSet& set) {
  int nf = static_cast<int>(set.family_names.size());
  for (const auto& inc : set.inclusions) nf = std::max(nf, inc.family + 1);
  std::vector<bool> coated(nf, false), debonded(nf, false);
  for (const auto& inc : set.inclusions) {
    coated[inc.family] = coated[inc.family] || inc.mod.coated();
    debonded[inc.family] = debonded[inc.family] || inc.mod.debonded();
  }
  auto name_of = [&](int f) {
    return f < static_cast<int>(set.family_names.size()) ? set.family_names[f]
                                                         : "family " + std::to_string(f);
  };
  std::vector<Phase> out;
  out.push_back({0, "matrix", PhaseKind::kMatrix, -1});
  for (int f = 0; f < nf; ++f) out.push_back({core_label(f), name_of(f), PhaseKind::kCore, f});
  for (int f = 0; f < nf; ++f) {
    if (coated[f]) {
      out.push_back(
          {static_cast<int>(out.size()), name_of(f) + " interphase", PhaseKind::kInterphase, f});
    }
    if (debonded[f]) {
      out.push_back({static_cast<int>(out.size()), name_of(f) + " void", PhaseKind::kVoid, f});
    }
  }
  return out;
}

namespace {

std::vector<int> labels_of(const std::vector<Phase>& phases, int families, PhaseKind kind) {
  std::vector<int> out(static_cast<size_t>(std::max(families, 0)), -1);
  for (const Phase& p : phases) {
    if (p.kind != kind || p.family < 0) continue;
    if (p.family >= static_cast<int>(out.size())) out.resize(p.family + 1, -1);
    out[p.family] = p.label;
  }
  return out;
}

}  // namespace

std::vector<int> interphase_labels(const std::vector<Phase>& phases, int families) {
  return labels_of(phases, families, PhaseKind::kInterphase);
}

std::vector<int> void_labels(const std::vector<Phase>& phases, int families) {
  return labels_of(phases, families, PhaseKind::kVoid);
}

}  // namespace rvegen
