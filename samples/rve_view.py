"""The standard picture of an RVE: inclusions coloured by family inside the box outline.

Shared by samples/render_rve.py and the plugin's image-regression test.
"""
import os

from paraview.simple import (ColorBy, CreateView, GetColorTransferFunction, GetScalarBar, Outline, Render,
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


def save_rve_picture(inclusions, box_source, out_png, size, surfaces=None, glyphs=True):
    """Renders `inclusions` (points with glyph attributes: the RVE Generator's Inclusions output
    or inclusions.vtp) as glyphs, the surfaces of `surfaces` when given (the generator's Surfaces
    output: the modified inclusions, or all with Mesh), and the outline of `box_source` (the
    voxel image) to `out_png`, `size` pixels square, coloured by family. Without `glyphs`, the
    surfaces alone (to compare glyphs with the mesh)."""
    view = white_view()
    view.ViewSize = [size, size]
    shown = show_glyph_inclusions(inclusions, view) if glyphs else []
    if surfaces is not None:
        disp = Show(surfaces, view)
        ColorBy(disp, ("CELLS", "family"))
        shown.append(disp)
    family_colours(shown, inclusions)
    outline = Show(Outline(Input=box_source), view)
    outline.DiffuseColor = [0, 0, 0]
    view.CameraPosition = [2.6, 2.0, 1.8]
    view.CameraFocalPoint = [0.5, 0.5, 0.5]
    view.CameraViewUp = [0, 0, 1]
    # Framed by the box and a margin of a tenth of it for the periodic images: the glyphs'
    # bounds are conservative (each point padded by the largest glyph) and would zoom out.
    box_source.UpdatePipeline()
    b = box_source.GetDataInformation().GetBounds()
    pad = [0.1 * (b[2 * a + 1] - b[2 * a]) for a in range(3)]
    view.ResetCamera(*[b[k] + (pad[k // 2] if k % 2 else -pad[k // 2]) for k in range(6)])
    _DisableFirstRenderCameraReset()
    Render(view)
    SaveScreenshot(out_png, view, ImageResolution=[size, size])


# Family colours of the named legend (report pictures).
FAMILY_COLOURS = [[0.12, 0.35, 0.70], [0.70, 0.15, 0.30], [0.15, 0.55, 0.30], [0.50, 0.30, 0.65],
                  [0.85, 0.45, 0.10], [0.35, 0.35, 0.35]]


def family_colours(shown, inclusions, names=None, view=None):
    """One "family" colour map over the representations `shown`, spanning the families of
    `inclusions` (points with a "family" point array). With `names` (one per family) and `view`,
    the map is categorical and its legend, drawn in `view`, names the families."""
    lut = GetColorTransferFunction("family" if names is None else "family_named")
    if names is None:
        lut.ApplyPreset("Rainbow Uniform", True)
    for d in shown:
        d.LookupTable = lut
    if names is not None:
        lut.InterpretValuesAsCategories = 1
        lut.Annotations = sum([[str(k), n] for k, n in enumerate(names)], [])
        lut.IndexedColors = sum([FAMILY_COLOURS[k % len(FAMILY_COLOURS)] for k in range(len(names))], [])
        if shown and view is not None:
            bar = GetScalarBar(lut, view)
            bar.Title = "family"
            bar.ComponentTitle = ""
            bar.TitleColor = bar.LabelColor = [0, 0, 0]
            bar.WindowLocation = "Lower Center"
            bar.Orientation = "Horizontal"
            bar.ScalarBarLength = 0.6
            shown[0].SetScalarBarVisibility(view, True)
        return
    inclusions.UpdatePipeline()
    arr = inclusions.PointData.GetArray("family")
    lo, hi = arr.GetRange() if arr is not None else (0.0, 0.0)
    lut.RescaleTransferFunction(lo, max(hi, lo + 1e-9))


def show_axes(view):
    """Coordinates (box units) on the view's axes: the scale of the picture."""
    view.AxesGrid.Visibility = 1
    for t in ("XTitle", "YTitle", "ZTitle"):
        setattr(view.AxesGrid, t, t[0])
    for c in ("XTitleColor", "YTitleColor", "ZTitleColor", "XLabelColor", "YLabelColor",
              "ZLabelColor", "GridColor"):
        setattr(view.AxesGrid, c, [0, 0, 0])


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


def show_glyph_inclusions(points, view):
    """Shows the plain inclusions of `points` (the RVE Generator's Inclusions output, or
    inclusions.vtp) as glyphs: spheres and ellipsoids as sphere glyphs, cylinders as cylinder
    glyphs. Returns the representations."""
    points.UpdatePipeline()
    arr = points.PointData.GetArray("shape")
    lo, hi = arr.GetRange() if arr is not None else (0, -1)
    shown = []
    for glyph, shape in (("Sphere", 0), ("Cylinder", 1), ("Sphere", 2)):
        if lo <= shape <= hi:
            shown.append(show_glyphs(points, view, glyph, [shape, shape]))
    return shown


def show_inclusions(rve_dir, view, glyphs_only=False):
    """Shows an RVE directory's inclusions: glyphs from inclusions.vtp for the plain ones, and the
    surfaces of surfaces.vtp (wavy, deformed, coated, debonded, or all with "mesh") when
    present (not with `glyphs_only`). Returns the representations."""
    shown = []
    points = XMLPolyDataReader(FileName=[os.path.join(rve_dir, "inclusions.vtp")])
    points.UpdatePipeline()
    surfaces_path = os.path.join(rve_dir, "surfaces.vtp")
    has_mesh = os.path.exists(surfaces_path) and not glyphs_only
    shown += show_glyph_inclusions(points, view)
    if has_mesh:
        surfaces = XMLPolyDataReader(FileName=[surfaces_path])
        disp = Show(surfaces, view)
        ColorBy(disp, ("CELLS", "family"))
        shown.append(disp)
    return shown


def save_rve_dir_picture(rve_dir, box_source, out_png, size, draw="all", reset_camera=True,
                         family_names=None, axes=False):
    """The standard picture of an RVE written by `rvegen generate` (see show_inclusions);
    `draw`: "all", "glyphs" (no surfaces.vtp) or "mesh" (surfaces.vtp alone); without
    `reset_camera` the camera frames the box, whatever is shown. With `family_names`, a legend
    names the families; with `axes`, the axes carry their coordinates."""
    view = white_view()
    view.ViewSize = [size, size]
    if draw == "mesh":
        disp = Show(XMLPolyDataReader(FileName=[os.path.join(rve_dir, "surfaces.vtp")]), view)
        ColorBy(disp, ("CELLS", "family"))
        shown = [disp]
    else:
        shown = show_inclusions(rve_dir, view, glyphs_only=draw == "glyphs")
    family_colours(shown, XMLPolyDataReader(FileName=[os.path.join(rve_dir, "inclusions.vtp")]),
                   names=family_names, view=view)
    if axes:
        show_axes(view)
    outline = Show(Outline(Input=box_source), view)
    outline.DiffuseColor = [0, 0, 0]
    view.CameraPosition = [2.6, 2.0, 1.8]
    view.CameraFocalPoint = [0.5, 0.5, 0.5]
    view.CameraViewUp = [0, 0, 1]
    if reset_camera:
        view.ResetCamera()
        if family_names is not None:
            view.GetActiveCamera().Dolly(0.8)  # room for the legend below
    else:
        box_source.UpdatePipeline()
        view.ResetCamera(*box_source.GetDataInformation().GetBounds())
        _DisableFirstRenderCameraReset()
    Render(view)
    SaveScreenshot(out_png, view, ImageResolution=[size, size])
