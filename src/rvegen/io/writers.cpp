#include "rvegen/io/writers.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <tbb/parallel_for.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <list>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

namespace rvegen {
namespace {

std::string header(const char* type, bool compressed = false) {
  return std::string("<?xml version=\"1.0\"?>\n<VTKFile type=\"") + type +
         "\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\"" +
         (compressed ? " compressor=\"vtkZLibDataCompressor\"" : "") + ">\n";
}

std::string array_tag(const char* vtk_type, const char* name, int components, size_t offset) {
  std::ostringstream s;
  s << "      <DataArray type=\"" << vtk_type << "\" Name=\"" << name << "\"";
  if (components > 1) s << " NumberOfComponents=\"" << components << "\"";
  s << " format=\"appended\" offset=\"" << offset << "\"/>\n";
  return s.str();
}

}  // namespace

namespace {

// Appended raw arrays streamed from their vectors: the offsets are known from the sizes alone.
struct RawArray {
  const char* data;
  uint64_t bytes;
  bool prefixed = true;  // false: `data` carries its own header (compressed arrays)
};

void put(std::FILE* out, const void* data, size_t bytes) {
  if (bytes > 0 && std::fwrite(data, 1, bytes, out) != bytes) {
    throw OutputError(std::string("write failed: ") + std::strerror(errno));
  }
}

void put(std::FILE* out, const std::string& s) {
  put(out, s.data(), s.size());
}

void put_appended(std::FILE* out, const std::vector<RawArray>& arrays) {
  put(out, std::string("  <AppendedData encoding=\"raw\">\n   _"));
  for (const RawArray& a : arrays) {
    if (a.prefixed) put(out, &a.bytes, sizeof a.bytes);
    put(out, a.data, a.bytes);
  }
  put(out, std::string("\n  </AppendedData>\n</VTKFile>\n"));
}

// The arrays of one file, in order: the offset of each is known when it is added, the bytes are
// written by put_appended (the data must live until then). Compressed lists (the file says
// compressor="vtkZLibDataCompressor") deflate each array at once in blocks of kBlock bytes, as
// VTK's XML readers expect: a UInt64 header (blocks, block size, size of the last partial block
// or 0, compressed size of each block) followed by the compressed blocks.
class AppendedList {
 public:
  explicit AppendedList(bool compressed = false) : compressed_(compressed) {}
  template <class T>
  uint64_t add(const T* data, size_t n) {
    const uint64_t offset = at_;
    const char* bytes = reinterpret_cast<const char*>(data);
    const uint64_t size = n * sizeof(T);
    if (!compressed_) {
      arrays_.push_back({bytes, size});
      at_ += sizeof(uint64_t) + size;
      return offset;
    }
    blobs_.push_back(deflate_blocks(bytes, size));
    arrays_.push_back({blobs_.back().data(), blobs_.back().size(), false});
    at_ += blobs_.back().size();
    return offset;
  }
  const std::vector<RawArray>& arrays() const { return arrays_; }
  bool compressed() const { return compressed_; }

 private:
  static constexpr uint64_t kBlock = 1 << 16;
  // Blocks are deflated in parallel (each on its own), then joined in order: the bytes do not
  // depend on the number of threads.
  static std::string deflate_blocks(const char* data, uint64_t size) {
    const uint64_t blocks = (size + kBlock - 1) / kBlock;
    std::vector<uint64_t> head = {blocks, kBlock, size % kBlock};
    std::vector<std::vector<Bytef>> packed(blocks);
    std::atomic<bool> failed{false};
    tbb::parallel_for(uint64_t{0}, blocks, [&](uint64_t b) {
      const uint64_t len = std::min(kBlock, size - b * kBlock);
      // A scratch buffer of the worst-case size, then only the deflated bytes are kept (the
      // worst case of every block at once would be the whole image again).
      std::vector<Bytef> buf(compressBound(static_cast<uLong>(len)));
      uLongf out = static_cast<uLongf>(buf.size());
      if (compress2(buf.data(), &out, reinterpret_cast<const Bytef*>(data + b * kBlock),
                    static_cast<uLong>(len), 1) != Z_OK) {
        failed = true;
      }
      packed[b].assign(buf.data(), buf.data() + out);
    });
    if (failed) throw OutputError("zlib: compression failed");
    std::string joined(reinterpret_cast<const char*>(head.data()), 0);
    size_t total = 0;
    for (const auto& buf : packed) {
      head.push_back(buf.size());
      total += buf.size();
    }
    joined.reserve(head.size() * sizeof(uint64_t) + total);
    joined.append(reinterpret_cast<const char*>(head.data()), head.size() * sizeof(uint64_t));
    for (auto& buf : packed) {
      joined.append(reinterpret_cast<const char*>(buf.data()), buf.size());
      std::vector<Bytef>().swap(buf);
    }
    return joined;
  }
  bool compressed_;
  std::list<std::string> blobs_;  // stable addresses
  std::vector<RawArray> arrays_;
  uint64_t at_ = 0;
};

std::string with_file(const std::function<void(std::FILE*)>& fill) {
  char* buf = nullptr;
  size_t size = 0;
  std::FILE* f = open_memstream(&buf, &size);
  if (!f) throw std::bad_alloc();
  try {
    fill(f);
  } catch (...) {
    std::fclose(f);
    std::free(buf);
    throw;
  }
  std::fclose(f);
  std::string out(buf, size);
  std::free(buf);
  return out;
}

}  // namespace

void write_vti(const VoxelImage& im, std::FILE* out, bool compressed) {
  AppendedList app(compressed);
  const uint64_t offset[3] = {app.add(im.phase.data(), im.phase.size()),
                              app.add(im.inclusion_id.data(), im.inclusion_id.size()),
                              app.add(im.fraction.data(), im.fraction.size())};
  std::ostringstream s;
  s.precision(17);
  s << header("ImageData", app.compressed());
  s << "  <ImageData WholeExtent=\"0 " << im.dims[0] << " 0 " << im.dims[1] << " 0 " << im.dims[2]
    << "\" Origin=\"" << im.origin[0] << " " << im.origin[1] << " " << im.origin[2]
    << "\" Spacing=\"" << im.spacing[0] << " " << im.spacing[1] << " " << im.spacing[2] << "\">\n";
  // Cell extents [lo, hi) are point extents lo..hi.
  s << "    <Piece Extent=\"" << im.extent[0] << " " << im.extent[1] << " " << im.extent[2] << " "
    << im.extent[3] << " " << im.extent[4] << " " << im.extent[5] << "\">\n";
  s << "    <CellData Scalars=\"phase\">\n";
  s << array_tag("UInt8", "phase", 1, offset[0]);
  s << array_tag("Int32", "inclusion_id", 1, offset[1]);
  if (!im.fraction.empty()) s << array_tag("Float32", "fraction", 1, offset[2]);
  s << "    </CellData>\n    </Piece>\n  </ImageData>\n";
  put(out, s.str());
  put_appended(out, app.arrays());
}

std::string vti_bytes(const VoxelImage& im, bool compressed) {
  return with_file([&](std::FILE* f) { write_vti(im, f, compressed); });
}

namespace {

// An unstructured grid of one cell type with the cell data `phase` and `inclusion_id`.
void write_unstructured(std::FILE* out, const std::vector<double>& xyz,
                        const std::vector<int64_t>& conn, const std::vector<int64_t>& offsets,
                        const std::vector<uint8_t>& types, const std::vector<uint8_t>& phase,
                        const std::vector<int32_t>& inclusion_id,
                        const std::string& field_data = "") {
  AppendedList app(true);
  const uint64_t at[6] = {
      app.add(xyz.data(), xyz.size()),         app.add(conn.data(), conn.size()),
      app.add(offsets.data(), offsets.size()), app.add(types.data(), types.size()),
      app.add(phase.data(), phase.size()),     app.add(inclusion_id.data(), inclusion_id.size())};
  std::ostringstream s;
  s << header("UnstructuredGrid", true);
  s << "  <UnstructuredGrid>\n"
    << field_data << "    <Piece NumberOfPoints=\"" << xyz.size() / 3 << "\" NumberOfCells=\""
    << types.size() << "\">\n";
  s << "    <Points>\n" << array_tag("Float64", "Points", 3, at[0]) << "    </Points>\n";
  s << "    <Cells>\n"
    << array_tag("Int64", "connectivity", 1, at[1]) << array_tag("Int64", "offsets", 1, at[2])
    << array_tag("UInt8", "types", 1, at[3]) << "    </Cells>\n";
  s << "    <CellData Scalars=\"phase\">\n"
    << array_tag("UInt8", "phase", 1, at[4]) << array_tag("Int32", "inclusion_id", 1, at[5])
    << "    </CellData>\n    </Piece>\n  </UnstructuredGrid>\n";
  put(out, s.str());
  put_appended(out, app.arrays());
}

}  // namespace

void write_voxel_mesh_vtu(const VoxelImage& im, std::FILE* out) {
  const int nx = im.size(0), ny = im.size(1), nz = im.size(2);
  const size_t cells = im.count();
  const size_t points = static_cast<size_t>(nx + 1) * (ny + 1) * (nz + 1);
  auto node = [&](int i, int j, int k) {
    return static_cast<int64_t>(i) +
           static_cast<int64_t>(nx + 1) * (j + static_cast<int64_t>(ny + 1) * k);
  };
  const Vec3 o =
      im.origin + Vec3(im.extent[0], im.extent[2], im.extent[4]).cwiseProduct(im.spacing);
  std::vector<double> xyz(3 * points);
  for (int k = 0, p = 0; k <= nz; ++k) {
    for (int j = 0; j <= ny; ++j) {
      for (int i = 0; i <= nx; ++i, ++p) {
        xyz[3 * p] = o[0] + i * im.spacing[0];
        xyz[3 * p + 1] = o[1] + j * im.spacing[1];
        xyz[3 * p + 2] = o[2] + k * im.spacing[2];
      }
    }
  }
  std::vector<int64_t> conn(8 * cells), offsets(cells);
  std::vector<uint8_t> types(cells, 12);  // VTK_HEXAHEDRON
  for (int k = 0, v = 0; k < nz; ++k) {
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i, ++v) {
        const int64_t c[8] = {node(i, j, k),
                              node(i + 1, j, k),
                              node(i + 1, j + 1, k),
                              node(i, j + 1, k),
                              node(i, j, k + 1),
                              node(i + 1, j, k + 1),
                              node(i + 1, j + 1, k + 1),
                              node(i, j + 1, k + 1)};
        std::copy(c, c + 8, conn.begin() + 8 * static_cast<size_t>(v));
        offsets[v] = 8 * (static_cast<int64_t>(v) + 1);
      }
    }
  }
  write_unstructured(out, xyz, conn, offsets, types, im.phase, im.inclusion_id);
}

void write_tet_mesh_vtu(const TetMesh& mesh, std::FILE* out) {
  const size_t cells = mesh.tets.size(), points = mesh.nodes.size();
  std::vector<double> xyz(3 * points);
  for (size_t i = 0; i < points; ++i) {
    for (int a = 0; a < 3; ++a) xyz[3 * i + a] = mesh.nodes[i][a];
  }
  // VTK_TETRA, or VTK_QUADRATIC_TETRA (its midside nodes in the order of TetMesh::mid).
  const size_t n = mesh.mid.empty() ? 4 : 10;
  std::vector<int64_t> conn(n * cells), offsets(cells);
  for (size_t e = 0; e < cells; ++e) {
    for (int c = 0; c < 4; ++c) conn[n * e + c] = mesh.tets[e][c];
    for (size_t c = 4; c < n; ++c) conn[n * e + c] = mesh.mid[e][c - 4];
    offsets[e] = static_cast<int64_t>(n * (e + 1));
  }
  std::vector<uint8_t> types(cells, n == 4 ? 10 : 24);
  const std::vector<uint8_t> phase(mesh.phase.begin(), mesh.phase.end());
  // The cell the mesh fills (the box moved along its axes: field data cell_origin, as the
  // ParaView filter's output has it).
  char origin[160];
  std::snprintf(origin, sizeof origin, "%.17g %.17g %.17g", mesh.box.origin[0], mesh.box.origin[1],
                mesh.box.origin[2]);
  const std::string field_data =
      std::string(
          "    <FieldData>\n      <DataArray type=\"Float64\" Name=\"cell_origin\" "
          "NumberOfComponents=\"3\" NumberOfTuples=\"1\" format=\"ascii\">") +
      origin + "</DataArray>\n    </FieldData>\n";
  write_unstructured(out, xyz, conn, offsets, types, phase, mesh.inclusion_id, field_data);
}

std::vector<uint16_t> amitex_material_ids(const VoxelImage& im) {
  // Phases absent from the image would leave holes in 1..N, which AMITEX rejects: labels are
  // renumbered densely in label order.
  std::vector<int> present(256, 0);
  for (uint8_t p : im.phase) present[p] = 1;
  std::vector<uint16_t> id(256, 0);
  uint16_t next = 1;
  for (int l = 0; l < 256; ++l) {
    if (present[l]) id[l] = next++;
  }
  return id;
}

void write_legacy_cells(const VoxelImage& im, const char* title, const char* name, bool wide,
                        const std::function<uint32_t(size_t)>& value, std::FILE* out) {
  std::ostringstream s;
  s.precision(17);
  s << "# vtk DataFile Version 4.5\n" << title << "\nBINARY\nDATASET STRUCTURED_POINTS\n";
  s << "DIMENSIONS " << im.size(0) + 1 << " " << im.size(1) + 1 << " " << im.size(2) + 1 << "\n";
  s << "ORIGIN " << im.origin[0] + im.extent[0] * im.spacing[0] << " "
    << im.origin[1] + im.extent[2] * im.spacing[1] << " "
    << im.origin[2] + im.extent[4] * im.spacing[2] << "\n";
  s << "SPACING " << im.spacing[0] << " " << im.spacing[1] << " " << im.spacing[2] << "\n";
  s << "CELL_DATA " << im.count() << "\n";
  s << "SCALARS " << name << " " << (wide ? "int" : "unsigned_short") << "\nLOOKUP_TABLE default\n";
  put(out, s.str());
  const int width = wide ? 4 : 2;
  std::vector<unsigned char> block;
  constexpr size_t kBlock = size_t(1) << 20;
  const size_t count = im.count();
  for (size_t at = 0; at < count; at += kBlock) {
    const size_t n = std::min(kBlock, count - at);
    block.resize(width * n);
    for (size_t i = 0; i < n; ++i) {
      const uint32_t v = value(at + i);
      for (int b = 0; b < width; ++b) {
        block[width * i + b] = static_cast<unsigned char>(v >> (8 * (width - 1 - b)));
      }
    }
    put(out, block.data(), block.size());
  }
}

void write_material_vtk(const VoxelImage& im, std::FILE* out) {
  // Materials numbered 1..N as big-endian unsigned shorts.
  const std::vector<uint16_t> id = amitex_material_ids(im);
  write_legacy_cells(
      im, "Materiau", "MaterialId", false,
      [&](size_t v) { return static_cast<uint32_t>(id[im.phase[v]]); }, out);
}

std::string material_vtk_bytes(const VoxelImage& im) {
  return with_file([&](std::FILE* f) { write_material_vtk(im, f); });
}

namespace {
// The inclusion list as a string in field data (VTK's ascii form: byte values, then 0), so the
// RVE filters work on inclusions read back from the file.
// The inclusion list as field data "rvegen_inclusions" (a String array of one value, stored as
// its bytes and a terminating NUL in the appended data), so that the RVE filters work on
// inclusions read back from the file.
void field_data_inclusions(std::ostringstream& s, AppendedList* app,
                           const std::string& inclusions_json) {
  if (inclusions_json.empty()) return;
  // c_str() is NUL-terminated: the NUL is the string's terminator in the file.
  const uint64_t at = app->add(inclusions_json.c_str(), inclusions_json.size() + 1);
  s << "    <FieldData>\n      <Array type=\"String\" Name=\"rvegen_inclusions\" "
       "NumberOfTuples=\"1\" format=\"appended\" offset=\""
    << at << "\"/>\n    </FieldData>\n";
}
}  // namespace

void write_surfaces_vtp(const SurfaceMesh& m, const std::string& inclusions_json, std::FILE* out) {
  // Points as Float32 (the tessellation error is far above float precision).
  std::vector<float> pts(3 * m.points.size());
  for (size_t i = 0; i < m.points.size(); ++i) {
    for (int a = 0; a < 3; ++a) pts[3 * i + a] = static_cast<float>(m.points[i][a]);
  }
  std::vector<int64_t> conn(3 * m.triangles.size()), offs(m.triangles.size());
  for (size_t i = 0; i < m.triangles.size(); ++i) {
    for (int a = 0; a < 3; ++a) conn[3 * i + a] = m.triangles[i][a];
    offs[i] = static_cast<int64_t>(3 * (i + 1));
  }
  AppendedList app(true);
  std::ostringstream s;
  s << header("PolyData", app.compressed()) << "  <PolyData>\n";
  field_data_inclusions(s, &app, inclusions_json);
  const uint64_t o_pts = app.add(pts.data(), pts.size());
  const uint64_t o_conn = app.add(conn.data(), conn.size());
  const uint64_t o_offs = app.add(offs.data(), offs.size());
  const uint64_t o_id = app.add(m.inclusion_id.data(), m.inclusion_id.size());
  const uint64_t o_fam = app.add(m.family.data(), m.family.size());
  const uint64_t o_shape = app.add(m.shape.data(), m.shape.size());
  const uint64_t o_phase = app.add(m.phase.data(), m.phase.size());
  const uint64_t o_axis = app.add(reinterpret_cast<const float*>(m.axis.data()), 3 * m.axis.size());
  s << "    <Piece NumberOfPoints=\"" << m.points.size()
    << "\" NumberOfVerts=\"0\" NumberOfLines=\"0\""
    << " NumberOfStrips=\"0\" NumberOfPolys=\"" << m.triangles.size() << "\">\n";
  s << "    <Points>\n" << array_tag("Float32", "Points", 3, o_pts) << "    </Points>\n";
  s << "    <Polys>\n"
    << array_tag("Int64", "connectivity", 1, o_conn) << array_tag("Int64", "offsets", 1, o_offs)
    << "    </Polys>\n";
  s << "    <CellData Scalars=\"family\">\n"
    << array_tag("Int32", "inclusion_id", 1, o_id) << array_tag("Int32", "family", 1, o_fam)
    << array_tag("Int32", "shape", 1, o_shape) << array_tag("Int32", "phase", 1, o_phase)
    << array_tag("Float32", "axis", 3, o_axis) << "    </CellData>\n";
  s << "    </Piece>\n  </PolyData>\n";
  put(out, s.str());
  put_appended(out, app.arrays());
}

void write_points_vtp(const InclusionSet& set, const std::string& inclusions_json, std::FILE* out) {
  const GlyphPoints g = glyph_points(set);
  const size_t n = g.size();
  std::vector<int64_t> conn(n), offs(n);
  for (size_t i = 0; i < n; ++i) {
    conn[i] = static_cast<int64_t>(i);
    offs[i] = static_cast<int64_t>(i + 1);
  }
  // zlib-compressed like the other VTK files: most arrays are constant or repeat (a sphere's
  // axes, quaternion and flags) and the inclusion list is text.
  AppendedList app(true);
  std::ostringstream s;
  s << header("PolyData", app.compressed()) << "  <PolyData>\n";
  field_data_inclusions(s, &app, inclusions_json);
  const uint64_t o_pts = app.add(g.points.data(), g.points.size());
  const uint64_t o_conn = app.add(conn.data(), conn.size());
  const uint64_t o_offs = app.add(offs.data(), offs.size());
  const uint64_t o_id = app.add(g.inclusion_id.data(), n), o_fam = app.add(g.family.data(), n),
                 o_shape = app.add(g.shape.data(), n), o_phase = app.add(g.phase.data(), n),
                 o_image = app.add(g.image.data(), n), o_mod = app.add(g.modified.data(), n),
                 o_r = app.add(g.radius.data(), n), o_ct = app.add(g.coating.data(), n),
                 o_ha = app.add(g.half_axis.data(), 3 * n),
                 o_sa = app.add(g.semi_axes.data(), 3 * n),
                 o_q = app.add(g.orientation.data(), 4 * n),
                 o_dir = app.add(g.direction.data(), 3 * n), o_sc = app.add(g.scale.data(), 3 * n);
  s << "    <Piece NumberOfPoints=\"" << n << "\" NumberOfVerts=\"" << n
    << "\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"0\">\n";
  s << "    <Points>\n" << array_tag("Float64", "Points", 3, o_pts) << "    </Points>\n";
  s << "    <Verts>\n"
    << array_tag("Int64", "connectivity", 1, o_conn) << array_tag("Int64", "offsets", 1, o_offs)
    << "    </Verts>\n";
  s << "    <PointData Scalars=\"family\">\n"
    << array_tag("Int32", "inclusion_id", 1, o_id) << array_tag("Int32", "family", 1, o_fam)
    << array_tag("Int32", "shape", 1, o_shape) << array_tag("Int32", "phase", 1, o_phase)
    << array_tag("Int32", "image", 1, o_image) << array_tag("Int32", "modified", 1, o_mod)
    << array_tag("Float64", "radius", 1, o_r) << array_tag("Float64", "coating", 1, o_ct)
    << array_tag("Float64", "half_axis", 3, o_ha) << array_tag("Float64", "semi_axes", 3, o_sa)
    << array_tag("Float64", "orientation", 4, o_q) << array_tag("Float64", "direction", 3, o_dir)
    << array_tag("Float64", "scale", 3, o_sc) << "    </PointData>\n";
  s << "    </Piece>\n  </PolyData>\n";
  put(out, s.str());
  put_appended(out, app.arrays());
}

namespace {

namespace fs = std::filesystem;

// Staging directories are named .<dir name>.rvegen-<pid>-XXXXXX next to the output directory.
std::string staging_prefix(const fs::path& target) {
  return "." + target.filename().string() + ".rvegen-";
}

// A process that may still write: it exists and is not a zombie (a killed run whose parent
// has not reaped it still answers kill(pid, 0)).
bool process_alive(long pid) {
  if (pid <= 0) return false;
  if (::kill(static_cast<pid_t>(pid), 0) != 0 && errno != EPERM) return false;
  std::FILE* f = std::fopen(("/proc/" + std::to_string(pid) + "/stat").c_str(), "r");
  if (!f) return true;  // no /proc: trust kill()
  char state = '?';
  // "pid (comm) state ...": comm may hold spaces and parentheses; the state follows the last ')'.
  char buf[512];
  const size_t n = std::fread(buf, 1, sizeof buf - 1, f);
  std::fclose(f);
  buf[n] = '\0';
  const char* close = std::strrchr(buf, ')');
  if (close && close[1] == ' ') state = close[2];
  return state != 'Z' && state != 'X';
}

// Old runs of this program wrote hidden temporaries (.<name>.tmp.<pid>) into the directory.
bool own_file(const std::string& name) {
  for (const std::string& known : OutputSet::file_names()) {
    if (name == known) return true;
    const std::string tmp = "." + known + ".tmp.";
    if (name.compare(0, tmp.size(), tmp) == 0) return true;
  }
  return false;
}

// The process number of a staging directory's name (prefix, digits, '-', six characters of
// mkdtemp, and "-old" for a set moved aside), or -1 when the name is not one.
long staging_pid(const std::string& name, const std::string& prefix) {
  if (name.compare(0, prefix.size(), prefix) != 0) return -1;
  size_t at = prefix.size(), digits = 0;
  while (at < name.size() && name[at] >= '0' && name[at] <= '9') ++at, ++digits;
  if (digits == 0 || digits > 10 || at >= name.size() || name[at] != '-') return -1;
  const std::string rest = name.substr(at + 1);
  if (rest.size() != 6 && !(rest.size() == 10 && rest.compare(6, 4, "-old") == 0)) return -1;
  return std::strtol(name.c_str() + prefix.size(), nullptr, 10);
}

bool move_users_entries(const fs::path& from, const fs::path& to);
bool own_report(const fs::path& target, const std::vector<std::string>& named);

// The output names `dir` holds as regular files (a staged file's ".part" counts as its name);
// false in `only_ours` when it holds anything else.
std::vector<std::string> own_entries(const fs::path& dir, bool* only_ours) {
  std::vector<std::string> named;
  *only_ours = true;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code kind;
    std::string name = it->path().filename().string();
    if (name.size() > 5 && name.compare(name.size() - 5, 5, ".part") == 0)
      name.resize(name.size() - 5);
    if (own_file(name) && fs::is_regular_file(it->symlink_status(kind))) {
      named.push_back(name);
    } else {
      *only_ours = false;
    }
  }
  if (ec) *only_ours = false;
  return named;
}

// Leftovers of killed runs: staging directories whose process is gone. One that holds only
// output files is removed. A run killed after it swapped the sets leaves there the previous
// set (its report.json lists its files) and what the user put into the directory meanwhile:
// the user's entries go back into the directory, then the set is removed. A directory under
// such a name that holds anything else is the user's, and stays.
void remove_orphans(const fs::path& target) {
  const std::string prefix = staging_prefix(target);
  std::error_code ec;
  std::vector<fs::path> stale;
  for (fs::directory_iterator it(target.parent_path(), ec), end; !ec && it != end;
       it.increment(ec)) {
    const long pid = staging_pid(it->path().filename().string(), prefix);
    std::error_code kind;
    if (pid < 0 || process_alive(pid) || !fs::is_directory(it->symlink_status(kind))) continue;
    stale.push_back(it->path());
  }
  for (const fs::path& dir : stale) {
    bool only_ours = false;
    const std::vector<std::string> named = own_entries(dir, &only_ours);
    if (!only_ours) {
      std::error_code there;
      const bool previous_set =
          std::find(named.begin(), named.end(), "report.json") != named.end() &&
          own_report(dir, named);
      if (!previous_set || !fs::is_directory(fs::symlink_status(target, there)) ||
          !move_users_entries(dir, target))
        continue;
      own_entries(dir, &only_ours);
      if (!only_ours) continue;
    }
    std::error_code rm;
    fs::remove_all(dir, rm);
  }
}

// Whether report.json in `target` is one rvegen wrote for the files beside it: a JSON object
// with the report's keys, whose "files" (name and bytes) holds each of `named` with its size.
bool own_report(const fs::path& target, const std::vector<std::string>& named) {
  std::string text;
  try {
    text = read_file((target / "report.json").string(), size_t(64) << 20);
  } catch (const std::exception&) {
    return false;
  }
  const nlohmann::json r = nlohmann::json::parse(text, nullptr, false);
  if (r.is_discarded() || !r.is_object() || !r.contains("status") || !r.contains("seed") ||
      !r.contains("timings"))
    return false;
  if (!r.contains("files")) return false;  // every set lists its files
  const nlohmann::json& files = r["files"];
  if (!files.is_object()) return false;
  for (const std::string& name : named) {
    if (name == "report.json") continue;
    std::error_code ec;
    const auto size = fs::file_size(target / name, ec);
    if (ec || !files.contains(name) || !files[name].is_number_unsigned() ||
        files[name].get<uintmax_t>() != size)
      return false;
  }
  return true;
}

// Moves what a user put into the previous set's directory `from` while the run worked (anything
// rvegen does not write: another name, or not a regular file) into the new set's directory
// `to`, where the user put it. False when an entry stays (its name is taken in `to`, or the
// move failed): the previous set's directory must then stay too.
bool move_users_entries(const fs::path& from, const fs::path& to) {
  bool all = true;
  std::error_code ec;
  for (fs::directory_iterator it(from, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    std::error_code kind;
    if (own_file(name) && fs::is_regular_file(it->symlink_status(kind)) && !kind) continue;
    std::error_code there;
    if (fs::exists(fs::symlink_status(to / name, there)) ||
        ::rename(it->path().c_str(), (to / name).c_str()) != 0) {
      all = false;
    }
  }
  return all && !ec;
}

}  // namespace

const std::vector<std::string>& OutputSet::file_names() {
  static const std::vector<std::string> names = {"inclusions.json",
                                                 "inclusions.vtp",
                                                 "surfaces.vtp",
                                                 "voxels.vti",
                                                 "material.vtk",
                                                 "zoneID.vtk",
                                                 "amitex_materials.xml",
                                                 "amitex_loading.xml",
                                                 "amitex_algorithm.xml",
                                                 "amitex_conductivity_materials.xml",
                                                 "amitex_conductivity_loading.xml",
                                                 "amitex_conductivity_algorithm.xml",
                                                 "amitex_run.sh",
                                                 "rve.h5",
                                                 "rve.xdmf",
                                                 "levelsets.vdb",
                                                 "report.json",
                                                 "mesh_voxel.inp",
                                                 "run_voxel_conductivity.inp",
                                                 "run_voxel_elasticity.inp",
                                                 "mesh_voxel.msh",
                                                 "mesh_voxel.vtu",
                                                 "mesh_tet.inp",
                                                 "mesh_tet.vtu",
                                                 "mesh_tet.msh",
                                                 "run_tet_conductivity.inp",
                                                 "run_tet_elasticity.inp"};
  return names;
}

OutputSet::OutputSet(const std::string& dir) : dir_(dir) {
  std::error_code ec;
  if (dir.empty()) throw OutputError("output directory: empty path");
  fs::path target = fs::absolute(fs::path(dir), ec).lexically_normal();
  if (ec) throw OutputError("output directory " + dir + ": " + ec.message());
  if (fs::is_symlink(fs::symlink_status(target, ec))) {
    // A link to the output directory: the set replaces the directory it points to.
    target = fs::canonical(target, ec);
    if (ec) throw OutputError("output directory " + dir + ": " + ec.message());
  }
  if (target.filename().empty()) target = target.parent_path();
  if (!target.has_parent_path() || target == target.root_path()) {
    throw OutputError("output directory " + dir + ": cannot replace the root directory");
  }
  const fs::path cwd = fs::current_path(ec);
  if (!ec) {
    const auto rel = cwd.lexically_relative(target);
    if (!rel.empty() && *rel.begin() != "..") {
      throw OutputError("output directory " + dir +
                        ": is the current directory or holds it; rvegen replaces the output "
                        "directory as a whole, so name a directory of its own");
    }
  }
  const fs::file_status st = fs::status(target, ec);
  if (fs::exists(st)) {
    if (!fs::is_directory(st)) {
      throw OutputError("output directory " + dir + ": exists and is not a directory");
    }
    std::vector<std::string> foreign;
    for (fs::directory_iterator it(target, ec), end; !ec && it != end; it.increment(ec)) {
      const std::string name = it->path().filename().string();
      // rvegen writes regular files only: a directory, link or device under one of its names
      // is the user's.
      std::error_code kind;
      const bool regular = fs::is_regular_file(it->symlink_status(kind)) && !kind;
      if (!own_file(name)) {
        foreign.push_back(name);
      } else if (!regular) {
        foreign.push_back(name + " (not a regular file)");
      }
    }
    if (ec) throw OutputError("output directory " + dir + ": " + ec.message());
    // Every set rvegen writes holds report.json: files under its other names without one are
    // the user's (a hand-made inclusions.json, say), not an earlier set to replace.
    std::vector<std::string> named;
    for (const std::string& name : file_names()) {
      std::error_code there;
      if (fs::exists(fs::symlink_status(target / name, there))) named.push_back(name);
    }
    if (foreign.empty() && !named.empty() &&
        std::find(named.begin(), named.end(), "report.json") == named.end()) {
      std::string list;
      for (size_t i = 0; i < named.size() && i < 5; ++i) list += (i ? ", " : "") + named[i];
      throw OutputError("output directory " + dir + " holds " + list +
                        " but no report.json, so no earlier run wrote it (every set has one); "
                        "rvegen replaces the output directory as a whole, so give a new or empty "
                        "directory, or one an earlier run wrote");
    }
    if (foreign.empty() && !named.empty() && !own_report(target, named)) {
      throw OutputError("output directory " + dir +
                        " holds a report.json that is not the report of the files beside it "
                        "(an earlier run lists its files and their sizes there), so no earlier "
                        "run wrote them; rvegen replaces the output directory as a whole, so give "
                        "a new or empty directory, or one an earlier run wrote");
    }
    if (!foreign.empty()) {
      std::string list;
      for (size_t i = 0; i < foreign.size() && i < 5; ++i) list += (i ? ", " : "") + foreign[i];
      if (foreign.size() > 5) list += ", ...";
      throw OutputError("output directory " + dir + " holds files rvegen did not write (" + list +
                        "); rvegen replaces the output directory as a whole, so give a new or "
                        "empty directory, or one an earlier run wrote");
    }
  }
  fs::create_directories(target.parent_path(), ec);
  if (ec) {
    throw OutputError("cannot create " + target.parent_path().string() + ": " + ec.message());
  }
  target_ = target.string();
  remove_orphans(target);
  std::string tmpl =
      (target.parent_path() / (staging_prefix(target) + std::to_string(::getpid()) + "-XXXXXX"))
          .string();
  if (!::mkdtemp(tmpl.data())) {
    throw OutputError("cannot write in " + target.parent_path().string() + ": " +
                      std::strerror(errno));
  }
  stage_ = tmpl;
}

OutputSet::~OutputSet() {
  if (committed_ || stage_.empty()) return;
  std::error_code ec;
  fs::remove_all(stage_, ec);
}

std::string OutputSet::staged_path(const std::string& name) const {
  const auto& names = file_names();
  if (std::find(names.begin(), names.end(), name) == names.end()) {
    throw OutputError("not an output file name: " + name);
  }
  return (fs::path(stage_) / name).string();
}

void OutputSet::write_with(const std::string& name, const std::function<void(std::FILE*)>& fill) {
  const std::string path = staged_path(name);
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0666);
  if (fd < 0) throw OutputError("cannot create " + path + ": " + std::strerror(errno));
  std::FILE* f = ::fdopen(fd, "wb");
  if (!f) {
    ::close(fd);
    throw OutputError("cannot open " + path + ": " + std::strerror(errno));
  }
  try {
    fill(f);
  } catch (const OutputError& e) {
    std::fclose(f);
    throw OutputError("cannot write " + path + ": " + e.what());
  } catch (...) {
    std::fclose(f);
    throw;
  }
  if (std::fflush(f) != 0 || std::ferror(f)) {
    const int err = errno;
    std::fclose(f);
    throw OutputError("cannot write " + path + ": " + std::strerror(err));
  }
  if (std::fclose(f) != 0) throw OutputError("cannot write " + path + ": " + std::strerror(errno));
}

std::string OutputSet::files_json() const {
  std::string out = "{";
  std::error_code ec;
  for (const std::string& name : file_names()) {
    const fs::path p = fs::path(stage_) / name;
    if (!fs::is_regular_file(fs::symlink_status(p, ec))) continue;
    const auto size = fs::file_size(p, ec);
    if (ec) continue;
    out += (out.size() > 1 ? ", \"" : "\"") + name + "\": " + std::to_string(size);
  }
  return out + "}";
}

void OutputSet::write(const std::string& name, const std::string& bytes) {
  write_with(name, [&](std::FILE* f) { put(f, bytes); });
}

void OutputSet::commit() {
  if (committed_) return;
  // The staging directory was created 0700; the set gets the usual permissions.
  const mode_t mask = ::umask(0);
  ::umask(mask);
  ::chmod(stage_.c_str(), 0777 & ~mask);
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(target_, ec))) {
    if (::rename(stage_.c_str(), target_.c_str()) != 0) {
      throw OutputError("cannot move " + stage_ + " to " + target_ + ": " + std::strerror(errno));
    }
    committed_ = true;
    return;
  }
  if (::renameat2(AT_FDCWD, stage_.c_str(), AT_FDCWD, target_.c_str(), RENAME_EXCHANGE) == 0) {
    // The staging name now holds the previous set, and whatever the user put into the
    // directory while the run worked: that goes back where the user put it.
    committed_ = true;
    if (!move_users_entries(stage_, target_)) {
      leftover_ = stage_;
      return;
    }
    fs::remove_all(stage_, ec);
    if (ec) leftover_ = stage_;
    return;
  }
  if (errno != EINVAL && errno != ENOSYS && errno != ENOTSUP) {
    throw OutputError("cannot replace " + target_ + ": " + std::strerror(errno));
  }
  // No atomic exchange on this file system: move the old set aside, then the new one in (and
  // the old one back if that fails).
  std::string aside = stage_ + "-old";
  if (::rename(target_.c_str(), aside.c_str()) != 0) {
    throw OutputError("cannot replace " + target_ + ": " + std::strerror(errno));
  }
  if (::rename(stage_.c_str(), target_.c_str()) != 0) {
    const int err = errno;
    ::rename(aside.c_str(), target_.c_str());
    throw OutputError("cannot move " + stage_ + " to " + target_ + ": " + std::strerror(err));
  }
  committed_ = true;
  if (!move_users_entries(aside, target_)) {
    leftover_ = aside;
    return;
  }
  fs::remove_all(aside, ec);
  if (ec) leftover_ = aside;
}

std::string read_file(const std::string& path, size_t max_bytes) {
  // O_NONBLOCK: opening a named pipe would otherwise wait for a writer, before the check below
  // could refuse it (reads of a regular file are not affected).
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) throw InputError(path + ": cannot read (" + std::strerror(errno) + ")");
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    throw InputError(path + ": not a regular file");
  }
  if (static_cast<unsigned long long>(st.st_size) > max_bytes) {
    ::close(fd);
    throw InputError(path + ": too large (" + std::to_string(st.st_size) + " bytes, at most " +
                     std::to_string(max_bytes) + ")");
  }
  std::string out(static_cast<size_t>(st.st_size), '\0');
  size_t got = 0;
  while (got < out.size()) {
    const ssize_t n = ::read(fd, out.data() + got, out.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    got += static_cast<size_t>(n);
  }
  ::close(fd);
  out.resize(got);
  return out;
}
namespace {

// "812 KB", "71.1 MB", "1.54 GB" (decimal units, three significant figures or so).
std::string human_bytes(uintmax_t bytes) {
  char buf[32];
  const double b = static_cast<double>(bytes);
  if (b < 1e3) {
    std::snprintf(buf, sizeof buf, "%.0f B", b);
  } else if (b < 1e6) {
    std::snprintf(buf, sizeof buf, "%.0f KB", b / 1e3);
  } else if (b < 1e9) {
    std::snprintf(buf, sizeof buf, "%.1f MB", b / 1e6);
  } else {
    std::snprintf(buf, sizeof buf, "%.2f GB", b / 1e9);
  }
  return buf;
}

// Bytes of the regular files in `dir` (what a run wrote).
uintmax_t directory_bytes(const std::string& dir, int* files) {
  uintmax_t total = 0;
  *files = 0;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    if (e.is_regular_file(ec)) {
      total += e.file_size(ec);
      ++*files;
    }
  }
  return total;
}

}  // namespace

std::string describe_directory(const std::string& dir) {
  int files = 0;
  const uintmax_t bytes = directory_bytes(dir, &files);
  return human_bytes(bytes) + " in " + std::to_string(files) + " files";
}

}  // namespace rvegen
