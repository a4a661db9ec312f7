#!/usr/bin/python3
"""Effective properties against volume fraction, with the Hashin-Shtrikman bounds: packs
spheres (conductivity 10, E = 70, nu = 0.2) in a matrix (conductivity 1, E = 3, nu = 0.35) at
volume fractions 0.1 to 0.5 with `rvegen generate`, computes the effective conductivity and
stiffness in the same run, and charts them against the bounds the report states.

Prints a table (also samples/charts/effective_table.md) and draws
samples/charts/effective_vs_bounds.png.

usage: /usr/bin/python3 samples/sweep_effective.py [BUILD_DIR] [RESOLUTION]
"""
import json
import os
import subprocess
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

build = sys.argv[1] if len(sys.argv) > 1 else "build"
res = int(sys.argv[2]) if len(sys.argv) > 2 else 48
exe = os.path.join(build, "bin", "rvegen")
work = tempfile.mkdtemp(prefix="rvegen-effective-")
rows = []
for phi in (0.1, 0.2, 0.3, 0.4, 0.5):
    scene = {"box": {"size": [1, 1, 1]}, "seed": 1,
             "families": [{"name": "spheres", "shape": "sphere", "radius": 0.08,
                           "volume_fraction": phi}],
             "voxels": {"resolution": res},
             "materials": {"matrix": {"conductivity": 1, "young": 3, "poisson": 0.35},
                           "spheres": {"conductivity": 10, "young": 70, "poisson": 0.2}},
             "homogenization": {"physics": ["conductivity", "elasticity"]},
             "outputs": ["inclusions"]}
    path = os.path.join(work, "s%.1f.json" % phi)
    out = os.path.join(work, "rve%.1f" % phi)
    with open(path, "w") as f:
        json.dump(scene, f)
    subprocess.run([exe, "generate", "-q", path, "-o", out], check=True)
    with open(os.path.join(out, "report.json")) as f:
        report = json.load(f)
    eff = report["effective"]
    c, s = eff["conductivity"], eff["stiffness"]
    rows.append({"phi": report["volume_fraction"],
                 "voxel_phi": 1.0 - eff["phase_shares"][0],
                 "k": c["mean_of_diagonal"], "k_hs": c["bounds"]["hashin_shtrikman"],
                 "bulk": s["isotropic_projection"]["bulk"], "bulk_hs": s["bounds"]["bulk"]["hashin_shtrikman"],
                 "shear": s["isotropic_projection"]["shear"], "shear_hs": s["bounds"]["shear"]["hashin_shtrikman"],
                 "seconds": c["seconds"] + s["seconds"]})
    print("phi %.1f done" % phi, file=sys.stderr)

lines = ["Spheres (k 10, E 70, nu 0.2) in a matrix (k 1, E 3, nu 0.35), %d^3 voxels, laminate voxels, rotated scheme, "
         "CG to 1e-6; bounds from the image's phase shares." % res, "",
         "| volume fraction (voxels) | conductivity | HS bounds | bulk modulus | HS bounds | shear modulus | HS bounds | solve (s) |",
         "|---|---|---|---|---|---|---|---|"]
for r in rows:
    lines.append("| %.3f | %.3f | %.3f-%.3f | %.3f | %.3f-%.3f | %.3f | %.3f-%.3f | %.1f |" % (
        r["voxel_phi"], r["k"], r["k_hs"][0], r["k_hs"][1], r["bulk"], r["bulk_hs"][0], r["bulk_hs"][1],
        r["shear"], r["shear_hs"][0], r["shear_hs"][1], r["seconds"]))
text = "\n".join(lines)
print(text)
charts = os.path.join("samples", "charts")
os.makedirs(charts, exist_ok=True)
with open(os.path.join(charts, "effective_table.md"), "w") as f:
    f.write(text + "\n")

fig, axes = plt.subplots(1, 3, figsize=(12, 3.8))
for ax, key, title in zip(axes, ("k", "bulk", "shear"), ("conductivity", "bulk modulus", "shear modulus")):
    x = [r["voxel_phi"] for r in rows]
    ax.fill_between(x, [r[key + "_hs"][0] for r in rows], [r[key + "_hs"][1] for r in rows],
                    color="#cfe0f3", label="Hashin-Shtrikman bounds")
    ax.plot(x, [r[key] for r in rows], "o-", color="#b03030", label="rvegen (FFT, %d^3)" % res)
    ax.set_xlabel("volume fraction of spheres (voxels)")
    ax.set_title("effective " + title)
    ax.legend(fontsize=8)
fig.tight_layout()
fig.savefig(os.path.join(charts, "effective_vs_bounds.png"), dpi=110)
print("wrote", os.path.join(charts, "effective_vs_bounds.png"))
