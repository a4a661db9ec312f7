// File writers for the command line: VTK XML (.vti image, .vtp surfaces) written directly,
// so the command-line tool needs no VTK. Files are written to a temporary name and renamed
// into place only when complete (see OutputTransaction).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "rvegen/mesh.hpp"
#include "rvegen/voxelize.hpp"

namespace rvegen {

/// VTK XML ImageData, one cell per voxel, cell arrays "phase" (UInt8), "inclusion_id" (Int32)
/// and, when computed, "fraction" (Float32).
std::string vti_bytes(const VoxelImage& image);
/// Legacy VTK STRUCTURED_POINTS material map as AMITEX_FFTP reads it (materialID.vtk): binary
/// big-endian unsigned short "MaterialId" per cell, numbered 1..N in phase-label order over the
/// labels present in the image.
std::string material_vtk_bytes(const VoxelImage& image);
/// VTK XML PolyData with cell arrays "inclusion_id", "family", "shape", "phase" (Int32) and
/// "axis" (Float32 x 3).
/// With `inclusions_json` (write_inclusions_json), field data "rvegen_inclusions" holds it.
std::string vtp_bytes(const SurfaceMesh& mesh, const std::string& inclusions_json = "");

/// Collects output files and writes them all or none: each goes to a hidden temporary file in
/// the target directory; commit() renames them into place once every write has succeeded.
class OutputTransaction {
 public:
  explicit OutputTransaction(std::string dir) : dir_(std::move(dir)) {}
  ~OutputTransaction();
  void add(const std::string& name, std::string bytes) {
    files_.emplace_back(name, std::move(bytes));
  }
  /// Creates the directory if needed, writes and renames. Throws std::runtime_error on failure
  /// (and removes what it wrote).
  void commit();

 private:
  std::string dir_;
  std::vector<std::pair<std::string, std::string>> files_;
  std::vector<std::string> temps_;
};

std::string read_file(const std::string& path);

}  // namespace rvegen
