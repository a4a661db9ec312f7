"""Inclusions as glyphs (inclusions.vtp) are the inclusions: numerically (each point's scale and
quaternion turn the unit glyph into the inclusion of inclusions.json) and in a picture (glyphs
against the tessellated mesh of the same RVE, same camera).

usage: pvpython --force-offscreen-rendering test_glyphs.py RVEGEN WORK_DIR
"""
import json
import math
import os
import subprocess
import sys

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, here)
sys.path.insert(0, os.path.join(here, "..", "..", "samples"))
from checks import image_error  # noqa: E402
from paraview.simple import XMLImageDataReader, XMLPolyDataReader  # noqa: E402
from paraview import servermanager  # noqa: E402
from rve_view import save_rve_dir_picture  # noqa: E402

rvegen, work = sys.argv[1:3]
os.makedirs(work, exist_ok=True)
scene = json.loads(subprocess.run([rvegen, "default-scene"], check=True, capture_output=True,
                                  text=True).stdout)
scene["outputs"] = ["inclusions", "voxels", "mesh"]
scene_path = os.path.join(work, "scene.json")
with open(scene_path, "w") as f:
    json.dump(scene, f)
rve = os.path.join(work, "rve")
subprocess.run([rvegen, "generate", "-q", scene_path, "-o", rve], check=True)
failures = []


def check(ok, what):
    if not ok:
        failures.append(what)
        print("FAIL:", what)


def rotate(q, v):
    w, x, y, z = q
    r = [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
         [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
         [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]
    return [sum(r[i][k] * v[k] for k in range(3)) for i in range(3)]


with open(os.path.join(rve, "inclusions.json")) as f:
    inclusions = {i["id"]: i for i in json.load(f)["inclusions"]}
points = servermanager.Fetch(XMLPolyDataReader(FileName=[os.path.join(rve, "inclusions.vtp")]))
pd = points.GetPointData()
arr = {n: pd.GetArray(n) for n in ("inclusion_id", "image", "scale", "orientation")}
worst, own = 0.0, 0
for p in range(points.GetNumberOfPoints()):
    inc = inclusions[int(arr["inclusion_id"].GetValue(p))]
    q = arr["orientation"].GetTuple4(p)
    sc = arr["scale"].GetTuple3(p)
    check(abs(math.sqrt(sum(c * c for c in q)) - 1.0) < 1e-9, "quaternion not unit at %d" % p)
    if arr["image"].GetValue(p) == 0:
        own += 1
        c = points.GetPoint(p)
        worst = max(worst, max(abs(c[k] - inc["center"][k]) for k in range(3)))
    # Each glyph axis, scaled and turned, is an axis of the inclusion.
    if inc["shape"] == "sphere":
        worst = max(worst, max(abs(s - 2 * inc["radius"]) for s in sc))
    elif inc["shape"] == "cylinder":
        axis = rotate(q, [0, 0.5 * sc[1], 0])
        worst = max(worst, max(abs(abs(axis[k]) - abs(inc["half_axis"][k])) for k in range(3)))
        worst = max(worst, abs(sc[0] - 2 * inc["radius"]), abs(sc[2] - 2 * inc["radius"]))
    else:
        for k in range(3):
            e = [0, 0, 0]
            e[k] = 0.5 * sc[k]
            a = rotate(q, e)
            col = [inc["rotation"][i][k] * inc["semi_axes"][k] for i in range(3)]
            worst = max(worst, min(max(abs(a[i] - col[i]) for i in range(3)),
                                   max(abs(a[i] + col[i]) for i in range(3))))
print("glyph attributes against inclusions.json: worst difference %.3g" % worst)
check(worst < 1e-12, "glyphs differ from the inclusions by %.3g" % worst)
check(own == len(inclusions), "%d own points for %d inclusions" % (own, len(inclusions)))
check(points.GetNumberOfPoints() > own, "no periodic image points in a periodic box")

# surfaces.vtp (zlib-compressed appended data) reads back whole: every inclusion meshed, and
# its field data is inclusions.json byte for byte.
with open(os.path.join(rve, "surfaces.vtp"), "rb") as f:
    check(b'compressor="vtkZLibDataCompressor"' in f.read(400), "surfaces.vtp is not compressed")
mesh = servermanager.Fetch(XMLPolyDataReader(FileName=[os.path.join(rve, "surfaces.vtp")]))
mesh_ids = mesh.GetCellData().GetArray("inclusion_id")
check(mesh_ids is not None and {int(mesh_ids.GetValue(i)) for i in range(mesh_ids.GetNumberOfTuples())}
      == set(inclusions), "surfaces.vtp does not mesh every inclusion")
check(mesh.GetPoints() is not None and mesh.GetPoints().GetDataType() == 10,  # VTK_FLOAT
      "surfaces.vtp points are not Float32")
listed = mesh.GetFieldData().GetAbstractArray("rvegen_inclusions")
with open(os.path.join(rve, "inclusions.json")) as f:
    check(listed is not None and listed.GetValue(0) == f.read(),
          "surfaces.vtp field data differs from inclusions.json")

# The same RVE drawn from glyphs and from its mesh, same camera.
voxels = XMLImageDataReader(FileName=[os.path.join(rve, "voxels.vti")])
glyph_png, mesh_png = os.path.join(work, "glyphs.png"), os.path.join(work, "mesh.png")
save_rve_dir_picture(rve, voxels, glyph_png, 400, draw="glyphs", reset_camera=False)
save_rve_dir_picture(rve, voxels, mesh_png, 400, draw="mesh", reset_camera=False)
err = image_error(glyph_png, mesh_png)
print("glyphs against mesh, image difference (thresholded): %.1f" % err)
check(err <= 10.0, "glyph picture differs from the mesh picture (error %.1f)" % err)

print("%d failure(s)" % len(failures) if failures else "ok")
sys.stdout.flush()
os._exit(1 if failures else 0)  # no GL teardown at exit (GLXBadContext under Xvfb)
