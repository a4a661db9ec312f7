"""The standard picture of an RVE: inclusions coloured by family inside the box outline.

Shared by samples/render_rve.py and the plugin's image-regression test.
"""
from paraview.simple import (ColorBy, CreateView, GetColorTransferFunction, Outline, Render,
                             SaveScreenshot, Show)


def white_view():
    """A render view with a white background and no orientation axes."""
    view = CreateView("RenderView")
    view.OrientationAxesVisibility = 0
    view.Background = [1, 1, 1]
    try:
        view.UseColorPaletteForBackground = 0
    except AttributeError:
        pass
    return view


def save_rve_picture(surfaces, box_source, out_png, size):
    """Renders `surfaces` (polydata with cell array `family`) and the outline of `box_source`
    (the voxel image) to `out_png`, `size` pixels square."""
    view = white_view()
    view.ViewSize = [size, size]
    disp = Show(surfaces, view)
    ColorBy(disp, ("CELLS", "family"))
    GetColorTransferFunction("family").ApplyPreset("Rainbow Uniform", True)
    disp.RescaleTransferFunctionToDataRange(False, True)
    outline = Show(Outline(Input=box_source), view)
    outline.DiffuseColor = [0, 0, 0]
    view.CameraPosition = [2.6, 2.0, 1.8]
    view.CameraFocalPoint = [0.5, 0.5, 0.5]
    view.CameraViewUp = [0, 0, 1]
    view.ResetCamera()
    Render(view)
    SaveScreenshot(out_png, view, ImageResolution=[size, size])
