#include "vtkRVEEffectiveProperties.h"

#include <algorithm>
#include <cmath>

#include "rvegen/homogenize/effective.hpp"
#include "rvegen/io/scene_json.hpp"
#include "rvegen/packing/packing.hpp"
#include "vtkCellData.h"
#include "vtkDataArray.h"
#include "vtkDoubleArray.h"
#include "vtkImageData.h"
#include "vtkInformation.h"
#include "vtkInformationVector.h"
#include "vtkIntArray.h"
#include "vtkObjectFactory.h"
#include "vtkRVECommon.h"
#include "vtkStringArray.h"
#include "vtkTable.h"

vtkStandardNewMacro(vtkRVEEffectiveProperties);

vtkRVEEffectiveProperties::vtkRVEEffectiveProperties()
    : Materials(R"({"matrix": {"conductivity": 1, "young": 3, "poisson": 0.35},)"
                R"( "spheres": {"conductivity": 10, "young": 70, "poisson": 0.2},)"
                R"( "fibres": {"axial_conductivity": 50, "transverse_conductivity": 5,)"
                R"( "axial_young": 230, "transverse_young": 15, "axial_shear": 27,)"
                R"( "axial_poisson": 0.2, "transverse_poisson": 0.4},)"
                R"( "grains": {"conductivity": 10, "young": 70, "poisson": 0.2}})") {}

int vtkRVEEffectiveProperties::FillInputPortInformation(int, vtkInformation* info) {
  info->Set(vtkAlgorithm::INPUT_REQUIRED_DATA_TYPE(), "vtkImageData");
  return 1;
}

namespace {

// The scene the materials are checked against: the inclusion list's families (name, shape,
// coating).
rvegen::Scene scene_of(const rvegen::InclusionSet& set) {
  rvegen::Scene s;
  s.box = set.box;
  s.families.resize(set.family_names.size());
  for (size_t f = 0; f < s.families.size(); ++f) s.families[f].name = set.family_names[f];
  for (const rvegen::Inclusion& inc : set.inclusions) {
    if (inc.family < 0 || inc.family >= static_cast<int>(s.families.size())) continue;
    rvegen::Family& fam = s.families[inc.family];
    fam.shape = inc.shape.kind;
    fam.modifiers.coating = std::max(fam.modifiers.coating, inc.mod.coating);
  }
  return s;
}

}  // namespace

int vtkRVEEffectiveProperties::RequestData(vtkInformation*, vtkInformationVector** in,
                                           vtkInformationVector* out) {
  vtkImageData* input = vtkImageData::GetData(in[0]);
  vtkTable* table = vtkTable::GetData(out);
  rvegen::InclusionSet set;
  std::string error;
  if (!input || !RVEInclusionsFromFieldData(input, &set, &error)) {
    vtkErrorMacro(<< (input ? error : "the input is not an image"));
    return 0;
  }
  // The whole image, as the generator lays it out.
  int ext[6];
  input->GetExtent(ext);
  const std::array<int, 3> dims = {ext[1] - ext[0], ext[3] - ext[2], ext[5] - ext[4]};
  for (int a = 0; a < 3; ++a) {
    const double expect = set.box.size[a] / input->GetSpacing()[a];
    if (ext[2 * a] != 0 || dims[a] < 1 || std::abs(expect - dims[a]) > 1e-6 * dims[a]) {
      vtkErrorMacro(<< "the input must be the whole voxel image of the RVE's box (axis " << a
                    << ": extent " << ext[2 * a] << ".." << ext[2 * a + 1] << ")");
      return 0;
    }
  }
  vtkDataArray* phase = input->GetCellData()->GetArray("phase");
  vtkDataArray* ids = input->GetCellData()->GetArray("inclusion_id");
  const vtkIdType n = input->GetNumberOfCells();
  if (!phase || !ids || phase->GetNumberOfTuples() != n || ids->GetNumberOfTuples() != n) {
    vtkErrorMacro(<< "the input has no cell data phase and inclusion_id (use the Voxels output)");
    return 0;
  }
  rvegen::Scene scene = scene_of(set);
  rvegen::HomogenizationSpec& h = scene.homogenization;
  h.conductivity = this->Physics != 1;
  h.elasticity = this->Physics != 0;
  const char* rules[] = {"plain", "voigt", "reuss", "laminate"};
  h.voxel_rule = rules[this->VoxelRule];
  h.scheme = this->Scheme == 1 ? "moulinec_suquet" : "rotated";
  h.tolerance = this->Tolerance;
  h.max_iterations = this->MaxIterations;
  rvegen::VoxelImage image;
  try {
    rvegen::read_materials_json(this->Materials, &scene);
    rvegen::validate_homogenization(scene);
    image = rvegen::voxel_layout(set, dims);
    image.phase.resize(n);
    image.inclusion_id.resize(n);
    for (vtkIdType i = 0; i < n; ++i) {
      const double p = phase->GetTuple1(i);
      if (!(p >= 0.0 && p < static_cast<double>(image.phases.size()))) {
        throw rvegen::InputError("voxel " + std::to_string(i) + " has no phase of the RVE");
      }
      image.phase[i] = static_cast<uint8_t>(p);
      image.inclusion_id[i] = static_cast<int32_t>(ids->GetTuple1(i));
    }
  } catch (const std::exception& e) {
    vtkErrorMacro(<< e.what());
    return 0;
  }

  // Progress: load cases done plus the current one's share, its residual's way down to the
  // tolerance on a log scale; never falling.
  const int total = (h.conductivity ? 3 : 0) + (h.elasticity ? 6 : 0);
  double shown = 0.0;
  this->UpdateProgress(0.0);
  auto progress = [&](const char* physics, int load, int, int, double rel) {
    const int before = std::string(physics) == "elasticity" && h.conductivity ? 3 : 0;
    const double part =
        rel > 0.0 ? std::clamp(std::log(rel) / std::log(h.tolerance), 0.0, 0.99) : 0.99;
    const double f = (before + load + part) / total;
    if (f > shown + 0.005) {
      shown = f;
      this->UpdateProgress(f);
    }
    return !this->GetAbortExecute();
  };
  rvegen::EffectiveProperties e;
  try {
    e = rvegen::effective_properties(scene, set, image, progress);
  } catch (const rvegen::Cancelled&) {
    vtkWarningMacro(<< "aborted; the table is empty");
    this->SetAbortExecute(0);
    return 1;
  } catch (const std::exception& ex) {
    vtkErrorMacro(<< ex.what());
    return 0;
  }

  RVELongTable rows;
  auto bounds = [&](const char* q, const rvegen::Bounds& b) {
    if (!b.stated) return;
    rows.Row(q, "voigt", 0, b.voigt);
    rows.Row(q, "reuss", 1, b.reuss);
    rows.Row(q, "hs_lower", 2, b.hs_lower);
    rows.Row(q, "hs_upper", 3, b.hs_upper);
  };
  auto ij = [](const char* p, int i, int j) {
    return std::string(p) + std::to_string(i + 1) + std::to_string(j + 1);
  };
  rows.Row("cut_voxels", e.voxel_rule, 0, static_cast<double>(e.cut_voxels));
  if (e.has_conductivity) {
    const rvegen::ConductivityResult& r = e.conductivity;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j)
        rows.Row("conductivity", ij("k", i, j), 3 * i + j, r.tensor(i, j));
    }
    bounds("conductivity_bound", e.conductivity_bounds);
    for (int l = 0; l < 3; ++l) {
      rows.Row("iterations", "conductivity", l, r.iterations[l]);
      rows.Row("residual", "conductivity", l, r.residual[l]);
    }
    rows.Row("seconds", "conductivity", 0, r.seconds);
  }
  if (e.has_stiffness) {
    const rvegen::ElasticityResult& r = e.stiffness;
    for (int i = 0; i < 6; ++i) {
      for (int j = 0; j < 6; ++j)
        rows.Row("stiffness", ij("C", i, j), 6 * i + j, r.stiffness(i, j));
    }
    const rvegen::EngineeringConstants& k = e.constants;
    const std::pair<const char*, double> constants[] = {
        {"E1", k.e1},   {"E2", k.e2},     {"E3", k.e3},     {"G23", k.g23},  {"G13", k.g13},
        {"G12", k.g12}, {"nu12", k.nu12}, {"nu13", k.nu13}, {"nu23", k.nu23}};
    int c = 0;
    for (const auto& [nm, v] : constants) rows.Row("engineering_constant", nm, c++, v);
    rows.Row("isotropic_projection", "bulk", 0, e.bulk);
    rows.Row("isotropic_projection", "shear", 1, e.shear);
    bounds("bulk_bound", e.bulk_bounds);
    bounds("shear_bound", e.shear_bounds);
    for (int l = 0; l < 6; ++l) {
      rows.Row("iterations", "elasticity", l, r.iterations[l]);
      rows.Row("residual", "elasticity", l, r.residual[l]);
    }
    rows.Row("seconds", "elasticity", 0, r.seconds);
  }
  rows.AddTo(table);
  this->UpdateProgress(1.0);
  return 1;
}
