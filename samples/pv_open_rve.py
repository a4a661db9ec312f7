"""Open an RVE written earlier by `rvegen generate` in pvpython: statistics and a picture.

usage: xvfb-run -a -s "-screen 0 1280x1024x24" pvpython --force-offscreen-rendering \\
         samples/pv_open_rve.py RVE_DIR [OUT.png]

Reads inclusions.vtp (the inclusions, carrying the inclusion list) and voxels.vti (the voxel
image), prints the RVE Statistics table, re-voxelizes the RVE at 96^3 with RVE Voxelize (no
repacking), and saves a slice of the new image coloured by phase to OUT.png, by default next to
the RVE directory (RVE_DIR_slice96.png), never inside it: the directory stays a set that
`rvegen generate -o RVE_DIR` may replace.
"""
import os
import sys

from paraview import servermanager
from paraview.simple import (ColorBy, CreateView, OpenDataFile, SaveScreenshot, Show, Slice,
                             XMLPolyDataReader)

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rvegen_paraview import load_rvegen, statistics_rows  # noqa: E402

rve = sys.argv[1]
out = sys.argv[2] if len(sys.argv) > 2 else os.path.normpath(rve) + "_slice96.png"
load_rvegen(globals())  # defines RVEStatistics, RVEVoxelize, RVEGenerator here
surfaces = XMLPolyDataReader(FileName=[os.path.join(rve, "inclusions.vtp")])
image = OpenDataFile(os.path.join(rve, "voxels.vti"))
image.UpdatePipeline()
print("voxels.vti:", image.GetDataInformation().GetNumberOfCells(), "voxels")
for q, n, i, v in statistics_rows(servermanager.Fetch(RVEStatistics(Input=surfaces))):
    if q in ("volume_fraction", "count", "nearest_neighbour_distance"):
        print("%-28s %-24s %g" % (q, n, v))
fine = RVEVoxelize(Input=surfaces, Resolution=[96, 96, 96])
cut = Slice(Input=fine)
cut.SliceType.Origin = [0.5, 0.5, 0.5]
cut.SliceType.Normal = [0, 0, 1]
view = CreateView("RenderView")
view.OrientationAxesVisibility = 0
ColorBy(Show(cut, view), ("CELLS", "phase"))
view.ResetCamera()
SaveScreenshot(out, view, ImageResolution=[500, 500])
print("wrote", out)
sys.stdout.flush()
os._exit(0)  # no GL teardown at exit (GLXBadContext under Xvfb)
