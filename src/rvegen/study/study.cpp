#include "rvegen/study/study.hpp"

#include <fcntl.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>

#include "rvegen/homogenize/effective.hpp"
#include "rvegen/io/json_util.hpp"
#include "rvegen/io/report.hpp"
#include "rvegen/io/scene_json.hpp"
#include "rvegen/io/writers.hpp"
#include "rvegen/model/errors.hpp"
#include "rvegen/model/phases.hpp"
#include "rvegen/model/representativity.hpp"
#include "rvegen/model/resources.hpp"
#include "rvegen/model/stats.hpp"
#include "rvegen/packing/packing.hpp"
#include "rvegen/raster/voxelize.hpp"

namespace rvegen {

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;

namespace {

// A record is a few kilobytes (tens of properties): far larger ones are not the study's.
constexpr size_t kMaxRecordBytes = size_t(1) << 20;
constexpr size_t kMaxRecordProperties = 1000;

// A realization's seed from the scene's, the size and the realization's number: the same
// realization always gets the same seed, however many are asked for.
uint64_t realization_seed(uint64_t seed, double size, int k) {
  uint64_t x = seed ^ (static_cast<uint64_t>(std::llround(size * 1e6)) * 0x9E3779B97F4A7C15ull) ^
               (static_cast<uint64_t>(k) << 32);
  x += 0x9E3779B97F4A7C15ull;  // splitmix64
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return (x ^ (x >> 31)) & ((uint64_t(1) << 53) - 1);  // exact in a JSON number
}

std::string size_name(double m) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g", m);
  return buf;
}

// The scene at edge multiple m: box and counts scaled, voxel size kept.
Scene scaled_scene(const Scene& base, double m, uint64_t seed) {
  Scene s = base;
  s.seed = seed;
  s.box.size = base.box.size * m;
  const double v = m * m * m;
  for (size_t f = 0; f < s.families.size(); ++f) {
    auto& fam = s.families[f];
    if (fam.count > 0) {
      const double c = std::round(fam.count * v);
      if (c < 1.0 || c > 1e8) {
        throw InputError("families[" + std::to_string(f) + "].count: " + std::to_string(fam.count) +
                         " at size " + size_name(m) + " gives " + size_name(c) +
                         " inclusions (must be in [1, 1e8])");
      }
      fam.count = static_cast<int>(c);
    }
  }
  for (int a = 0; a < 3; ++a) {
    s.resolution[a] = std::max(1, static_cast<int>(std::lround(base.resolution[a] * m)));
  }
  validate_scene(s);
  return s;
}

std::string family_label(const InclusionSet& set, int f) {
  if (f < static_cast<int>(set.family_names.size()) && !set.family_names[f].empty())
    return set.family_names[f];
  return "family " + std::to_string(f);
}

// Windows of the window method: edges of at least this many of the largest bounding radius
// (the integral range's law holds for windows past the correlation length, and the fit takes
// out the first surface term only), and of at least kWindowVoxels voxels.
constexpr double kWindowEdgeInRadii = 12.0;
constexpr int kWindowVoxels = 4;

// The k (windows per axis, k^3 windows) that cut the scene's image into equal cubic windows
// large enough, from 2 up; none when fewer than two qualify, or the box is not a cube.
std::vector<int> window_counts(const Scene& scene) {
  std::vector<int> ks;
  const auto& n = scene.resolution;
  const double edge = scene.box.size[0];
  if (n[0] != n[1] || n[1] != n[2] || scene.box.size[1] != edge || scene.box.size[2] != edge)
    return ks;
  double r = 0.0;
  for (const Family& f : scene.families) r = std::max(r, f.max_bounding_radius());
  for (int k = 2; k <= n[0] / kWindowVoxels; ++k) {
    if (n[0] % k == 0 && edge / k >= kWindowEdgeInRadii * r) ks.push_back(k);
  }
  if (ks.size() < 2) ks.clear();
  return ks;
}

// The properties of one realization, by name.
// The window method's variances go to `windows` (a list of [k, volume, windows, variance,
// mean]).
json realization_properties(const Scene& scene, const PackingResult& r, json* windows,
                            std::string* not_converged) {
  json p = json::object();
  const InclusionSet& set = r.set;
  const int nf = static_cast<int>(scene.families.size());
  const std::vector<double> fam = family_volume_fractions(set, nf);
  double total = 0.0;
  for (double v : fam) total += v;
  p["volume_fraction"] = total;
  const std::vector<Phase> phases = phase_table(set);
  const std::vector<double> exact = phase_volume_fractions(set, phases);
  for (const Phase& ph : phases) {
    if (ph.kind == PhaseKind::kMatrix) continue;
    p["volume_fraction." + ph.name] = exact[ph.label];
  }
  VoxelOptions vopt;
  vopt.partial_volume = scene.partial_volume;
  vopt.subsamples = scene.subsamples;
  const VoxelImage image = voxelize(set, scene.resolution, vopt);
  const std::vector<double> voxel = label_fractions(image);
  for (const Phase& ph : phases) {
    if (ph.kind == PhaseKind::kMatrix || ph.label >= static_cast<int>(voxel.size())) continue;
    p["voxel_fraction." + ph.name] = voxel[ph.label];
  }
  // The window method's variances of the inclusions' share (the cores' partial volumes when
  // the scene asks for them, else the core labels), for windows of at least kWindowEdgeInRadii
  // bounding radii.
  const std::vector<int> ks = window_counts(scene);
  if (!ks.empty()) {
    std::vector<float> field = image.fraction;
    if (field.empty()) {
      field.resize(image.phase.size());
      for (size_t i = 0; i < field.size(); ++i)
        field[i] = image.phases[image.phase[i]].kind == PhaseKind::kCore ? 1.0f : 0.0f;
    }
    const Vec3 h = image.spacing;
    json w = json::array();
    for (const WindowVariance& v : window_variances(field, image.dims, h.x() * h.y() * h.z(), ks)) {
      w.push_back({v.k, v.volume, v.windows, v.variance, v.mean});
    }
    (*windows)["volume_fraction"] = w;
  }
  // Orientation tensors of the fibre and ellipsoid families (diagonal), as the report has them.
  for (int f = 0; f < nf; ++f) {
    bool oriented = false;
    for (const Inclusion& inc : set.inclusions) {
      oriented = oriented || (inc.family == f && inc.shape.kind != ShapeKind::Sphere);
    }
    if (!oriented) continue;
    const Mat3 a = orientation_tensor(set, f);
    const std::string name = "orientation." + family_label(set, f);
    p[name + ".a11"] = a(0, 0);
    p[name + ".a22"] = a(1, 1);
    p[name + ".a33"] = a(2, 2);
  }
  // The report's statistics: the nearest-neighbour distance, and for sphere families g(r)
  // summarised by its first peak (the height and where it is: the contact shell of a dense
  // packing).
  const ReportStatistics st = report_statistics(scene, r);
  if (st.nearest.n > 0) p["nearest_neighbour.mean"] = st.nearest.mean;
  for (int f = 0; f < nf; ++f) {
    const RadialDistribution& g = st.radial[f];
    if (g.g.empty()) continue;
    const size_t peak = static_cast<size_t>(std::max_element(g.g.begin(), g.g.end()) - g.g.begin());
    p["radial_distribution." + family_label(set, f) + ".peak"] = g.g[peak];
    p["radial_distribution." + family_label(set, f) + ".peak_r"] = g.r[peak];
  }
  if (scene.homogenization.any()) {
    const EffectiveProperties e = effective_properties(scene, set, image);
    *not_converged = unconverged(e, scene.homogenization.tolerance);
    if (e.has_conductivity) {
      const Mat3& k = e.conductivity.tensor;
      p["conductivity.k11"] = k(0, 0);
      p["conductivity.k22"] = k(1, 1);
      p["conductivity.k33"] = k(2, 2);
      p["conductivity.mean"] = k.trace() / 3.0;
    }
    if (e.has_stiffness) {
      p["stiffness.bulk"] = e.bulk;
      p["stiffness.shear"] = e.shear;
      p["stiffness.c11"] = e.stiffness.stiffness(0, 0);
    }
  }
  return p;
}

}  // namespace

void write_whole(const fs::path& path, const std::string& text) {
  // A ".part" left there (a file, or a link planted in its place) is removed, never followed:
  // the text goes into a new regular file, which then replaces `path` itself (a link there
  // included, not what it points to).
  const fs::path tmp = path.string() + ".part";
  ::unlink(tmp.c_str());
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0666);
  if (fd < 0) throw OutputError("cannot write " + tmp.string() + ": " + std::strerror(errno));
  size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = errno;
      ::close(fd);
      throw OutputError("cannot write " + tmp.string() + ": " + std::strerror(err));
    }
    done += static_cast<size_t>(n);
  }
  if (::close(fd) != 0)
    throw OutputError("cannot write " + tmp.string() + ": " + std::strerror(errno));
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) throw OutputError("cannot write " + path.string() + ": " + ec.message());
}

namespace {

std::vector<double> parse_sizes_impl(const std::string& text) {
  std::vector<double> out;
  size_t at = 0;
  while (at <= text.size()) {
    const size_t comma = std::min(text.find(',', at), text.size());
    const std::string item = text.substr(at, comma - at);
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    if (item.empty() || *end != '\0' || !std::isfinite(v) || v <= 0.0 || v > 100.0) {
      throw InputError("--sizes: \"" + item + "\" is not an edge multiple in (0, 100]");
    }
    out.push_back(v);
    at = comma + 1;
  }
  std::sort(out.begin(), out.end());
  for (size_t i = 1; i < out.size(); ++i) {
    if (size_name(out[i]) == size_name(out[i - 1]))
      throw InputError("--sizes: " + size_name(out[i]) + " is given twice");
  }
  return out;
}

// The window method's answer for the inclusions' share, from the largest size whose
// realizations have windows: the pooled variances, the integral range fitted with its surface
// term, and the volume at which n realizations give phi to the target relative error.
json window_summary(const std::vector<std::vector<std::vector<WindowVariance>>>& windows,
                    const std::vector<double>& sizes, double phi, double target_error, int n) {
  for (size_t i = sizes.size(); i-- > 0;) {
    if (windows[i].empty()) continue;
    const std::vector<WindowVariance> pooled = pool_window_variances(windows[i]);
    const WindowIntegralRange r = window_integral_range(pooled, phi);
    json out;
    out["size"] = sizes[i];
    out["realizations"] = windows[i].size();
    out["mean"] = pooled.empty() ? 0.0 : pooled.front().mean;  // of the voxel shares
    json rows = json::array();
    for (const WindowVariance& v : pooled) {
      rows.push_back(
          {{"k", v.k}, {"volume", v.volume}, {"windows", v.windows}, {"variance", v.variance}});
    }
    out["per_window"] = rows;
    out["law"] = "V D^2(V) = phi (1 - phi) (A3 - b / L), L the window edge";
    if (r.fitted && r.integral_range > 0.0) {
      out["integral_range"] = r.integral_range;
      out["surface_term"] = r.surface_term;
      // 2 sqrt(phi (1 - phi) A3 / V) / (phi sqrt n) = target error.
      out["volume_for_target"] = 4.0 * (1.0 - phi) * r.integral_range /
                                 (phi * target_error * target_error * static_cast<double>(n));
    }
    return out;
  }
  return json();
}

// A record's digest: FNV-1a (64 bits) of its text without the digest, keyed by the study's
// scene, so that a record edited by hand, or copied from another study, is found.
std::string record_digest(json rec, const std::string& signature) {
  rec.erase("digest");
  uint64_t h = 0xcbf29ce484222325ull;
  for (const std::string& body : {signature, rec.dump()}) {
    for (unsigned char c : body) h = (h ^ c) * 0x100000001b3ull;
  }
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

// The record of realization k of the box size factor m.
std::string record_file(double m, int k) {
  return "size_" + size_name(m) + "_" + std::to_string(k) + ".json";
}

// The records of a study's realizations, read back for its statistics.
struct StudyRecords {
  std::map<std::string, std::vector<std::vector<double>>> values;  // property -> size -> values
  std::vector<std::string> order;  // properties in the order first met
  std::vector<int> not_reached;    // per size: realizations that missed their target
  std::vector<int> not_converged;  // per size: realizations whose homogenization did not converge
  // The window method's variances of the inclusions' share: size -> realization -> k.
  std::vector<std::vector<std::vector<WindowVariance>>> windows;
};

// Checks a record read back against what the study would have written there: its size,
// realization, seed and digest, a known status, and properties that are finite numbers in
// their ranges. Throws InputError naming the record and the key.
void check_record(const json& rec, const StudyPlan& plan, size_t i, int k, const fs::path& p) {
  auto bad = [&p](const std::string& what) {
    return InputError(p.string() + ": " + what + " (remove the record to compute it again)");
  };
  if (!rec.is_object()) throw bad("not a JSON object");
  auto number = [&](const char* key) {
    if (!rec.contains(key) || !rec[key].is_number()) throw bad(std::string(key) + ": not a number");
    return rec[key];
  };
  if (size_name(number("size").get<double>()) != size_name(plan.sizes[i]))
    throw bad("size: " + rec["size"].dump() + ", where the study expects " +
              size_name(plan.sizes[i]));
  const json& real = number("realization");
  if (!real.is_number_integer() || real.get<long long>() != k)
    throw bad("realization: " + real.dump() + ", where the study expects " + std::to_string(k));
  const json& seed = number("seed");
  const uint64_t want = realization_seed(plan.seed, plan.sizes[i], k);
  if (!seed.is_number_unsigned() || seed.get<uint64_t>() != want)
    throw bad("seed: " + seed.dump() + ", where the study draws " + std::to_string(want));
  if (!rec.contains("status") || !rec["status"].is_string()) throw bad("status: not a string");
  const std::string status = rec["status"].get<std::string>();
  if (status != "ok" && status != "target_not_reached" && status != "not_converged" &&
      status != "nothing_placed")
    throw bad("status: \"" + status + "\" is not a status the study writes");
  if (!rec.contains("digest") || !rec["digest"].is_string())
    throw bad("digest: missing (the study writes one in every record)");
  // The values first (an error names the one that is wrong), then the digest.
  const bool same = rec["digest"].get<std::string>() == record_digest(rec, plan.signature);
  if (status != "ok") {
    if (!same) throw bad("changed after the study wrote it (its digest does not match)");
    return;
  }
  if (!rec.contains("properties") || !rec["properties"].is_object())
    throw bad("properties: not an object");
  if (rec["properties"].size() > kMaxRecordProperties)
    throw bad("properties: " + std::to_string(rec["properties"].size()) +
              ", more than a study records (" + std::to_string(kMaxRecordProperties) + ")");
  for (auto it = rec["properties"].begin(); it != rec["properties"].end(); ++it) {
    const std::string& name = it.key();
    const std::string where = "properties." + name;
    if (!it.value().is_number() || !std::isfinite(it.value().get<double>()))
      throw bad(where + ": " + it.value().dump() + " is not a finite number");
    const double v = it.value().get<double>();
    auto starts = [&name](const char* prefix) { return name.rfind(prefix, 0) == 0; };
    const bool share =
        starts("volume_fraction") || starts("voxel_fraction") || starts("orientation.");
    if (share && !(v >= 0.0 && v <= 1.0))
      throw bad(where + ": " + it.value().dump() + " is not in [0, 1]");
    if ((starts("conductivity.") || starts("stiffness.")) && !(v > 0.0))
      throw bad(where + ": " + it.value().dump() + " is not positive");
    if (!share && !(v >= 0.0)) throw bad(where + ": " + it.value().dump() + " is negative");
  }
  if (rec.contains("windows")) {
    const json& w = rec["windows"];
    if (!w.is_object() || !w.contains("volume_fraction") || !w["volume_fraction"].is_array())
      throw bad("windows: not the study's window variances");
    for (const json& row : w["volume_fraction"]) {
      bool ok = row.is_array() && row.size() == 5 && row[0].is_number_integer() &&
                row[2].is_number_unsigned();
      for (size_t c = 0; ok && c < 5; ++c)
        ok = row[c].is_number() && std::isfinite(row[c].get<double>()) &&
             row[c].get<double>() >= 0.0;
      if (!ok)
        throw bad("windows.volume_fraction: " + row.dump() +
                  " is not [k, volume, windows, variance, mean]");
    }
  }
  if (!same) throw bad("changed after the study wrote it (its digest does not match)");
}

// Reads and checks the record of realization k of size i.
json read_record(const StudyPlan& plan, size_t i, int k) {
  const fs::path p = plan.rdir / record_file(plan.sizes[i], k);
  // A record is a regular file the study wrote: not a link to another file. Read strictly
  // first (keys given twice, depth, the JSON library's errors named plainly), then in the
  // order it was written, which its digest covers.
  std::error_code ec;
  if (fs::is_symlink(fs::symlink_status(p, ec)))
    throw InputError(p.string() +
                     " is not a realization record: a link, not a file the study "
                     "wrote (remove the record to compute it again)");
  json rec;
  try {
    const std::string text = read_file(p.string(), kMaxRecordBytes);
    json_util::parse(text, "the record");
    rec = json::parse(text);
  } catch (const std::exception& e) {
    throw InputError(p.string() + " is not a realization record: " + e.what() +
                     " (remove the record to compute it again)");
  }
  check_record(rec, plan, i, k, p);
  return rec;
}

// Reads the records of the realizations asked for (files beyond them are kept, not used);
// throws InputError naming a record that cannot be read.
StudyRecords read_records(const StudyPlan& plan) {
  const std::vector<double>& sizes = plan.sizes;
  StudyRecords r;
  r.not_reached.assign(sizes.size(), 0);
  r.not_converged.assign(sizes.size(), 0);
  r.windows.resize(sizes.size());
  for (size_t i = 0; i < sizes.size(); ++i) {
    for (int k = 0; k < plan.realizations; ++k) {
      const json rec = read_record(plan, i, k);
      const std::string status = rec.value("status", "");
      if (status != "ok") {
        ++(status == "not_converged" ? r.not_converged : r.not_reached)[i];
        continue;
      }
      for (auto it = rec["properties"].begin(); it != rec["properties"].end(); ++it) {
        auto& per = r.values[it.key()];
        if (per.empty()) {
          per.resize(sizes.size());
          r.order.push_back(it.key());
        }
        per[i].push_back(it.value().get<double>());
      }
      if (rec.contains("windows") && rec["windows"].contains("volume_fraction")) {
        std::vector<WindowVariance> w;
        for (const auto& row : rec["windows"]["volume_fraction"]) {
          WindowVariance v;
          v.k = row[0].get<int>();
          v.volume = row[1].get<double>();
          v.windows = row[2].get<size_t>();
          v.variance = row[3].get<double>();
          v.mean = row[4].get<double>();
          w.push_back(v);
        }
        r.windows[i].push_back(w);
      }
    }
  }
  return r;
}

// The statistics of one property over the sizes (study.json's properties.NAME), its rows
// added to `csv`.
json property_statistics(const std::string& name, const std::vector<std::vector<double>>& per,
                         const StudyPlan& plan, const StudyRecords& records,
                         std::ostringstream& csv) {
  const std::vector<double>& sizes = plan.sizes;
  const std::vector<double>& volumes = plan.volumes;
  const int realizations = plan.realizations;
  const double target_error = plan.target_error;
  std::vector<SampleSummary> sum(sizes.size());
  double scale = 0.0;
  for (size_t i = 0; i < sizes.size(); ++i) {
    sum[i] = summarize(per[i]);
    scale = std::max(scale, std::abs(sum[i].mean));
  }
  const VarianceLaw law = fit_variance_law(volumes, sum, scale);
  json p;
  json rows = json::array();
  for (size_t i = 0; i < sizes.size(); ++i) {
    const SampleSummary& s = sum[i];
    const double rel =
        s.n > 0 && s.mean != 0.0 ? 2.0 * s.sd / (std::abs(s.mean) * std::sqrt(double(s.n))) : 0.0;
    const long long need = realizations_needed(s.sd * s.sd, s.mean, target_error);
    rows.push_back({{"size", sizes[i]},
                    {"volume", volumes[i]},
                    {"n", s.n},
                    {"mean", s.mean},
                    {"sd", s.sd},
                    {"ci95", {s.ci_low, s.ci_high}},
                    {"relative_error", rel},
                    {"realizations_needed", need}});
    csv << name << "," << sizes[i] << "," << volumes[i] << "," << s.n << "," << s.mean << ","
        << s.sd << "," << s.ci_low << "," << s.ci_high << "," << rel << "," << need << "\n";
  }
  p["per_size"] = rows;
  json l;
  l["exact"] = law.exact;
  l["fitted"] = law.fitted;
  l["points"] = law.points;
  if (!law.exact && law.K > 0.0) {
    l["K"] = law.K;
    l["alpha"] = law.alpha;
  }
  // Exact phase fractions have a point variance phi (1 - phi): their integral range (the
  // voxel fractions' variance is mostly the discretization's, not the microstructure's).
  const double phi = sum.back().mean;
  if (name.rfind("volume_fraction", 0) == 0 && !law.exact && law.K > 0.0 && phi > 0.0 &&
      phi < 1.0) {
    l["integral_range"] = law.integral_range(phi * (1.0 - phi));
  }
  p["variance_law"] = l;
  if (name == "volume_fraction") {
    const json w =
        window_summary(records.windows, sizes, sum.back().mean, target_error, realizations);
    if (!w.is_null()) p["windows"] = w;
  }
  // The size recommended: from the law where it decays (never below the smallest size
  // studied, which then already meets the target), else the smallest size whose measured
  // error meets the target.
  int measured = -1;
  for (size_t i = 0; i < sizes.size() && measured < 0; ++i) {
    const SampleSummary& m = sum[i];
    if (m.n >= 2 && m.mean != 0.0 &&
        2.0 * m.sd / (std::abs(m.mean) * std::sqrt(double(m.n))) <= target_error) {
      measured = static_cast<int>(i);
    }
  }
  json rec;
  rec["measured_size"] = measured >= 0 ? json(sizes[measured]) : json(nullptr);
  const double v = recommended_volume(law, phi, target_error, realizations);
  if (law.exact) {
    rec["volume"] = volumes.front();
    rec["size"] = sizes.front();
    rec["basis"] = "exact: the property does not vary between realizations";
  } else if (std::isfinite(v) && law.K > 0.0 && law.alpha > 0.0) {
    rec["law_volume"] = v;
    if (v <= volumes.front()) {
      rec["volume"] = volumes.front();
      rec["size"] = sizes.front();
      rec["basis"] = "law: the smallest size studied already meets the target";
    } else {
      rec["volume"] = v;
      rec["size"] = std::cbrt(v / plan.base_volume);
      rec["basis"] = v > volumes.back() ? "law, extrapolated beyond the sizes studied" : "law";
    }
  } else if (measured >= 0) {
    rec["volume"] = volumes[measured];
    rec["size"] = sizes[measured];
    rec["basis"] = "measured: the variance shows no decay over the sizes studied";
  } else {
    rec["volume"] = nullptr;
    rec["size"] = nullptr;
    rec["basis"] =
        "none: no decay of the variance was measured and no size studied meets the target "
        "(study larger sizes or more realizations)";
  }
  rec["realizations"] = realizations;
  p["recommended"] = rec;
  return p;
}

// The records this rank computes: its share of the missing realizations, on its cores, with
// a progress line each. Returns the first failure (empty: none) and the records by file name.
std::string compute_share(const StudyPlan& plan, const std::vector<int>& missing,
                          const Ranks& ranks, int at_once, const ProgressFn& progress,
                          json* records) {
  struct Task {
    size_t size;
    int k;
  };
  std::vector<Task> todo;
  for (size_t t = static_cast<size_t>(ranks.rank()); t < missing.size();
       t += static_cast<size_t>(ranks.size()))
    todo.push_back(
        {static_cast<size_t>(missing[t] / plan.realizations), missing[t] % plan.realizations});
  std::error_code ec;
  if (!ranks.root()) fs::create_directories(plan.rdir, ec);  // rank 0 gets a copy of each
  const std::string who = ranks.size() > 1 ? "rank " + std::to_string(ranks.rank()) + ": " : "";
  std::mutex say;
  std::atomic<size_t> done{0};
  std::string failure;
  std::vector<std::string> written(todo.size());
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                            static_cast<size_t>(at_once));
  tbb::parallel_for(size_t(0), todo.size(), size_t(1), [&](size_t t) {
    {
      std::lock_guard<std::mutex> lock(say);
      if (!failure.empty()) return;
    }
    const Task& task = todo[t];
    const std::string file = study_record_file(plan.sizes[task.size], task.k);
    std::string status, error;
    double seconds = 0.0;
    try {
      written[t] = run_realization(plan, task.size, task.k, ranks.size() > 1 ? ranks.rank() : -1,
                                   &status, &seconds);
      write_whole(plan.rdir / file, written[t]);
    } catch (const std::bad_alloc&) {
      error = "out of memory in realization " + std::to_string(task.k) + " at size " +
              study_size_name(plan.sizes[task.size]) +
              " (run fewer at once: --jobs, or --max-memory)";
    } catch (const std::exception& e) {
      error = e.what();
    }
    std::lock_guard<std::mutex> lock(say);
    if (!error.empty()) {
      if (failure.empty()) failure = error;
      written[t].clear();
      return;
    }
    if (progress) {
      char buf[200];
      std::snprintf(buf, sizeof buf, "%zu/%zu done (size %s, realization %d, %s, %.1f s)", ++done,
                    todo.size(), study_size_name(plan.sizes[task.size]).c_str(), task.k,
                    status.c_str(), seconds);
      progress(who + buf);
    }
  });
  *records = json::object();
  for (size_t t = 0; t < todo.size(); ++t) {
    if (!written[t].empty())
      (*records)[study_record_file(plan.sizes[todo[t].size], todo[t].k)] = written[t];
  }
  return failure;
}

// Only the records and each rank's peak memory travel to rank 0 (a record is a few hundred
// bytes: no image, no inclusion list). Rank 0 keeps a copy of any record it does not see on
// its own disk, and returns the first rank's failure (empty: none); `peaks` gets every rank's
// peak memory on rank 0.
std::string gather_records(const StudyPlan& plan, const Ranks& ranks, const std::string& failure,
                           const json& records, std::vector<double>* peaks) {
  json mine = json::object();
  mine["failure"] = failure;
  mine["records"] = records;
  mine["peak_memory_mb"] = peak_memory_mb();
  if (!ranks.root()) {
    ranks.gather(mine.dump());
    return "";
  }
  std::string first;
  std::error_code ec;
  for (const std::string& text : ranks.gather(mine.dump())) {
    const json theirs = json::parse(text);
    peaks->push_back(theirs["peak_memory_mb"].get<double>());
    const std::string f = theirs["failure"].get<std::string>();
    if (first.empty()) first = f;
    for (auto it = theirs["records"].begin(); it != theirs["records"].end(); ++it) {
      if (fs::exists(plan.rdir / it.key(), ec)) continue;
      try {
        write_whole(plan.rdir / it.key(), it.value().get<std::string>());
      } catch (const std::exception& e) {
        if (first.empty()) first = e.what();
      }
    }
  }
  return first;
}

}  // namespace

std::vector<double> parse_study_sizes(const std::string& text) {
  return parse_sizes_impl(text);
}

std::string study_size_name(double m) {
  return size_name(m);
}

std::string study_record_file(double m, int k) {
  return record_file(m, k);
}

StudyOutcome write_study_statistics(const StudyPlan& plan, std::vector<double> rank_peaks_mb) {
  const StudyRecords records = read_records(plan);
  json out;
  out["scene"] = fs::absolute(plan.scene_path).string();
  out["sizes"] = plan.sizes;
  out["volumes"] = plan.volumes;
  out["realizations"] = plan.realizations;
  out["target_error"] = plan.target_error;
  out["not_reached"] = records.not_reached;
  out["not_converged"] = records.not_converged;
  out["ranks"] = plan.ranks;  // processes of this run (the statistics do not depend on it)
  out["law"] = "D^2(V) = K V^-alpha; relative error of the mean of n: 2 D(V) / (|mean| sqrt n)";
  json props = json::object();
  std::ostringstream csv;
  csv.precision(10);
  csv << "property,size,volume,n,mean,sd,ci95_low,ci95_high,relative_error,realizations_needed\n";
  for (const std::string& name : records.order)
    props[name] = property_statistics(name, records.values.at(name), plan, records, csv);
  out["properties"] = props;
  out["seconds"] =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - plan.start).count();
  // The largest process's peak; under MPI each rank's too (rank 0's now, after the statistics).
  out["peak_memory_mb"] = peak_memory_mb();
  if (rank_peaks_mb.size() > 1) {
    rank_peaks_mb[0] = peak_memory_mb();
    out["peak_memory_mb"] = *std::max_element(rank_peaks_mb.begin(), rank_peaks_mb.end());
    out["peak_memory_mb_ranks"] = rank_peaks_mb;
  }
  write_whole(plan.dir / "study.json", out.dump(2) + "\n");
  write_whole(plan.dir / "study.csv", csv.str());
  StudyOutcome outcome;
  for (int n : records.not_reached) outcome.not_reached += n;
  for (int n : records.not_converged) outcome.not_converged += n;
  return outcome;
}

StudyPlan plan_study(const Scene& base, const std::string& scene_path, const std::string& dir,
                     const std::vector<double>& sizes, int realizations, double target_error) {
  if (base.homogenization.fields)
    throw InputError("homogenization.fields: a study keeps no local fields; leave it out");
  StudyPlan plan;
  plan.scene_path = scene_path;
  plan.dir = dir;
  plan.rdir = plan.dir / "realizations";
  plan.sizes = sizes;
  plan.realizations = realizations;
  plan.target_error = target_error;
  plan.seed = base.seed;
  plan.signature = scene_to_json(base);
  plan.base_volume = base.box.volume();
  for (double m : sizes) {
    plan.scenes.emplace_back();
    for (int k = 0; k < realizations; ++k)
      plan.scenes.back().push_back(scaled_scene(base, m, realization_seed(base.seed, m, k)));
    plan.volumes.push_back(plan.scenes.back()[0].box.volume());
  }
  return plan;
}

int study_jobs_that_fit(const StudyPlan& plan, const MemoryLimit& limit, int wanted,
                        int local_ranks, std::string* note) {
  // The largest size's realization: packing, image and solver (a study writes no outputs of
  // its own), times the realizations run at once on this machine (its ranks' jobs together).
  ResourceEstimate largest;
  double largest_size = 0.0;
  for (size_t i = 0; i < plan.sizes.size(); ++i) {
    Scene sized = plan.scenes[i][0];
    sized.outputs = Outputs{};
    sized.outputs.inclusions = sized.outputs.levelsets = false;
    const ResourceEstimate need = estimate_resources(sized);
    if (need.total_bytes() > largest.total_bytes()) largest = need, largest_size = plan.sizes[i];
  }
  const double one = largest.total_bytes() * std::max(1, local_ranks);
  const std::string where = limit.above().substr(std::string(", above ").size());
  if (limit.exceeded_by(one)) {
    throw InputError("a realization at size " + size_name(largest_size) + " needs about " +
                     describe(largest) + (local_ranks > 1 ? " per rank" : "") + limit.above() +
                     ": give smaller --sizes (or a coarser voxels.resolution)");
  }
  if (!limit.exceeded_by(one * wanted)) return wanted;
  const int fit = std::max(1, static_cast<int>(limit.bytes / one));
  *note = std::to_string(fit) + " realization(s) at once (of " + std::to_string(wanted) +
          "): each needs about " + format_bytes(largest.total_bytes()) + ", within " + where;
  return fit;
}

void prepare_study_directory(const StudyPlan& plan) {
  std::error_code ec;
  const fs::path held = plan.dir / "study_scene.json";
  if (fs::exists(held, ec)) {
    if (read_file(held.string(), kMaxRecordBytes) != plan.signature) {
      throw InputError(plan.dir.string() + " holds a study of another scene (remove it, or " +
                       "give another -o)");
    }
  } else if (fs::exists(plan.dir, ec) && !fs::is_empty(plan.dir, ec)) {
    throw OutputError(plan.dir.string() + " is not empty and holds no study: give a new or " +
                      "empty directory");
  }
  for (const fs::path& d : {plan.dir, plan.rdir}) {
    if (fs::exists(fs::symlink_status(d, ec)) && !fs::is_directory(fs::status(d, ec)))
      throw OutputError(d.string() + " is not a directory: the study cannot write there");
  }
  fs::create_directories(plan.rdir, ec);
  if (ec) throw OutputError("cannot write the study in " + plan.dir.string() + ": " + ec.message());
  write_whole(held, plan.signature);
}

std::vector<int> missing_realizations(const StudyPlan& plan) {
  std::vector<int> missing;
  std::error_code ec;
  for (size_t i = 0; i < plan.sizes.size(); ++i) {
    for (int k = 0; k < plan.realizations; ++k) {
      if (fs::exists(plan.rdir / record_file(plan.sizes[i], k), ec)) {
        read_record(plan, i, k);  // checked before any work
      } else {
        missing.push_back(static_cast<int>(i) * plan.realizations + k);
      }
    }
  }
  return missing;
}

std::string run_realization(const StudyPlan& plan, size_t i, int k, int rank, std::string* status,
                            double* seconds) {
  const Scene& s = plan.scenes[i][k];
  const auto t1 = std::chrono::steady_clock::now();
  json rec;
  rec["size"] = plan.sizes[i];
  rec["realization"] = k;
  rec["seed"] = s.seed;
  rec["box"] = {s.box.size[0], s.box.size[1], s.box.size[2]};
  rec["volume"] = s.box.volume();
  try {
    const PackingResult r = pack_scene(s, Monitor{}).result;
    rec["status"] = status_name(r.status);
    rec["count"] = r.set.inclusions.size();
    json windows = json::object();
    std::string not_converged;
    rec["properties"] = realization_properties(s, r, &windows, &not_converged);
    if (!windows.empty()) rec["windows"] = windows;
    // A tensor that did not converge is no effective property: the realization is left out
    // of the statistics, as one that missed its target is.
    if (r.status == PackingStatus::kOk && !not_converged.empty()) {
      rec["status"] = "not_converged";
      rec["not_converged"] = not_converged;
    }
  } catch (const NothingPlaced&) {
    rec["status"] = "nothing_placed";
  }
  *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  rec["seconds"] = *seconds;
  if (rank >= 0) rec["rank"] = rank;
  rec["digest"] = record_digest(rec, plan.signature);
  *status = rec["status"].get<std::string>();
  return rec.dump(1) + "\n";
}

std::string run_study_share(const StudyPlan& plan, const std::vector<int>& missing,
                            const Ranks& ranks, int at_once, const ProgressFn& progress,
                            std::vector<double>* peaks) {
  json records;
  const std::string failure = compute_share(plan, missing, ranks, at_once, progress, &records);
  return gather_records(plan, ranks, failure, records, peaks);
}

}  // namespace rvegen
