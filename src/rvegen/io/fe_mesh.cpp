#include "rvegen/io/fe_mesh.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <exception>
#include <functional>
#include <map>
#include <sstream>
#include <vector>

#include "rvegen/io/writers.hpp"

namespace rvegen {

namespace {

// Abaqus names: letters, digits and underscores, starting with a letter.
std::string set_name(const std::string& phase) {
  return deck_name(phase);
}

struct Grid {
  int nx, ny, nz;
  long long node(int i, int j, int k) const {
    return 1 + i + static_cast<long long>(nx + 1) * (j + static_cast<long long>(ny + 1) * k);
  }
  long long nodes() const { return static_cast<long long>(nx + 1) * (ny + 1) * (nz + 1); }
};

// Ids in lines of 16.
void id_lines(std::ostringstream& s, const std::vector<long long>& ids) {
  for (size_t a = 0; a < ids.size(); ++a) {
    s << ids[a] << ((a % 16 == 15 || a + 1 == ids.size()) ? "\n" : ", ");
  }
}

void put(std::FILE* out, const std::string& text) {
  if (!text.empty() && std::fwrite(text.data(), 1, text.size(), out) != text.size()) {
    throw OutputError(std::string("write failed: ") + std::strerror(errno));
  }
}

// Rows of numbers for the large blocks (nodes, elements), formatted by std::to_chars: the same
// characters as the streams' (a double as printf's %.<digits>g), faster. Written
// out every 256 KiB.
class Rows {
 public:
  Rows(std::FILE* out, int digits) : out_(out), digits_(digits) { text_.reserve(kChunk + 256); }
  ~Rows() noexcept(false) {
    if (!std::uncaught_exceptions()) flush();
  }
  Rows& operator<<(double v) {
    char b[32];
    text_.append(b, std::to_chars(b, b + sizeof b, v, std::chars_format::general, digits_).ptr);
    return *this;
  }
  Rows& operator<<(long long v) {
    char b[24];
    text_.append(b, std::to_chars(b, b + sizeof b, v).ptr);
    return *this;
  }
  Rows& operator<<(const char* t) {
    text_ += t;
    return *this;
  }
  // Ends a row.
  void end() {
    text_ += '\n';
    if (text_.size() >= kChunk) flush();
  }
  void flush() {
    put(out_, text_);
    text_.clear();
  }

 private:
  static constexpr size_t kChunk = 1 << 18;
  std::FILE* out_;
  int digits_;
  std::string text_;
};

// The phases that label at least one voxel or element, in label order.
template <class Labels>
std::vector<const Phase*> phases_labelled(const std::vector<Phase>& phases, const Labels& labels) {
  std::vector<char> present(phases.size(), 0);
  for (const auto l : labels) present[l] = 1;
  std::vector<const Phase*> used;
  for (const Phase& p : phases) {
    if (present[p.label]) used.push_back(&p);
  }
  return used;
}
std::vector<const Phase*> phases_present(const VoxelImage& im) {
  return phases_labelled(im.phases, im.phase);
}
std::vector<const Phase*> phases_present(const TetMesh& mesh) {
  return phases_labelled(mesh.phases, mesh.phase);
}

// One row per hexahedron of phase `label`: element id (voxel + 1), then its eight nodes (the
// lower face counter-clockwise, then the upper one: C3D8's order and Gmsh's), separated by
// `sep`; flushed to `out` row of voxels by row.
void element_rows(const VoxelImage& im, const Grid& g, int label, const char* sep,
                  std::ostringstream& s, std::FILE* out) {
  size_t v = 0;
  for (int k = 0; k < g.nz; ++k) {
    for (int j = 0; j < g.ny; ++j) {
      for (int i = 0; i < g.nx; ++i, ++v) {
        if (im.phase[v] != label) continue;
        s << v + 1 << sep << g.node(i, j, k) << sep << g.node(i + 1, j, k) << sep
          << g.node(i + 1, j + 1, k) << sep << g.node(i, j + 1, k) << sep << g.node(i, j, k + 1)
          << sep << g.node(i + 1, j, k + 1) << sep << g.node(i + 1, j + 1, k + 1) << sep
          << g.node(i, j + 1, k + 1) << "\n";
      }
      put(out, s.str());
      s.str("");
    }
  }
}

// Significant digits of numbers in Abaqus files: CalculiX reads a field of at most 20
// characters, and -1.2345678901234e-05 is 20 with 14 digits (17 digits overflowed it).
constexpr int kAbaqusDigits = 14;

// A void's modulus against the stiffest phase's in the decks.
constexpr double kVoidShare = 1e-6;

// The elements of core phase p (element ids), inclusion by inclusion.
using ElementsByInclusion = std::map<int, std::vector<long long>>;

// The elements (index + 1) labelled `label`, grouped by their inclusion id.
template <class Labels, class Ids>
ElementsByInclusion elements_by_inclusion(const Labels& labels, const Ids& ids, int label) {
  ElementsByInclusion elements;
  for (size_t e = 0; e < labels.size(); ++e) {
    if (labels[e] == label) elements[ids[e]].push_back(static_cast<long long>(e + 1));
  }
  return elements;
}

// Each inclusion's elements: an element set I<id>, the orientation O<id> whose local direction
// 1 is the inclusion's axis, and a section of material M_<name> in that orientation.
void turned_sections(const InclusionSet& set, const ElementsByInclusion& elements,
                     const std::string& name, std::ostringstream& s) {
  std::map<int, const Inclusion*> by_id;
  for (const Inclusion& inc : set.inclusions) by_id[inc.id] = &inc;
  for (const auto& [id, ids] : elements) {
    const auto it = by_id.find(id);
    if (it == by_id.end()) throw OutputError("mesh: a core element of no listed inclusion");
    const Vec3 a = principal_axis(it->second->shape);
    const Vec3 b = any_orthogonal(a);
    s << "*ELSET, ELSET=I" << id << "\n";
    id_lines(s, ids);
    s << "*ORIENTATION, NAME=O" << id << ", SYSTEM=RECTANGULAR\n"
      << a[0] << ", " << a[1] << ", " << a[2] << ", " << b[0] << ", " << b[1] << ", " << b[2]
      << "\n";
    s << "*SOLID SECTION, ELSET=I" << id << ", MATERIAL=M_" << name << ", ORIENTATION=O" << id
      << "\n";
  }
}

// The node sets of the box's faces (XMIN .. ZMAX), edges (EDGE_Y0Z0 ..) and corners
// (CORNER_X0Y0Z0 ..): nodes_where(at) gives the nodes at those ends (at[a]: -1 anywhere along
// axis a, 0 at its lower end, 1 at its upper end).
template <class Where>
void boundary_sets(std::ostringstream& s, const Where& nodes_where) {
  const char* axis = "XYZ";
  for (int a = 0; a < 3; ++a) {
    for (int end = 0; end < 2; ++end) {
      int at[3] = {-1, -1, -1};
      at[a] = end;
      s << "*NSET, NSET=" << axis[a] << (end ? "MAX" : "MIN") << "\n";
      id_lines(s, nodes_where(at));
    }
  }
  for (int a = 0; a < 3; ++a) {  // edges along axis a
    const int b = (a + 1) % 3, c = (a + 2) % 3;
    const int lo = std::min(b, c), hi = std::max(b, c);
    for (int eb = 0; eb < 2; ++eb) {
      for (int ec = 0; ec < 2; ++ec) {
        int at[3] = {-1, -1, -1};
        at[lo] = eb;
        at[hi] = ec;
        s << "*NSET, NSET=EDGE_" << axis[lo] << eb << axis[hi] << ec << "\n";
        id_lines(s, nodes_where(at));
      }
    }
  }
  for (int cz = 0; cz < 2; ++cz) {
    for (int cy = 0; cy < 2; ++cy) {
      for (int cx = 0; cx < 2; ++cx) {
        const int at[3] = {cx, cy, cz};
        s << "*NSET, NSET=CORNER_X" << cx << "Y" << cy << "Z" << cz << "\n";
        id_lines(s, nodes_where(at));
      }
    }
  }
}

// Gmsh format 4.1 (ASCII), up to the node coordinates: a physical group and a volume entity
// per phase present (tag label + 1, named after the phase), six surface entities for the box's
// faces (XMIN, XMAX, YMIN, YMAX, ZMIN, ZMAX: tags 1-6, which $Periodic names), and the head of
// the $Nodes section: all `nodes` nodes (tags 1..nodes) in one block of the first volume.
void gmsh_head(std::ostringstream& s, const std::vector<const Phase*>& used, const Vec3& o,
               const Vec3& hi, long long nodes, std::FILE* out) {
  s << "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$PhysicalNames\n" << used.size() << "\n";
  for (const Phase* p : used) s << "3 " << p->label + 1 << " \"" << set_name(p->name) << "\"\n";
  s << "$EndPhysicalNames\n$Entities\n0 0 6 " << used.size() << "\n";
  for (int a = 0; a < 3; ++a) {
    for (int end = 0; end < 2; ++end) {
      Vec3 lo = o, up = hi;
      lo[a] = up[a] = end ? hi[a] : o[a];
      s << 1 + 2 * a + end << " " << lo[0] << " " << lo[1] << " " << lo[2] << " " << up[0] << " "
        << up[1] << " " << up[2] << " 0 0\n";
    }
  }
  for (const Phase* p : used) {
    s << p->label + 1 << " " << o[0] << " " << o[1] << " " << o[2] << " " << hi[0] << " " << hi[1]
      << " " << hi[2] << " 1 " << p->label + 1 << " 0\n";
  }
  s << "$EndEntities\n$Nodes\n1 " << nodes << " 1 " << nodes << "\n3 " << used.front()->label + 1
    << " 0 " << nodes << "\n";
  put(out, s.str());
  s.str("");
  Rows rows(out, 17);
  for (long long n = 1; n <= nodes; ++n) (rows << n).end();
}

// The head of axis a's block of $Periodic: surface 2 + 2a (upper) is the image of 1 + 2a
// (lower) by the translation of `length` along a; `pairs` (upper, lower) node pairs follow.
void gmsh_periodic_head(std::ostringstream& s, int a, double length, long long pairs) {
  s << "2 " << 2 + 2 * a << " " << 1 + 2 * a << "\n16";
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) s << " " << (r == c ? 1.0 : (c == 3 && r == a ? length : 0.0));
  }
  s << "\n" << pairs << "\n";
}

// One row per tetrahedron of phase `label`: element id (its index + 1), then its four corners
// and, for second order, its six midside nodes (in Gmsh's order when `gmsh`: the last two
// swapped), separated by `sep`; what `s` holds is written first, the rows through Rows.
void tet_rows(const TetMesh& mesh, int label, const char* sep, bool gmsh, std::ostringstream& s,
              std::FILE* out) {
  put(out, s.str());
  s.str("");
  Rows rows(out, 17);
  using Id = long long;
  for (size_t e = 0; e < mesh.tets.size(); ++e) {
    if (mesh.phase[e] != label) continue;
    const auto& t = mesh.tets[e];
    rows << static_cast<Id>(e + 1);
    for (int k = 0; k < 4; ++k) rows << sep << static_cast<Id>(t[k] + 1);
    if (!mesh.mid.empty()) {
      const auto& m = mesh.mid[e];
      for (int k : {0, 1, 2, 3, gmsh ? 5 : 4, gmsh ? 4 : 5})
        rows << sep << static_cast<Id>(m[k] + 1);
    }
    rows.end();
  }
}

// The Abaqus element type of the mesh: C3D4, or C3D10 for second order.
const char* abaqus_tet_type(const TetMesh& mesh) {
  return mesh.mid.empty() ? "C3D4" : "C3D10";
}

}  // namespace

void write_abaqus_voxel_mesh(const VoxelImage& im, std::FILE* out) {
  const Grid g{im.size(0), im.size(1), im.size(2)};
  std::ostringstream s;
  s.precision(kAbaqusDigits);
  s << "** rvegen voxel mesh: " << g.nx << " x " << g.ny << " x " << g.nz
    << " hexahedra (C3D8), element sets per phase, periodic node sets, reference nodes REFX, "
       "REFY, REFZ.\n*NODE, NSET=ALLNODES\n";
  const Vec3 o =
      im.origin + Vec3(im.extent[0], im.extent[2], im.extent[4]).cwiseProduct(im.spacing);
  for (int k = 0; k <= g.nz; ++k) {
    for (int j = 0; j <= g.ny; ++j) {
      for (int i = 0; i <= g.nx; ++i) {
        s << g.node(i, j, k) << ", " << o[0] + i * im.spacing[0] << ", " << o[1] + j * im.spacing[1]
          << ", " << o[2] + k * im.spacing[2] << "\n";
      }
      put(out, s.str());
      s.str("");
    }
  }
  // Reference nodes, at the origin (they belong to no element).
  const long long ref = g.nodes();
  for (int a = 0; a < 3; ++a)
    s << ref + 1 + a << ", " << o[0] << ", " << o[1] << ", " << o[2] << "\n";
  // Elements, one block per phase present.
  for (const Phase* p : phases_present(im)) {
    s << "*ELEMENT, TYPE=C3D8, ELSET=" << set_name(p->name) << "\n";
    element_rows(im, g, p->label, ", ", s, out);
  }
  // Node sets: faces, edges, corners (each the nodes whose coordinates lie at those ends).
  const int n[3] = {g.nx, g.ny, g.nz};
  // at[a]: -1 free, 0 lower end, 1 upper end.
  auto nodes_where = [&](const int at[3]) {
    int lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
      lo[a] = at[a] < 0 ? 0 : (at[a] ? n[a] : 0);
      hi[a] = at[a] < 0 ? n[a] : lo[a];
    }
    std::vector<long long> ids;
    for (int k = lo[2]; k <= hi[2]; ++k) {
      for (int j = lo[1]; j <= hi[1]; ++j) {
        for (int i = lo[0]; i <= hi[0]; ++i) ids.push_back(g.node(i, j, k));
      }
    }
    return ids;
  };
  boundary_sets(s, nodes_where);
  s << "*ELSET, ELSET=EALL, GENERATE\n1, " << im.count() << ", 1\n";
  s << "*NSET, NSET=ORIGIN\n" << g.node(0, 0, 0) << "\n";
  s << "*NSET, NSET=REFX\n" << ref + 1 << "\n*NSET, NSET=REFY\n" << ref + 2 << "\n";
  s << "*NSET, NSET=REFZ\n" << ref + 3 << "\n*NSET, NSET=REFS\n";
  s << ref + 1 << ", " << ref + 2 << ", " << ref + 3 << "\n";
  put(out, s.str());
}

void write_gmsh_voxel_mesh(const VoxelImage& im, std::FILE* out) {
  const Grid g{im.size(0), im.size(1), im.size(2)};
  const std::vector<const Phase*> used = phases_present(im);
  const Vec3 o =
      im.origin + Vec3(im.extent[0], im.extent[2], im.extent[4]).cwiseProduct(im.spacing);
  const Vec3 hi = o + Vec3(g.nx, g.ny, g.nz).cwiseProduct(im.spacing);
  std::ostringstream s;
  s.precision(17);
  gmsh_head(s, used, o, hi, g.nodes(), out);
  for (int k = 0; k <= g.nz; ++k) {
    for (int j = 0; j <= g.ny; ++j) {
      for (int i = 0; i <= g.nx; ++i) {
        s << o[0] + i * im.spacing[0] << " " << o[1] + j * im.spacing[1] << " "
          << o[2] + k * im.spacing[2] << "\n";
      }
      put(out, s.str());
      s.str("");
    }
  }
  s << "$EndNodes\n$Elements\n" << used.size() << " " << im.count() << " 1 " << im.count() << "\n";
  for (const Phase* p : used) {
    size_t count = 0;
    for (uint8_t l : im.phase) count += l == p->label;
    s << "3 " << p->label + 1 << " 5 " << count << "\n";
    element_rows(im, g, p->label, " ", s, out);
  }
  s << "$EndElements\n$Periodic\n3\n";
  const int n[3] = {g.nx, g.ny, g.nz};
  for (int a = 0; a < 3; ++a) {
    const int b = (a + 1) % 3, c = (a + 2) % 3;
    gmsh_periodic_head(s, a, hi[a] - o[a], static_cast<long long>(n[b] + 1) * (n[c] + 1));
    for (int u = 0; u <= n[b]; ++u) {
      for (int w = 0; w <= n[c]; ++w) {
        int up[3], lo[3];
        up[a] = n[a], lo[a] = 0;
        up[b] = lo[b] = u;
        up[c] = lo[c] = w;
        s << g.node(up[0], up[1], up[2]) << " " << g.node(lo[0], lo[1], lo[2]) << "\n";
      }
    }
    put(out, s.str());
    s.str("");
  }
  s << "$EndPeriodic\n";
  put(out, s.str());
}

void write_abaqus_tet_mesh(const TetMesh& mesh, std::FILE* out) {
  const Box& box = mesh.box;
  std::ostringstream s;
  s.precision(kAbaqusDigits);
  s << "** rvegen tetrahedral mesh: " << mesh.tets.size() << " tetrahedra ("
    << abaqus_tet_type(mesh) << "), " << mesh.nodes.size()
    << " nodes, element sets per phase, periodic node sets, reference nodes REFX, REFY, "
       "REFZ.\n*NODE, NSET=ALLNODES\n";
  put(out, s.str());
  s.str("");
  {
    Rows rows(out, kAbaqusDigits);
    for (size_t i = 0; i < mesh.nodes.size(); ++i) {
      const Vec3& x = mesh.nodes[i];
      (rows << static_cast<long long>(i + 1) << ", " << x[0] << ", " << x[1] << ", " << x[2]).end();
    }
  }
  const long long ref = static_cast<long long>(mesh.nodes.size());
  for (int a = 0; a < 3; ++a) {
    s << ref + 1 + a << ", " << box.origin[0] << ", " << box.origin[1] << ", " << box.origin[2]
      << "\n";
  }
  for (const Phase* p : phases_present(mesh)) {
    s << "*ELEMENT, TYPE=" << abaqus_tet_type(mesh) << ", ELSET=" << set_name(p->name) << "\n";
    tet_rows(mesh, p->label, ", ", false, s, out);
  }
  const std::vector<std::array<int8_t, 3>> at = node_ends(mesh);
  long long origin = -1;
  for (size_t i = 0; i < at.size(); ++i) {
    if (at[i][0] == 0 && at[i][1] == 0 && at[i][2] == 0) origin = static_cast<long long>(i) + 1;
  }
  if (origin < 0) throw OutputError("tetrahedral mesh: no node at the box's lower corner");
  // Nodes whose position matches `want` on the axes it fixes (-1: any).
  auto nodes_where = [&](const int want[3]) {
    std::vector<long long> ids;
    for (size_t i = 0; i < at.size(); ++i) {
      bool ok = true;
      for (int a = 0; a < 3; ++a) ok = ok && (want[a] < 0 ? true : at[i][a] == want[a]);
      if (ok) ids.push_back(static_cast<long long>(i) + 1);
    }
    return ids;
  };
  boundary_sets(s, nodes_where);
  s << "*ELSET, ELSET=EALL, GENERATE\n1, " << mesh.tets.size() << ", 1\n";
  s << "*NSET, NSET=ORIGIN\n" << origin << "\n";
  s << "*NSET, NSET=REFX\n" << ref + 1 << "\n*NSET, NSET=REFY\n" << ref + 2 << "\n";
  s << "*NSET, NSET=REFZ\n" << ref + 3 << "\n*NSET, NSET=REFS\n";
  s << ref + 1 << ", " << ref + 2 << ", " << ref + 3 << "\n";
  put(out, s.str());
}

namespace {

// What a periodic deck needs of a mesh.
struct DeckMesh {
  const char* kind;     // "voxel" or "tet": the deck's and the mesh file's names
  long long nodes = 0;  // the reference nodes are nodes + 1 .. nodes + 3
  Vec3 length;          // the box's sides
  std::vector<const Phase*> present;
  std::function<ElementsByInclusion(const Phase&)> core_elements;
  /// Calls back (dependent, master, axes brought back: bit a) for every node on an upper face.
  std::function<void(const std::function<void(long long, long long, int)>&)> pairs;
  /// Elements of unequal volumes: the steps print each element's volume too (EVOL).
  bool print_volumes = false;
};

std::string periodic_deck(const Scene& scene, const InclusionSet& set, const DeckMesh& m,
                          bool elasticity) {
  std::ostringstream s;
  s.precision(kAbaqusDigits);
  const std::string physics = elasticity ? "elasticity" : "conductivity";
  s << "** rvegen: periodic " << physics << " of the "
    << (m.print_volumes ? "tetrahedral" : "voxel") << " mesh (CalculiX: ccx -i run_" << m.kind
    << "_" << physics << "). Each step prints the " << (elasticity ? "stress" : "heat flux")
    << " at every integration point of EALL"
    << (m.print_volumes ? " and the volume of every element (the mean over the box weights each "
                          "element by its volume).\n"
                        : " (equal hexahedra with equal weights: their mean is the mean over the "
                          "box).\n");
  s << "*INCLUDE, INPUT=mesh_" << m.kind << ".inp\n";
  // Voids get kVoidShare of the stiffest phase's modulus (an element needs a material; zero
  // would leave the nodes inside a void free).
  double largest = 0.0;
  for (const Phase* phase : m.present) {
    const Material* mat =
        phase->kind == PhaseKind::kVoid ? nullptr : scene.material(material_key(scene, *phase));
    if (!mat) continue;
    largest =
        std::max({largest, elasticity ? mat->young : mat->conductivity,
                  elasticity ? std::max(mat->axial_young, mat->transverse_young)
                             : std::max(mat->axial_conductivity, mat->transverse_conductivity)});
  }
  for (const Phase* phase : m.present) {
    const Phase& p = *phase;
    const std::string name = set_name(p.name);
    if (p.kind == PhaseKind::kVoid) {
      s << "*MATERIAL, NAME=M_" << name << "\n";
      if (elasticity) {
        s << "*ELASTIC\n" << kVoidShare * largest << ", 0.\n";
      } else {
        s << "*CONDUCTIVITY\n" << kVoidShare * largest << "\n";
      }
      s << "*SOLID SECTION, ELSET=" << name << ", MATERIAL=M_" << name << "\n";
      continue;
    }
    const Material* mat = scene.material(material_key(scene, p));
    if (!mat) return "";
    const bool turned = elasticity ? mat->transverse_elasticity() : mat->transverse_conduction();
    s << "*MATERIAL, NAME=M_" << name << "\n";
    if (turned) {
      // About each inclusion's own axis: local direction 1 is the axis.
      if (p.kind != PhaseKind::kCore) return "";
      if (elasticity) {
        const double g_tt = mat->transverse_young / (2.0 * (1.0 + mat->transverse_poisson));
        s << "*ELASTIC, TYPE=ENGINEERING CONSTANTS\n"
          << mat->axial_young << ", " << mat->transverse_young << ", " << mat->transverse_young
          << ", " << mat->axial_poisson << ", " << mat->axial_poisson << ", "
          << mat->transverse_poisson << ", " << mat->axial_shear << ", " << mat->axial_shear << "\n"
          << g_tt << "\n";
      } else {
        s << "*CONDUCTIVITY, TYPE=ORTHO\n"
          << mat->axial_conductivity << ", " << mat->transverse_conductivity << ", "
          << mat->transverse_conductivity << "\n";
      }
      turned_sections(set, m.core_elements(p), name, s);
      continue;
    }
    if (elasticity) {
      if (!(mat->young > 0.0)) return "";
      s << "*ELASTIC\n" << mat->young << ", " << mat->poisson << "\n";
    } else {
      if (!(mat->conductivity > 0.0)) return "";
      s << "*CONDUCTIVITY\n" << mat->conductivity << "\n";
    }
    s << "*SOLID SECTION, ELSET=" << name << ", MATERIAL=M_" << name << "\n";
  }
  // Periodic equations: every node on an upper face tied to its master.
  const long long ref = m.nodes;
  s << "*EQUATION\n";
  m.pairs([&](long long dep, long long master, int wrap) {
    const int dofs = elasticity ? 3 : 1;
    for (int d = 0; d < dofs; ++d) {
      const int dof = elasticity ? d + 1 : 11;
      // Terms: dep, master, then one per axis brought back; at most four per line.
      std::vector<std::string> terms;
      terms.push_back(std::to_string(dep) + ", " + std::to_string(dof) + ", 1.");
      terms.push_back(std::to_string(master) + ", " + std::to_string(dof) + ", -1.");
      for (int a = 0; a < 3; ++a) {
        if (!(wrap >> a & 1)) continue;
        std::ostringstream t;
        t.precision(kAbaqusDigits);
        t << ref + 1 + a << ", " << dof << ", " << -m.length[a];
        terms.push_back(t.str());
      }
      s << terms.size() << "\n";
      for (size_t t = 0; t < terms.size(); ++t) {
        s << terms[t] << ((t % 4 == 3 || t + 1 == terms.size()) ? "\n" : ", ");
      }
    }
  });
  // Load steps: the reference nodes prescribed, the origin fixed.
  const double r = 1.0 / std::sqrt(2.0);
  const int loads = elasticity ? 6 : 3;
  const char* ref_name[3] = {"REFX", "REFY", "REFZ"};
  for (int load = 0; load < loads; ++load) {
    // CalculiX's iterative Cholesky solver: the problems are symmetric positive definite
    // and large, where the default direct solver (SPOOLES) is far slower for the same
    // digits (README, finite-element meshes).
    s << "*STEP\n"
      << (elasticity ? "*STATIC, SOLVER=ITERATIVE CHOLESKY\n"
                     : "*HEAT TRANSFER, STEADY STATE, SOLVER=ITERATIVE CHOLESKY\n1., 1.\n");
    s << "*BOUNDARY, OP=NEW\n";
    if (elasticity) {
      s << "ORIGIN, 1, 3, 0.\n";
      // H (the mean displacement gradient) of the unit Mandel strain `load`: column a on
      // reference node a.
      double h[3][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
      const int pair[6][2] = {{0, 0}, {1, 1}, {2, 2}, {1, 2}, {0, 2}, {0, 1}};
      const int p = pair[load][0], q = pair[load][1];
      if (p == q) {
        h[p][p] = 1.0;
      } else {
        h[p][q] = h[q][p] = r;
      }
      for (int a = 0; a < 3; ++a) {
        for (int c = 0; c < 3; ++c) {
          s << ref_name[a] << ", " << c + 1 << ", " << c + 1 << ", " << h[c][a] << "\n";
        }
      }
      s << "*EL PRINT, ELSET=EALL\nS" << (m.print_volumes ? ", EVOL" : "") << "\n";
    } else {
      s << "ORIGIN, 11, 11, 0.\n";
      for (int a = 0; a < 3; ++a) {
        s << ref_name[a] << ", 11, 11, " << (a == load ? 1.0 : 0.0) << "\n";
      }
      s << "*EL PRINT, ELSET=EALL\nHFL" << (m.print_volumes ? ", EVOL" : "") << "\n";
    }
    s << "*END STEP\n";
  }
  return s.str();
}

}  // namespace

void write_gmsh_tet_mesh(const TetMesh& mesh, std::FILE* out) {
  const std::vector<const Phase*> used = phases_present(mesh);
  if (used.empty()) throw OutputError("tetrahedral mesh: no elements");
  const Vec3 o = mesh.box.origin, hi = mesh.box.origin + mesh.box.size;
  std::ostringstream s;
  s.precision(17);
  gmsh_head(s, used, o, hi, static_cast<long long>(mesh.nodes.size()), out);
  {
    Rows rows(out, 17);
    for (size_t i = 0; i < mesh.nodes.size(); ++i) {
      const Vec3& x = mesh.nodes[i];
      (rows << x[0] << " " << x[1] << " " << x[2]).end();
    }
  }
  s << "$EndNodes\n$Elements\n"
    << used.size() << " " << mesh.tets.size() << " 1 " << mesh.tets.size() << "\n";
  for (const Phase* p : used) {
    const auto count = std::count(mesh.phase.begin(), mesh.phase.end(), p->label);
    // Element type 4: 4-node tetrahedron; 11: 10-node.
    s << "3 " << p->label + 1 << (mesh.mid.empty() ? " 4 " : " 11 ") << count << "\n";
    tet_rows(mesh, p->label, " ", true, s, out);
  }
  // The image of a node across one face: the node of the same periodic class (the nodes tied
  // to one master, and the master) with the same ends but that axis's brought to the lower end.
  const std::vector<std::array<int8_t, 3>> at = node_ends(mesh);
  std::vector<int32_t> master(mesh.nodes.size());
  for (size_t i = 0; i < master.size(); ++i) master[i] = static_cast<int32_t>(i);
  for (const auto& [dep, m] : mesh.periodic) master[dep] = m;
  auto upper_bits = [&](size_t i) {
    return (at[i][0] == 1 ? 1 : 0) | (at[i][1] == 1 ? 2 : 0) | (at[i][2] == 1 ? 4 : 0);
  };
  std::map<std::pair<int32_t, int>, int32_t> member;
  for (size_t i = 0; i < master.size(); ++i) {
    // (Only nodes on a face are ever an image.)
    if (at[i][0] < 0 && at[i][1] < 0 && at[i][2] < 0) continue;
    member[{master[i], upper_bits(i)}] = static_cast<int32_t>(i);
  }
  s << "$EndElements\n$Periodic\n3\n";
  for (int a = 0; a < 3; ++a) {
    std::vector<std::pair<int32_t, int32_t>> pairs;
    for (size_t i = 0; i < at.size(); ++i) {
      if (at[i][a] != 1) continue;
      const auto it = member.find({master[i], upper_bits(i) & ~(1 << a)});
      if (it == member.end()) {
        throw OutputError(
            "tetrahedral mesh: a node on an upper face has no image on the lower one");
      }
      pairs.push_back({static_cast<int32_t>(i), it->second});
    }
    gmsh_periodic_head(s, a, mesh.box.size[a], static_cast<long long>(pairs.size()));
    for (const auto& [up, lo] : pairs) s << up + 1 << " " << lo + 1 << "\n";
    put(out, s.str());
    s.str("");
  }
  s << "$EndPeriodic\n";
  put(out, s.str());
}

std::string abaqus_voxel_deck(const Scene& scene, const InclusionSet& set, const VoxelImage& im,
                              bool elasticity) {
  const Grid g{im.size(0), im.size(1), im.size(2)};
  DeckMesh m;
  m.kind = "voxel";
  m.nodes = g.nodes();
  m.length = Vec3(im.spacing[0] * g.nx, im.spacing[1] * g.ny, im.spacing[2] * g.nz);
  m.present = phases_present(im);
  m.core_elements = [&](const Phase& p) {
    return elements_by_inclusion(im.phase, im.inclusion_id, p.label);
  };
  m.pairs = [&](const std::function<void(long long, long long, int)>& tie) {
    const int n[3] = {g.nx, g.ny, g.nz};
    for (int k = 0; k <= g.nz; ++k) {
      for (int j = 0; j <= g.ny; ++j) {
        for (int i = 0; i <= g.nx; ++i) {
          const int c[3] = {i, j, k};
          int lower[3], wrap = 0;
          for (int a = 0; a < 3; ++a) {
            const bool up = c[a] == n[a];
            lower[a] = up ? 0 : c[a];
            wrap |= up << a;
          }
          if (wrap) tie(g.node(i, j, k), g.node(lower[0], lower[1], lower[2]), wrap);
        }
      }
    }
  };
  return periodic_deck(scene, set, m, elasticity);
}

std::string abaqus_tet_deck(const Scene& scene, const InclusionSet& set, const TetMesh& mesh,
                            bool elasticity) {
  DeckMesh m;
  m.kind = "tet";
  m.nodes = static_cast<long long>(mesh.nodes.size());
  m.length = mesh.box.size;
  m.present = phases_present(mesh);
  m.core_elements = [&](const Phase& p) {
    return elements_by_inclusion(mesh.phase, mesh.inclusion_id, p.label);
  };
  m.pairs = [&](const std::function<void(long long, long long, int)>& tie) {
    for (const auto& [dep, master] : mesh.periodic) {
      int wrap = 0;
      for (int a = 0; a < 3; ++a) {
        wrap |= (mesh.nodes[dep][a] - mesh.nodes[master][a] > 0.5 * mesh.box.size[a]) << a;
      }
      tie(dep + 1LL, master + 1LL, wrap);
    }
  };
  m.print_volumes = true;
  return periodic_deck(scene, set, m, elasticity);
}

}  // namespace rvegen
