#!/usr/bin/python3
"""Accuracy against resolution and cost of the voxel rules (plain, Voigt, Reuss, laminate).

1. Inclined laminates (rvegen_bench_accuracy inclined): layers of shares 0.4 / 0.6 with normals
   (1,1,0)/sqrt 2 and (1,2,3)/sqrt 14, contrast 10, conductivity and stiffness; the error is
   against the exact laminate tensor.
2. The simple cubic array of spheres (rvegen_bench_accuracy cubic), volume fractions 0.3 and
   0.45, conductivity contrast 10, 32^3 to 256^3: the converged value by Richardson
   extrapolation of the laminate values at 64, 128 and 256^3, the 64^3 error against it, and
   the distance to Rayleigh's formula (terms to f^(10/3)).
3. Two packed RVEs through the command line (`rvegen homogenize DIR SCENE`, wall time of the
   whole command): spheres at 0.3 and short fibres (aspect ratio 5, isotropic) at 0.15,
   conductivity contrast 10, each rule at 32, 64 and 128^3; the reference is the 256^3
   laminate value.

Prints the tables (also samples/charts/voxel_rules_table.md) and draws
samples/charts/voxel_rules.png.

usage: /usr/bin/python3 samples/bench_voxel_rules.py [BUILD_DIR]
"""
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

build = sys.argv[1] if len(sys.argv) > 1 else "build"
acc = os.path.join(build, "bin", "rvegen_bench_accuracy")
exe = os.path.join(build, "bin", "rvegen")
here = os.path.dirname(os.path.abspath(__file__))
charts = os.path.join(here, "charts")
RULES = ["plain", "voigt", "reuss", "laminate"]
STYLE = {"plain": "o-", "voigt": "s--", "reuss": "v--", "laminate": "D-"}


def rows_of(args):
    out = subprocess.run([acc] + [str(a) for a in args], check=True, capture_output=True, text=True)
    return [line.split("\t") for line in out.stdout.strip().splitlines()]


lines = []

# 1. Inclined laminates.
inclined = {}
for physics in ("conductivity", "elasticity"):
    for normal in ((1, 1, 0), (1, 2, 3)):
        for res in (8, 16, 32, 64):
            for rule, _, err, _ in rows_of(["inclined", physics, res, *normal, 10]):
                inclined.setdefault((physics, normal, rule), []).append((res, float(err)))
        print("inclined %s %s done" % (physics, normal), file=sys.stderr)
lines += ["## Inclined laminates (contrast 10, shares 0.4 / 0.6): relative error against the exact tensor", "",
          "| physics | normal | rule | 8^3 | 16^3 | 32^3 | 64^3 |", "|---|---|---|---|---|---|---|"]
for (physics, normal, rule), pts in inclined.items():
    lines.append("| %s | (%d,%d,%d) | %s | %s |" % (physics, *normal, rule,
                                                    " | ".join("%.1e" % e for _, e in pts)))


# 2. Simple cubic array.
def rayleigh(f, rho):
    # Rayleigh (1892) for the simple cubic array, terms to f^(10/3):
    # k / k_m = 1 + 3 f / (T - f - 1.305 (rho - 1) / (rho + 4/3) f^(10/3)), T = (rho + 2) / (rho - 1).
    t = (rho + 2.0) / (rho - 1.0)
    return 1.0 + 3.0 * f / (t - f - 1.305 * (rho - 1.0) / (rho + 4.0 / 3.0) * f ** (10.0 / 3.0))


cubic = {}
for f in (0.3, 0.45):
    for res in (32, 64, 128, 256):
        for rule, _, kxx, kmean, sec, it in rows_of(["cubic", res, f, 10]):
            cubic.setdefault((f, rule), []).append((res, float(kmean), float(sec)))
        print("cubic f=%.2f %d^3 done" % (f, res), file=sys.stderr)
lines += ["", "## Simple cubic array of spheres, conductivity contrast 10", "",
          "| volume fraction | rule | 32^3 | 64^3 | 128^3 | 256^3 | extrapolated | 64^3 error | Rayleigh | distance to Rayleigh |",
          "|---|---|---|---|---|---|---|---|---|---|"]
extrapolated = {}
for f in (0.3, 0.45):
    lam = {r: k for r, k, _ in cubic[(f, "laminate")]}
    d1, d2 = lam[64] - lam[128], lam[128] - lam[256]
    p = math.log2(abs(d1 / d2)) if d2 != 0 and d1 / d2 > 0 else 1.0
    kinf = lam[256] - d2 / (2 ** p - 1.0)
    extrapolated[f] = kinf
    ray = rayleigh(f, 10.0)
    for rule in RULES:
        ks = {r: k for r, k, _ in cubic[(f, rule)]}
        lines.append("| %.2f | %s | %s | %s | %.2f %% | %.5f | %s |" % (
            f, rule, " | ".join("%.5f" % ks[r] for r in (32, 64, 128, 256)),
            "%.5f (order %.2f)" % (kinf, p) if rule == "laminate" else "",
            100 * abs(ks[64] / kinf - 1), ray,
            "%.2f %%" % (100 * (kinf / ray - 1)) if rule == "laminate" else ""))


# 3. Packed RVEs through the command line.
work = tempfile.mkdtemp(prefix="rvegen-voxel-rules-")
scenes = {
    "spheres 0.3": {"name": "spheres", "shape": "sphere", "radius": 0.1, "volume_fraction": 0.3},
    "fibres 0.15": {"name": "fibres", "shape": "cylinder", "radius": 0.05, "aspect_ratio": 5,
                    "volume_fraction": 0.15},
}
rve = {}
for label, fam in scenes.items():
    base = {"box": {"size": [1, 1, 1]}, "seed": 2, "families": [fam],
            "materials": {"matrix": {"conductivity": 1}, fam["name"]: {"conductivity": 10}},
            "homogenization": {"physics": ["conductivity"]}, "outputs": ["inclusions"]}
    d = os.path.join(work, fam["name"])
    path = os.path.join(work, fam["name"] + ".json")
    with open(path, "w") as fh:
        json.dump(base, fh)
    subprocess.run([exe, "generate", "-q", path, "-o", d], check=True)
    for res, rules in ((32, RULES), (64, RULES), (128, RULES), (256, ["laminate"])):
        for rule in rules:
            scene = dict(base, voxels={"resolution": res})
            scene["homogenization"] = {"physics": ["conductivity"], "voxel_rule": rule}
            sp = os.path.join(work, "%s_%d_%s.json" % (fam["name"], res, rule))
            with open(sp, "w") as fh:
                json.dump(scene, fh)
            t = time.time()
            out = subprocess.run([exe, "homogenize", d, sp], check=True, capture_output=True, text=True)
            wall = time.time() - t
            k = json.loads(out.stdout)["conductivity"]["mean_of_diagonal"]
            rve.setdefault((label, rule), []).append((res, k, wall))
        print("%s %d^3 done" % (label, res), file=sys.stderr)
lines += ["", "## Packed RVEs (`rvegen homogenize`, whole command), conductivity contrast 10: "
          "relative error against the 256^3 laminate value, and wall seconds", "",
          "| RVE | rule | 32^3 | 64^3 | 128^3 | 256^3 (reference) |", "|---|---|---|---|---|---|"]
ref = {label: rve[(label, "laminate")][-1][1] for label in scenes}
for (label, rule), pts in rve.items():
    cells = ["%.2e (%.1f s)" % (abs(k / ref[label] - 1), w) for r, k, w in pts if r < 256]
    last = "%.5f (%.1f s)" % (pts[-1][1], pts[-1][2]) if pts[-1][0] == 256 else ""
    lines.append("| %s | %s | %s | %s |" % (label, rule, " | ".join(cells), last))

text = "\n".join(lines)
print(text)
with open(os.path.join(charts, "voxel_rules_table.md"), "w") as fh:
    fh.write(text + "\n")

fig, ax = plt.subplots(2, 3, figsize=(15, 9))
for i, (physics, normal) in enumerate((("conductivity", (1, 2, 3)), ("elasticity", (1, 2, 3)))):
    a = ax[0][i]
    for rule in RULES:
        pts = inclined[(physics, normal, rule)]
        a.loglog([r for r, _ in pts], [max(e, 1e-16) for _, e in pts], STYLE[rule], label=rule)
    a.set_title("laminate normal (1,2,3)/sqrt 14, %s" % physics)
    a.set_xlabel("voxels per side")
    a.set_ylabel("relative error")
    a.legend()
a = ax[0][2]
for f in (0.3, 0.45):
    for rule in ("plain", "laminate"):
        pts = cubic[(f, rule)]
        a.loglog([r for r, _, _ in pts], [abs(k / extrapolated[f] - 1) for _, k, _ in pts],
                 STYLE[rule], label="f = %.2f, %s" % (f, rule))
a.set_title("simple cubic array, contrast 10")
a.set_xlabel("voxels per side")
a.set_ylabel("error against the extrapolated value")
a.legend()
for i, label in enumerate(scenes):
    a = ax[1][i]
    for rule in RULES:
        pts = [p for p in rve[(label, rule)] if p[0] < 256]
        a.loglog([w for _, _, w in pts], [abs(k / ref[label] - 1) for _, k, _ in pts], STYLE[rule],
                 label=rule)
        for r, k, w in pts:
            a.annotate("%d" % r, (w, abs(k / ref[label] - 1)), fontsize=7)
    a.set_title("%s: error against wall time (labels: voxels per side)" % label)
    a.set_xlabel("seconds (whole rvegen homogenize command)")
    a.set_ylabel("error against 256^3 laminate")
    a.legend()
a = ax[1][2]
for label in scenes:
    for rule in ("plain", "laminate"):
        pts = [p for p in rve[(label, rule)] if p[0] < 256]
        a.loglog([r for r, _, _ in pts], [abs(k / ref[label] - 1) for _, k, _ in pts], STYLE[rule],
                 label="%s, %s" % (label, rule))
a.set_title("packed RVEs: error against resolution")
a.set_xlabel("voxels per side")
a.set_ylabel("error against 256^3 laminate")
a.legend()
fig.tight_layout()
fig.savefig(os.path.join(charts, "voxel_rules.png"), dpi=90)
print("wrote samples/charts/voxel_rules.png", file=sys.stderr)
