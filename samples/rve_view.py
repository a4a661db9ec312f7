"""The standard picture of an RVE: inclusions coloured by family inside the box outline.

Shared by samples/render_rve.py and the plugin's image-regression test.
"""
import os

from paraview.simple import (ColorBy, CreateView, GetColorTransferFunction, Outline, Render,
                             SaveScreenshot, Show, Threshold, XMLPolyDataReader,
                             _DisableFirstRenderCameraReset)


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


def show_glyphs(points, view, glyph, shapes, resolution=32):
    """Shows the inclusions of `points` (inclusions.vtp: one vertex per inclusion, see the README)
    whose `shape` is in `shapes` and that are not modified, as ParaView 3D glyphs of type `glyph`
    ("Sphere" for spheres and ellipsoids, "Cylinder" for cylinders), scaled by the `scale`
    components and turned by the `orientation` quaternion: each glyph is the inclusion exactly.
    Returns the representation, coloured by `family`."""
    lo, hi = min(shapes), max(shapes)
    part = Threshold(Input=points, Scalars=["POINTS", "shape"], LowerThreshold=lo, UpperThreshold=hi)
    part = Threshold(Input=part, Scalars=["POINTS", "modified"], LowerThreshold=0, UpperThreshold=0)
    disp = Show(part, view)
    disp.SetRepresentationType("3D Glyphs")
    disp.GlyphType = glyph
    if glyph == "Sphere":
        disp.GlyphType.ThetaResolution = resolution
        disp.GlyphType.PhiResolution = resolution
    else:
        disp.GlyphType.Resolution = resolution
    disp.Scaling = 1
    disp.ScaleMode = "Vector Components"
    disp.SelectScaleArray = "scale"
    disp.ScaleFactor = 1.0
    disp.Orient = 1
    disp.OrientationMode = "Quaternion"
    disp.SelectOrientationVectors = "orientation"
    ColorBy(disp, ("POINTS", "family"))
    return disp


def show_inclusions(rve_dir, view, glyphs_only=False):
    """Shows an RVE directory's inclusions: glyphs from inclusions.vtp for the plain ones, and the
    surfaces of surfaces.vtp (wavy, deformed, coated, debonded, or all with "mesh") when
    present (not with `glyphs_only`). Returns the representations."""
    shown = []
    points = XMLPolyDataReader(FileName=[os.path.join(rve_dir, "inclusions.vtp")])
    points.UpdatePipeline()
    surfaces_path = os.path.join(rve_dir, "surfaces.vtp")
    has_mesh = os.path.exists(surfaces_path) and not glyphs_only
    shape = points.PointData["shape"].GetRange() if points.PointData.GetArray("shape") else (0, -1)
    if shape[0] <= 2 and shape[1] >= 0:
        shown.append(show_glyphs(points, view, "Sphere", [0, 0]))
        shown.append(show_glyphs(points, view, "Sphere", [2, 2]))
        shown.append(show_glyphs(points, view, "Cylinder", [1, 1]))
    if has_mesh:
        surfaces = XMLPolyDataReader(FileName=[surfaces_path])
        disp = Show(surfaces, view)
        ColorBy(disp, ("CELLS", "family"))
        shown.append(disp)
    return shown


def save_rve_dir_picture(rve_dir, box_source, out_png, size, draw="all", reset_camera=True):
    """The standard picture of an RVE written by `rvegen generate` (see show_inclusions);
    `draw`: "all", "glyphs" (no surfaces.vtp) or "mesh" (surfaces.vtp alone); without
    `reset_camera` the camera frames the box, whatever is shown."""
    view = white_view()
    view.ViewSize = [size, size]
    if draw == "mesh":
        disp = Show(XMLPolyDataReader(FileName=[os.path.join(rve_dir, "surfaces.vtp")]), view)
        ColorBy(disp, ("CELLS", "family"))
        shown = [disp]
    else:
        shown = show_inclusions(rve_dir, view, glyphs_only=draw == "glyphs")
    lut = GetColorTransferFunction("family")
    lut.ApplyPreset("Rainbow Uniform", True)
    lo, hi = 0.0, 0.0
    for d in shown:
        d.LookupTable = lut
    families = XMLPolyDataReader(FileName=[os.path.join(rve_dir, "inclusions.vtp")])
    families.UpdatePipeline()
    arr = families.PointData.GetArray("family")
    if arr is not None:
        lo, hi = arr.GetRange()
    lut.RescaleTransferFunction(lo, max(hi, lo + 1e-9))
    outline = Show(Outline(Input=box_source), view)
    outline.DiffuseColor = [0, 0, 0]
    view.CameraPosition = [2.6, 2.0, 1.8]
    view.CameraFocalPoint = [0.5, 0.5, 0.5]
    view.CameraViewUp = [0, 0, 1]
    if reset_camera:
        view.ResetCamera()
    else:
        box_source.UpdatePipeline()
        view.ResetCamera(*box_source.GetDataInformation().GetBounds())
        _DisableFirstRenderCameraReset()
    Render(view)
    SaveScreenshot(out_png, view, ImageResolution=[size, size])
