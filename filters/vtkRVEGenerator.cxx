#include "vtkRVEGenerator.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <memory>
#include <utility>

#include "rvegen/io/inclusions_json.hpp"
#include "rvegen/io/scene_json.hpp"
#include "rvegen/io/writers.hpp"
#include "rvegen/model/scene.hpp"
#include "rvegen/packing/packing.hpp"
#include "rvegen/pipeline/run.hpp"
#include "rvegen/raster/glyphs.hpp"
#include "rvegen/raster/levelset.hpp"
#include "rvegen/raster/mesh.hpp"
#include "rvegen/raster/voxelize.hpp"
#include "vtkCellArray.h"
#include "vtkCellData.h"
#include "vtkDemandDrivenPipeline.h"
#include "vtkDoubleArray.h"
#include "vtkFieldData.h"
#include "vtkFloatArray.h"
#include "vtkImageData.h"
#include "vtkInformation.h"
#include "vtkInformationVector.h"
#include "vtkIntArray.h"
#include "vtkMultiProcessController.h"
#include "vtkNew.h"
#include "vtkObjectFactory.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"
#include "vtkProcessModule.h"
#include "vtkRVECommon.h"
#include "vtkStreamingDemandDrivenPipeline.h"
#include "vtkStringArray.h"
#include "vtkTypeInt64Array.h"
#include "vtkUnsignedCharArray.h"

vtkStandardNewMacro(vtkRVEGenerator);

namespace {
// Share of the progress bar taken by the packing (the outputs take the rest).
constexpr double kPackingShare = 0.9;
const char* const kAbortedMessage = "aborted";
}  // namespace

struct vtkRVEGenerator::Cache {
  std::string key;  // scene JSON without the voxel resolution
  rvegen::PackingResult result;
  int nudged = 0;  // inclusions the scene's mesh_tet moved off its cell's faces (pack_scene)
};

vtkRVEGenerator::vtkRVEGenerator() {
  this->SetNumberOfInputPorts(0);
  this->SetNumberOfOutputPorts(4);
  const rvegen::Scene d = rvegen::default_scene();
  this->Seed = static_cast<int>(d.seed);
  for (int a = 0; a < 3; ++a) {
    this->BoxSize[a] = d.box.size[a];
    this->Resolution[a] = d.resolution[a];
    this->EllipsoidSemiAxes[a] = d.families[2].semi_axes[a].p1;
  }
  this->Periodic = d.box.periodic;
  this->MinGap = d.min_gap;
  this->SphereRadius = d.families[0].radius.p1;
  this->SphereVolumeFraction = d.families[0].volume_fraction;
  this->FibreRadius = d.families[1].radius.p1;
  this->FibreAspectRatio = d.families[1].aspect_ratio.p1;
  this->FibreVolumeFraction = d.families[1].volume_fraction;
  this->EllipsoidVolumeFraction = d.families[2].volume_fraction;
  this->SceneFile = nullptr;
  this->ClipSurfaces = d.clip_surfaces;
  this->Mesh = d.outputs.mesh;
  this->Method = static_cast<int>(d.method);
  this->TimeBudget = d.md.max_seconds;
  this->SphereRadiusStd = 0.0;
  this->SphereCount = 100;
  this->FibreRadiusStd = 0.0;
  this->FibreCount = 100;
  this->EllipsoidCount = 100;
  this->FibreOrientation = 0;
  this->FibreKappa = 10.0;
  this->EllipsoidOrientation = 0;
  this->EllipsoidKappa = 10.0;
  this->SphereCoating = 0.0;
  this->FibreCoating = 0.0;
  this->EllipsoidCoating = 0.0;
  this->ShellsMayTouch = false;
  this->FibreWaveAmplitude = 0.0;
  this->FibreWavelength = 0.2;
  this->FibreCurvatureRadius = 0.0;
  this->SphereDeformation = 0.0;
  this->EllipsoidDeformation = 0.0;
  this->DeformationSmoothness = 1.0;
  this->SphereDebondFraction = 0.0;
  this->SphereDebondGap = 0.0;
  this->PartialVolume = d.partial_volume;
  this->LevelSetVoxelSize = d.levelset_voxel_size;
  for (int a = 0; a < 3; ++a) this->FibreAxis[a] = this->EllipsoidAxis[a] = a == 2 ? 1.0 : 0.0;
  for (int k = 0; k < 6; ++k) this->FibreOrientationTensor[k] = k < 3 ? 1.0 / 3.0 : 0.0;
}

vtkRVEGenerator::~vtkRVEGenerator() {
  this->SetSceneFile(nullptr);
}

int vtkRVEGenerator::FillOutputPortInformation(int port, vtkInformation* info) {
  info->Set(vtkDataObject::DATA_TYPE_NAME(), port == 1 ? "vtkImageData" : "vtkPolyData");
  return 1;
}

namespace {
// The scene the properties describe (families with a zero volume fraction are left out).
rvegen::Scene SceneFromProperties(const vtkRVEGenerator* g) {
  rvegen::Scene s = rvegen::default_scene();
  auto* self = const_cast<vtkRVEGenerator*>(g);
  s.seed = static_cast<uint64_t>(self->GetSeed());
  s.box.size = rvegen::Vec3(self->GetBoxSize()[0], self->GetBoxSize()[1], self->GetBoxSize()[2]);
  s.box.periodic = self->GetPeriodic();
  s.min_gap = self->GetMinGap();
  s.md.max_seconds = s.rsa_max_seconds = self->GetTimeBudget();
  s.method = static_cast<rvegen::Method>(self->GetMethod());
  auto size = [](double value, double std) {
    rvegen::SizeLaw law(value);
    if (std > 0.0) {
      law.kind = rvegen::SizeLaw::Kind::kLognormal;
      law.p2 = std;
    }
    return law;
  };
  auto amount = [](rvegen::Family& f, int by_count, double vf, int count) {
    f.volume_fraction = by_count ? -1.0 : vf;
    f.count = by_count ? count : -1;
  };
  auto orientation = [](int kind, const double* axis, double kappa) {
    rvegen::OrientationLaw law;
    const rvegen::Vec3 u(axis[0], axis[1], axis[2]);
    law.axis = u.norm() > 0.0 ? rvegen::Vec3(u.normalized()) : rvegen::Vec3::UnitZ();
    law.kappa = kappa;
    law.kind = kind == 1   ? rvegen::OrientationLaw::Kind::kAligned
               : kind == 2 ? rvegen::OrientationLaw::Kind::kVonMisesFisher
               : kind == 3 ? rvegen::OrientationLaw::Kind::kPlanar
                           : rvegen::OrientationLaw::Kind::kIsotropic;
    return law;
  };
  rvegen::Family& sph = s.families[0];
  rvegen::Family& fib = s.families[1];
  rvegen::Family& ell = s.families[2];
  sph.radius = size(self->GetSphereRadius(), self->GetSphereRadiusStd());
  amount(sph, self->GetSphereAmount(), self->GetSphereVolumeFraction(), self->GetSphereCount());
  fib.radius = size(self->GetFibreRadius(), self->GetFibreRadiusStd());
  fib.aspect_ratio = self->GetFibreAspectRatio();
  if (self->GetFibreLengthLaw() == 1) {
    fib.aspect_ratio.kind = rvegen::SizeLaw::Kind::kLognormal;
    fib.aspect_ratio.p2 = self->GetFibreAspectRatioStd();
  } else if (self->GetFibreLengthLaw() == 2) {
    fib.aspect_ratio.kind = rvegen::SizeLaw::Kind::kWeibull;
    fib.aspect_ratio.p1 = self->GetFibreWeibullShape();
    fib.aspect_ratio.p2 = self->GetFibreWeibullScale();
  }
  amount(fib, self->GetFibreAmount(), self->GetFibreVolumeFraction(), self->GetFibreCount());
  fib.orientation =
      orientation(self->GetFibreOrientation(), self->GetFibreAxis(), self->GetFibreKappa());
  if (self->GetFibreOrientation() == 4) {
    const double* t = self->GetFibreOrientationTensor();
    fib.orientation.kind = rvegen::OrientationLaw::Kind::kTensor;
    fib.orientation.a2 << t[0], t[3], t[4], t[3], t[1], t[5], t[4], t[5], t[2];
    fib.orientation.a2 = rvegen::OrientationLaw::as_typed(fib.orientation.a2);
  }
  for (int a = 0; a < 3; ++a) ell.semi_axes[a] = self->GetEllipsoidSemiAxes()[a];
  amount(ell, self->GetEllipsoidAmount(), self->GetEllipsoidVolumeFraction(),
         self->GetEllipsoidCount());
  ell.orientation = orientation(self->GetEllipsoidOrientation(), self->GetEllipsoidAxis(),
                                self->GetEllipsoidKappa());
  const double coat[3] = {self->GetSphereCoating(), self->GetFibreCoating(),
                          self->GetEllipsoidCoating()};
  for (int f = 0; f < 3; ++f) {
    s.families[f].modifiers.coating = coat[f];
    s.families[f].modifiers.shells_may_touch = self->GetShellsMayTouch();
    s.families[f].modifiers.smoothness = self->GetDeformationSmoothness();
  }
  fib.modifiers.wave_amplitude = self->GetFibreWaveAmplitude();
  fib.modifiers.wave_length = self->GetFibreWavelength();
  fib.modifiers.bend_radius = self->GetFibreCurvatureRadius();
  sph.modifiers.deform_amplitude = self->GetSphereDeformation();
  ell.modifiers.deform_amplitude = self->GetEllipsoidDeformation();
  sph.modifiers.debond_fraction = self->GetSphereDebondFraction();
  sph.modifiers.debond_gap = self->GetSphereDebondGap();
  std::vector<rvegen::Family> kept;
  for (const auto& f : s.families) {
    if (f.volume_fraction > 0.0 || f.count > 0) kept.push_back(f);
  }
  s.families = kept;
  for (int a = 0; a < 3; ++a) s.resolution[a] = self->GetResolution()[a];
  s.clip_surfaces = self->GetClipSurfaces();
  s.outputs.mesh = self->GetMesh();
  s.partial_volume = self->GetPartialVolume();
  s.levelset_voxel_size = self->GetLevelSetVoxelSize();
  return s;
}

// The piece a port is asked for: {piece, number of pieces} ({0, 1} when none is set).
std::pair<int, int> RequestedPiece(vtkInformation* info) {
  using SDDP = vtkStreamingDemandDrivenPipeline;
  return {
      info->Has(SDDP::UPDATE_PIECE_NUMBER()) ? info->Get(SDDP::UPDATE_PIECE_NUMBER()) : 0,
      info->Has(SDDP::UPDATE_NUMBER_OF_PIECES()) ? info->Get(SDDP::UPDATE_NUMBER_OF_PIECES()) : 1};
}

// The inclusions of the piece that `info` asks for: those whose centre lies in the piece's slab
// of the box along z (centres outside the box go to the nearest slab). Every inclusion is in
// exactly one piece.
rvegen::InclusionSet PieceOf(const rvegen::InclusionSet& set, vtkInformation* info) {
  const auto [piece, pieces] = RequestedPiece(info);
  if (pieces <= 1) return set;
  rvegen::InclusionSet out;
  out.box = set.box;
  out.family_names = set.family_names;
  for (const rvegen::Inclusion& inc : set.inclusions) {
    const double t = (inc.shape.center[2] - set.box.origin[2]) / set.box.size[2];
    const int slab = std::min(pieces - 1, std::max(0, static_cast<int>(std::floor(t * pieces))));
    if (slab == piece) out.inclusions.push_back(inc);
  }
  return out;
}

// The amounts SceneFromProperties reads: 0 leaves a family out, a negative one is an error
// (it was left out silently too), named by its property.
void CheckAmounts(const vtkRVEGenerator* g) {
  auto* self = const_cast<vtkRVEGenerator*>(g);
  const struct {
    const char* vf_name;
    double vf;
    const char* n_name;
    int n;
    int by_count;
  } fams[3] = {{"SphereVolumeFraction", self->GetSphereVolumeFraction(), "SphereCount",
                self->GetSphereCount(), self->GetSphereAmount()},
               {"FibreVolumeFraction", self->GetFibreVolumeFraction(), "FibreCount",
                self->GetFibreCount(), self->GetFibreAmount()},
               {"EllipsoidVolumeFraction", self->GetEllipsoidVolumeFraction(), "EllipsoidCount",
                self->GetEllipsoidCount(), self->GetEllipsoidAmount()}};
  for (const auto& f : fams) {
    if (f.by_count ? f.n < 0 : !(f.vf >= 0.0)) {
      throw rvegen::InputError(std::string(f.by_count ? f.n_name : f.vf_name) +
                               ": must be >= 0 (0 leaves the family " + "out), got " +
                               (f.by_count ? std::to_string(f.n) : std::to_string(f.vf)));
    }
  }
}

// The choices and limits are checked as the command line checks a scene's: a value out of range
// is named, never clamped or cast. `scene_file`: the packing's settings come from it, and only
// the source's own (Threads, MeshUpTo) are checked here.
void CheckRanges(const vtkRVEGenerator* g, bool scene_file) {
  auto* self = const_cast<vtkRVEGenerator*>(g);
  const struct {
    const char* name;
    double value, lo, hi;
  } ranges[] = {{"Method", double(self->GetMethod()), 0, 1},
                {"SphereAmount", double(self->GetSphereAmount()), 0, 1},
                {"FibreAmount", double(self->GetFibreAmount()), 0, 1},
                {"EllipsoidAmount", double(self->GetEllipsoidAmount()), 0, 1},
                {"FibreLengthLaw", double(self->GetFibreLengthLaw()), 0, 2},
                {"FibreOrientation", double(self->GetFibreOrientation()), 0, 4},
                {"EllipsoidOrientation", double(self->GetEllipsoidOrientation()), 0, 3},
                {"Seed", double(self->GetSeed()), 0, 2147483647.0},
                {"TimeBudget", self->GetTimeBudget(), 1e-3, 1e7},
                {"MeshUpTo", double(self->GetMeshUpTo()), 0, 1e9},
                {"Threads", double(self->GetThreads()), 0, 1024}};
  for (const auto& r : ranges) {
    const std::string name = r.name;
    if (scene_file && name != "MeshUpTo" && name != "Threads") continue;
    if (!(r.value >= r.lo && r.value <= r.hi)) {
      char buf[200];
      std::snprintf(buf, sizeof buf, "%s: must lie in [%g, %g], got %g", r.name, r.lo, r.hi,
                    r.value);
      throw rvegen::InputError(buf);
    }
  }
}

}  // namespace

int vtkRVEGenerator::RequestInformation(vtkInformation*, vtkInformationVector**,
                                        vtkInformationVector* outVec) {
  // The image geometry comes from the properties, or from the scene file when it is readable
  // (errors are reported by RequestData).
  rvegen::Scene scene = SceneFromProperties(this);
  if (this->SceneFile && *this->SceneFile) {
    try {
      scene = rvegen::parse_scene(rvegen::read_file(this->SceneFile, size_t(16) << 20));
    } catch (const std::exception&) {
    }
  }
  vtkInformation* info = outVec->GetInformationObject(1);
  int extent[6] = {0, scene.resolution[0], 0, scene.resolution[1], 0, scene.resolution[2]};
  double spacing[3], origin[3];
  for (int a = 0; a < 3; ++a) {
    spacing[a] = scene.box.size[a] / std::max(1, scene.resolution[a]);
    origin[a] = scene.box.origin[a];
  }
  info->Set(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT(), extent, 6);
  // The image is computed for whatever extent is asked (under MPI each rank its own slab).
  info->Set(vtkAlgorithm::CAN_PRODUCE_SUB_EXTENT(), 1);
  // The polydata ports give each piece its own inclusions (PieceOf).
  for (int port : {0, 2, 3}) {
    outVec->GetInformationObject(port)->Set(vtkAlgorithm::CAN_HANDLE_PIECE_REQUEST(), 1);
  }
  info->Set(vtkDataObject::SPACING(), spacing, 3);
  info->Set(vtkDataObject::ORIGIN(), origin, 3);
  return 1;
}

vtkTypeBool vtkRVEGenerator::ProcessRequest(vtkInformation* request, vtkInformationVector** in,
                                            vtkInformationVector* out) {
  if (request->Has(vtkDemandDrivenPipeline::REQUEST_DATA_NOT_GENERATED())) {
    // Only the port that asked is computed; the others are marked not generated, so their
    // previous data stays and the pipeline executes again (reusing the cached packing) when
    // they are asked for.
    if (request->Has(vtkDemandDrivenPipeline::FROM_OUTPUT_PORT())) {
      const int asked = request->Get(vtkDemandDrivenPipeline::FROM_OUTPUT_PORT());
      for (int port = 0; asked >= 0 && port < this->GetNumberOfOutputPorts(); ++port) {
        if (port != asked) {
          out->GetInformationObject(port)->Set(vtkDemandDrivenPipeline::DATA_NOT_GENERATED(), 1);
        }
      }
    }
    return 1;
  }
  return this->Superclass::ProcessRequest(request, in, out);
}

int vtkRVEGenerator::RequestData(vtkInformation* request, vtkInformationVector**,
                                 vtkInformationVector* outVec) {
  vtkImageData* image = vtkImageData::GetData(outVec, 1);
  rvegen::Scene scene;
  try {
    CheckRanges(this, this->SceneFile && *this->SceneFile);
    if (this->SceneFile && *this->SceneFile) {
      scene = rvegen::parse_scene(rvegen::read_file(this->SceneFile, size_t(16) << 20));
    } else {
      CheckAmounts(this);
      scene = SceneFromProperties(this);
      rvegen::validate_scene(scene);
    }
  } catch (const std::exception& e) {
    this->Status = "invalid";
    vtkErrorMacro(<< "invalid scene: " << e.what());
    return 0;
  }
  // Output settings do not change the packing: the cache is keyed by the packing part alone,
  // and by what moves the packed inclusions (a scene's tetrahedral mesh nudges them off its
  // cell's faces, as the command line does).
  const rvegen::TetMeshSpec& tm = scene.tet_mesh;
  const std::string key = rvegen::packing_to_json(scene) +
                          (scene.outputs.mesh_tet && tm.shift_cell && tm.nudge ? "|nudged" : "");
  // After an abort the flag is cleared, so the next update runs; but the other ports of the
  // update that was aborted (ParaView updates ports 0, 1, 2, 3 in turn) must not start the
  // packing again: a later port asked for the same scene is left empty at once.
  const int port = request->Has(vtkDemandDrivenPipeline::FROM_OUTPUT_PORT())
                       ? request->Get(vtkDemandDrivenPipeline::FROM_OUTPUT_PORT())
                       : 0;
  if (this->AbortedPort >= 0 && port > this->AbortedPort && key == this->AbortedKey) {
    return this->EndAborted(outVec, key, port);
  }
  this->AbortedPort = -1;
  this->AbortPending = false;
  // A new update: an abort asked for after the last execution ended is not carried into it.
  this->SetAbortExecute(0);
  const bool packed = !this->Cached || this->Cached->key != key;
  if (packed) {
    this->Cached.reset();
    std::unique_ptr<Cache> cache(new Cache{key, {}});
    bool aborted = false;
    const std::string error = this->PackShared(scene, cache.get(), &aborted);
    if (aborted) {
      vtkWarningMacro(<< "packing aborted; nothing was kept");
      return this->EndAborted(outVec, key, port);
    }
    if (!error.empty()) {
      this->Status = "error";
      vtkErrorMacro(<< error);
      return 0;
    }
    this->Cached = std::move(cache);
  }
  const rvegen::PackingResult& result = this->Cached->result;
  this->Status = rvegen::status_name(result.status);
  if (result.status != rvegen::PackingStatus::kOk) {
    vtkWarningMacro(<< "target volume fraction not reached (" << rvegen::status_name(result.status)
                    << "); showing the best configuration found");
  }

  // Ports marked not generated (see ProcessRequest) keep their data and are skipped.
  auto wanted = [&](int port) {
    return !outVec->GetInformationObject(port)->Get(vtkDemandDrivenPipeline::DATA_NOT_GENERATED());
  };
  vtkNew<vtkStringArray> status;
  status->SetName("status");
  status->InsertNextValue(rvegen::status_name(result.status));
  // The outputs share what is left of the progress bar after a packing (all of it without).
  const double base = packed ? kPackingShare : 0.0;
  int outputs_left = 0;
  for (int port = 0; port < this->GetNumberOfOutputPorts(); ++port) outputs_left += wanted(port);
  const double share = (1.0 - base) / std::max(1, outputs_left);
  double done = base;
  auto output_done = [&] {
    done += share;
    this->UpdateProgress(std::min(1.0, done));
  };
  // An abort between or inside outputs leaves the ports not yet computed empty and not
  // generated (the packing stays cached).
  auto abort_rest = [&] {
    vtkWarningMacro(<< "aborted; the outputs not yet computed are empty");
    return this->EndAborted(outVec, key, port);
  };

  if (wanted(0)) {
    this->FillPoints(scene, result.set, outVec, status);
    output_done();
  }
  if (wanted(3)) {
    if (this->GetAbortExecute()) return abort_rest();
    this->FillSurfaces(scene, result.set, outVec, status);
    output_done();
  }
  if (wanted(1)) {
    if (this->GetAbortExecute()) return abort_rest();
    const double start = done;
    if (!this->FillVoxels(scene, result.set, outVec, image,
                          [&](double f) { this->UpdateProgress(start + share * f); })) {
      return abort_rest();
    }
    output_done();
  }
  if (wanted(2)) {
    if (this->GetAbortExecute()) return abort_rest();
    this->FillLevelSets(scene, result.set, outVec);
    output_done();
  }
  return 1;
}

std::string vtkRVEGenerator::PackShared(const rvegen::Scene& scene, Cache* cache, bool* aborted) {
  // generate() audits the packed RVE exactly; an RVE that fails is never shown. Where every
  // rank runs the pipeline in step (pvbatch --symmetric), rank 0 packs and broadcasts the
  // inclusion list. Otherwise (pvbatch driven from rank 0, a ParaView server) a collective
  // here would wait for ranks that are not executing, so each rank packs the same RVE itself
  // (same seed, same result).
  std::string error;
  vtkMultiProcessController* mpc = vtkMultiProcessController::GetGlobalController();
  const bool in_step =
      vtkProcessModule::GetProcessModule() && vtkProcessModule::GetSymmetricMPIMode();
  const int ranks = mpc && in_step ? mpc->GetNumberOfProcesses() : 1;
  const int rank = ranks > 1 ? mpc->GetLocalProcessId() : 0;
  int packed_here = 0;
  if (rank == 0) {
    // Progress: the packing takes the first kPackingShare of the bar, the outputs the rest.
    // An abort (SetAbortExecute, the ParaView progress bar's abort) stops the packing at its
    // next check, within a step.
    rvegen::Monitor monitor;
    monitor.fraction = [this](double f) { this->UpdateProgress(kPackingShare * f); };
    monitor.cancelled = [this] { return this->GetAbortExecute() != 0; };
    try {
      // The packing on this->Threads cores (the same RVE for any number).
      tbb::task_arena packing(this->Threads > 0 ? this->Threads : tbb::task_arena::automatic);
      packing.execute([&] {
        rvegen::Packed packed = rvegen::pack_scene(scene, monitor);
        cache->result = std::move(packed.result);
        cache->nudged = packed.nudged.moved;
      });
      packed_here = 1;
    } catch (const rvegen::Cancelled&) {
      *aborted = true;
      error = kAbortedMessage;
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  if (ranks <= 1) {
    this->PackingRuns += packed_here;
    return error;
  }
  // ok flag and status, then the inclusion list (or the error) as JSON text.
  int head[3] = {error.empty() ? 1 : 0, static_cast<int>(cache->result.status), cache->nudged};
  mpc->Broadcast(head, 3, 0);
  std::string text = rank != 0        ? std::string()
                     : !error.empty() ? error
                                      : rvegen::write_inclusions_json(cache->result.set);
  long long length = static_cast<long long>(text.size());
  mpc->Broadcast(&length, 1, 0);
  text.resize(static_cast<size_t>(length));
  if (length > 0) mpc->Broadcast(&text[0], length, 0);
  if (rank != 0) {
    if (head[0]) {
      cache->result.set = rvegen::read_inclusions_json(text);
      cache->result.status = static_cast<rvegen::PackingStatus>(head[1]);
      cache->nudged = head[2];
    } else {
      error = text;
      *aborted = error == kAbortedMessage;
    }
  }
  int total = 0;
  mpc->AllReduce(&packed_here, &total, 1, vtkCommunicator::SUM_OP);
  this->PackingRuns += total;
  return error;
}

void vtkRVEGenerator::FillPoints(const rvegen::Scene& scene, const rvegen::InclusionSet& set,
                                 vtkInformationVector* outVec, vtkStringArray* status) {
  // One vertex per inclusion (and periodic image) with glyph attributes, for the inclusions
  // of this piece; the whole inclusion list in field data for the RVE filters.
  vtkPolyData* points = vtkPolyData::GetData(outVec, 0);
  RVEPolyDataFromGlyphs(rvegen::glyph_points(PieceOf(set, outVec->GetInformationObject(0))),
                        points);
  points->GetFieldData()->AddArray(status);
  vtkNew<vtkStringArray> inclusions;
  inclusions->SetName("rvegen_inclusions");
  inclusions->InsertNextValue(rvegen::write_inclusions_json(set));
  points->GetFieldData()->AddArray(inclusions);
  // The scene's least gap, which the RVE Tetrahedral Mesh keeps when it nudges inclusions.
  vtkNew<vtkDoubleArray> min_gap;
  min_gap->SetName("rvegen_min_gap");
  min_gap->InsertNextValue(scene.min_gap);
  points->GetFieldData()->AddArray(min_gap);
  // The inclusions the scene's own mesh_tet nudged off its cell's faces (as the command line
  // does before any output): the RVE Tetrahedral Mesh counts them with its own.
  vtkNew<vtkIntArray> nudged;
  nudged->SetName("nudged_inclusions");
  nudged->InsertNextValue(this->Cached ? this->Cached->nudged : 0);
  points->GetFieldData()->AddArray(nudged);
  ++this->PortExecutions[0];
}

void vtkRVEGenerator::FillSurfaces(const rvegen::Scene& scene, const rvegen::InclusionSet& set,
                                   vtkInformationVector* outVec, vtkStringArray* status) {
  // The tessellated surfaces of this piece's inclusions: of every inclusion with Mesh or
  // when the RVE holds at most MeshUpTo inclusions, otherwise of the modified ones.
  const rvegen::MeshOptions mopt = rvegen::mesh_options(scene, scene.box);
  vtkPolyData* surfaces = vtkPolyData::GetData(outVec, 3);
  const rvegen::InclusionSet piece = PieceOf(set, outVec->GetInformationObject(3));
  const bool every =
      scene.outputs.mesh || set.inclusions.size() <= static_cast<size_t>(this->MeshUpTo);
  RVEPolyDataFromMesh(rvegen::tessellate(rvegen::meshed_inclusions(piece, every), mopt), surfaces);
  surfaces->GetFieldData()->AddArray(status);
  ++this->PortExecutions[3];
}

bool vtkRVEGenerator::FillVoxels(const rvegen::Scene& scene, const rvegen::InclusionSet& set,
                                 vtkInformationVector* outVec, vtkImageData* image,
                                 const std::function<void(double)>& progress) {
  rvegen::VoxelOptions vopt;
  vopt.partial_volume = scene.partial_volume;
  vopt.subsamples = scene.subsamples;
  // The update extent (point extent: cells lo..hi-1); the whole image when none is set.
  vtkInformation* imageInfo = outVec->GetInformationObject(1);
  int ext[6] = {0, scene.resolution[0], 0, scene.resolution[1], 0, scene.resolution[2]};
  if (imageInfo->Has(vtkStreamingDemandDrivenPipeline::UPDATE_EXTENT())) {
    imageInfo->Get(vtkStreamingDemandDrivenPipeline::UPDATE_EXTENT(), ext);
  }
  vopt.extent = {ext[0], ext[1], ext[2], ext[3], ext[4], ext[5]};
  tbb::task_arena arena(this->Threads > 0 ? this->Threads : tbb::task_arena::automatic);
  const long long conflicts = RVEVoxelizeInto(
      set, rvegen::voxel_layout(set, scene.resolution, vopt), vopt, image, arena, [&](double f) {
        progress(f);
        return !this->GetAbortExecute();
      });
  if (conflicts < 0) return false;
  ++this->PortExecutions[1];
  return true;
}

void vtkRVEGenerator::FillLevelSets(const rvegen::Scene& scene, const rvegen::InclusionSet& set,
                                    vtkInformationVector* outVec) {
  // Zero iso-surfaces of the level sets (wavy, deformed, coated inclusions); empty otherwise.
  rvegen::LevelSetOptions lopt;
  lopt.voxel_size = scene.levelset_voxel_size;
  lopt.half_width = scene.levelset_half_width;
  // Straight coated shells are exact: grids only where a scene file names "levelsets" in
  // its outputs (the Surfaces port meshes them; a level set of a thin box's many fibres
  // needs gigabytes).
  lopt.exact_shapes = scene.outputs.levelsets_asked;
  // Shells of neighbours may merge, so the level sets are not split by inclusion: piece 0
  // computes them all, the other pieces are empty.
  if (RequestedPiece(outVec->GetInformationObject(2)).first == 0) {
    const rvegen::LevelSets ls = rvegen::build_level_sets(set, lopt);
    RVEPolyDataFromMesh(rvegen::level_set_surfaces(ls), vtkPolyData::GetData(outVec, 2));
  }
  ++this->PortExecutions[2];
}

int vtkRVEGenerator::EndAborted(vtkInformationVector* outVec, const std::string& key, int port) {
  // The later ports of this update, asked for the same scene, end here at once.
  this->AbortedKey = key;
  this->AbortedPort = port;
  // Nothing of this execution is kept: its outputs (those not marked not generated by
  // ProcessRequest) are emptied; the abort flag is cleared, and until the next execution that
  // is not part of the aborted update, GetMTime() is always newer than any output, so the next
  // update computes everything again (the same properties give the same RVE).
  this->Status = "aborted";
  for (int p = 0; p < this->GetNumberOfOutputPorts(); ++p) {
    vtkInformation* info = outVec->GetInformationObject(p);
    if (!info->Get(vtkDemandDrivenPipeline::DATA_NOT_GENERATED())) {
      vtkDataObject::GetData(info)->Initialize();
    }
  }
  this->AbortPending = true;
  this->SetAbortExecute(0);
  return 1;
}

vtkMTimeType vtkRVEGenerator::GetMTime() {
  if (this->AbortPending) this->AbortTime.Modified();
  const vtkMTimeType t = this->Superclass::GetMTime();
  return this->AbortPending ? std::max(t, this->AbortTime.GetMTime()) : t;
}

void vtkRVEGenerator::PrintSelf(ostream& os, vtkIndent indent) {
  this->Superclass::PrintSelf(os, indent);
  auto v3 = [&](const char* name, const auto* v) {
    os << indent << name << ": " << v[0] << " " << v[1] << " " << v[2] << "\n";
  };
  os << indent << "SceneFile: " << (this->SceneFile ? this->SceneFile : "(none)") << "\n";
  os << indent << "Seed: " << this->Seed << "\n";
  os << indent << "Method: " << this->Method << " ("
     << (this->Method == 0 || this->Method == 1
             ? rvegen::method_name(static_cast<rvegen::Method>(this->Method))
             : "not a method")
     << ")\n";
  v3("BoxSize", this->BoxSize);
  os << indent << "Periodic: " << this->Periodic << "\n";
  os << indent << "MinGap: " << this->MinGap << "\n";
  os << indent << "SphereRadius: " << this->SphereRadius << "\n";
  os << indent << "SphereRadiusStd: " << this->SphereRadiusStd << "\n";
  os << indent << "SphereVolumeFraction: " << this->SphereVolumeFraction << "\n";
  os << indent << "SphereAmount: " << this->SphereAmount << "\n";
  os << indent << "SphereCount: " << this->SphereCount << "\n";
  os << indent << "SphereCoating: " << this->SphereCoating << "\n";
  os << indent << "SphereDeformation: " << this->SphereDeformation << "\n";
  os << indent << "SphereDebondFraction: " << this->SphereDebondFraction << "\n";
  os << indent << "SphereDebondGap: " << this->SphereDebondGap << "\n";
  os << indent << "FibreRadius: " << this->FibreRadius << "\n";
  os << indent << "FibreRadiusStd: " << this->FibreRadiusStd << "\n";
  os << indent << "FibreAspectRatio: " << this->FibreAspectRatio << "\n";
  os << indent << "FibreLengthLaw: " << this->FibreLengthLaw << "\n";
  os << indent << "FibreAspectRatioStd: " << this->FibreAspectRatioStd << "\n";
  os << indent << "FibreWeibullShape: " << this->FibreWeibullShape << "\n";
  os << indent << "FibreWeibullScale: " << this->FibreWeibullScale << "\n";
  os << indent << "FibreVolumeFraction: " << this->FibreVolumeFraction << "\n";
  os << indent << "FibreAmount: " << this->FibreAmount << "\n";
  os << indent << "FibreCount: " << this->FibreCount << "\n";
  os << indent << "FibreOrientation: " << this->FibreOrientation << "\n";
  v3("FibreAxis", this->FibreAxis);
  os << indent << "FibreOrientationTensor:";
  for (double v : this->FibreOrientationTensor) os << " " << v;
  os << "\n";
  os << indent << "FibreKappa: " << this->FibreKappa << "\n";
  os << indent << "FibreCoating: " << this->FibreCoating << "\n";
  os << indent << "FibreWaveAmplitude: " << this->FibreWaveAmplitude << "\n";
  os << indent << "FibreWavelength: " << this->FibreWavelength << "\n";
  os << indent << "FibreCurvatureRadius: " << this->FibreCurvatureRadius << "\n";
  v3("EllipsoidSemiAxes", this->EllipsoidSemiAxes);
  os << indent << "EllipsoidVolumeFraction: " << this->EllipsoidVolumeFraction << "\n";
  os << indent << "EllipsoidAmount: " << this->EllipsoidAmount << "\n";
  os << indent << "EllipsoidCount: " << this->EllipsoidCount << "\n";
  os << indent << "EllipsoidOrientation: " << this->EllipsoidOrientation << "\n";
  v3("EllipsoidAxis", this->EllipsoidAxis);
  os << indent << "EllipsoidKappa: " << this->EllipsoidKappa << "\n";
  os << indent << "EllipsoidCoating: " << this->EllipsoidCoating << "\n";
  os << indent << "EllipsoidDeformation: " << this->EllipsoidDeformation << "\n";
  os << indent << "ShellsMayTouch: " << this->ShellsMayTouch << "\n";
  os << indent << "DeformationSmoothness: " << this->DeformationSmoothness << "\n";
  v3("Resolution", this->Resolution);
  os << indent << "PartialVolume: " << this->PartialVolume << "\n";
  os << indent << "ClipSurfaces: " << this->ClipSurfaces << "\n";
  os << indent << "Mesh: " << this->Mesh << "\n";
  os << indent << "LevelSetVoxelSize: " << this->LevelSetVoxelSize << "\n";
  os << indent << "Threads: " << this->Threads << "\n";
  os << indent << "TimeBudget: " << this->TimeBudget << "\n";
  os << indent << "MeshUpTo: " << this->MeshUpTo << "\n";
  os << indent << "PackingRuns: " << this->PackingRuns << "\n";
  os << indent << "PortExecutions:";
  for (int e : this->PortExecutions) os << " " << e;
  os << "\n";
  os << indent << "Status: " << this->Status << "\n";
}
