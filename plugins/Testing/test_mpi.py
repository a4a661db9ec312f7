"""Distributed voxels: run under `mpirun -np 2 pvbatch`. The source computes the packing on every
rank (same seed, same RVE) and voxelizes only the extent each rank is asked for. The image is
written in parallel (.pvti: one piece per rank), read back and compared voxel by voxel with the
serial image of the command line for the same (default) scene.

usage: mpirun -np 2 pvbatch test_mpi.py PLUGIN.so OUT_DIR CLI_OUTPUT_DIR
"""
import os
import sys

from paraview.simple import *  # noqa: F401,F403
from paraview import servermanager
from vtkmodules.vtkIOXML import vtkXMLImageDataReader, vtkXMLPImageDataReader

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from checks import differing_values  # noqa: E402

plugin, out_dir, cli_dir = sys.argv[1:4]
os.makedirs(out_dir, exist_ok=True)
failures = []


def check(cond, msg):
    if not cond:
        failures.append(msg)
        print("FAIL:", msg)


ranks = servermanager.vtkProcessModule.GetProcessModule().GetNumberOfLocalPartitions()
check(ranks == 2, "expected 2 ranks, got %d" % ranks)
LoadPlugin(plugin, ns=globals())
gen = RVEGenerator()
SaveData(os.path.join(out_dir, "voxels.pvti"), proxy=OutputPort(gen, 1))

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

if failures:
    print("%d failure(s)" % len(failures))
    sys.exit(1)
print("ok")
