#!/usr/bin/python3
"""The FFT solver against phase contrast: iterations and whole-command time of the six elastic
load cases (and the three conductive ones) as the contrast grows, for each gradient scheme.

  1. Poisson's ratio: a rubbery matrix (E 2.4) with stiff spheres (E 400, nu 0.25) at 0.27,
     the matrix's nu from 0.3 to 0.499999;
  2. contrast: the same spheres E_s = c E_m and k_s = c k_m (nu 0.3 both), c from 1e-6
     (nearly voids) to 1e6 (nearly rigid).

Each point is one `rvegen generate` on the same packing (seed 1), with the default tolerance
(1e-6) and --max-iterations (default 1000): a load case that stops there is "not converged",
one whose arithmetic failed "breakdown". The table goes to stdout and
samples/charts/contrast_table.md, the chart (iterations against 1 / (1 - 2 nu) and against the
contrast, one curve per scheme and resolution) to samples/charts/contrast.png.

usage: /usr/bin/python3 samples/bench_contrast.py [BUILD_DIR] [--resolutions 32,64]
                                                  [--max-iterations 1000] [--quick]
"""
import math
import os
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_util import generate, machine, option  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
COMMAND = " ".join(sys.argv[1:])
resolutions = option("--resolutions", [32, 64], int)
max_iterations = option("--max-iterations", [1000], int)[0]
quick = "--quick" in sys.argv
args = [a for a in sys.argv[1:] if not a.startswith("--")]
build = args[0] if args else os.path.join(HERE, "..", "build")
exe = os.path.join(build, "bin", "rvegen")

POISSON = [0.3, 0.49, 0.4995, 0.4999, 0.49999, 0.499999]
CONTRAST = [1e-6, 1e-3, 1e-1, 10.0, 1e3, 1e6]
if quick:
    POISSON, CONTRAST = [0.3, 0.4999], [1e-3, 1e3]


def scene(resolution, scheme, matrix, spheres, physics):
    return {"box": {"size": [1, 1, 1]}, "seed": 1,
            "families": [{"name": "spheres", "shape": "sphere", "radius": 0.1,
                          "volume_fraction": 0.27}],
            "voxels": {"resolution": resolution}, "outputs": ["inclusions"],
            "materials": {"matrix": matrix, "spheres": spheres},
            "homogenization": {"physics": physics, "scheme": scheme,
                               "max_iterations": max_iterations}}


def outcome(physics_report):
    if physics_report.get("breakdown") and any(physics_report["breakdown"]):
        return "breakdown"
    return "converged" if physics_report["converged"] else "not converged"


rows = []
with tempfile.TemporaryDirectory() as work:
    for scheme in ["rotated", "moulinec_suquet"]:
        for res in resolutions:
            for nu in POISSON:
                s = scene(res, scheme, {"young": 2.4, "poisson": nu},
                          {"young": 400, "poisson": 0.25}, ["elasticity"])
                rc, wall, peak, rep = generate(exe, s, work, "nu")
                e = rep["effective"]["stiffness"]
                rows.append(("nu", scheme, res, nu, max(e["iterations"]), sum(e["iterations"]),
                             wall, outcome(e)))
                print(*rows[-1], flush=True)
            for c in CONTRAST:
                s = scene(res, scheme, {"young": 1.0, "poisson": 0.3, "conductivity": 1.0},
                          {"young": c, "poisson": 0.3, "conductivity": c},
                          ["conductivity", "elasticity"])
                rc, wall, peak, rep = generate(exe, s, work, "contrast")
                e, k = rep["effective"]["stiffness"], rep["effective"]["conductivity"]
                rows.append(("contrast", scheme, res, c, max(e["iterations"]),
                             sum(e["iterations"]) + sum(k["iterations"]), wall,
                             outcome(e) + " / " + outcome(k)))
                print(*rows[-1], flush=True)

header = ("| sweep | scheme | resolution | nu or contrast | most iterations of a load case | "
          "iterations in all | seconds (whole command) | outcome (elasticity / conductivity) |\n"
          "|---|---|---|---|---|---|---|---|\n")
table = header + "".join("| %s | %s | %d^3 | %g | %d | %d | %.2f | %s |\n" % r for r in rows)
note = "\nMachine: %s. Command: /usr/bin/python3 samples/bench_contrast.py %s\n" % (
    machine(), COMMAND)
print(table + note)
os.makedirs(os.path.join(HERE, "charts"), exist_ok=True)
with open(os.path.join(HERE, "charts", "contrast_table.md"), "w") as f:
    f.write(table + note)

fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.5))
for scheme in ["rotated", "moulinec_suquet"]:
    for res in resolutions:
        pts = [r for r in rows if r[0] == "nu" and r[1] == scheme and r[2] == res]
        a.plot([1.0 / (1.0 - 2.0 * r[3]) for r in pts], [r[4] for r in pts], "o-",
               label="%s %d^3" % (scheme, res))
        pts = [r for r in rows if r[0] == "contrast" and r[1] == scheme and r[2] == res]
        b.plot([r[3] for r in pts], [r[4] for r in pts], "o-", label="%s %d^3" % (scheme, res))
for ax, xl in ((a, "1 / (1 - 2 nu) of the matrix"), (b, "contrast E_s / E_m = k_s / k_m")):
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(xl)
    ax.set_ylabel("most iterations of a load case (cap %d)" % max_iterations)
    ax.axhline(max_iterations, color="grey", lw=0.8, ls="--")
    ax.legend(fontsize=8)
a.set_title("rubbery matrix, stiff spheres at 0.27")
b.set_title("spheres at 0.27, nu 0.3")
fig.tight_layout()
fig.savefig(os.path.join(HERE, "charts", "contrast.png"), dpi=110)
print("chart: samples/charts/contrast.png")
