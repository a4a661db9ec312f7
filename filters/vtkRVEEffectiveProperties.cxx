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
#include "vtkMPI.h"
#include "vtkMPICommunicator.h"
#include "vtkMPIController.h"
#include "vtkObjectFactory.h"
#include "vtkProcessModule.h"
#include "vtkRVECommon.h"
#include "vtkStreamingDemandDrivenPipeline.h"
#include "vtkStringArray.h"
#include "vtkTable.h"

vtkStandardNewMacro(vtkRVEEffectiveProperties);

// clang-format off
vtkRVEEffectiveProperties::vtkRVEEffectiveProperties()
    : Materials(R"({"matrix": {"conductivity": 1, "young": 3, "poisson": 0.35},)" "\n"
                R"( "spheres": {"conductivity": 10, "young": 70, "poisson": 0.2},)" "\n"
                R"( "fibres": {"axial_conductivity": 50, "transverse_conductivity": 5,)" "\n"
                R"(            "axial_young": 230, "transverse_young": 15, "axial_shear": 27,)" "\n"
                R"(            "axial_poisson": 0.2, "transverse_poisson": 0.4},)" "\n"
                R"( "grains": {"conductivity": 10, "young": 70, "poisson": 0.2}})") {}
// clang-format on

int vtkRVEEffectiveProperties::FillInputPortInformation(int, vtkInformation* info) {
  info->Set(vtkAlgorithm::INPUT_REQUIRED_DATA_TYPE(), "vtkImageData");
  return 1;
}

namespace {

// The ranks that run the pipeline in step (pvbatch --symmetric) under MPI, for the distributed
// solve; unset otherwise. Driven from rank 0 or from a client, the other ranks may not be
// executing when this one does, so no collective is made there.
rvegen::Communicator ranks_in_step() {
  auto* mpc = vtkMPIController::SafeDownCast(vtkMultiProcessController::GetGlobalController());
  const bool in_step =
      vtkProcessModule::GetProcessModule() && vtkProcessModule::GetSymmetricMPIMode();
  if (!mpc || !in_step || mpc->GetNumberOfProcesses() < 2) return {};
  auto* comm = vtkMPICommunicator::SafeDownCast(mpc->GetCommunicator());
  if (!comm || !comm->GetMPIComm() || !comm->GetMPIComm()->GetHandle()) return {};
  return rvegen::Communicator::from_fortran(MPI_Comm_c2f(*comm->GetMPIComm()->GetHandle()));
}

// The voxel planes along z this rank solves: its slab of FFTW's distribution, or all of them.
std::array<int, 2> planes_here(const int whole[6], const rvegen::Communicator& comm) {
  const std::array<int, 3> dims = {whole[1] - whole[0], whole[3] - whole[2], whole[5] - whole[4]};
  if (dims[0] < 1 || dims[1] < 1 || dims[2] < 1) return {0, 0};
  const std::array<int, 2> z = rvegen::spectral::fft_slab(dims, comm);
  return {whole[4] + z[0], whole[4] + z[1]};
}

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

// The input checked, the scene of its inclusions with the filter's settings, and this rank's
// slab of the image (the whole image in one process); the message of what is wrong, or "".
std::string read_input(vtkRVEEffectiveProperties* self, vtkImageData* input, vtkInformation* info,
                       const rvegen::Communicator& comm, rvegen::Scene* scene,
                       rvegen::InclusionSet* set, rvegen::VoxelImage* image) {
  std::string error;
  if (!input || !RVEInclusionsFromFieldData(input, set, &error)) {
    return input ? error : "the input is not an image";
  }
  // The whole image, as the generator lays it out, and the planes this rank solves.
  int whole[6], ext[6];
  info->Get(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT(), whole);
  input->GetExtent(ext);
  const std::array<int, 3> dims = {whole[1] - whole[0], whole[3] - whole[2], whole[5] - whole[4]};
  for (int a = 0; a < 3; ++a) {
    const double expect = set->box.size[a] / input->GetSpacing()[a];
    if (whole[2 * a] != 0 || dims[a] < 1 || std::abs(expect - dims[a]) > 1e-6 * dims[a]) {
      return "the input must be the voxel image of the RVE's box (axis " + std::to_string(a) +
             ": whole extent " + std::to_string(whole[2 * a]) + ".." +
             std::to_string(whole[2 * a + 1]) + ")";
    }
  }
  const std::array<int, 2> z = planes_here(whole, comm);
  const bool empty = z[1] <= z[0];
  if (!empty && (ext[0] != 0 || ext[1] != dims[0] || ext[2] != 0 || ext[3] != dims[1] ||
                 ext[4] > z[0] || ext[5] < z[1])) {
    return "the input holds planes " + std::to_string(ext[4]) + ".." + std::to_string(ext[5]) +
           " along z, not " + std::to_string(z[0]) + ".." + std::to_string(z[1]);
  }
  vtkDataArray* phase = input->GetCellData()->GetArray("phase");
  vtkDataArray* ids = input->GetCellData()->GetArray("inclusion_id");
  const vtkIdType have = input->GetNumberOfCells();
  if (!empty &&
      (!phase || !ids || phase->GetNumberOfTuples() != have || ids->GetNumberOfTuples() != have)) {
    return "the input has no cell data phase and inclusion_id (use the Voxels output)";
  }
  // Enumerations are checked, not clamped (a Physics of 5 was both physics without a word).
  if (self->GetPhysics() < 0 || self->GetPhysics() > 2)
    return "Physics: must be 0 (conductivity), 1 (elasticity) or 2 (both), got " +
           std::to_string(self->GetPhysics());
  if (self->GetVoxelRule() < 0 || self->GetVoxelRule() > 3)
    return "VoxelRule: must be 0 (plain), 1 (voigt), 2 (reuss) or 3 (laminate), got " +
           std::to_string(self->GetVoxelRule());
  if (self->GetScheme() < 0 || self->GetScheme() > 1)
    return "Scheme: must be 0 (rotated) or 1 (moulinec_suquet), got " +
           std::to_string(self->GetScheme());
  *scene = scene_of(*set);
  rvegen::HomogenizationSpec& h = scene->homogenization;
  h.conductivity = self->GetPhysics() != 1;
  h.elasticity = self->GetPhysics() != 0;
  const char* rules[] = {"plain", "voigt", "reuss", "laminate"};
  h.voxel_rule = rules[self->GetVoxelRule()];
  h.scheme = self->GetScheme() == 1 ? "moulinec_suquet" : "rotated";
  h.tolerance = self->GetTolerance();
  h.max_iterations = self->GetMaxIterations();
  try {
    rvegen::read_materials_json(self->GetMaterials(), scene);
    rvegen::validate_homogenization(*scene);
    rvegen::VoxelOptions slab;
    slab.extent = {0, dims[0], 0, dims[1], z[0], z[1]};
    *image = rvegen::voxel_layout(*set, dims, slab);
    const size_t n = image->count();
    image->phase.resize(n);
    image->inclusion_id.resize(n);
    // The slab's voxels, from the planes of the input that hold them.
    const vtkIdType skip = static_cast<vtkIdType>(z[0] - ext[4]) * dims[0] * dims[1];
    for (size_t i = 0; i < n; ++i) {
      const vtkIdType at = skip + static_cast<vtkIdType>(i);
      const double p = phase->GetTuple1(at);
      if (!(p >= 0.0 && p < static_cast<double>(image->phases.size()))) {
        throw rvegen::InputError("voxel " + std::to_string(at) + " has no phase of the RVE");
      }
      image->phase[i] = static_cast<uint8_t>(p);
      image->inclusion_id[i] = static_cast<int32_t>(ids->GetTuple1(at));
    }
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

}  // namespace

int vtkRVEEffectiveProperties::RequestUpdateExtent(vtkInformation*, vtkInformationVector** in,
                                                   vtkInformationVector*) {
  // Under MPI in step, each rank asks for its own slab of the image (never the whole image);
  // otherwise for the whole image.
  vtkInformation* info = in[0]->GetInformationObject(0);
  if (!info || !info->Has(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT())) return 1;
  int whole[6];
  info->Get(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT(), whole);
  const std::array<int, 2> z = planes_here(whole, ranks_in_step());
  int ext[6] = {whole[0], whole[1], whole[2], whole[3], z[0], z[1]};
  if (z[1] <= z[0]) {  // no planes here: nothing to voxelize
    for (int a = 0; a < 3; ++a) ext[2 * a] = 0, ext[2 * a + 1] = -1;
  }
  // One piece of one: a producer that can give sub-extents would otherwise turn the piece
  // request of the ranks into an extent of its own choosing.
  info->Set(vtkStreamingDemandDrivenPipeline::UPDATE_PIECE_NUMBER(), 0);
  info->Set(vtkStreamingDemandDrivenPipeline::UPDATE_NUMBER_OF_PIECES(), 1);
  info->Set(vtkStreamingDemandDrivenPipeline::UPDATE_NUMBER_OF_GHOST_LEVELS(), 0);
  info->Set(vtkStreamingDemandDrivenPipeline::UPDATE_EXTENT(), ext, 6);
  info->Set(vtkStreamingDemandDrivenPipeline::EXACT_EXTENT(), 1);
  return 1;
}

int vtkRVEEffectiveProperties::RequestData(vtkInformation*, vtkInformationVector** in,
                                           vtkInformationVector* out) {
  vtkImageData* input = vtkImageData::GetData(in[0]);
  vtkTable* table = vtkTable::GetData(out);
  const rvegen::Communicator comm = ranks_in_step();
  rvegen::Scene scene;
  rvegen::InclusionSet set;
  rvegen::VoxelImage image;
  // The input checked and this rank's slab of it read; a clear message otherwise. Under MPI
  // the ranks agree before the solve, so that one rank's refusal stops them all.
  std::string error =
      read_input(this, input, in[0]->GetInformationObject(0), comm, &scene, &set, &image);
  double refused = error.empty() ? 0.0 : 1.0;
  rvegen::sum_over_ranks(&refused, 1, comm);
  if (refused > 0.0) {
    vtkErrorMacro(<< (error.empty() ? "another rank refused its part of the input" : error));
    return 0;
  }
  const rvegen::HomogenizationSpec& h = scene.homogenization;

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
    e = rvegen::effective_properties(scene, set, image, progress, comm);
  } catch (const rvegen::Cancelled&) {
    vtkWarningMacro(<< "aborted; the table is empty");
    this->SetAbortExecute(0);
    return 1;
  } catch (const std::exception& ex) {
    vtkErrorMacro(<< ex.what());
    return 0;
  }
  const std::string not_converged = rvegen::unconverged(e, this->Tolerance);
  if (!not_converged.empty()) {
    vtkWarningMacro(<< "did not converge, so the table's tensors are not the RVE's effective "
                       "properties (rows \"converged\" are 0): "
                    << not_converged);
  }

  // Every rank has the result; rank 0 alone gives the table (so that gathering the ranks'
  // tables does not repeat it).
  if (rvegen::rank_of(comm) != 0) {
    this->UpdateProgress(1.0);
    return 1;
  }
  RVELongTable rows;
  rows.Row("ranks", "solve", 0, rvegen::ranks_of(comm));
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
    rows.Row("converged", "conductivity", 0, r.converged ? 1.0 : 0.0);
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
    rows.Row("converged", "elasticity", 0, r.converged ? 1.0 : 0.0);
  }
  rows.AddTo(table);
  this->UpdateProgress(1.0);
  return 1;
}

void vtkRVEEffectiveProperties::PrintSelf(ostream& os, vtkIndent indent) {
  this->Superclass::PrintSelf(os, indent);
  os << indent << "Physics: " << this->Physics << "\n"
     << indent << "VoxelRule: " << this->VoxelRule << "\n"
     << indent << "Scheme: " << this->Scheme << "\n"
     << indent << "Tolerance: " << this->Tolerance << "\n"
     << indent << "MaxIterations: " << this->MaxIterations << "\n";
}
