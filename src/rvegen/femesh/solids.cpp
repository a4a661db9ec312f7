// The inclusions as OpenCASCADE solids, through Gmsh: spheres, cylinders and ellipsoids (their
// shells grown by the coating), the pieces inside the box of images cut by its faces, and the
// voids of debonded spheres, each built in the frame that keeps its seam and poles off the
// box faces it crosses.
#include <gmsh.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "rvegen/femesh/mesh_parts.hpp"
#include "rvegen/femesh/mesh_tolerances.hpp"
#include "rvegen/femesh/offset_solid.hpp"

namespace rvegen::mesh_parts {

namespace {

// OpenCASCADE's spheres (and the ellipsoids made of them) have two poles and a seam, the
// meridian through +x of their frame (poles at +-z); its cylinders a seam along the mantle at
// +x, between two vertices on the rims. They are edges of the surfaces: a box face that passes near
// a pole, or runs along a seam, cuts a sliver between the two, and the elements there are slivers
// too (seen: a face a hair from an ellipsoid's pole; a face nearly along a fibre's seam).
// Each solid that crosses a box face is built in the frame, of a fixed set, that keeps them
// farthest from the faces: its score is the least, over the seam's points near each face, of the
// larger of the point's distance to the face (over the shape's extent across it) and the sine of
// the seam's angle to the face (0 at the poles and at a cylinder seam's ends).
//
// The seam of a shape in frame P: points x(t) of the unit shape's seam and their unit tangents,
// mapped by x -> c + M P x (M: the shape's own map; a cylinder's P turns about its axis).
struct Seam {
  std::vector<Vec3> at, tangent;
};
constexpr int kSeamPoints = 65;
Seam seam_of(const Shape& s, const Mat3& P) {
  Seam seam;
  if (s.kind == ShapeKind::Cylinder) {
    const Vec3 side = P.col(0), along = s.half_axis;  // P's first column: the seam's direction
    for (int k = 0; k < kSeamPoints; ++k) {
      const double t = -1.0 + 2.0 * k / (kSeamPoints - 1);
      seam.at.push_back(s.center + s.radius * side + t * along);
      // Its ends are vertices on the rims, scored by their distance alone (as poles are): a
      // seam that crosses a face steeply scores well wherever it lies, and one fibre's seam
      // ended a hair from the face that cut its end disk (slivers between that vertex and the
      // face's cut, whatever the sizes).
      const bool end = k == 0 || k == kSeamPoints - 1;
      seam.tangent.push_back(end ? Vec3::Zero() : Vec3(along.normalized()));
    }
    return seam;
  }
  const Mat3 M = s.kind == ShapeKind::Sphere ? Mat3(s.radius * P)
                                             : Mat3(s.rotation * s.semi_axes.asDiagonal() * P);
  for (int k = 0; k < kSeamPoints; ++k) {
    const double phi = M_PI * k / (kSeamPoints - 1);
    seam.at.push_back(s.center + M * Vec3(std::sin(phi), 0.0, std::cos(phi)));
    const bool pole = k == 0 || k == kSeamPoints - 1;
    seam.tangent.push_back(pole ? Vec3::Zero()
                                : Vec3(M * Vec3(std::cos(phi), 0.0, -std::sin(phi))).normalized());
  }
  return seam;
}

// The frames tried: the identity, then rotations about axes spread over the sphere (a Fibonacci
// lattice) by angles spread by the golden ratio; for cylinders, turns about the axis.
constexpr int kFrames = 32;
Mat3 frame(const Shape& s, int k) {
  if (s.kind == ShapeKind::Cylinder) {
    const Vec3 u = s.half_axis.normalized(), w = any_orthogonal(u), v = u.cross(w);
    const double psi = 2.0 * M_PI * k / kFrames;
    Mat3 P;
    P.col(0) = std::cos(psi) * w + std::sin(psi) * v;
    P.col(1) = u.cross(P.col(0));
    P.col(2) = u;
    return P;
  }
  if (k == 0) return Mat3::Identity();
  const double golden = 0.5 * (std::sqrt(5.0) - 1.0);
  const double z = 1.0 - (2.0 * k + 1.0) / kFrames, r = std::sqrt(std::max(0.0, 1.0 - z * z));
  const double az = 2.0 * M_PI * golden * k;
  const Vec3 axis(r * std::cos(az), r * std::sin(az), z);
  return Eigen::AngleAxisd(2.0 * M_PI * std::fmod(golden * k * 7.0, 1.0), axis).toRotationMatrix();
}

// Per box face the shape crosses, the least over the seam's points of the larger of the two
// terms above; ascending. Frames compare by these in order (lexicographically): a face whose
// term is the same for every frame (one the seam crosses at a fixed angle, its tangent's term)
// then leaves the choice to the next face, not to the first frame.
std::vector<double> frame_score(const Shape& s, const Seam& seam, const Box& box) {
  Vec3 lo, hi;
  s.aabb(&lo, &hi);
  std::vector<double> score;
  for (int a = 0; a < 3; ++a) {
    const double L = box.size[a], half = 0.5 * (hi[a] - lo[a]);
    for (double f = box.origin[a] + L * std::ceil((lo[a] - box.origin[a]) / L); f < hi[a]; f += L) {
      double least = 1e300;
      for (size_t k = 0; k < seam.at.size(); ++k) {
        least = std::min(
            least, std::max(std::abs(seam.at[k][a] - f) / half, std::abs(seam.tangent[k][a])));
      }
      score.push_back(least);
    }
  }
  std::sort(score.begin(), score.end());
  return score;
}

// The solid swept by a profile (a plane surface in the half plane x >= 0 of y = 0) turned about
// z, its seam at +x; the profile and the points that only served its arcs as centres go.
int revolved_solid(int profile, std::initializer_list<int> centres) {
  namespace occ = gmsh::model::occ;
  gmsh::vectorpair out;
  occ::revolve({{2, profile}}, 0, 0, 0, 0, 0, 1, 2.0 * M_PI, out);
  int solid = -1;
  for (const auto& dt : out) {
    if (dt.first == 3) solid = dt.second;
  }
  occ::remove({{2, profile}}, true);
  gmsh::vectorpair points;
  for (const int c : centres) points.push_back({0, c});
  occ::remove(points);
  return solid;
}

// The frame of rank `rank` among kFrames by frame_score, best first (equal scores in the order
// of the frames; a shape that crosses no face scores alike in every frame).
int ranked_frame(const Shape& s, const Box& box, int rank) {
  std::vector<std::pair<std::vector<double>, int>> scored;
  const std::vector<double> first = frame_score(s, seam_of(s, frame(s, 0)), box);
  scored.emplace_back(first, 0);
  for (int k = 1; k < kFrames && (!first.empty() || rank > 0); ++k) {
    scored.emplace_back(frame_score(s, seam_of(s, frame(s, k)), box), k);
  }
  std::stable_sort(scored.begin(), scored.end(),
                   [](const auto& a, const auto& b) { return b.first < a.first; });
  return scored[static_cast<size_t>(rank) % scored.size()].second;
}

// The OCC solid of a shape grown by `offset` (every point within it of the shape: an
// interphase shell's outer surface), built in the frame that keeps its
// seam and poles off the faces of `box` it crosses (the shape's own, whatever the offset), or
// in the frame of rank `rank` by that measure; its tag.
}  // namespace

int add_solid(const Shape& s, const Box& box, double offset, const Mat3* given, int rank) {
  const Mat3 P = given ? *given : frame(s, ranked_frame(s, box, rank));
  const Vec3 c = s.center;
  auto turn = [&](int tag, const Mat3& R) {
    const Eigen::AngleAxisd aa(R);
    if (aa.angle() > 0.0) {
      gmsh::model::occ::rotate({{3, tag}}, 0, 0, 0, aa.axis()[0], aa.axis()[1], aa.axis()[2],
                               aa.angle());
    }
    gmsh::model::occ::translate({{3, tag}}, c[0], c[1], c[2]);
    return tag;
  };
  switch (s.kind) {
    case ShapeKind::Sphere:
      return turn(gmsh::model::occ::addSphere(0, 0, 0, s.radius + offset), P);
    case ShapeKind::Cylinder: {
      // Built along +z with its seam at +x, then turned so that z is the axis and x the seam's
      // side (P's columns).
      const double h = s.half_axis.norm(), r = s.radius;
      if (offset <= 0.0) return turn(gmsh::model::occ::addCylinder(0, 0, -h, 0, 0, 2.0 * h, r), P);
      // Grown: its profile in the half plane x >= 0 of y = 0 (end disks of radius r moved out
      // by the offset t, the mantle at r + t, quarter circles of radius t about the rims),
      // turned about z: its seam at +x too.
      const double t = offset;
      namespace occ = gmsh::model::occ;
      const int a0 = occ::addPoint(0, 0, -h - t), a1 = occ::addPoint(r, 0, -h - t),
                rim0 = occ::addPoint(r, 0, -h), a2 = occ::addPoint(r + t, 0, -h),
                a3 = occ::addPoint(r + t, 0, h), rim1 = occ::addPoint(r, 0, h),
                a4 = occ::addPoint(r, 0, h + t), a5 = occ::addPoint(0, 0, h + t);
      const int loop = occ::addCurveLoop({occ::addLine(a0, a1), occ::addCircleArc(a1, rim0, a2),
                                          occ::addLine(a2, a3), occ::addCircleArc(a3, rim1, a4),
                                          occ::addLine(a4, a5), occ::addLine(a5, a0)});
      return turn(revolved_solid(occ::addPlaneSurface({loop}), {rim0, rim1}), P);
    }
    case ShapeKind::Ellipsoid: {
      // A unit sphere mapped by x -> c + R diag(semi-axes) P x (a spline surface in
      // OpenCASCADE); grown, that surface's offset.
      const Mat3 M = s.rotation * s.semi_axes.asDiagonal() * P;
      if (offset > 0.0) return add_ellipsoid_offset(M, c, offset);
      const int tag = gmsh::model::occ::addSphere(0, 0, 0, 1);
      std::vector<double> a(12);
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) a[4 * i + j] = M(i, j);
        a[4 * i + 3] = c[i];
      }
      gmsh::model::occ::affineTransform({{3, tag}}, a);
      return tag;
    }
  }
  return -1;
}

// The OCC solid of a shape inside the box, made where it lies (its seam and poles meet no box
// face, whatever their frame; Gmsh's moves of a solid cost in proportion to the shapes it
// holds, so turning and moving many fibres after the cut is slow); its tag. With `rank` above
// 0, built as add_solid builds it in that frame.
int add_inside_solid(const Shape& s, const Box& box, int rank) {
  if (rank > 0) return add_solid(s, box, 0.0, nullptr, rank);
  const Vec3& c = s.center;
  switch (s.kind) {
    case ShapeKind::Sphere:
      return gmsh::model::occ::addSphere(c[0], c[1], c[2], s.radius);
    case ShapeKind::Cylinder: {
      const Vec3 a = c - s.half_axis, d = 2.0 * s.half_axis;
      return gmsh::model::occ::addCylinder(a[0], a[1], a[2], d[0], d[1], d[2], s.radius);
    }
    case ShapeKind::Ellipsoid:
      break;
  }
  return add_solid(s, box);
}

// The frame of a debonded sphere's void and core: z along the debonding axis (the core's poles
// on it, so that its meridians, its seam among them, cross the cap's rim square: a seam
// grazing the rim left a sliver of surface along it, and sliver elements), and the
// seam turned about the axis off the faces of `box` it crosses.
Mat3 void_frame(const Inclusion& in, const Box& box) {
  const Shape& s = in.shape;
  const Modifiers& m = in.mod;
  const double r = s.radius, g = m.debond_gap, cos_cap = m.debond_cos_cap();
  const double theta = std::acos(std::clamp(cos_cap, -1.0, 1.0));
  const Vec3 u = m.debond_axis.normalized(), w = any_orthogonal(u), v = u.cross(w);
  Shape outer = s;
  outer.radius = r + g;
  Mat3 P = Mat3::Identity();
  double best = -1.0;
  for (int k = 0; k < kFrames && best < 1e300; ++k) {
    const double psi = 2.0 * M_PI * k / kFrames;
    Mat3 F;
    F.col(0) = std::cos(psi) * w + std::sin(psi) * v;
    F.col(1) = u.cross(F.col(0));
    F.col(2) = u;
    Seam seam;  // the core's meridian from pole to pole, and the void's to the cap's rim
    for (const double rho : {r, r + g}) {
      const double end = rho == r ? M_PI : theta;
      for (int j = 0; j < kSeamPoints; ++j) {
        const double phi = end * j / (kSeamPoints - 1);
        seam.at.push_back(s.center + rho * (std::sin(phi) * F.col(0) + std::cos(phi) * u));
        const bool pole = j == 0 || (rho == r && j == kSeamPoints - 1);
        seam.tangent.push_back(pole ? Vec3::Zero()
                                    : Vec3(std::cos(phi) * F.col(0) - std::sin(phi) * u));
      }
    }
    const std::vector<double> faces = frame_score(outer, seam, box);
    const double score = faces.empty() ? 1e300 : faces.front();
    if (score > best) {
      best = score;
      P = F;
    }
  }
  return P;
}

// The OCC solid of a debonded sphere's void: the points between the sphere (radius r) and the
// sphere of radius r + g over the cap of half-angle theta about the debonding axis (cos theta =
// 1 - 2 f), the profile in the half plane of its seam turned about the axis; when the cap is the
// whole sphere, the sphere of radius r + g (the fragment against the core leaves the shell).
// Built in void_frame.
int add_void_solid(const Inclusion& in, const Box& box) {
  const Shape& s = in.shape;
  const Modifiers& m = in.mod;
  const double r = s.radius, g = m.debond_gap, cos_cap = m.debond_cos_cap();
  if (cos_cap <= -1.0 + kWholeCap) return add_solid(s, box, g);
  const double sin_cap = std::sqrt(std::max(0.0, 1.0 - cos_cap * cos_cap));
  const Mat3 P = void_frame(in, box);
  namespace occ = gmsh::model::occ;
  const int centre = occ::addPoint(0, 0, 0), pole_in = occ::addPoint(0, 0, r),
            pole_out = occ::addPoint(0, 0, r + g),
            rim_in = occ::addPoint(r * sin_cap, 0, r * cos_cap),
            rim_out = occ::addPoint((r + g) * sin_cap, 0, (r + g) * cos_cap);
  const int loop = occ::addCurveLoop(
      {occ::addCircleArc(pole_in, centre, rim_in), occ::addLine(rim_in, rim_out),
       occ::addCircleArc(rim_out, centre, pole_out), occ::addLine(pole_out, pole_in)});
  const int solid = revolved_solid(occ::addPlaneSurface({loop}), {centre});
  const Eigen::AngleAxisd aa(P);
  if (aa.angle() > 0.0) {
    occ::rotate({{3, solid}}, 0, 0, 0, aa.axis()[0], aa.axis()[1], aa.axis()[2], aa.angle());
  }
  occ::translate({{3, solid}}, s.center[0], s.center[1], s.center[2]);
  return solid;
}

}  // namespace rvegen::mesh_parts
