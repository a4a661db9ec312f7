"""Pictures of an RVE for a report, made headless.

usage: xvfb-run -a -s "-screen 0 1280x1024x24" \\
         pvbatch --force-offscreen-rendering samples/rve_report.py RVE_DIR OUT_DIR [SIZE]

RVE_DIR is what `rvegen generate` wrote. Writes in OUT_DIR:
  inclusions_3d.png     3D view of the inclusions coloured by family, inside the box outline
  voxel_slices.png      two slices of the voxel image side by side (z and x through the middle),
                        coloured by phase (the paper's Figure 4)
  interphase_slice.png  a z slice with the interphase and void phases highlighted (Figure 5)
  charts/*.png          the benchmark charts (samples/charts)
"""
import json
import os
import shutil
import sys

from paraview.simple import (AssignViewToLayout, ColorBy, CreateLayout, GetColorTransferFunction,
                             Render, SaveScreenshot, Show, Slice, XMLImageDataReader,
                             XMLPolyDataReader)

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, here)
from rve_view import save_rve_dir_picture, white_view  # noqa: E402

rve, out = sys.argv[1], sys.argv[2]
size = int(sys.argv[3]) if len(sys.argv) > 3 else 600
os.makedirs(out, exist_ok=True)
with open(os.path.join(rve, "report.json")) as f:
    report = json.load(f)
phases = report["phases"]
voxels = XMLImageDataReader(FileName=[os.path.join(rve, "voxels.vti")])
voxels.UpdatePipeline()
bounds = voxels.GetDataInformation().GetBounds()
centre = [0.5 * (bounds[2 * a] + bounds[2 * a + 1]) for a in range(3)]

save_rve_dir_picture(rve, voxels, os.path.join(out, "inclusions_3d.png"), size)

# Phase colours: matrix light grey, cores in distinct dark colours, interphases bright yellow,
# voids black (the highlight of Figure 5 uses the same table with the cores toned down).
CORE_COLOURS = [[0.12, 0.35, 0.70], [0.70, 0.15, 0.30], [0.15, 0.55, 0.30], [0.50, 0.30, 0.65],
                [0.85, 0.45, 0.10], [0.35, 0.35, 0.35]]


def phase_lut(highlight):
    lut = GetColorTransferFunction("phase_" + ("hl" if highlight else "plain"))
    lut.InterpretValuesAsCategories = 1
    values, colours, labels = [], [], []
    for p in phases:
        if p["kind"] == "matrix":
            c = [0.92, 0.92, 0.92]
        elif p["kind"] == "core":
            c = [0.55, 0.60, 0.70] if highlight else CORE_COLOURS[p["family"] % len(CORE_COLOURS)]
        elif p["kind"] == "interphase":
            c = [1.0, 0.85, 0.0]
        else:  # void
            c = [0.0, 0.0, 0.0]
        values.append(p["label"])
        colours += c
        labels += [str(p["label"]), p["name"]]
    lut.Annotations = labels
    lut.IndexedColors = colours
    return lut


def slice_view(normal, highlight):
    view = white_view()
    cut = Slice(Input=voxels)
    cut.SliceType = "Plane"
    cut.SliceType.Origin = centre
    cut.SliceType.Normal = normal
    disp = Show(cut, view)
    ColorBy(disp, ("CELLS", "phase"))
    disp.LookupTable = phase_lut(highlight)
    view.CameraParallelProjection = 1
    view.CameraFocalPoint = centre
    view.CameraPosition = [centre[a] + 3.0 * normal[a] for a in range(3)]
    view.CameraViewUp = [0, 1, 0] if normal[2] else [0, 0, 1]
    view.ResetCamera()
    return view


layout = CreateLayout("slices")
left = slice_view([0, 0, 1], False)
AssignViewToLayout(view=left, layout=layout, hint=0)
layout.SplitHorizontal(0, 0.5)
right = slice_view([1, 0, 0], False)
AssignViewToLayout(view=right, layout=layout, hint=2)
Render(left)
Render(right)
SaveScreenshot(os.path.join(out, "voxel_slices.png"), layout, ImageResolution=[2 * size, size])

hl = slice_view([0, 0, 1], True)
Render(hl)
SaveScreenshot(os.path.join(out, "interphase_slice.png"), hl, ImageResolution=[size, size])

charts = os.path.join(here, "charts")
if os.path.isdir(charts):
    os.makedirs(os.path.join(out, "charts"), exist_ok=True)
    for name in sorted(os.listdir(charts)):
        if name.endswith(".png") and "_quick" not in name:
            shutil.copy(os.path.join(charts, name), os.path.join(out, "charts", name))
print("wrote", out)
