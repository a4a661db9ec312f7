#include "rvegen/io/amitex.hpp"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <map>
#include <sstream>
#include <vector>

#include "rvegen/io/writers.hpp"
#include "rvegen/model/elastic_constants.hpp"

namespace rvegen {

namespace {

// Zone of each voxel's inclusion within its core material: per family, the ids present in
// the image's core voxels, numbered 1.. in id order. Returns the zone per voxel.
std::vector<uint32_t> zones(const VoxelImage& image, std::map<int, std::vector<int>>* ids) {
  std::vector<char> core(image.phases.size(), 0);
  for (const Phase& p : image.phases) core[p.label] = p.kind == PhaseKind::kCore;
  for (size_t v = 0; v < image.phase.size(); ++v) {
    if (core[image.phase[v]]) (*ids)[image.phase[v]].push_back(image.inclusion_id[v]);
  }
  std::map<int, std::map<int, uint32_t>> zone_of;
  for (auto& [label, list] : *ids) {
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
    for (size_t k = 0; k < list.size(); ++k) zone_of[label][list[k]] = static_cast<uint32_t>(k + 1);
  }
  std::vector<uint32_t> z(image.phase.size(), 1);
  for (size_t v = 0; v < image.phase.size(); ++v) {
    if (core[image.phase[v]]) z[v] = zone_of[image.phase[v]][image.inclusion_id[v]];
  }
  return z;
}

}  // namespace

void write_zone_vtk(const VoxelImage& im, std::FILE* out) {
  std::map<int, std::vector<int>> ids;
  const std::vector<uint32_t> z = zones(im, &ids);
  size_t most = 1;
  for (const auto& [label, list] : ids) most = std::max(most, list.size());
  write_legacy_cells(
      im, "Zones", "ZoneId", most > 65535, [&](size_t v) { return z[v]; }, out);
}

std::string amitex_materials_xml(const Scene& scene, const InclusionSet& set,
                                 const VoxelImage& image) {
  const std::vector<uint16_t> id = amitex_material_ids(image);
  std::map<int, std::vector<int>> ids;
  zones(image, &ids);
  std::map<int, const Inclusion*> by_id;
  for (const Inclusion& inc : set.inclusions) by_id[inc.id] = &inc;
  std::ostringstream x;
  x.precision(17);
  // Lame coefficients of the isotropic phases, for the reference material (the mean of the
  // extremes, Moulinec and Suquet's choice; with convergence acceleration it matters little).
  double lmin = 1e300, lmax = 0.0, mmin = 1e300, mmax = 0.0;
  auto lame = [](const Material& m, double* l, double* mu) {
    *l = m.young * m.poisson / ((1.0 + m.poisson) * (1.0 - 2.0 * m.poisson));
    *mu = m.young / (2.0 * (1.0 + m.poisson));
  };
  for (const Phase& p : image.phases) {
    const Material* m = id[p.label] ? scene.material(material_key(scene, p)) : nullptr;
    if (!m || m->young < 0.0) continue;
    double l, mu;
    lame(*m, &l, &mu);
    lmin = std::min(lmin, l), lmax = std::max(lmax, l);
    mmin = std::min(mmin, mu), mmax = std::max(mmax, mu);
  }
  x << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<!-- Written by rvegen for material.vtk and "
       "zoneID.vtk; run with amitex_run.sh. -->\n<Materials>\n";
  if (lmax > 0.0 || mmax > 0.0) {
    x << "  <Reference_Material Lambda0=\"" << 0.5 * (lmin + lmax) << "\" Mu0=\""
      << 0.5 * (mmin + mmax) << "\"/>\n";
  } else {
    x << "  <Reference_Material Lambda0=\"FILL_IN\" Mu0=\"FILL_IN\"/>\n";
  }
  for (const Phase& p : image.phases) {
    if (!id[p.label]) continue;
    const std::string key = material_key(scene, p);
    const Material* m = scene.material(key);
    x << "  <!-- " << p.name << " (materials." << key << ") -->\n";
    if (m && m->transverse_elasticity() && p.kind == PhaseKind::kCore) {
      // elasaniso: C11 C12 C13 C22 C23 C33 C44 C55 C66 in the fibre frame (1 = the fibre's
      // axis), in AMITEX's component order xx yy zz xy xz yz (so C44, C55 and C66 are the
      // shear moduli of the planes 12, 13 and 23), then the frame's e1 and e2, one zone per
      // fibre.
      const auto c = transverse_voigt_stiffness(m->axial_young, m->transverse_young, m->axial_shear,
                                                m->axial_poisson, m->transverse_poisson, 0);
      // c is in the order 23, 13, 12 for its shear rows.
      const double coeff[9] = {c(0, 0), c(0, 1), c(0, 2), c(1, 1), c(1, 2),
                               c(2, 2), c(5, 5), c(4, 4), c(3, 3)};
      x << "  <Material numM=\"" << id[p.label] << "\" Lib=\"\" Law=\"elasaniso\">\n";
      for (int k = 0; k < 9; ++k) {
        x << "    <Coeff Index=\"" << k + 1 << "\" Type=\"Constant\" Value=\"" << coeff[k]
          << "\"/>\n";
      }
      const std::vector<int>& list = ids[p.label];
      std::vector<Vec3> e1(list.size()), e2(list.size());
      for (size_t z = 0; z < list.size(); ++z) {
        const Inclusion* inc = by_id.count(list[z]) ? by_id[list[z]] : nullptr;
        const Vec3 a = inc ? principal_axis(inc->shape) : Vec3::UnitX();
        e1[z] = a.norm() > 0.0 ? a.normalized() : Vec3::UnitX();
        e2[z] = e1[z].unitOrthogonal();
      }
      for (int k = 0; k < 6; ++k) {
        x << "    <Coeff Index=\"" << 10 + k << "\" Type=\"Constant_Zone\">";
        for (size_t z = 0; z < list.size(); ++z) {
          const Vec3& v = k < 3 ? e1[z] : e2[z];
          x << "<Zone numZ=\"" << z + 1 << "\" Value=\"" << v[k % 3] << "\"/>";
        }
        x << "</Coeff>\n";
      }
      x << "  </Material>\n";
      continue;
    }
    x << "  <Material numM=\"" << id[p.label] << "\" Lib=\"\" Law=\"elasiso\">\n";
    if (p.kind == PhaseKind::kVoid) {
      x << "    <!-- a debonding void: no stiffness -->\n";
      x << "    <Coeff Index=\"1\" Type=\"Constant\" Value=\"0\"/>\n";
      x << "    <Coeff Index=\"2\" Type=\"Constant\" Value=\"0\"/>\n";
    } else if (m && m->young >= 0.0) {
      double l, mu;
      lame(*m, &l, &mu);
      x << "    <Coeff Index=\"1\" Type=\"Constant\" Value=\"" << l << "\"/>\n";
      x << "    <Coeff Index=\"2\" Type=\"Constant\" Value=\"" << mu << "\"/>\n";
    } else {
      x << "    <!-- no young and poisson for \"" << key << "\" in the scene's materials -->\n";
      x << "    <Coeff Index=\"1\" Type=\"Constant\" Value=\"FILL_IN\"/>\n";
      x << "    <Coeff Index=\"2\" Type=\"Constant\" Value=\"FILL_IN\"/>\n";
    }
    x << "  </Material>\n";
  }
  x << "</Materials>\n";
  return x.str();
}

namespace {

// Loadings of one increment each, component `load` of the mean driving quantity going to
// `unit` in loading `load`, the others back to 0; `output` the vtk output element.
std::string unit_loadings_xml(const char* comment, const char* output,
                              const std::vector<const char*>& comp, const char* driving,
                              const char* unit) {
  std::ostringstream x;
  x << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<!-- " << comment
    << " -->\n<Loading_Output>\n  <Output>\n    " << output << "\n  </Output>\n";
  for (size_t load = 0; load < comp.size(); ++load) {
    x << "  <Loading Tag=\"" << load + 1 << "\">\n";
    x << "    <Time_Discretization Discretization=\"Linear\" Nincr=\"1\" Tfinal=\"" << load + 1
      << "\"/>\n";
    for (size_t c = 0; c < comp.size(); ++c) {
      x << "    <" << comp[c] << " Driving=\"" << driving << "\" Evolution=\"Linear\" Value=\""
        << (c == load ? unit : "0") << "\"/>\n";
    }
    x << "  </Loading>\n";
  }
  x << "</Loading_Output>\n";
  return x.str();
}

}  // namespace

std::string amitex_loading_xml() {
  return unit_loadings_xml(
      "Six unit mean strains (1e-3; shear in Voigt form, xy = 2 eps_xy), one increment each: "
      "column k of the stiffness is the mean stress at the end of loading k over 1e-3 (rvegen "
      "reports it in Mandel form: shear rows and columns times sqrt 2).",
      "<vtk_StressStrain Strain=\"0\" Stress=\"0\"/>", {"xx", "yy", "zz", "xy", "xz", "yz"},
      "Strain", "1e-3");
}

std::string amitex_algorithm_xml() {
  return "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
         "<Algorithm_Parameters>\n"
         "  <Algorithm Type=\"Basic_Scheme\">\n"
         "    <Convergence_Criterion Value=\"Default\"/>\n"
         "    <Convergence_Acceleration Value=\"true\"/>\n"
         "  </Algorithm>\n"
         "  <Mechanics>\n"
         "    <Filter Type=\"Default\"/>\n"
         "    <Small_Perturbations Value=\"true\"/>\n"
         "  </Mechanics>\n"
         "</Algorithm_Parameters>\n";
}

bool amitex_conductivity_wanted(const Scene& scene) {
  for (const auto& [key, m] : scene.materials) {
    if (m.conducts()) return true;
  }
  return false;
}

std::string amitex_conductivity_materials_xml(const Scene& scene, const VoxelImage& image) {
  const std::vector<uint16_t> id = amitex_material_ids(image);
  std::ostringstream x;
  x.precision(17);
  // The reference conductivity: the mean of the extremes, as for the elastic reference.
  double kmin = 1e300, kmax = 0.0;
  for (const Phase& p : image.phases) {
    const Material* m = id[p.label] ? scene.material(material_key(scene, p)) : nullptr;
    if (p.kind == PhaseKind::kVoid || !m || m->conductivity < 0.0) continue;
    kmin = std::min(kmin, m->conductivity), kmax = std::max(kmax, m->conductivity);
  }
  x << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<!-- Written by rvegen for material.vtk; "
       "AMITEX's stationary diffusion, run with amitex_run.sh. -->\n<Materials>\n";
  if (kmax > 0.0) {
    x << "  <Reference_MaterialD K0=\"" << 0.5 * (kmin + kmax) << "\"/>\n";
  } else {
    x << "  <Reference_MaterialD K0=\"FILL_IN\"/>\n";
  }
  for (const Phase& p : image.phases) {
    if (!id[p.label]) continue;
    const std::string key = material_key(scene, p);
    const Material* m = scene.material(key);
    x << "  <!-- " << p.name << " (materials." << key << ") -->\n";
    x << "  <Material numM=\"" << id[p.label] << "\" LibK=\"\" LawK=\"Fourier_iso\">\n";
    if (p.kind == PhaseKind::kVoid) {
      x << "    <!-- a debonding void: no conduction -->\n";
      x << "    <CoeffK Index=\"1\" Type=\"Constant\" Value=\"0\"/>\n";
    } else if (m && m->conductivity >= 0.0) {
      x << "    <CoeffK Index=\"1\" Type=\"Constant\" Value=\"" << m->conductivity << "\"/>\n";
    } else {
      x << "    <!-- "
        << (m && m->transverse_conduction()
                ? "transversely isotropic: give an anisotropic Fourier law by hand"
                : "no conductivity for \"" + key + "\" in the scene's materials")
        << " -->\n";
      x << "    <CoeffK Index=\"1\" Type=\"Constant\" Value=\"FILL_IN\"/>\n";
    }
    x << "  </Material>\n";
  }
  x << "</Materials>\n";
  return x.str();
}

std::string amitex_conductivity_loading_xml() {
  return unit_loadings_xml(
      "Three unit mean gradients, one increment each: column k of the conductivity is the mean "
      "flux at the end of loading k (its sign as AMITEX writes Fourier's law).",
      "<vtk_FluxDGradD FluxD=\"0\" GradD=\"0\"/>", {"x0", "y0", "z0"}, "GradD", "1");
}

std::string amitex_conductivity_algorithm_xml() {
  return "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
         "<Algorithm_Parameters>\n"
         "  <Algorithm Type=\"Basic_Scheme\">\n"
         "    <Convergence_Criterion Value=\"Default\"/>\n"
         "    <Convergence_Acceleration Value=\"true\"/>\n"
         "  </Algorithm>\n"
         "  <Diffusion>\n"
         "    <Filter Type=\"Default\"/>\n"
         "    <Stationary Value=\"true\"/>\n"
         "  </Diffusion>\n"
         "</Algorithm_Parameters>\n";
}

std::string amitex_run_sh(const Scene& scene) {
  bool elastic = scene.materials.empty();
  for (const auto& [key, m] : scene.materials) elastic = elastic || m.elastic();
  std::string s =
      "#!/bin/sh\n"
      "# AMITEX_FFTP on this RVE: sh amitex_run.sh (MPIRUN=\"mpirun -np 4\" to choose the\n"
      "# launcher). Mean stresses per loading end up in amitex_out/rve.std";
  s += amitex_conductivity_wanted(scene) ? ", mean fluxes in\n# amitex_out/conductivity.std.\n"
                                         : ".\n";
  s += "set -e\ncd \"$(dirname \"$0\")\"\nmkdir -p amitex_out\n";
  if (elastic) {
    s += "${MPIRUN:-mpirun -np 2} amitex_fftp -nm material.vtk -nz zoneID.vtk "
         "-m amitex_materials.xml -c amitex_loading.xml -a amitex_algorithm.xml "
         "-s amitex_out/rve\n";
  }
  if (amitex_conductivity_wanted(scene)) {
    s += "${MPIRUN:-mpirun -np 2} amitex_fftp -nm material.vtk "
         "-m amitex_conductivity_materials.xml -c amitex_conductivity_loading.xml "
         "-a amitex_conductivity_algorithm.xml -s amitex_out/conductivity\n";
  }
  return s;
}

}  // namespace rvegen
