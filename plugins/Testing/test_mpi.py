"""Distributed run: under `mpirun -np 2 pvbatch`. Rank 0 packs and broadcasts the inclusion list
(the packing runs once in all), each rank voxelizes only the extent it is asked for and gives the
glyph points of its own inclusions. The image is written in parallel (.pvti: one piece per rank),
read back and compared voxel by voxel with the serial image of the command line for the same
(default) scene; the gathered points are compared with the command line's inclusions.vtp.

With --symmetric every rank runs this script and the pipeline in step: rank 0 packs and
broadcasts (PackingRuns, summed over the ranks, is 1). Without it only rank 0 runs the script and
every rank packs the same RVE itself (no collective where satellites may not be executing).

RVE Effective Properties on the Voxels port: with --symmetric the ranks solve together, each on
its own z slab of the image (its input holds only those planes), and the conductivity equals
`rvegen homogenize` in one process to 1e-10 relative; driven from rank 0, each rank solves the
whole image (no collective) and the result is the same.

usage: mpirun -np 2 pvbatch [--symmetric] test_mpi.py PLUGIN.so OUT_DIR CLI_OUTPUT_DIR RVEGEN
"""
import json
import os
import subprocess
import sys

from paraview.simple import *  # noqa: F401,F403
from paraview import servermanager
from vtkmodules.vtkIOXML import vtkXMLImageDataReader, vtkXMLPImageDataReader, vtkXMLPolyDataReader, vtkXMLPPolyDataReader

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from checks import differing_values  # noqa: E402

plugin, out_dir, cli_dir, rvegen = sys.argv[1:5]
os.makedirs(out_dir, exist_ok=True)
failures = []


def check(cond, msg):
    if not cond:
        failures.append(msg)
        print("FAIL:", msg)


pm = servermanager.vtkProcessModule.GetProcessModule()
ranks = pm.GetNumberOfLocalPartitions()
symmetric = pm.GetSymmetricMPIMode()
check(ranks == 2, "expected 2 ranks, got %d" % ranks)
LoadPlugin(plugin, ns=globals())
gen = RVEGenerator()
# Collective steps first (with --symmetric every rank runs them), then rank 0 checks the files.
SaveData(os.path.join(out_dir, "voxels.pvti"), proxy=OutputPort(gen, 1))
SaveData(os.path.join(out_dir, "inclusions.pvtp"), proxy=OutputPort(gen, 0))
gen.UpdatePropertyInformation()
runs = gen.GetProperty("PackingRuns").GetElement(0)
if symmetric:
    check(runs == 1, "the RVE was packed %d times over 2 ranks" % runs)

# Effective conductivity on the Voxels port (collective with --symmetric).
materials = {"matrix": {"conductivity": 1}, "spheres": {"conductivity": 10},
             "fibres": {"axial_conductivity": 50, "transverse_conductivity": 5},
             "grains": {"conductivity": 5}}
tolerance = 1e-9
eff = RVEEffectiveProperties(Input=OutputPort(gen, 1), Materials=json.dumps(materials),
                             Physics=0, Tolerance=tolerance)
eff.UpdatePipeline()
planes = eff.GetClientSideObject().GetInputDataObject(0, 0).GetExtent()[4:6]
print("rank %d solved planes %d..%d of z" % (pm.GetPartitionId(), planes[0], planes[1]))
if symmetric:
    check(0 < planes[1] - planes[0] < 64, "rank %d was given planes %s of 64"
          % (pm.GetPartitionId(), planes))
effective_table = servermanager.Fetch(eff)


def effective_rows(table):
    q, n, v = (table.GetColumnByName(c) for c in ("quantity", "name", "value"))
    if q is None:
        return {}
    return {(q.GetValue(i), n.GetValue(i)): v.GetValue(i) for i in range(table.GetNumberOfRows())}


def check_effective():
    """Rank 0: the table against rvegen homogenize in one process on the same inclusions."""
    got = effective_rows(effective_table)
    solved_by = got.get(("ranks", "solve"))
    check(solved_by == (2 if symmetric else 1), "solved by %s ranks" % solved_by)
    scene = json.loads(subprocess.run([rvegen, "default-scene"], check=True, capture_output=True,
                                      text=True).stdout)
    scene["materials"] = materials
    scene["homogenization"] = {"physics": ["conductivity"], "tolerance": tolerance}
    path = os.path.join(out_dir, "effective_scene.json")
    with open(path, "w") as f:
        json.dump(scene, f)
    # One process: without the launcher's variables, which would make it a rank of its own.
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_", "PMIX", "PMI_"))}
    one = json.loads(subprocess.run([rvegen, "homogenize", cli_dir, path], check=True, env=env,
                                    capture_output=True, text=True).stdout)
    k = one["conductivity"]["tensor"]
    worst = max(abs(k[i][j] - got.get(("conductivity", "k%d%d" % (i + 1, j + 1)), float("nan")))
                for i in range(3) for j in range(3))
    print("conductivity: largest difference to one process %.2e (k11 %.6f)" % (worst, k[0][0]))
    check(worst < 1e-10 * k[0][0], "the ranks' conductivity differs from one process's by %s"
          % worst)



def check_files():
    """Rank 0: the written pieces against the command line's files."""
    # One piece per rank, each a strict part of the image.
    reader = vtkXMLPImageDataReader()
    reader.SetFileName(os.path.join(out_dir, "voxels.pvti"))
    reader.Update()
    pieces = reader.GetNumberOfPieces()
    check(pieces == 2, "%d pieces written" % pieces)
    cells = []
    piece_files = sorted(f for f in os.listdir(os.path.join(out_dir, "voxels")) if f.endswith(".vti")) \
        if os.path.isdir(os.path.join(out_dir, "voxels")) else []
    for f in piece_files:
        r = vtkXMLImageDataReader()
        r.SetFileName(os.path.join(out_dir, "voxels", f))
        r.Update()
        cells.append(r.GetOutput().GetNumberOfCells())
    check(len(cells) == 2 and all(0 < c < 64 ** 3 for c in cells) and sum(cells) == 64 ** 3,
          "piece sizes %s" % cells)

    # Inclusions: each rank wrote the points of its own inclusions; together they are
    # inclusions.vtp's points, each once.
    points_reader = vtkXMLPPolyDataReader()
    points_reader.SetFileName(os.path.join(out_dir, "inclusions.pvtp"))
    points_reader.Update()
    check(points_reader.GetNumberOfPieces() == 2, "%d point pieces" % points_reader.GetNumberOfPieces())
    points = points_reader.GetOutput()
    serial_points = vtkXMLPolyDataReader()
    serial_points.SetFileName(os.path.join(cli_dir, "inclusions.vtp"))
    serial_points.Update()
    want = serial_points.GetOutput()


    def point_keys(pd):
        ids = pd.GetPointData().GetArray("inclusion_id")
        if ids is None:
            return []
        return sorted((int(ids.GetValue(i)),) + tuple(round(x, 9) for x in pd.GetPoint(i))
                      for i in range(pd.GetNumberOfPoints()))


    check(point_keys(points) == point_keys(want), "gathered points (%d) differ from inclusions.vtp (%d)"
          % (points.GetNumberOfPoints(), want.GetNumberOfPoints()))

    whole = reader.GetOutput()
    serial = vtkXMLImageDataReader()
    serial.SetFileName(os.path.join(cli_dir, "voxels.vti"))
    serial.Update()
    ref = serial.GetOutput()
    check(whole.GetNumberOfCells() == ref.GetNumberOfCells(), "assembled image has %d cells" % whole.GetNumberOfCells())
    for name in ("phase", "inclusion_id", "fraction"):
        a = whole.GetCellData().GetArray(name)
        b = ref.GetCellData().GetArray(name)
        check(a is not None and b is not None, "array %s missing" % name)
        if a is not None and b is not None and a.GetNumberOfTuples() == b.GetNumberOfTuples():
            diff = differing_values(a, b)
            check(diff == 0, "%s differs from the serial image in %d voxels" % (name, diff))



# With --symmetric the other ranks only took part in the collective steps; pvbatch must end by
# leaving the script normally (exiting early breaks MPI's finalization).
if not symmetric or pm.GetPartitionId() == 0:
    check_files()
    check_effective()
print("%s (%s, %d packing runs)" % ("%d failure(s)" % len(failures) if failures else "ok",
                                    "symmetric" if symmetric else "driven from rank 0", runs))
if failures:
    sys.exit(1)
