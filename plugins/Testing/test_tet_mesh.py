"""pvpython test: the RVE Tetrahedral Mesh filter on the generator's Inclusions output.

1. The analyst's sample scene (samples/scenes/fe_spheres_rods.json): an unstructured grid of
   tetrahedra whose volumes are positive and fill the box, each phase's volume within 1 % of the
   exact one (computed here from the inclusion list the input carries), phase names in field
   data; progress rises to 1 through values strictly between 0 and 1.
2. An abort set from a progress observer inside the volume stage (progress above 0.36) ends
   the run at the end of that stage (Gmsh cannot be interrupted inside one): no progress after
   it, sooner than the whole run, an empty mesh; the filter then meshes again.
3. A scene the mesher cannot take (the default one with wavy fibres), a bad chord error and
   a mesh larger than the machine's memory (the default scene at a chord error of 1e-5: about
   10^10 elements) give errors and no mesh.
4. ParaView reads mesh_tet.vtu that `rvegen generate` writes (a coarse mesh of the sample):
   tetrahedra with phase and inclusion_id, as many as report.json counts.
5. Order 2 on the filter (a coarse mesh): quadratic tetrahedra whose corners fill the box and
   whose midside nodes lie in the middle of their edges; ParaView reads the command line's
   10-node mesh_tet.vtu.
6. Debonded spheres and coated ellipsoids: their voids and shells are phases of the mesh, the
   voids' volume within 1 % of the exact one.
7. One pipeline: a scene's mesh from the RVE Generator and this filter is the command line's.
   The inclusions meshed (field data rvegen_inclusions, after the nudge) are those of
   inclusions.json, number for number; the cell (field data cell_origin, and the information
   property CellOrigin) and the nudged count (NudgedInclusions) are report.json's; the mesh fills
   that cell; the nodes on the cell's faces (the surface mesh there, which fixes the periodic
   pairs) are the command line's mesh_tet.vtu's, node for node; its element count is within 3 %
   and each phase's volume within 0.1 % of the command line's. (Gmsh's HXT does not give the
   same inside nodes and elements twice, even on one thread and from one process: it orders the
   surface nodes it is given by their addresses in memory. So those are compared by count and
   volume.)
8. Reproducible meshes ("reproducible": true, the filter's Reproducible): the command line's
   mesh_tet.vtu and the filter's output are the same nodes and elements, exactly.

usage: pvpython test_tet_mesh.py PLUGIN.so SAMPLES_DIR RVEGEN WORK_DIR
"""
import json
import math
import os
import subprocess
import sys
import time

from paraview.simple import *  # noqa: F401,F403
from paraview import servermanager
from vtkmodules.util.numpy_support import vtk_to_numpy
import numpy as np

plugin, samples, rvegen, work = sys.argv[1:5]
failures = []


def check(cond, msg):
    if not cond:
        failures.append(msg)
        print("FAIL:", msg)


def volumes(grid, nodes=4):
    """Element volumes and phases of an unstructured grid of tetrahedra (`nodes` 4 or 10)."""
    pts = vtk_to_numpy(grid.GetPoints().GetData())
    conn = vtk_to_numpy(grid.GetCells().GetConnectivityArray()).reshape(-1, nodes)
    P = pts[conn]
    vol = np.einsum("ij,ij->i", P[:, 1] - P[:, 0],
                    np.cross(P[:, 2] - P[:, 0], P[:, 3] - P[:, 0])) / 6
    phase = vtk_to_numpy(grid.GetCellData().GetArray("phase")).astype(int)
    return vol, phase


LoadPlugin(plugin, ns=globals())
gen = RVEGenerator(SceneFile=samples + "/scenes/fe_spheres_rods.json")
mesh = RVETetrahedralMesh(Input=OutputPort(gen, 0))
alg = mesh.GetClientSideObject()
gen.UpdatePipeline()  # the packing first: `whole` times the mesh alone
values = []
tag = alg.AddObserver("ProgressEvent", lambda o, e: values.append(o.GetProgress()))
start = time.monotonic()
mesh.UpdatePipeline()
whole = time.monotonic() - start
alg.RemoveObserver(tag)
grid = servermanager.Fetch(mesh)
vol, phase = volumes(grid)
print("tetrahedra %d, progress values %d" % (len(vol), len(values)))
check(len(vol) > 100000, "only %d tetrahedra" % len(vol))
check(vol.min() > 0, "an element has volume %g" % vol.min())
incs = json.loads(servermanager.Fetch(gen).GetFieldData().GetAbstractArray("rvegen_inclusions").GetValue(0))
L = incs["box"]["size"][0]
check(abs(vol.sum() / L ** 3 - 1) < 1e-9, "the elements do not fill the box: %g" % vol.sum())
exact = {}
for i in incs["inclusions"]:
    v = (4 / 3 * math.pi * i["radius"] ** 3 if i["shape"] == "sphere"
         else math.pi * i["radius"] ** 2 * 2 * np.linalg.norm(i["half_axis"]))
    exact[i["family"] + 1] = exact.get(i["family"] + 1, 0.0) + v
exact[0] = L ** 3 - sum(exact.values())
for label, v in exact.items():
    got = vol[phase == label].sum()
    check(abs(got / v - 1) < 0.01, "phase %d: volume %g, exact %g" % (label, got, v))
names = grid.GetFieldData().GetAbstractArray("phase_names")
check(names is not None and names.GetValue(0) == "matrix", "no phase_names")
check(values and values[-1] == 1.0, "progress does not end at 1: %s" % values[-3:])
check(len([v for v in values if 0 < v < 1]) >= 4, "progress: %s" % values)
check(all(a <= b for a, b in zip(values, values[1:])), "progress falls: %s" % values)

# 2. Abort inside the volume stage.
state = {"at": None, "after": []}


def on_progress(obj, ev):
    if state["at"] is None and obj.GetProgress() > 0.36:
        state["at"] = time.monotonic()
        obj.SetAbortExecute(1)
    elif state["at"] is not None:
        state["after"].append(obj.GetProgress())


# The same settings as the whole run above, so that the abort is timed against the same work:
# a value pushed and the default back, so that the filter runs again.
default_max_size = mesh.MaxSize
mesh.MaxSize = 0.05
mesh.SMProxy.UpdateVTKObjects()
mesh.MaxSize = default_max_size
tag = alg.AddObserver("ProgressEvent", on_progress)
mesh.UpdatePipeline()
end = time.monotonic()
alg.RemoveObserver(tag)
check(state["at"] is not None, "the abort was never set")
if state["at"] is not None:
    print("abort returned after %.2f s (whole run %.2f s)" % (end - state["at"], whole))
    check(end - state["at"] < whole, "abort took %.2f s, the whole run %.2f s" % (end - state["at"], whole))
    # The pipeline itself reports 1 when the filter returns.
    check(state["after"] in ([], [1.0]), "progress after the abort: %s" % state["after"])
check(servermanager.Fetch(mesh).GetNumberOfCells() == 0, "an aborted mesh is not empty")
mesh.MaxSize = 0.06
mesh.UpdatePipeline()
check(servermanager.Fetch(mesh).GetNumberOfCells() > 100000, "no mesh after the abort")

# 3. What the mesher refuses.
wavy = RVEGenerator(Resolution=[8, 8, 8], FibreWaveAmplitude=0.01)
refused = RVETetrahedralMesh(Input=OutputPort(wavy, 0))
refused.UpdatePipeline()
check(servermanager.Fetch(refused).GetNumberOfCells() == 0, "wavy fibres were meshed")
default = RVEGenerator(Resolution=[8, 8, 8])
huge = RVETetrahedralMesh(Input=OutputPort(default, 0), ChordError=1e-5)
huge.UpdatePipeline()
check(servermanager.Fetch(huge).GetNumberOfCells() == 0, "a mesh beyond the memory was not refused")
mesh.ChordError = 0.5
mesh.UpdatePipeline()
check(servermanager.Fetch(mesh).GetNumberOfCells() == 0, "a chord error of 0.5 was meshed")
mesh.ChordError = 0.03
mesh.Order = 5
mesh.UpdatePipeline()
check(servermanager.Fetch(mesh).GetNumberOfCells() == 0, "Order 5 was meshed")
mesh.Order = 1
for gap in (float("nan"), float("inf")):
    mesh.MinGap = gap
    mesh.UpdatePipeline()
    check(servermanager.Fetch(mesh).GetNumberOfCells() == 0, "MinGap %s was taken" % gap)
mesh.MinGap = -1.0

# 4. The command line's mesh_tet.vtu in ParaView's reader.
os.makedirs(work, exist_ok=True)
scene = json.load(open(samples + "/scenes/fe_spheres_rods.json"))
scene["mesh_tet"] = {"chord_error": 0.03}
scene["outputs"] = ["mesh_tet"]
with open(os.path.join(work, "coarse.json"), "w") as f:
    json.dump(scene, f)
subprocess.run([rvegen, "generate", "-q", os.path.join(work, "coarse.json"), "-o",
                os.path.join(work, "coarse")], check=True)
counted = json.load(open(os.path.join(work, "coarse", "report.json")))["mesh_tet"]["tetrahedra"]
reader = XMLUnstructuredGridReader(FileName=[os.path.join(work, "coarse", "mesh_tet.vtu")])  # noqa: F405
reader.UpdatePipeline()
read = servermanager.Fetch(reader)
check(read.GetNumberOfCells() == counted and read.GetCellType(0) == 10,
      "mesh_tet.vtu: %d cells of type %d, report %d" % (read.GetNumberOfCells(), read.GetCellType(0), counted))
check(read.GetCellData().GetArray("phase") is not None
      and read.GetCellData().GetArray("inclusion_id") is not None, "mesh_tet.vtu lacks its arrays")

# 5. Second order.
mesh.ChordError = 0.03
mesh.Order = 2
mesh.UpdatePipeline()
quad = servermanager.Fetch(mesh)
check(quad.GetNumberOfCells() > 1000 and quad.GetCellType(0) == 24,
      "Order 2: %d cells of type %d" % (quad.GetNumberOfCells(), quad.GetCellType(0)))
if quad.GetNumberOfCells() > 0 and quad.GetCellType(0) == 24:
    vol, _ = volumes(quad, 10)
    check(vol.min() > 0 and abs(vol.sum() / L ** 3 - 1) < 1e-9, "Order 2: the corners' elements")
    pts = vtk_to_numpy(quad.GetPoints().GetData())
    conn = vtk_to_numpy(quad.GetCells().GetConnectivityArray()).reshape(-1, 10)
    off = max(np.abs(pts[conn[:, 4 + k]] - 0.5 * (pts[conn[:, a]] + pts[conn[:, b]])).max()
              for k, (a, b) in enumerate([(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]))
    check(off < 1e-12, "Order 2: a midside node %g off its edge's middle" % off)
scene["mesh_tet"]["order"] = 2
with open(os.path.join(work, "quadratic.json"), "w") as f:
    json.dump(scene, f)
subprocess.run([rvegen, "generate", "-q", os.path.join(work, "quadratic.json"), "-o",
                os.path.join(work, "quadratic")], check=True)
reader = XMLUnstructuredGridReader(FileName=[os.path.join(work, "quadratic", "mesh_tet.vtu")])  # noqa: F405
reader.UpdatePipeline()
read = servermanager.Fetch(reader)
check(read.GetNumberOfCells() > 1000 and read.GetCellType(0) == 24,
      "10-node mesh_tet.vtu: %d cells of type %d" % (read.GetNumberOfCells(), read.GetCellType(0)))

# 6. Debonded spheres and coated ellipsoids, through the generator's inclusion list (which
#    carries the debonding axes): the voids and the shells are phases of their own.
mixed = {"box": {"size": [0.6, 0.6, 0.6]}, "seed": 2, "min_gap": 0.01, "families": [
    {"name": "loose", "shape": "sphere", "radius": 0.1, "count": 2,
     "debonding": {"fraction": 0.4, "gap": 0.02}},
    {"name": "grains", "shape": "ellipsoid", "semi_axes": [0.1, 0.07, 0.05], "count": 2,
     "coating": {"thickness": 0.01}, "orientation": {"law": "isotropic"}}]}
with open(os.path.join(work, "mixed.json"), "w") as f:
    json.dump(mixed, f)
gen6 = RVEGenerator(SceneFile=os.path.join(work, "mixed.json"))
mesh6 = RVETetrahedralMesh(Input=OutputPort(gen6, 0), ChordError=0.03)
mesh6.UpdatePipeline()
grid6 = servermanager.Fetch(mesh6)
check(grid6.GetNumberOfCells() > 1000, "debonded spheres and coated ellipsoids were not meshed")
if grid6.GetNumberOfCells() > 1000:
    vol, phase = volumes(grid6)
    arr = grid6.GetFieldData().GetAbstractArray("phase_names")
    names = [arr.GetValue(k) for k in range(arr.GetNumberOfValues())]
    check(names == ["matrix", "loose", "grains", "loose void", "grains interphase"], "phases: %s" % names)
    check(vol.min() > 0 and abs(vol.sum() / 0.6 ** 3 - 1) < 1e-9, "the mixed mesh does not fill the box")
    incs6 = json.loads(servermanager.Fetch(gen6).GetFieldData().GetAbstractArray("rvegen_inclusions").GetValue(0))
    voids = sum(0.4 * 4 / 3 * math.pi * ((i["radius"] + 0.02) ** 3 - i["radius"] ** 3)
                for i in incs6["inclusions"] if i["shape"] == "sphere")
    if "loose void" in names:
        got = vol[phase == names.index("loose void")].sum()
        check(abs(got / voids - 1) < 0.01, "voids: volume %g, exact %g" % (got, voids))
    if "grains interphase" in names:
        check(vol[phase == names.index("grains interphase")].sum() > 0, "no interphase volume")

# 7. One pipeline: the command line's mesh of a scene and ParaView's.
scene["mesh_tet"] = {"chord_error": 0.03}
scene["outputs"] = ["inclusions", "mesh_tet"]
with open(os.path.join(work, "same.json"), "w") as f:
    json.dump(scene, f)
subprocess.run([rvegen, "generate", "-q", os.path.join(work, "same.json"), "-o",
                os.path.join(work, "same")], check=True)
cli_report = json.load(open(os.path.join(work, "same", "report.json")))["mesh_tet"]
cli_incs = json.load(open(os.path.join(work, "same", "inclusions.json")))
gen7 = RVEGenerator(SceneFile=os.path.join(work, "same.json"))
mesh7 = RVETetrahedralMesh(Input=OutputPort(gen7, 0), ChordError=0.03)
mesh7.UpdatePipeline()
grid7 = servermanager.Fetch(mesh7)
fd = grid7.GetFieldData()
check(fd.GetAbstractArray("rvegen_inclusions") is not None, "no rvegen_inclusions on the mesh")
if fd.GetAbstractArray("rvegen_inclusions") is not None:
    pv_incs = json.loads(fd.GetAbstractArray("rvegen_inclusions").GetValue(0))
    check(pv_incs["inclusions"] == cli_incs["inclusions"],
          "ParaView meshed other inclusions than the command line")
origin = fd.GetArray("cell_origin")
check(origin is not None and list(origin.GetTuple3(0)) == cli_report["cell_origin"],
      "cell_origin: %s, command line %s" % (origin and origin.GetTuple3(0), cli_report["cell_origin"]))
# The generator's own nudge (the scene lists mesh_tet) and the filter's add up to the command
# line's count; the filter's information properties CellOrigin and NudgedInclusions show the
# same as its field data.
gen_nudged = servermanager.Fetch(gen7).GetFieldData().GetArray("nudged_inclusions")
check(gen_nudged is not None and gen_nudged.GetValue(0) <= cli_report["nudged_inclusions"],
      "the generator carries no nudged_inclusions, or more than the command line's")
mesh7.UpdatePropertyInformation()
panel_origin = [mesh7.SMProxy.GetProperty("CellOrigin").GetElement(k) for k in range(3)]
check(panel_origin == cli_report["cell_origin"],
      "CellOrigin %s, command line %s" % (panel_origin, cli_report["cell_origin"]))
check(mesh7.SMProxy.GetProperty("NudgedInclusions").GetElement(0) == cli_report["nudged_inclusions"],
      "NudgedInclusions differ from the command line's")
nudged = fd.GetArray("nudged_inclusions")
check(nudged is not None and nudged.GetValue(0) == cli_report["nudged_inclusions"],
      "nudged_inclusions differ from the command line's %d" % cli_report["nudged_inclusions"])
n7 = grid7.GetNumberOfCells()
check(abs(n7 / cli_report["tetrahedra"] - 1) < 0.03,
      "%d tetrahedra, the command line %d" % (n7, cli_report["tetrahedra"]))
if n7 > 0 and origin is not None:
    b = grid7.GetBounds()
    o = origin.GetTuple3(0)
    check(max(abs(b[2 * k] - o[k]) for k in range(3)) < 1e-12
          and max(abs(b[2 * k + 1] - o[k] - L) for k in range(3)) < 1e-12,
          "the mesh %s does not fill the cell at %s" % (b, o))
    # The nodes on the cell's faces, node for node.
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader
    reader = vtkXMLUnstructuredGridReader()
    reader.SetFileName(os.path.join(work, "same", "mesh_tet.vtu"))
    reader.Update()

    def face_nodes(grid):
        xyz = vtk_to_numpy(grid.GetPoints().GetData()).astype(float)
        lo, hi = np.array(o), np.array(o) + L
        on = (np.abs(xyz - lo) < 1e-9 * L).any(axis=1) | (np.abs(xyz - hi) < 1e-9 * L).any(axis=1)
        f = xyz[on]
        return f[np.lexsort((f[:, 2], f[:, 1], f[:, 0]))]

    cli_origin = reader.GetOutput().GetFieldData().GetArray("cell_origin")
    check(cli_origin is not None and list(cli_origin.GetTuple3(0)) == cli_report["cell_origin"],
          "the command line's mesh_tet.vtu carries no cell_origin, or another one")
    pv_faces, cli_faces = face_nodes(grid7), face_nodes(reader.GetOutput())
    check(len(cli_faces) > 100 and pv_faces.shape == cli_faces.shape
          and np.abs(pv_faces - cli_faces).max() <= 1e-12 * L,
          "the nodes on the cell's faces differ: %d in ParaView, %d from the command line"
          % (len(pv_faces), len(cli_faces)))
    vol, phase = volumes(grid7)
    for p in cli_report["phases"]:
        got = vol[phase == p["label"]].sum()
        check(abs(got / p["volume"] - 1) < 1e-3,
              "phase %s: %g in ParaView, %g from the command line" % (p["name"], got, p["volume"]))

# 8. Reproducible meshes (Gmsh's Delaunay volume mesher, one thread): the command line's
# mesh_tet.vtu and the filter's output are the same mesh, node for node and element for element.
scene["mesh_tet"] = {"chord_error": 0.03, "reproducible": True}
with open(os.path.join(work, "repro.json"), "w") as f:
    json.dump(scene, f)
subprocess.run([rvegen, "generate", "-q", os.path.join(work, "repro.json"), "-o",
                os.path.join(work, "repro")], check=True)
repro_report = json.load(open(os.path.join(work, "repro", "report.json")))["mesh_tet"]
check(repro_report["mesher"].endswith("Delaunay)"), "reproducible: mesher %s" % repro_report["mesher"])
gen8 = RVEGenerator(SceneFile=os.path.join(work, "repro.json"))
mesh8 = RVETetrahedralMesh(Input=OutputPort(gen8, 0), ChordError=0.03, Reproducible=1)
mesh8.UpdatePipeline()
grid8 = servermanager.Fetch(mesh8)
from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader  # noqa: E402
reader8 = vtkXMLUnstructuredGridReader()
reader8.SetFileName(os.path.join(work, "repro", "mesh_tet.vtu"))
reader8.Update()
cli8 = reader8.GetOutput()


def arrays(grid):
    return (vtk_to_numpy(grid.GetPoints().GetData()).astype(float),
            vtk_to_numpy(grid.GetCells().GetConnectivityArray()).astype(np.int64),
            vtk_to_numpy(grid.GetCellData().GetArray("phase")).astype(np.int64))


if grid8.GetNumberOfCells() > 0 and cli8.GetNumberOfCells() > 0:
    (px, pc, pp), (cx, cc, cp) = arrays(grid8), arrays(cli8)
    check(px.shape == cx.shape and np.array_equal(px, cx),
          "reproducible: %d nodes in ParaView, %d from the command line, or at other places"
          % (len(px), len(cx)))
    check(pc.shape == cc.shape and np.array_equal(pc, cc) and np.array_equal(pp, cp),
          "reproducible: the elements differ (%d and %d)"
          % (grid8.GetNumberOfCells(), cli8.GetNumberOfCells()))
else:
    check(False, "reproducible: an empty mesh")

# A failed mesh leaves no cell: CellOrigin NaN, NudgedInclusions -1 (not the last mesh's).
mesh7.ChordError = 0.5
try:
    mesh7.UpdatePipeline()
except Exception:
    pass
mesh7.UpdatePropertyInformation()
check(all(math.isnan(mesh7.SMProxy.GetProperty("CellOrigin").GetElement(k)) for k in range(3))
      and mesh7.SMProxy.GetProperty("NudgedInclusions").GetElement(0) == -1,
      "a failed mesh kept the last mesh's CellOrigin or NudgedInclusions")

if failures:
    print("%d failure(s)" % len(failures))
    sys.exit(1)
print("all tetrahedral mesh filter checks passed")
