"""Renders an RVE written by `rvegen generate` to a PNG (headless under xvfb-run).

usage: pvpython --force-offscreen-rendering samples/render_rve.py RVE_DIR [OUT.png]
"""
import os
import sys

from paraview.simple import *  # noqa: F401,F403

rve = sys.argv[1]
out = sys.argv[2] if len(sys.argv) > 2 else os.path.join(rve, "rve.png")
surfaces = XMLPolyDataReader(FileName=[os.path.join(rve, "inclusions.vtp")])
voxels = XMLImageDataReader(FileName=[os.path.join(rve, "voxels.vti")])
view = CreateView("RenderView")
view.ViewSize = [800, 800]
view.OrientationAxesVisibility = 0
view.Background = [1, 1, 1]
try:
    view.UseColorPaletteForBackground = 0
except AttributeError:
    pass
disp = Show(surfaces, view)
ColorBy(disp, ("CELLS", "family"))
GetColorTransferFunction("family").ApplyPreset("Rainbow Uniform", True)
outline = Show(Outline(Input=voxels), view)
outline.DiffuseColor = [0, 0, 0]
view.CameraPosition = [2.6, 2.0, 1.8]
view.CameraFocalPoint = [0.5, 0.5, 0.5]
view.CameraViewUp = [0, 0, 1]
view.ResetCamera()
Render(view)
SaveScreenshot(out, view, ImageResolution=[800, 800])
print("wrote", out)
