#include "rvegen/io/hdf5_writer.hpp"

#include <hdf5.h>

#include <algorithm>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <vector>

#include "rvegen/raster/cut_voxels.hpp"

namespace rvegen {
namespace {

void check(herr_t status, const char* what) {
  if (status < 0) throw std::runtime_error(std::string("HDF5: cannot write ") + what);
}

// A dataset written at once. With `image_slices` (a [nz][ny][nx] voxel image) it is chunked by
// z slices and deflated: label images compress well. Tables stay contiguous (chunked by row,
// a long table costs an index entry per row).
template <class T>
void dataset(hid_t parent, const char* name, hid_t type, const std::vector<hsize_t>& dims,
             const T* data, bool image_slices = false) {
  const hid_t space = H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr);
  hid_t plist = H5P_DEFAULT;
  size_t total = 1;
  for (hsize_t d : dims) total *= d;
  if (image_slices && dims.size() == 3 && total > 0) {
    plist = H5Pcreate(H5P_DATASET_CREATE);
    const hsize_t chunk[3] = {1, dims[1], dims[2]};
    H5Pset_chunk(plist, 3, chunk);
    H5Pset_deflate(plist, 4);
  }
  const hid_t set = H5Dcreate2(parent, name, type, space, H5P_DEFAULT, plist, H5P_DEFAULT);
  if (set < 0) throw std::runtime_error(std::string("HDF5: cannot create ") + name);
  if (total > 0) check(H5Dwrite(set, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), name);
  H5Dclose(set);
  H5Sclose(space);
  if (plist != H5P_DEFAULT) H5Pclose(plist);
}

void attribute(hid_t obj, const char* name, const std::vector<double>& v) {
  const hsize_t n = v.size();
  const hid_t space = H5Screate_simple(1, &n, nullptr);
  const hid_t a = H5Acreate2(obj, name, H5T_NATIVE_DOUBLE, space, H5P_DEFAULT, H5P_DEFAULT);
  check(H5Awrite(a, H5T_NATIVE_DOUBLE, v.data()), name);
  H5Aclose(a);
  H5Sclose(space);
}

void text_attribute(hid_t obj, const char* name, const std::string& s) {
  const hid_t type = H5Tcopy(H5T_C_S1);
  H5Tset_size(type, std::max<size_t>(1, s.size()));
  const hid_t space = H5Screate(H5S_SCALAR);
  const hid_t a = H5Acreate2(obj, name, type, space, H5P_DEFAULT, H5P_DEFAULT);
  check(H5Awrite(a, type, s.empty() ? " " : s.data()), name);
  H5Aclose(a);
  H5Sclose(space);
  H5Tclose(type);
}

// Root attributes must stay below HDF5's 64 KB object-header limit.
constexpr size_t kMaxTextAttribute = 60000;

// A scalar fixed-length string dataset (any length).
void text_dataset(hid_t parent, const char* name, const std::string& s) {
  const hid_t type = H5Tcopy(H5T_C_S1);
  H5Tset_size(type, std::max<size_t>(1, s.size()));
  const hid_t space = H5Screate(H5S_SCALAR);
  const hid_t set = H5Dcreate2(parent, name, type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  if (set < 0) throw std::runtime_error(std::string("HDF5: cannot create ") + name);
  check(H5Dwrite(set, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, s.empty() ? " " : s.data()), name);
  H5Dclose(set);
  H5Sclose(space);
  H5Tclose(type);
}

// Fixed-length string dataset (one row per string).
void strings(hid_t parent, const char* name, const std::vector<std::string>& v) {
  size_t len = 1;
  for (const auto& s : v) len = std::max(len, s.size());
  std::vector<char> buf(v.size() * len, '\0');
  for (size_t i = 0; i < v.size(); ++i) std::copy(v[i].begin(), v[i].end(), buf.begin() + i * len);
  const hid_t type = H5Tcopy(H5T_C_S1);
  H5Tset_size(type, len);
  H5Tset_strpad(type, H5T_STR_NULLPAD);
  dataset(parent, name, type, {v.size()}, buf.data());
  H5Tclose(type);
}

}  // namespace

namespace {

// /voxels: the labels, the inclusion ids and the partial volumes, with the grid.
void write_voxels(hid_t file, const VoxelImage& im) {
  const hid_t vox = H5Gcreate2(file, "voxels", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  const std::vector<hsize_t> dims = {static_cast<hsize_t>(im.size(2)),
                                     static_cast<hsize_t>(im.size(1)),
                                     static_cast<hsize_t>(im.size(0))};
  dataset(vox, "phase", H5T_NATIVE_UINT8, dims, im.phase.data(), true);
  dataset(vox, "inclusion_id", H5T_NATIVE_INT32, dims, im.inclusion_id.data(), true);
  if (!im.fraction.empty()) {
    dataset(vox, "fraction", H5T_NATIVE_FLOAT, dims, im.fraction.data(), true);
  }
  attribute(
      vox, "origin",
      {im.origin[0] + im.extent[0] * im.spacing[0], im.origin[1] + im.extent[2] * im.spacing[1],
       im.origin[2] + im.extent[4] * im.spacing[2]});
  attribute(vox, "spacing", {im.spacing[0], im.spacing[1], im.spacing[2]});
  attribute(vox, "resolution",
            {static_cast<double>(im.dims[0]), static_cast<double>(im.dims[1]),
             static_cast<double>(im.dims[2])});
  H5Gclose(vox);
}

// /phases: the phase table.
void write_phases(hid_t file, const VoxelImage& im) {
  const hid_t ph = H5Gcreate2(file, "phases", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  std::vector<int32_t> label, family;
  std::vector<std::string> name, kind;
  for (const auto& p : im.phases) {
    label.push_back(p.label);
    family.push_back(p.family);
    name.push_back(p.name);
    kind.push_back(phase_kind_name(p.kind));
  }
  dataset(ph, "label", H5T_NATIVE_INT32, {label.size()}, label.data());
  dataset(ph, "family", H5T_NATIVE_INT32, {family.size()}, family.data());
  strings(ph, "name", name);
  strings(ph, "kind", kind);
  H5Gclose(ph);
}

// /inclusions: one row per inclusion.
void write_inclusion_table(hid_t file, const InclusionSet& set) {
  const hid_t tab = H5Gcreate2(file, "inclusions", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  const size_t n = set.inclusions.size();
  std::vector<int32_t> id(n), fam(n), shape(n);
  std::vector<double> center(3 * n), radius(n), half(3 * n), semi(3 * n), rot(9 * n);
  for (size_t i = 0; i < n; ++i) {
    const Inclusion& inc = set.inclusions[i];
    id[i] = inc.id;
    fam[i] = inc.family;
    shape[i] = static_cast<int32_t>(inc.shape.kind);
    radius[i] = inc.shape.radius;
    for (int a = 0; a < 3; ++a) {
      center[3 * i + a] = inc.shape.center[a];
      half[3 * i + a] = inc.shape.half_axis[a];
      semi[3 * i + a] = inc.shape.semi_axes[a];
      for (int b = 0; b < 3; ++b) rot[9 * i + 3 * a + b] = inc.shape.rotation(a, b);
    }
  }
  dataset(tab, "id", H5T_NATIVE_INT32, {n}, id.data());
  dataset(tab, "family", H5T_NATIVE_INT32, {n}, fam.data());
  dataset(tab, "shape", H5T_NATIVE_INT32, {n}, shape.data());
  dataset(tab, "center", H5T_NATIVE_DOUBLE, {n, 3}, center.data());
  dataset(tab, "radius", H5T_NATIVE_DOUBLE, {n}, radius.data());
  dataset(tab, "half_axis", H5T_NATIVE_DOUBLE, {n, 3}, half.data());
  dataset(tab, "semi_axes", H5T_NATIVE_DOUBLE, {n, 3}, semi.data());
  dataset(tab, "rotation", H5T_NATIVE_DOUBLE, {n, 3, 3}, rot.data());
  text_attribute(tab, "shape_codes", std::string("0 sphere, 1 cylinder, 2 ellipsoid"));
  H5Gclose(tab);
}

void write_composite_voxels(hid_t file, const VoxelImage& im, const InclusionSet& set) {
  // Voxels cut by the surfaces of one inclusion, for solvers that take composite (laminate)
  // voxels.
  const CutVoxels cut = cut_voxels(set, im);
  const hid_t cv = H5Gcreate2(file, "composite_voxels", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  const size_t m = cut.voxels.size();
  std::vector<uint64_t> voxel(m);
  std::vector<int32_t> owner(m);
  std::vector<uint8_t> inside(m), outside(m), middle(m);
  std::vector<double> share(m), middle_share(m), normal(3 * m);
  for (size_t i = 0; i < m; ++i) {
    const CutVoxel& c = cut.voxels[i];
    voxel[i] = c.voxel;
    owner[i] = set.inclusions[c.inclusion].id;
    inside[i] = c.inside;
    outside[i] = c.outside;
    share[i] = c.fraction;
    middle[i] = c.middle;
    middle_share[i] = c.middle_fraction;
    for (int a = 0; a < 3; ++a) normal[3 * i + a] = c.normal[a];
  }
  dataset(cv, "voxel", H5T_NATIVE_UINT64, {m}, voxel.data());
  dataset(cv, "inclusion_id", H5T_NATIVE_INT32, {m}, owner.data());
  dataset(cv, "inside_phase", H5T_NATIVE_UINT8, {m}, inside.data());
  dataset(cv, "outside_phase", H5T_NATIVE_UINT8, {m}, outside.data());
  dataset(cv, "fraction", H5T_NATIVE_DOUBLE, {m}, share.data());
  dataset(cv, "middle_phase", H5T_NATIVE_UINT8, {m}, middle.data());
  dataset(cv, "middle_fraction", H5T_NATIVE_DOUBLE, {m}, middle_share.data());
  dataset(cv, "normal", H5T_NATIVE_DOUBLE, {m, 3}, normal.data());
  text_attribute(
      cv, "description",
      std::string("voxels cut by the surfaces of one inclusion: voxel = index x fastest (i + "
                  "nx (j + ny k)), the share of the voxel inside the core (fraction), for a "
                  "coated inclusion the shell's label and share (middle_phase, "
                  "middle_fraction; 0 otherwise), the outside phase the rest, the core's "
                  "outward unit normal (the shell's surfaces are parallel to it)"));
  attribute(cv, "voxels_cut_by_two_cores", {static_cast<double>(cut.shared)});
  H5Gclose(cv);
}

void write_fields(hid_t file, const VoxelImage& im, const std::vector<LocalField>& fields) {
  // Local fields, components last (what XDMF and ParaView read as a vector per cell).
  if (fields.empty()) return;
  {
    const hid_t lcpl = H5Pcreate(H5P_LINK_CREATE);
    H5Pset_create_intermediate_group(lcpl, 1);
    const size_t n = im.count();
    std::vector<float> interleaved;
    for (const LocalField& f : fields) {
      if (!f.values || f.values->size() != n * f.count) {
        throw std::runtime_error("HDF5: local field " + f.name + " has the wrong size");
      }
      interleaved.resize(n * f.count);
      for (int c = 0; c < f.count; ++c) {
        for (size_t i = 0; i < n; ++i) interleaved[i * f.count + c] = (*f.values)[c * n + i];
      }
      const std::string path_in = "fields/" + f.name;
      const hsize_t dims[4] = {static_cast<hsize_t>(im.size(2)), static_cast<hsize_t>(im.size(1)),
                               static_cast<hsize_t>(im.size(0)), static_cast<hsize_t>(f.count)};
      const hid_t space = H5Screate_simple(4, dims, nullptr);
      const hid_t ds = H5Dcreate2(file, path_in.c_str(), H5T_NATIVE_FLOAT, space, lcpl, H5P_DEFAULT,
                                  H5P_DEFAULT);
      if (ds < 0) throw std::runtime_error("HDF5: cannot create " + path_in);
      check(H5Dwrite(ds, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, interleaved.data()),
            path_in.c_str());
      text_attribute(ds, "components", f.components);
      H5Dclose(ds);
      H5Sclose(space);
    }
    H5Pclose(lcpl);
  }
}

}  // namespace

void write_hdf5(const std::string& path, const VoxelImage& im, const InclusionSet& set,
                const std::string& scene_json, const std::string& report_json,
                const std::vector<LocalField>& fields) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  const hid_t file = H5Fcreate(path.c_str(), H5F_ACC_EXCL, H5P_DEFAULT, H5P_DEFAULT);
  if (file < 0) throw std::runtime_error("HDF5: cannot create " + path);
  try {
    text_attribute(file, "format", std::string("rvegen.h5/1"));
    attribute(file, "box_origin", {set.box.origin[0], set.box.origin[1], set.box.origin[2]});
    attribute(file, "box_size", {set.box.size[0], set.box.size[1], set.box.size[2]});
    attribute(file, "periodic", std::vector<double>{set.box.periodic ? 1.0 : 0.0});
    // Scene and report: always as datasets (/scene, /report: any length), and also as root
    // attributes when they fit HDF5's 64 KB attribute limit.
    for (const auto& [name, text] :
         {std::pair<const char*, const std::string&>{"scene", scene_json},
          {"report", report_json}}) {
      text_dataset(file, name, text);
      if (text.size() < kMaxTextAttribute) text_attribute(file, name, text);
    }

    write_voxels(file, im);
    write_phases(file, im);
    write_inclusion_table(file, set);
    write_composite_voxels(file, im, set);
    write_fields(file, im, fields);
  } catch (...) {
    H5Fclose(file);
    throw;
  }
  if (H5Fclose(file) < 0) throw std::runtime_error("HDF5: cannot close " + path);
}

std::string xdmf_text(const VoxelImage& im, const std::string& h5,
                      const std::vector<LocalField>& fields) {
  std::ostringstream s;
  s.precision(17);
  const int nx = im.size(0), ny = im.size(1), nz = im.size(2);
  s << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n <Domain>\n"
    << "  <Grid Name=\"rve\" GridType=\"Uniform\">\n"
    << "   <Topology TopologyType=\"3DCoRectMesh\" Dimensions=\"" << nz + 1 << " " << ny + 1 << " "
    << nx + 1 << "\"/>\n"
    << "   <Geometry GeometryType=\"ORIGIN_DXDYDZ\">\n"
    << "    <DataItem Dimensions=\"3\" NumberType=\"Float\" Precision=\"8\" Format=\"XML\">"
    << im.origin[2] + im.extent[4] * im.spacing[2] << " "
    << im.origin[1] + im.extent[2] * im.spacing[1] << " "
    << im.origin[0] + im.extent[0] * im.spacing[0] << "</DataItem>\n"
    << "    <DataItem Dimensions=\"3\" NumberType=\"Float\" Precision=\"8\" Format=\"XML\">"
    << im.spacing[2] << " " << im.spacing[1] << " " << im.spacing[0] << "</DataItem>\n"
    << "   </Geometry>\n";
  auto attr = [&](const char* name, const char* type, int precision) {
    s << "   <Attribute Name=\"" << name << "\" Center=\"Cell\" AttributeType=\"Scalar\">\n"
      << "    <DataItem Dimensions=\"" << nz << " " << ny << " " << nx << "\" NumberType=\"" << type
      << "\" Precision=\"" << precision << "\" Format=\"HDF\">" << h5 << ":/voxels/" << name
      << "</DataItem>\n   </Attribute>\n";
  };
  attr("phase", "UChar", 1);
  attr("inclusion_id", "Int", 4);
  if (!im.fraction.empty()) attr("fraction", "Float", 4);
  for (const LocalField& f : fields) {
    std::string name = f.name;
    std::replace(name.begin(), name.end(), '/', '_');
    s << "   <Attribute Name=\"" << name << "\" Center=\"Cell\" AttributeType=\""
      << (f.count == 3 ? "Vector" : "Matrix") << "\">\n"
      << "    <DataItem Dimensions=\"" << nz << " " << ny << " " << nx << " " << f.count
      << "\" NumberType=\"Float\" Precision=\"4\" Format=\"HDF\">" << h5 << ":/fields/" << f.name
      << "</DataItem>\n   </Attribute>\n";
  }
  s << "  </Grid>\n </Domain>\n</Xdmf>\n";
  return s.str();
}

}  // namespace rvegen
