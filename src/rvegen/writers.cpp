#include "rvegen/writers.hpp"

#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace rvegen {
namespace {

// Appended raw data: each array is a UInt64 byte count followed by the bytes.
class Appended {
 public:
  template <class T>
  size_t add(const T* data, size_t n) {
    const size_t offset = buf_.size();
    const uint64_t bytes = n * sizeof(T);
    buf_.append(reinterpret_cast<const char*>(&bytes), sizeof bytes);
    buf_.append(reinterpret_cast<const char*>(data), bytes);
    return offset;
  }
  const std::string& bytes() const { return buf_; }

 private:
  std::string buf_;
};

std::string header(const char* type) {
  return std::string("<?xml version=\"1.0\"?>\n<VTKFile type=\"") + type +
         "\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n";
}

std::string array_tag(const char* vtk_type, const char* name, int components, size_t offset) {
  std::ostringstream s;
  s << "      <DataArray type=\"" << vtk_type << "\" Name=\"" << name << "\"";
  if (components > 1) s << " NumberOfComponents=\"" << components << "\"";
  s << " format=\"appended\" offset=\"" << offset << "\"/>\n";
  return s.str();
}

std::string footer(const Appended& app) {
  return "  <AppendedData encoding=\"raw\">\n   _" + app.bytes() +
         "\n  </AppendedData>\n</VTKFile>\n";
}

}  // namespace

std::string vti_bytes(const VoxelImage& im) {
  Appended app;
  const size_t o_phase = app.add(im.phase.data(), im.phase.size());
  const size_t o_id = app.add(im.inclusion_id.data(), im.inclusion_id.size());
  const size_t o_frac = app.add(im.fraction.data(), im.fraction.size());
  std::ostringstream s;
  s.precision(17);
  s << header("ImageData");
  s << "  <ImageData WholeExtent=\"0 " << im.dims[0] << " 0 " << im.dims[1] << " 0 " << im.dims[2]
    << "\" Origin=\"" << im.origin[0] << " " << im.origin[1] << " " << im.origin[2]
    << "\" Spacing=\"" << im.spacing[0] << " " << im.spacing[1] << " " << im.spacing[2] << "\">\n";
  // Cell extents [lo, hi) are point extents lo..hi.
  s << "    <Piece Extent=\"" << im.extent[0] << " " << im.extent[1] << " " << im.extent[2] << " "
    << im.extent[3] << " " << im.extent[4] << " " << im.extent[5] << "\">\n";
  s << "    <CellData Scalars=\"phase\">\n";
  s << array_tag("UInt8", "phase", 1, o_phase);
  s << array_tag("Int32", "inclusion_id", 1, o_id);
  if (!im.fraction.empty()) s << array_tag("Float32", "fraction", 1, o_frac);
  s << "    </CellData>\n    </Piece>\n  </ImageData>\n";
  return s.str() + footer(app);
}

std::string material_vtk_bytes(const VoxelImage& im) {
  // AMITEX_FFTP's header, exactly 10 lines; materials numbered 1..N (phase label + 1) as
  // big-endian unsigned shorts. Phases absent from the image would leave holes in 1..N, which
  // AMITEX rejects: labels are renumbered densely in label order.
  std::vector<int> present(256, 0);
  for (uint8_t p : im.phase) present[p] = 1;
  std::vector<uint16_t> id(256, 0);
  uint16_t next = 1;
  for (int l = 0; l < 256; ++l) {
    if (present[l]) id[l] = next++;
  }
  std::ostringstream s;
  s.precision(17);
  s << "# vtk DataFile Version 4.5\nMateriau\nBINARY\nDATASET STRUCTURED_POINTS\n";
  s << "DIMENSIONS " << im.size(0) + 1 << " " << im.size(1) + 1 << " " << im.size(2) + 1 << "\n";
  s << "ORIGIN " << im.origin[0] + im.extent[0] * im.spacing[0] << " "
    << im.origin[1] + im.extent[2] * im.spacing[1] << " "
    << im.origin[2] + im.extent[4] * im.spacing[2] << "\n";
  s << "SPACING " << im.spacing[0] << " " << im.spacing[1] << " " << im.spacing[2] << "\n";
  s << "CELL_DATA " << im.count() << "\n";
  s << "SCALARS MaterialId unsigned_short\nLOOKUP_TABLE default\n";
  std::string out = s.str();
  const size_t head = out.size();
  out.resize(head + 2 * im.phase.size());
  for (size_t i = 0; i < im.phase.size(); ++i) {
    const uint16_t v = id[im.phase[i]];
    out[head + 2 * i] = static_cast<char>(v >> 8);
    out[head + 2 * i + 1] = static_cast<char>(v & 0xff);
  }
  return out;
}

std::string vtp_bytes(const SurfaceMesh& m, const std::string& inclusions_json) {
  Appended app;
  std::vector<double> pts(3 * m.points.size());
  for (size_t i = 0; i < m.points.size(); ++i) {
    for (int a = 0; a < 3; ++a) pts[3 * i + a] = m.points[i][a];
  }
  std::vector<int64_t> conn(3 * m.triangles.size()), offs(m.triangles.size());
  for (size_t i = 0; i < m.triangles.size(); ++i) {
    for (int a = 0; a < 3; ++a) conn[3 * i + a] = m.triangles[i][a];
    offs[i] = static_cast<int64_t>(3 * (i + 1));
  }
  const size_t o_pts = app.add(pts.data(), pts.size());
  const size_t o_conn = app.add(conn.data(), conn.size());
  const size_t o_offs = app.add(offs.data(), offs.size());
  const size_t o_id = app.add(m.inclusion_id.data(), m.inclusion_id.size());
  const size_t o_fam = app.add(m.family.data(), m.family.size());
  const size_t o_shape = app.add(m.shape.data(), m.shape.size());
  const size_t o_phase = app.add(m.phase.data(), m.phase.size());
  const size_t o_axis = app.add(reinterpret_cast<const float*>(m.axis.data()), 3 * m.axis.size());
  std::ostringstream s;
  s << header("PolyData") << "  <PolyData>\n";
  if (!inclusions_json.empty()) {
    // The inclusion list as a string in field data (VTK's ascii form: byte values, then 0), so
    // the RVE filters work on surfaces read back from the file.
    s << "    <FieldData>\n      <Array type=\"String\" Name=\"rvegen_inclusions\" "
         "NumberOfTuples=\"1\" format=\"ascii\">\n";
    for (unsigned char c : inclusions_json) s << static_cast<int>(c) << ' ';
    s << "0\n      </Array>\n    </FieldData>\n";
  }
  s << "    <Piece NumberOfPoints=\"" << m.points.size()
    << "\" NumberOfVerts=\"0\" NumberOfLines=\"0\""
    << " NumberOfStrips=\"0\" NumberOfPolys=\"" << m.triangles.size() << "\">\n";
  s << "    <Points>\n" << array_tag("Float64", "Points", 3, o_pts) << "    </Points>\n";
  s << "    <Polys>\n"
    << array_tag("Int64", "connectivity", 1, o_conn) << array_tag("Int64", "offsets", 1, o_offs)
    << "    </Polys>\n";
  s << "    <CellData Scalars=\"family\">\n"
    << array_tag("Int32", "inclusion_id", 1, o_id) << array_tag("Int32", "family", 1, o_fam)
    << array_tag("Int32", "shape", 1, o_shape) << array_tag("Int32", "phase", 1, o_phase)
    << array_tag("Float32", "axis", 3, o_axis) << "    </CellData>\n";
  s << "    </Piece>\n  </PolyData>\n";
  return s.str() + footer(app);
}

OutputTransaction::~OutputTransaction() {
  for (const auto& t : temps_) std::remove(t.c_str());
}

void OutputTransaction::commit() {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec) throw std::runtime_error("cannot create output directory " + dir_ + ": " + ec.message());
  const std::string tag = ".tmp." + std::to_string(::getpid());
  for (const auto& [name, bytes] : files_) {
    const std::string tmp = (fs::path(dir_) / ("." + name + tag)).string();
    temps_.push_back(tmp);
    std::ofstream out(tmp, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out) throw std::runtime_error("cannot write " + tmp);
  }
  for (size_t i = 0; i < files_.size(); ++i) {
    const std::string dst = (fs::path(dir_) / files_[i].first).string();
    if (std::rename(temps_[i].c_str(), dst.c_str()) != 0) {
      throw std::runtime_error("cannot move " + temps_[i] + " to " + dst + ": " +
                               std::strerror(errno));
    }
  }
  temps_.clear();
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace rvegen
