"""pvpython test: the RVE Effective Properties filter on the generator's Voxels output.

1. The default RVE with isotropic materials: the conductivity table is symmetric, lies within
   the Hashin-Shtrikman bounds it states, and equals what `rvegen generate` reports for the
   same scene and materials (the command line shares the core, not the VTK plumbing: image
   arrays, inclusion list, materials text).
2. Progress rises with the load cases and ends at 1; an abort set from a progress observer
   stops the elasticity solve at once and leaves the table empty; the filter then runs again.
3. Bad materials (an unknown phase) give an error and no table.

usage: pvpython test_effective.py PLUGIN.so RVEGEN WORKDIR
"""
import json
import os
import subprocess
import sys
import time

from paraview.simple import *  # noqa: F401,F403
from paraview import servermanager

plugin, rvegen, work = sys.argv[1:4]
os.makedirs(work, exist_ok=True)
failures = []


def check(cond, msg):
    if not cond:
        failures.append(msg)
        print("FAIL:", msg)


def rows(table):
    q, n, v = (table.GetColumnByName(c) for c in ("quantity", "name", "value"))
    if q is None:
        return []
    return [(q.GetValue(i), n.GetValue(i), v.GetValue(i)) for i in range(table.GetNumberOfRows())]


LoadPlugin(plugin, ns=globals())
materials = {"matrix": {"conductivity": 1, "young": 3, "poisson": 0.35},
             "spheres": {"conductivity": 10, "young": 70, "poisson": 0.2},
             "fibres": {"conductivity": 30, "young": 230, "poisson": 0.25},
             "grains": {"conductivity": 5, "young": 70, "poisson": 0.2}}

# 1. Conductivity of the default RVE against the command line.
gen = RVEGenerator()
eff = RVEEffectiveProperties(Input=OutputPort(gen, 1), Materials=json.dumps(materials))
eff.UpdatePipeline()
table = rows(servermanager.Fetch(eff))
k = {n: v for q, n, v in table if q == "conductivity"}
check(len(k) == 9, "conductivity rows: %d" % len(k))
converged = [v for q, n, v in table if q == "converged" and n == "conductivity"]
check(converged == [1.0], "converged row: %s" % converged)
if len(k) == 9:
    check(all(abs(k["k%d%d" % (i, j)] - k["k%d%d" % (j, i)]) < 1e-6 * k["k11"]
              for i in (1, 2, 3) for j in (1, 2, 3)), "conductivity not symmetric: %s" % k)
    bound = {n: v for q, n, v in table if q == "conductivity_bound"}
    mean = (k["k11"] + k["k22"] + k["k33"]) / 3
    check(bound and bound["hs_lower"] < mean < bound["hs_upper"],
          "mean conductivity %s outside the bounds %s" % (mean, bound))
    scene = json.loads(subprocess.run([rvegen, "default-scene"], check=True, capture_output=True,
                                      text=True).stdout)
    scene["materials"] = materials
    scene["homogenization"] = {"physics": ["conductivity"]}
    scene["outputs"] = ["inclusions", "mesh_voxel"]
    path = os.path.join(work, "scene.json")
    with open(path, "w") as f:
        json.dump(scene, f)
    subprocess.run([rvegen, "generate", "-q", path, "-o", os.path.join(work, "rve")], check=True)
    with open(os.path.join(work, "rve", "report.json")) as f:
        cli = json.load(f)["effective"]["conductivity"]["tensor"]
    # ParaView reads the voxel mesh the command line wrote: a hexahedron per voxel, its phase.
    mesh = XMLUnstructuredGridReader(FileName=[os.path.join(work, "rve", "mesh_voxel.vtu")])
    mesh.UpdatePipeline()
    grid = servermanager.Fetch(mesh)
    check(grid.GetNumberOfCells() == 64 ** 3 and grid.GetCellType(0) == 12,
          "mesh_voxel.vtu: %d cells of type %d" % (grid.GetNumberOfCells(), grid.GetCellType(0)))
    check(grid.GetCellData().GetArray("phase") is not None, "mesh_voxel.vtu has no phase")
    worst = max(abs(cli[i][j] - k["k%d%d" % (i + 1, j + 1)]) for i in range(3) for j in range(3))
    print("largest difference to rvegen generate: %.3e" % worst)
    check(worst < 1e-9 * cli[0][0], "filter and command line differ by %.3e" % worst)

# 2. Progress, abort, and a run after it.
eff.Physics = 1  # elasticity: 6 load cases
alg = eff.GetClientSideObject()
values, stop_at = [], [None]


def on_progress(obj, ev):
    values.append(obj.GetProgress())
    # Once, inside the solve (the executive's final 1.0 comes after the filter returned).
    if stop_at[0] is not None and len(stop_at) == 1 and stop_at[0] < obj.GetProgress() < 1.0:
        obj.SetAbortExecute(1)
        stop_at.append(time.time())


tag = alg.AddObserver("ProgressEvent", on_progress)
eff.UpdatePipeline()
check(values and values[-1] == 1.0, "progress does not end at 1: %s" % values[-3:])
inner = [v for v in values if 0.0 < v < 1.0]
check(len(inner) >= 6, "fewer than 6 progress values inside (0, 1): %s" % inner)
check(all(a <= b for a, b in zip(values, values[1:])), "progress falls: %s" % values)
full = rows(servermanager.Fetch(eff))
check(any(q == "stiffness" for q, _, _ in full), "no stiffness rows")
values.clear()
stop_at[0] = 0.3
eff.Tolerance = 1e-7  # a new request
eff.UpdatePipeline()
done = time.time()
aborted = rows(servermanager.Fetch(eff))
check(len(stop_at) == 2, "the observer never aborted (progress %s)" % values[-3:])
if len(stop_at) == 2:
    print("update returned %.3f s after the abort" % (done - stop_at[1]))
    check(done - stop_at[1] < 2.0, "update returned %.1f s after the abort" % (done - stop_at[1]))
check(not aborted, "table after abort has %d rows" % len(aborted))
alg.RemoveObserver(tag)
eff.Tolerance = 1e-6
eff.UpdatePipeline()
again = rows(servermanager.Fetch(eff))
check(any(q == "stiffness" for q, _, _ in again), "no stiffness after the abort")

# 3. Bad materials: an error, no table.
eff.Materials = json.dumps({"matrx": {"conductivity": 1}})
eff.UpdatePipeline()
check(not rows(servermanager.Fetch(eff)), "a table for unknown materials")
# Enumerations out of range: an error and no table, as on the command line (they were clamped
# to the nearest value and solved).
eff.Materials = json.dumps(materials)
for prop, value in (("Physics", 5), ("VoxelRule", 7), ("Scheme", -1)):
    eff.GetProperty(prop).SetElement(0, value)
    eff.UpdateVTKObjects()
    eff.UpdatePipeline()
    check(not rows(servermanager.Fetch(eff)), "a table for %s %d" % (prop, value))
    eff.GetProperty(prop).SetElement(0, {"Physics": 0, "VoxelRule": 3, "Scheme": 0}[prop])
    eff.UpdateVTKObjects()

if failures:
    print("%d failure(s)" % len(failures))
    sys.exit(1)
print("ok")
