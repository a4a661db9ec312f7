// File writers for the command line: VTK XML (.vti image, .vtp surfaces) written directly,
// so the command-line tool needs no VTK; and the output set, which puts a run's files in place
// as one whole.
#pragma once

#include <cstdio>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "rvegen/femesh/tet_mesh.hpp"
#include "rvegen/io/inclusions_json.hpp"
#include "rvegen/model/inclusion_set.hpp"
#include "rvegen/raster/glyphs.hpp"
#include "rvegen/raster/mesh.hpp"
#include "rvegen/raster/voxelize.hpp"

namespace rvegen {

/// VTK XML ImageData, one cell per voxel, cell arrays "phase" (UInt8), "inclusion_id" (Int32)
/// and, when computed, "fraction" (Float32). `compressed`: zlib blocks as VTK writes them
/// (compressor="vtkZLibDataCompressor", level 1, blocks deflated in parallel); otherwise raw
/// arrays streamed to `out` without a copy.
void write_vti(const VoxelImage& image, std::FILE* out, bool compressed = true);
std::string vti_bytes(const VoxelImage& image, bool compressed = true);
/// Legacy VTK STRUCTURED_POINTS material map as AMITEX_FFTP reads it (materialID.vtk): binary
/// big-endian unsigned short "MaterialId" per cell, numbered 1..N in phase-label order over the
/// labels present in the image. Streamed in blocks.
void write_material_vtk(const VoxelImage& image, std::FILE* out);
std::string material_vtk_bytes(const VoxelImage& image);
/// VTK XML UnstructuredGrid of the voxel mesh (the nodes and hexahedra of mesh_voxel.inp, same
/// numbering less one): Float64 points, VTK_HEXAHEDRON cells, cell data phase (UInt8) and
/// inclusion_id (Int32); zlib-compressed.
void write_voxel_mesh_vtu(const VoxelImage& image, std::FILE* out);
/// mesh_tet.vtu: the tetrahedral mesh as an unstructured grid, cell data `phase` and
/// `inclusion_id` (-1 in the matrix).
void write_tet_mesh_vtu(const TetMesh& mesh, std::FILE* out);
/// Legacy VTK STRUCTURED_POINTS with one binary big-endian cell scalar `name` over the image,
/// as AMITEX_FFTP reads it (a 10-line header): unsigned short values, or int when `wide`;
/// value(v) for voxel v (x fastest). Streamed in blocks.
void write_legacy_cells(const VoxelImage& image, const char* title, const char* name, bool wide,
                        const std::function<uint32_t(size_t)>& value, std::FILE* out);
/// The AMITEX material number of each phase label (1..N over the labels present, in label
/// order; 0 for a label absent from the image): what write_material_vtk writes.
std::vector<uint16_t> amitex_material_ids(const VoxelImage& image);
/// VTK XML PolyData of a mesh, streamed to `out`: Float32 points (shared within each inclusion's
/// surface), triangles, cell arrays "inclusion_id", "family", "shape", "phase" (Int32) and "axis"
/// (Float32 x 3). With `inclusions_json` (write_inclusions_json), field data "rvegen_inclusions"
/// holds it (a String array, raw bytes in the appended data).
void write_surfaces_vtp(const SurfaceMesh& mesh, const std::string& inclusions_json,
                        std::FILE* out);
/// VTK XML PolyData of the inclusions as points (rvegen::glyph_points: one vertex per inclusion
/// and per periodic image whose bounding box reaches into the box), streamed to `out`: point data
/// "inclusion_id", "family", "shape" (0 sphere, 1 cylinder, 2 ellipsoid), "phase", "image" (1 for
/// a periodic image), "modified" (1 for wavy, bent, deformed or debonded: drawn from
/// surfaces.vtp; a straight coated inclusion's glyph is its core, its shell the "coating"),
/// "radius", "half_axis", "semi_axes", "direction" (axis), "orientation" (unit quaternion w, x, y,
/// z) and "scale": a unit sphere glyph (radius 0.5) or a cylinder glyph along y (height 1, radius
/// 0.5), scaled by "scale" then turned by "orientation", is the inclusion exactly. Field data as
/// write_surfaces_vtp.
void write_points_vtp(const InclusionSet& set, const std::string& inclusions_json, std::FILE* out);

/// The files one run writes into its output directory, and nothing else. An output directory
/// holds one complete set or the previous one, never a mix:
///  - the constructor checks, before any work, that `dir` is absent, empty or holds only an
///    earlier set (names in file_names(); anything else is refused, since the whole directory is
///    replaced), and creates a private staging directory (mode 0700, unpredictable name) next to
///    it, which also proves the place writable; it removes staging directories that killed runs
///    left behind;
///  - files are created in the staging directory exclusively (O_EXCL, O_NOFOLLOW);
///  - commit() swaps the staging directory in for `dir` in one rename (renameat2
///    RENAME_EXCHANGE; on file systems without it, two renames with the old set put back on
///    failure) and removes the previous set, stale files included.
/// Without commit() (an error, an exception) the staging directory is removed and `dir` is
/// untouched. Throws OutputError naming the path on any failure.
class OutputSet {
 public:
  explicit OutputSet(const std::string& dir);
  ~OutputSet();
  OutputSet(const OutputSet&) = delete;
  OutputSet& operator=(const OutputSet&) = delete;

  /// Names an output set may hold.
  static const std::vector<std::string>& file_names();
  /// Writes file `name` (one of file_names()) into the staging directory.
  void write(const std::string& name, const std::string& bytes);
  /// Writes file `name` through `fill`, which streams into the open file.
  void write_with(const std::string& name, const std::function<void(std::FILE*)>& fill);
  /// Path of `name` in the staging directory, for writers that open files themselves (HDF5);
  /// the file must not exist yet.
  std::string staged_path(const std::string& name) const;
  /// The files staged so far with their sizes in bytes, as a JSON object (report.json's
  /// "files": a later run takes a directory whose files it lists for one it may replace).
  std::string files_json() const;
  /// Puts the staged set in place of the directory (see above).
  void commit();
  /// The output directory as given, and the staging directory.
  const std::string& dir() const { return dir_; }
  const std::string& staging_dir() const { return stage_; }
  /// After commit(): where the previous set stays when it could not be removed (a DIR of
  /// another user, in a parent both may write: its files are not ours to delete); else empty.
  const std::string& leftover() const { return leftover_; }

 private:
  std::string dir_, target_, stage_, leftover_;
  bool committed_ = false;
};

/// A failure to write outputs (exit 1 of `rvegen generate`).
class OutputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// What a directory holds, as a run's last line gives it: "1.1 MB in 4 files" (its regular
/// files; decimal units).
std::string describe_directory(const std::string& dir);

/// Reads a whole file; refuses one that is not a regular file or is larger than `max_bytes`
/// (without reading it all). Throws InputError naming the path.
std::string read_file(const std::string& path, size_t max_bytes = size_t(1) << 30);

}  // namespace rvegen
