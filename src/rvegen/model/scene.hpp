// Scene description: what `rvegen generate` reads (JSON) and what the VTK source builds from
// its properties. Validation happens here, before any work or output.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "rvegen/geometry/random.hpp"
#include "rvegen/model/inclusion_set.hpp"
#include "rvegen/model/laws.hpp"
#include "rvegen/model/phases.hpp"

namespace rvegen {

/// Modifiers of a family (all zero: plain inclusions). See body.hpp for the geometry.
struct FamilyModifiers {
  double coating = 0.0;  // interphase thickness
  bool shells_may_touch = false;
  double wave_amplitude = 0.0, wave_length = 0.0;   // cylinders
  double bend_radius = 0.0;                         // cylinders: radius of curvature
  double deform_amplitude = 0.0, smoothness = 1.0;  // spheres, ellipsoids; amplitude < 0.5
  double debond_fraction = 0.0, debond_gap = 0.0;   // spheres
  bool any() const {
    return coating > 0.0 || wave_amplitude > 0.0 || bend_radius > 0.0 || deform_amplitude > 0.0 ||
           debond_gap > 0.0;
  }
  /// Draws the per-inclusion modifiers (random phases, planes, waves, cap axes).
  Modifiers draw(Random& rng) const;
};

struct Family {
  std::string name;
  FamilyModifiers modifiers;
  ShapeKind shape = ShapeKind::Sphere;
  SizeLaw radius;        // sphere, cylinder
  SizeLaw aspect_ratio;  // cylinder: a = |l| / r
  /// Cylinders: continuous fibres (JSON "length": "through"), each as long as the periodic box
  /// along the box axis the aligned law gives (this length, set from the box); 0: fibres of
  /// the lengths `aspect_ratio` gives.
  double through_length = 0.0;
  bool through() const { return through_length > 0.0; }
  std::array<SizeLaw, 3> semi_axes;
  double volume_fraction = -1.0;  // < 0 when only `count` is given
  int count = -1;                 // < 0 when only `volume_fraction` is given
  OrientationLaw orientation;

  /// Expected volume of one inclusion.
  double mean_volume() const;
  /// Largest half length of a cylinder of the family.
  double longest_half() const {
    return through() ? 0.5 * through_length : radius.upper() * aspect_ratio.upper();
  }
  /// Largest bounding radius any inclusion of the family can have.
  double max_bounding_radius() const;
  /// Largest smallest-width of any inclusion (the least box size every inclusion passes through).
  double max_min_width() const;
  /// Volume of a mean-size inclusion's packing envelope over its core volume (1 unmodified).
  double envelope_ratio() const;
  /// One inclusion drawn from the family's laws, centred at `center` (`acg`: the tensor law's
  /// fitted ACG, so it is not fitted again for every draw).
  Shape draw(const Vec3& center, Random& rng, const AcgLaw* acg = nullptr) const;
};

/// Settings of the molecular-dynamics packer (see packing.hpp).
struct MdSettings {
  long long max_steps = 2000000;
  double max_seconds = 600.0;
  /// Initial pressure m (force scale / valid scale - 1) and the steps over which a stalled
  /// valid scale halves it: more patience means slower compression and denser jamming.
  double pressure = 0.05;
  int patience = 100;
  /// A jam near the target is compressed again from the best configuration with every body
  /// moved by up to `shake` times its radius (its bounding capsule's) in a random direction and
  /// turned about a random axis so that its ends move up to as far (0: compressed again as it
  /// jammed, unmoved). Unset: kChainShake for scenes with wavy or bent fibres, 0 otherwise (a
  /// shaken dense sphere packing reaches its target more slowly). See md.cpp.
  std::optional<double> shake;
  static constexpr double kChainShake = 0.3;
  /// How contact torques may turn inclusions with an axis (JSON md.rotation):
  ///  kKeepTensor ("keep_tensor", default): they turn (never out of a plane or line the law
  ///    confines them to), and after every step one linear map of all the family's axes restores
  ///    the law's orientation tensor A2, so every configuration the packer keeps has A2 exactly;
  ///  kFixed ("fixed"): every inclusion keeps its drawn orientation (translation only);
  ///  kFree ("free"): the paper's free turning; A2 drifts (the report gives the obtained one).
  enum class Rotation { kKeepTensor, kFixed, kFree };
  Rotation rotation = Rotation::kKeepTensor;
};

/// The packing method: molecular dynamics (the default) or random sequential adsorption.
enum class Method { kMd, kRsa };
/// Its JSON name: "md", "rsa".
const char* method_name(Method method);

/// What the packing depends on, and nothing else: the same PackingSpec gives the same inclusions
/// (the VTK source caches its packing under this part alone).
struct PackingSpec {
  Box box;
  uint64_t seed = 42;
  Method method = Method::kMd;
  double min_gap = 0.0;
  std::vector<Family> families;
  /// RSA: attempts per inclusion before the target is declared out of reach.
  int rsa_max_attempts = 20000;
  /// RSA: time budget in seconds.
  double rsa_max_seconds = 600.0;
  MdSettings md;

  /// Expected number of inclusions of family f (its count, or volume fraction / mean volume).
  double expected_count(int f) const;
  /// Expected total volume fraction.
  double expected_volume_fraction() const;
};

/// Which files a run writes (JSON "outputs": a list of the names below). report.json always.
/// By default one voxel file (the compressed voxels.vti); rve.h5 and material.vtk, the same
/// image again, are written on request.
struct Outputs {
  bool inclusions = true;  // "inclusions": inclusions.json and inclusions.vtp (points, glyphs)
  bool voxels = true;      // "voxels": voxels.vti (zlib-compressed)
  bool h5 = false;         // "h5": rve.h5 and rve.xdmf
  bool amitex = false;     // "amitex": material.vtk
  bool levelsets = true;   // "levelsets": levelsets.vdb (wavy, bent and deformed inclusions)
  /// "levelsets" named in the outputs: the shells of straight coated inclusions get grids too
  /// (exact in closed form: by default they get none)
  bool levelsets_asked = false;
  bool mesh = false;  // "mesh": surfaces.vtp of every inclusion (else of the modified ones)
  /// "mesh_voxel": mesh_voxel.inp (8-node hexahedra, one per voxel, periodic node sets) and
  /// the CalculiX/Abaqus decks run_voxel_*.inp with periodic equations
  bool mesh_voxel = false;
  /// "mesh_tet": mesh_tet.inp and mesh_tet.vtu, a conforming periodic tetrahedral mesh (plain
  /// spheres and cylinders)
  bool mesh_tet = false;
  /// "statistics": g(r) of the sphere families and the nearest-neighbour distances in
  /// report.json (the costly part of the report)
  bool statistics = true;
  bool operator==(const Outputs& o) const {
    return inclusions == o.inclusions && voxels == o.voxels && h5 == o.h5 && amitex == o.amitex &&
           levelsets == o.levelsets && levelsets_asked == o.levelsets_asked && mesh == o.mesh &&
           mesh_voxel == o.mesh_voxel && mesh_tet == o.mesh_tet && statistics == o.statistics;
  }
  /// A voxel image is computed when one of its files is asked for.
  bool image() const { return voxels || h5 || amitex || mesh_voxel; }
};

/// Properties of one phase (kNotGiven: not given; no JSON number reads as it, so a value a user
/// gives, -1 included, is always checked as given). Isotropic conductivity and isotropic
/// elasticity (Young's modulus, Poisson's ratio); for a family's cores, transversely isotropic
/// alternatives about each inclusion's own axis (the fibre axis, an ellipsoid's longest one).
struct Material {
  static constexpr double kNotGiven = -std::numeric_limits<double>::infinity();
  static bool given(double v) { return v != kNotGiven; }
  double conductivity = kNotGiven;
  double young = kNotGiven;
  double poisson = kNotGiven;
  double axial_conductivity = kNotGiven, transverse_conductivity = kNotGiven;
  double axial_young = kNotGiven, transverse_young = kNotGiven, axial_shear = kNotGiven;
  double axial_poisson = kNotGiven, transverse_poisson = kNotGiven;
  bool transverse_conduction() const { return axial_conductivity >= 0.0; }
  bool transverse_elasticity() const { return axial_young >= 0.0; }
  bool conducts() const { return conductivity >= 0.0 || transverse_conduction(); }
  bool elastic() const { return young >= 0.0 || transverse_elasticity(); }
};

/// What `rvegen generate` computes of the packed RVE's effective properties (JSON
/// "homogenization"); nothing unless a physics is asked for.
struct HomogenizationSpec {
  bool conductivity = false;
  bool elasticity = false;
  std::string scheme = "rotated";  // "rotated" (Willot), "moulinec_suquet"
  std::string solver = "cg";       // "cg", "fixed_point" (conductivity only)
  double tolerance = 1e-6;
  int max_iterations = 1000;
  /// Voxels cut by a core surface: "laminate" (exact normal and share), "voigt", "reuss",
  /// "plain" (the phase at the voxel centre).
  std::string voxel_rule = "laminate";
  /// Write the local fields of every load case into rve.h5 (needs the h5 output).
  bool fields = false;
  bool any() const { return conductivity || elasticity; }
};

/// The element sizes of the conforming tetrahedral mesh (JSON "mesh_tet").
struct TetMeshSpec {
  /// Largest element size; 0: a tenth of the smallest box side.
  double max_size = 0.0;
  /// Least element size (where gaps are thinner than it, elements do not follow); 0: a
  /// fiftieth of the smallest inclusion size (radius, or half length if shorter).
  double min_size = 0.0;
  /// Chord error allowed against each inclusion's surface, relative to its least radius of
  /// curvature: the element size near a surface of radius rho is at most rho sqrt(8 chord).
  double chord_error = 0.003;
  /// Elements across the gap between two surfaces.
  double gap_elements = 2.0;
  /// The mesh's cell may be the box moved along its axes (the same periodic medium), so that no
  /// box face grazes an inclusion (a thin cap bounds its elements' angles); false: the box.
  bool shift_cell = true;
  /// With shift_cell, inclusions that every cell's faces would still graze (dense scenes: long
  /// fibres nearly along a face) move off them by a few of their sizes at most before anything is
  /// written, where there is room (nudge_off_cell; report.json's mesh_tet.nudged_inclusions);
  /// false: they stay where the packer put them.
  bool nudge = true;
  /// The nodes inside curved interfaces move along the surface's normal so that each phase keeps
  /// its exact volume (the facets, chords of the surface, would cut it short by about three
  /// times the chord error); false: every interface node on the exact surface.
  bool keep_volumes = true;
  /// Element order: 1 for 4-node tetrahedra (C3D4), 2 for 10-node ones (C3D10: a node at the
  /// middle of each edge, the edges straight).
  int order = 1;
  /// The volume mesher's optimiser improves the elements whose quality (Gmsh's aspect ratio,
  /// from 0 for a flat element to 1 for a regular one) is under this; 0.3, Gmsh's own default.
  /// Lower is faster and leaves more elements of middling quality (0: no optimisation).
  double optimize_threshold = 0.3;
  /// The same mesh, node for node and element for element, on every run: the volumes by Gmsh's
  /// Delaunay mesher (one thread; slower, more elements) instead of HXT, whose nodes come out in
  /// another order, and so other elements, from run to run.
  bool reproducible = false;
  /// The largest element size in `box`: max_size, or a tenth of the box's smallest side.
  double largest_size(const Box& box) const {
    return max_size > 0.0 ? max_size : box.size.minCoeff() / 10.0;
  }
  bool operator==(const TetMeshSpec& o) const {
    return max_size == o.max_size && min_size == o.min_size && chord_error == o.chord_error &&
           gap_elements == o.gap_elements && shift_cell == o.shift_cell && nudge == o.nudge &&
           keep_volumes == o.keep_volumes && order == o.order &&
           optimize_threshold == o.optimize_threshold && reproducible == o.reproducible;
  }
};

/// What only the representations of a packed set depend on.
struct OutputSpec {
  Outputs outputs;
  std::array<int, 3> resolution = {64, 64, 64};
  /// Voxel image: partial volumes ("fraction") and the subsamples per axis of boundary voxels.
  bool partial_volume = true;
  int subsamples = 4;
  /// Level sets: voxel size (0: smallest box size / 256) and narrow-band half width in voxels.
  double levelset_voxel_size = 0.0;
  double levelset_half_width = 3.0;
  /// Surfaces: cut periodic images at the box faces.
  bool clip_surfaces = false;
  /// Surfaces: largest distance between a tessellated surface and the true one, in voxels of
  /// the image (the smallest voxel size); each inclusion gets the segments this needs.
  double surface_chord_error = 0.1;
  /// Phase properties keyed by "matrix", a family's name, or "<family name>.coating" (JSON
  /// "materials"), and what to compute with them.
  std::vector<std::pair<std::string, Material>> materials;
  HomogenizationSpec homogenization;
  TetMeshSpec tet_mesh;
  /// The material given for "matrix", a family's name or "<family name>.coating"; null when
  /// the scene gives none.
  const Material* material(const std::string& key) const;
};

/// A whole scene: the packing and the outputs.
struct Scene : PackingSpec, OutputSpec {};

/// Checks every field and the cross-field constraints of a scene, however it was built (file,
/// VTK properties, code); parse_scene runs it too. Throws InputError naming the key.
void validate_scene(const Scene& scene);
/// The part of validate_scene that checks "mesh_tet" against the box (for callers that set
/// only those, such as the VTK filter).
void validate_tet_mesh_spec(const Scene& scene);
/// The part of validate_scene that checks "materials" and "homogenization" against the
/// scene's families (for callers that build only those, such as the VTK filter).
void validate_homogenization(const Scene& scene);
/// The "materials" key of a phase of the scene's image: "matrix", the family's name, or
/// "<family>.coating" for its interphase (a void's family name; it carries nothing).
std::string material_key(const Scene& scene, const Phase& phase);
/// The built-in default scene.
Scene default_scene();

/// Upper bound on the volume fraction that the scene's shapes can fill: the densest known
/// packing of the best-packing shape among the families: spheres pi/(3 sqrt 2) = 0.7405
/// (Kepler), ellipsoids 0.7707 (Donev et al. 2004), cylinders pi/(2 sqrt 3) = 0.9069 (aligned,
/// hexagonal). A target above it is rejected as invalid input before any work.
double max_packable_fraction(const PackingSpec& scene);

/// The inclusions a scene asks for, drawn from its laws (deterministic in scene.seed), centres
/// not yet placed; `shape` is each core, `mod` its modifiers (drawn from a second stream, so
/// adding a modifier does not change the cores). A `volume_fraction` family draws inclusions until
/// the next one would take the family's volume further from its target than stopping, so the drawn
/// volume is the target to within half an inclusion. The axes of each oriented family are then
/// corrected (match_orientation_tensor) so their <p p^T> is the law's tensor() exactly.
std::vector<Inclusion> draw_population(const PackingSpec& scene, Random& rng);

}  // namespace rvegen
