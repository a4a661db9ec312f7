#include "rvegen/packing/audit.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <memory>

#include "rvegen/model/body.hpp"
#include "rvegen/model/deformed_support.hpp"
#include "rvegen/model/neighbours.hpp"
#include "rvegen/model/parallel.hpp"
#include "rvegen/packing/body_contacts.hpp"

namespace rvegen {

namespace {

// The support tables of the deformed spheres (null for the others), built in parallel.
void tables_of(const std::vector<Inclusion>& inc,
               std::vector<std::shared_ptr<const DeformedSupport>>* table) {
  rvegen::parallel_for(size_t(0), inc.size(),
                       [&](size_t i) { (*table)[i] = support_table(inc[i]); });
}

// Spheres of which one at least is deformed, b shifted by `shift`: by their support functions
// (certified upper bounds; an undeformed sphere's is its radius), with the exact tests'
// tolerance.
Contact support_contact(const Inclusion& a, const DeformedSupport* ta, const Inclusion& b,
                        const DeformedSupport* tb, const Vec3& shift) {
  const Vec3 d = b.shape.center + shift - a.shape.center;
  const double tol = kContactRelTolerance * std::min(a.shape.min_size(), b.shape.min_size());
  double ha = 0.0, hb = 0.0;
  return round_contact(
      a.shape.center, d, d.norm(), 1.0,
      [&](const Vec3& u) { return ta ? envelope_support(a, *ta, u) : envelope(a).radius; }, 1.0,
      [&](const Vec3& u) { return tb ? envelope_support(b, *tb, u) : envelope(b).radius; }, tol,
      &ha, &hb);
}

// Pairs with a wavy fibre: its chain of pieces (body.hpp) against the other's chain or
// envelope (b shifted), piece by piece with the exact tests; the first overlap found. A deformed
// sphere's envelope is its ball: a piece it meets is apart when a plane separates it from the
// sphere's support function (as packed).
Contact chain_contact(const Inclusion& a, const Shape& env_a, const DeformedSupport* ta,
                      const Inclusion& b, const Shape& env_b, const DeformedSupport* tb,
                      const Vec3& shift) {
  auto pieces_of = [](const Inclusion& inc, const Shape& env, const Vec3& shift) {
    std::vector<Piece> out;
    if (packs_as_chain(inc)) {
      std::vector<ShearedPiece> parts;
      chain_pieces(inc, &parts);
      for (const ShearedPiece& p : parts) out.push_back(Piece::of(p.translated(shift)));
    } else {
      out.push_back(Piece::of(env.translated(shift)));
    }
    return out;
  };
  const std::vector<Piece> pa = pieces_of(a, env_a, Vec3::Zero()), pb = pieces_of(b, env_b, shift);
  std::vector<const Piece*> near_a;
  for (const Piece& p : pa) near_a.push_back(&p);
  // A deformed grain (not a chain) meets the pieces by its support function, as packed.
  const bool is_grain_a = ta && !packs_as_chain(a), is_grain_b = tb && !packs_as_chain(b);
  const Grain ga{a.shape.center, [&](const Vec3& u) { return envelope_support(a, *ta, u); }};
  const Grain gb{b.shape.center + shift,
                 [&](const Vec3& u) { return envelope_support(b, *tb, u); }};
  std::vector<Contact> found;
  piece_contacts(near_a, pb, is_grain_a ? &ga : nullptr, is_grain_b ? &gb : nullptr, true, &found);
  return found.empty() ? Contact{} : found.front();
}

}  // namespace

std::vector<OverlapRecord> find_overlaps(const InclusionSet& set, size_t limit,
                                         size_t* candidates) {
  const auto& inc = set.inclusions;
  // Modified inclusions are tested by their envelopes, which hold everything they add; deformed
  // spheres by their support functions (support_contact) and strongly wavy fibres by their
  // chains (chain_contact), as they were packed. Pairs whose envelopes are apart are apart (a
  // chain's pieces may reach beyond the envelope, the fibre does not).
  std::vector<Shape> env(inc.size());
  std::vector<std::shared_ptr<const DeformedSupport>> table(inc.size());
  for (size_t i = 0; i < inc.size(); ++i) env[i] = envelope(inc[i]);
  tables_of(inc, &table);
  std::vector<OverlapRecord> out;
  size_t tested = 0;
  if (candidates) *candidates = 0;
  if (limit == 0) return out;
  // Candidates: pairs (and images) whose envelopes' bounding spheres meet, found by the broad
  // phase the packer uses, which stays near-linear for any size ratio (a grid sized to the
  // small inclusions; large ones registered in every cell they reach).
  std::vector<Vec3> centre(inc.size());
  std::vector<double> reach(inc.size());
  for (size_t i = 0; i < inc.size(); ++i) {
    centre[i] = env[i].center;
    reach[i] = env[i].bounding_radius();
  }
  for_each_sphere_pair(set.box, centre, reach, [&](const SpherePair& p) {
    // Each pair once, as (i <= j, shift of j); an inclusion against its own image is met as k
    // and -k: the lexicographically positive one is kept.
    int i = p.i, j = p.j;
    std::array<int, 3> k = p.k;
    if (i > j || (i == j && (k[0] < 0 || (k[0] == 0 && (k[1] < 0 || (k[1] == 0 && k[2] < 0)))))) {
      if (i == j) return true;
      std::swap(i, j);
      k = {-k[0], -k[1], -k[2]};
    }
    const Vec3 s(k[0] * set.box.size[0], k[1] * set.box.size[1], k[2] * set.box.size[2]);
    if (continues_along(inc[i], inc[j], s)) return true;
    ++tested;
    const Shape& a = env[i];
    const Shape& b = env[j];
    Contact c;
    if (packs_as_chain(inc[i]) || packs_as_chain(inc[j])) {
      c = chain_contact(inc[i], a, table[i].get(), inc[j], b, table[j].get(), s);
    } else if ((table[i] || table[j]) && b.kind == ShapeKind::Sphere &&
               a.kind == ShapeKind::Sphere) {
      c = support_contact(inc[i], table[i].get(), inc[j], table[j].get(), s);
    } else {
      c = intersect(a, b.translated(s));
    }
    if (c.overlap) out.push_back({i, j, s, c});
    return out.size() < limit;
  });
  if (candidates) *candidates = tested;
  // In a fixed order: by the pair, then by the image.
  std::sort(out.begin(), out.end(), [](const OverlapRecord& x, const OverlapRecord& y) {
    if (x.a != y.a) return x.a < y.a;
    if (x.b != y.b) return x.b < y.b;
    return std::lexicographical_compare(x.shift.data(), x.shift.data() + 3, y.shift.data(),
                                        y.shift.data() + 3);
  });
  return out;
}

std::vector<int> find_outside(const InclusionSet& set) {
  std::vector<int> out;
  if (set.box.periodic) return out;
  const Vec3 lo_box = set.box.origin, hi_box = set.box.origin + set.box.size;
  for (int i = 0; i < static_cast<int>(set.inclusions.size()); ++i) {
    Vec3 lo, hi;
    set.inclusions[i].shape.aabb(&lo, &hi);
    const double tol = kContactRelTolerance * set.inclusions[i].shape.min_size();
    if ((lo.array() < lo_box.array() - tol).any() || (hi.array() > hi_box.array() + tol).any()) {
      out.push_back(i);
    }
  }
  return out;
}

AuditReport audit(const InclusionSet& set, size_t limit) {
  const auto t0 = std::chrono::steady_clock::now();
  AuditReport r;
  r.overlaps = find_overlaps(set, limit, &r.candidates);
  r.truncated = r.overlaps.size() >= limit;
  r.outside = find_outside(set);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

void check_rve_for_scene(const InclusionSet& set, const PackingSpec& scene,
                         const std::string& where) {
  const Box &a = set.box, &b = scene.box;
  if (a.periodic != b.periodic || a.origin != b.origin || a.size != b.size) {
    char buf[300];
    std::snprintf(buf, sizeof buf,
                  "%s: the RVE's box (origin %g %g %g, size %g %g %g, %s) is not the scene's "
                  "(origin %g %g %g, size %g %g %g, %s)",
                  where.c_str(), a.origin[0], a.origin[1], a.origin[2], a.size[0], a.size[1],
                  a.size[2], a.periodic ? "periodic" : "not periodic", b.origin[0], b.origin[1],
                  b.origin[2], b.size[0], b.size[1], b.size[2],
                  b.periodic ? "periodic" : "not periodic");
    throw InputError(buf);
  }
  const int nf = static_cast<int>(scene.families.size());
  for (const Inclusion& inc : set.inclusions) {
    const std::string p = where + ": inclusion " + std::to_string(inc.id);
    if (inc.family < 0 || inc.family >= nf) {
      throw InputError(p + ": family " + std::to_string(inc.family) + ", but the scene has " +
                       std::to_string(nf) + (nf == 1 ? " family" : " families"));
    }
    const Family& f = scene.families[inc.family];
    if (inc.shape.kind != f.shape) {
      throw InputError(p + ": a " + shape_name(inc.shape.kind) + ", but family \"" + f.name +
                       "\" holds " + shape_name(f.shape) + "s");
    }
    // A run stopped short of its target shrinks spheres, cylinders and ellipsoids with their
    // coating (not the coating of aligned fibres): a thinner coating, never a thicker one.
    const double t = f.modifiers.coating, tol = 1e-9 * std::max(t, inc.mod.coating);
    if (inc.mod.coating > t + tol || (t > 0.0) != (inc.mod.coating > 0.0) ||
        (t > 0.0 && inc.mod.shells_may_touch != f.modifiers.shells_may_touch)) {
      char buf[200];
      std::snprintf(buf, sizeof buf, ": coating %g%s, but family \"%s\" has %g%s", inc.mod.coating,
                    inc.mod.shells_may_touch ? " (shells may touch)" : "", f.name.c_str(), t,
                    f.modifiers.shells_may_touch ? " (shells may touch)" : "");
      throw InputError(p + buf);
    }
    if (inc.mod.through != f.through()) {
      throw InputError(p +
                       (f.through() ? ": not a continuous fibre, but family \""
                                    : ": a continuous fibre, but family \"") +
                       f.name + (f.through() ? "\" is continuous" : "\" is not"));
    }
  }
  const AuditReport r = audit(set, 3);
  if (!r.clean()) throw InputError(where + ": " + describe_failure(r, set));
}

std::string describe_failure(const AuditReport& report, const InclusionSet& set) {
  const auto& inc = set.inclusions;
  std::string out;
  char buf[200];
  for (size_t k = 0; k < report.overlaps.size() && k < 3; ++k) {
    const OverlapRecord& o = report.overlaps[k];
    std::snprintf(buf, sizeof buf, "%sinclusions %d and %d overlap by %.6g (%s%s)",
                  out.empty() ? "" : "; ", inc[o.a].id, inc[o.b].id, o.contact.depth,
                  contact_type_name(o.contact.type), o.shift.isZero() ? "" : ", periodic image");
    out += buf;
  }
  if (report.overlaps.size() > 3) {
    out += "; " + std::to_string(report.overlaps.size() - 3) +
           (report.truncated ? " or more" : "") + " more overlapping pairs";
  }
  for (size_t k = 0; k < report.outside.size() && k < 3; ++k) {
    std::snprintf(buf, sizeof buf, "%sinclusion %d leaves the box", out.empty() ? "" : "; ",
                  inc[report.outside[k]].id);
    out += buf;
  }
  if (report.outside.size() > 3) {
    out += "; " + std::to_string(report.outside.size() - 3) + " more outside the box";
  }
  return out;
}

}  // namespace rvegen
