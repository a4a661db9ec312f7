#include "rvegen/femesh/offset_solid.hpp"

#include <gmsh.h>

#include <BRepBuilderAPI_GTransform.hxx>
#include <BRepBuilderAPI_MakeShell.hxx>
#include <BRepBuilderAPI_MakeSolid.hxx>
#include <BRepOffsetAPI_MakeOffsetShape.hxx>
#include <Geom_SphericalSurface.hxx>
#include <Standard_Failure.hxx>
#include <TopoDS_Shape.hxx>
#include <TopoDS_Shell.hxx>
#include <TopoDS_Solid.hxx>
#include <gp_Ax3.hxx>
#include <gp_GTrsf.hxx>
#include <string>

#include "rvegen/femesh/tet_mesh.hpp"

namespace rvegen {

// (BRepPrimAPI_MakeSphere would do for the sphere, but its headers need one that Debian ships
// with OpenCASCADE's visualisation package; the sphere's surface made into a shell and a solid
// is the same solid.)
int add_ellipsoid_offset(const Mat3& M, const Vec3& c, double offset) {
  try {
    const Handle(Geom_SphericalSurface) unit = new Geom_SphericalSurface(gp_Ax3(gp::XOY()), 1.0);
    BRepBuilderAPI_MakeShell shell(unit);
    if (!shell.IsDone()) throw MeshError("OpenCASCADE could not make a sphere's shell");
    BRepBuilderAPI_MakeSolid solid(shell.Shell());
    if (!solid.IsDone()) throw MeshError("OpenCASCADE could not make a sphere's solid");
    gp_GTrsf map;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) map.SetValue(i + 1, j + 1, M(i, j));
    }
    map.SetTranslationPart(gp_XYZ(c[0], c[1], c[2]));
    BRepBuilderAPI_GTransform ellipsoid(solid.Solid(), map, true);
    if (!ellipsoid.IsDone()) throw MeshError("OpenCASCADE could not map a sphere to an ellipsoid");
    BRepOffsetAPI_MakeOffsetShape grown;
    grown.PerformBySimple(ellipsoid.Shape(), offset);
    if (!grown.IsDone()) {
      throw MeshError("OpenCASCADE could not offset an ellipsoid by " + std::to_string(offset));
    }
    const TopoDS_Shape shape = grown.Shape();
    gmsh::vectorpair out;
    gmsh::model::occ::importShapesNativePointer(&shape, out, true);
    if (out.size() != 1 || out[0].first != 3) {
      throw MeshError("an ellipsoid's offset is not one solid (" + std::to_string(out.size()) +
                      " entities)");
    }
    return out[0].second;
  } catch (const Standard_Failure& e) {
    throw MeshError(std::string("OpenCASCADE failed to offset an ellipsoid: ") +
                    e.GetMessageString());
  }
}

}  // namespace rvegen
