"""Pictures of an RVE for a report, made headless.

usage: xvfb-run -a -s "-screen 0 1280x1024x24" \\
         pvbatch --force-offscreen-rendering samples/rve_report.py RVE_DIR OUT_DIR [SIZE]

RVE_DIR is what `rvegen generate` wrote. Writes in OUT_DIR:
  inclusions_3d.png     3D view of the inclusions coloured by family, inside the box outline
  voxel_slices.png      two slices of the voxel image side by side (z and x through the middle),
                        coloured by phase (the paper's Figure 4)
  interphase_slice.png  a z slice with the interphase and void phases highlighted (Figure 5)
  charts/*.png          charts of this RVE: phase_fractions.png (exact against voxel volume
                        fraction per phase), radial_distribution.png (g(r) of each family's
                        centres), sizes.png (equivalent radius per family), orientation.png (A2
                        obtained against asked, per oriented family; only when there is one)
Every picture has its legend: family names on the 3D view, phase names on the slices, the
slice position written on each slice, and the axes' coordinates (box units) on every view.
"""
import json
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from paraview.simple import (AssignViewToLayout, ColorBy, CreateLayout, GetColorTransferFunction,
                             GetScalarBar, Render, SaveScreenshot, Show, Slice, Text,
                             XMLImageDataReader)

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, here)
from rve_view import save_rve_dir_picture, show_axes, white_view  # noqa: E402

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

family_names = [f["name"] for f in report["families"]]
save_rve_dir_picture(rve, voxels, os.path.join(out, "inclusions_3d.png"), size,
                     family_names=family_names, axes=True)

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
    lut = phase_lut(highlight)
    disp.LookupTable = lut
    # The phase names as a legend, the slice's position as a title, coordinates on the axes.
    bar = GetScalarBar(lut, view)
    bar.Title = ""  # the view's title says what the colours are
    bar.ComponentTitle = ""
    bar.TitleColor = bar.LabelColor = [0, 0, 0]
    # On the right of the slice, names to the right of the colours (long phase names fit).
    bar.WindowLocation = "Any Location"
    bar.Orientation = "Vertical"
    bar.TextPosition = "Ticks left/bottom, annotations right/top"
    bar.Position = [0.69, 0.2]
    bar.ScalarBarLength = 0.6
    bar.LabelFontSize = 9
    bar.TitleFontSize = 13
    disp.SetScalarBarVisibility(view, True)
    axis = "xyz"[[abs(c) for c in normal].index(1)]
    label = Text(Text="phase on the slice %s = %.4g (the middle of the box)" % (axis, centre["xyz".index(axis)]))
    ldisp = Show(label, view)
    ldisp.WindowLocation = "Upper Left Corner"
    ldisp.Color = [0, 0, 0]
    ldisp.FontSize = 14
    show_axes(view)
    view.CameraParallelProjection = 1
    view.CameraFocalPoint = centre
    view.CameraPosition = [centre[a] + 3.0 * normal[a] for a in range(3)]
    view.CameraViewUp = [0, 1, 0] if normal[2] else [0, 0, 1]
    # The slice on the left, with room for the axes' labels around it and the legend on the
    # right: the view's centre moves right (+x seen along z, +y seen along x).
    edge = max(bounds[2 * a + 1] - bounds[2 * a] for a in range(3) if not normal[a])
    view.CameraParallelScale = 1.05 * edge
    right = 0 if normal[2] else 1
    view.CameraFocalPoint = [centre[a] + (0.33 * edge if a == right else 0.0) for a in range(3)]
    view.CameraPosition = [view.CameraFocalPoint[a] + 3.0 * normal[a] for a in range(3)]
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

# Charts of this RVE (from report.json and inclusions.json, as written).
charts = os.path.join(out, "charts")
os.makedirs(charts, exist_ok=True)
with open(os.path.join(rve, "inclusions.json")) as f:
    inclusions = json.load(f)["inclusions"]

fig, ax = plt.subplots(figsize=(6, 3.6))
names = [p["name"] for p in phases]
x = range(len(phases))
ax.bar([i - 0.2 for i in x], [p["volume_fraction"] for p in phases], 0.4, label="exact")
ax.bar([i + 0.2 for i in x], [p.get("voxel_volume_fraction", float("nan")) for p in phases], 0.4,
       label="voxels (labels at voxel centres)")
ax.set_xticks(list(x))
ax.set_xticklabels(names, rotation=20, ha="right")
ax.set_ylabel("volume fraction")
ax.set_title("Phase volume fractions (total inclusions %.4f)" % report["volume_fraction"])
ax.legend()
fig.tight_layout()
fig.savefig(os.path.join(charts, "phase_fractions.png"), dpi=110)
plt.close(fig)

fig, ax = plt.subplots(figsize=(6, 3.6))
for fam in report["families"]:
    g = fam.get("radial_distribution")
    if g and g.get("r"):
        ax.plot(g["r"], g["g"], label=fam["name"])
ax.axhline(1.0, color="grey", lw=0.8, ls="--")
ax.set_xlabel("distance between centres r (box units)")
ax.set_ylabel("g(r)")
ax.set_title("Radial distribution of the centres, per family")
ax.legend()
fig.tight_layout()
fig.savefig(os.path.join(charts, "radial_distribution.png"), dpi=110)
plt.close(fig)


def equivalent_radius(inc):
    """Radius of the sphere of the same core volume."""
    if inc["shape"] == "sphere":
        return inc["radius"]
    if inc["shape"] == "cylinder":
        half = math.sqrt(sum(c * c for c in inc["half_axis"]))
        return (1.5 * inc["radius"] ** 2 * half) ** (1.0 / 3.0)
    a = inc["semi_axes"]
    return (a[0] * a[1] * a[2]) ** (1.0 / 3.0)


fig, ax = plt.subplots(figsize=(6, 3.6))
per_family = [[equivalent_radius(i) for i in inclusions if i["family"] == k]
              for k in range(len(report["families"]))]
every = [r for radii in per_family for r in radii]
if every:
    # Common bins over the sizes present (a fixed size is one narrow bar at its value).
    lo, hi = 0.95 * min(every), 1.05 * max(every)
    edges = [lo + (hi - lo) * b / 40.0 for b in range(41)]
    for fam, radii in zip(report["families"], per_family):
        if radii:
            ax.hist(radii, bins=edges, alpha=0.6, label="%s (%d)" % (fam["name"], len(radii)))
ax.set_xlabel("equivalent radius (sphere of the same volume, box units)")
ax.set_ylabel("inclusions")
ax.set_title("Sizes as written")
ax.legend()
fig.tight_layout()
fig.savefig(os.path.join(charts, "sizes.png"), dpi=110)
plt.close(fig)

oriented = [f for f in report["families"] if "orientation_tensor" in f]
if oriented:
    fig, ax = plt.subplots(figsize=(6, 3.6))
    comps = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]
    width = 0.8 / len(oriented)
    for k, fam in enumerate(oriented):
        got = [fam["orientation_tensor"][i][j] for i, j in comps]
        want = [fam["target_orientation_tensor"][i][j] for i, j in comps]
        xs = [c + (k - 0.5 * (len(oriented) - 1)) * width for c in range(6)]
        ax.bar(xs, got, width, label="%s (largest error %.1e)" % (fam["name"], fam["orientation_tensor_error"]))
        ax.scatter(xs, want, color="black", marker="_", s=200, zorder=3)
    ax.scatter([], [], color="black", marker="_", s=200, label="asked")
    ax.set_xticks(range(6))
    ax.set_xticklabels(["a11", "a22", "a33", "a12", "a13", "a23"])
    ax.set_ylabel("orientation tensor A2")
    ax.set_title("Orientation tensor as written against asked")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(charts, "orientation.png"), dpi=110)
    plt.close(fig)
print("wrote", out)
