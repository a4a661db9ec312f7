"""Mesh an RVE with conforming tetrahedra in ParaView and save a picture and the mesh, headless.

usage: xvfb-run -a -s "-screen 0 1280x1024x24" pvpython --force-offscreen-rendering \\
         samples/pv_tet_mesh.py [SCENE.json] [OUT_DIR] [CHORD_ERROR]

SCENE.json: plain spheres, cylinders and ellipsoids (default samples/scenes/fe_spheres_rods.json). Writes
OUT_DIR/mesh_tet.png (the elements behind a clip through the middle of the box, coloured by
phase, with their edges) and OUT_DIR/mesh_tet.vtu, and prints the element count and each
phase's volume.
"""
import os
import sys

from paraview.simple import (Clip, ColorBy, CreateView, OutputPort, SaveData, SaveScreenshot,
                             Show)
from paraview import servermanager
from vtkmodules.util.numpy_support import vtk_to_numpy
import numpy as np

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, here)
from rvegen_paraview import load_rvegen  # noqa: E402

scene = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "scenes", "fe_spheres_rods.json")
out = sys.argv[2] if len(sys.argv) > 2 else "rve_tet_mesh"
chord = float(sys.argv[3]) if len(sys.argv) > 3 else 0.003
os.makedirs(out, exist_ok=True)
load_rvegen(globals())  # defines RVEGenerator and RVETetrahedralMesh here
gen = RVEGenerator(SceneFile=scene)  # noqa: F821
mesh = RVETetrahedralMesh(Input=OutputPort(gen, 0), ChordError=chord)  # noqa: F821
mesh.UpdatePipeline()
grid = servermanager.Fetch(mesh)
if grid.GetNumberOfCells() == 0:
    sys.exit("no mesh (see the error above)")
pts = vtk_to_numpy(grid.GetPoints().GetData())
tets = pts[vtk_to_numpy(grid.GetCells().GetConnectivityArray()).reshape(-1, 4)]
vol = np.einsum("ij,ij->i", tets[:, 1] - tets[:, 0],
                np.cross(tets[:, 2] - tets[:, 0], tets[:, 3] - tets[:, 0])) / 6
phase = vtk_to_numpy(grid.GetCellData().GetArray("phase")).astype(int)
names = grid.GetFieldData().GetAbstractArray("phase_names")
print("%d tetrahedra, %d nodes" % (grid.GetNumberOfCells(), grid.GetNumberOfPoints()))
for label in sorted(set(phase)):
    print("  %-10s volume %.6g" % (names.GetValue(label), vol[phase == label].sum()))
SaveData(os.path.join(out, "mesh_tet.vtu"), proxy=mesh)
# Whole elements behind a plane through the box's centre (Crinkle: no cut elements).
bounds = grid.GetBounds()
cut = Clip(Input=mesh, ClipType="Plane", Crinkleclip=1)
cut.ClipType.Origin = [(bounds[0] + bounds[1]) / 2, (bounds[2] + bounds[3]) / 2,
                       (bounds[4] + bounds[5]) / 2]
cut.ClipType.Normal = [0, 1, 0]
view = CreateView("RenderView")
view.OrientationAxesVisibility = 0
shown = Show(cut, view)
shown.SetRepresentationType("Surface With Edges")
ColorBy(shown, ("CELLS", "phase"))
view.CameraPosition = [bounds[1] * 1.2, 3.0 * bounds[3], bounds[5] * 1.8]  # facing the cut
view.CameraFocalPoint = cut.ClipType.Origin
view.CameraViewUp = [0, 0, 1]
view.ResetCamera()
SaveScreenshot(os.path.join(out, "mesh_tet.png"), view, ImageResolution=[800, 700])
print("wrote", out)
sys.stdout.flush()
os._exit(0)  # no GL teardown at exit (GLXBadContext under Xvfb)
