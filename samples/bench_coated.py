#!/usr/bin/python3
"""Coated fibres and continuous fibres: the benchmark of the coated-fibre issue.

1. Every coated scene of the issue's table (seed 1-5) beside two uncoated twins:
   - the plain twin: the same cores without the coating (the output bytes are compared with it);
   - the outer twin: uncoated inclusions of the coated ones' outer size (radius + t, and half
     length + t for finite fibres) asked for the coated scene's outer volume fraction (cores and
     shells): the packing problem of the same difficulty (the wall times are compared with it).
2. Continuous fibres ("length": "through"): 500 fibres, monodisperse and with 8 % radius
   scatter (normal law), without and with an interphase of 5 % of the radius, at 0.60, 0.65 and
   0.70 (seeds 1-5), and the highest density each reaches (a target above reach: 0.90, coated
   0.82 of cores; a budget of 60 s).
3. The transverse isotropy of the continuous fibres' effective conductivity and stiffness (FFT
   on a 1024 x 1024 x 1 image of 0.60 and 0.70 RVEs, every seed).

Every result is audited by `rvegen check`. Wall time and peak memory are those of the whole
command (GNU time), one run at a time. Chart: samples/charts/continuous_fibres.png (volume
fraction reached against wall time).

Parts 1 and 2 write samples/charts/coated_table.md and the chart, part 3
samples/charts/continuous_isotropy_table.md.

usage: /usr/bin/python3 samples/bench_coated.py [BUILD_DIR] [--seeds 1,2,3,4,5]
       [--parts rows,continuous,isotropy] [--quick]
"""
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile

from bench_util import generate, machine, option

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

seeds = option("--seeds", [1, 2, 3, 4, 5], int)
parts = option("--parts", ["rows", "continuous", "isotropy"], str)
quick = "--quick" in sys.argv
args = [a for a in sys.argv[1:] if not a.startswith("--")]
build = args[0] if args else "build"
exe = os.path.abspath(os.path.join(build, "bin", "rvegen"))
work = tempfile.mkdtemp(prefix="rvegen-coated-")
charts = os.path.join("samples", "charts")
os.makedirs(charts, exist_ok=True)
T = 0.002  # the coating


def fibre(r, vf, t=0.0, aspect=None, box=(1, 1, 1), law=None, seed=1, through=False):
    fam = {"name": "fibres", "shape": "cylinder", "radius": r, "volume_fraction": vf}
    if through:
        fam["length"] = "through"
    else:
        fam["aspect_ratio"] = aspect
    fam["orientation"] = law or {"law": "aligned", "axis": [0, 0, 1]}
    if t > 0.0:
        fam["coating"] = {"thickness": t}
    return {"box": {"size": list(box)}, "seed": seed, "families": [fam]}


# The table: (name, r, aspect (None: through), box, law, target).
ROWS = [
    ("aligned r 0.05 a 6, 0.30", 0.05, 6, (1, 1, 1), None, 0.30),
    ("through the box r 0.03, 0.55", 0.03, None, (1, 1, 0.2), None, 0.55),
    ("through the box r 0.03, 0.30", 0.03, None, (1, 1, 0.2), None, 0.30),
    ("isotropic r 0.03 a 5, 0.25", 0.03, 5, (1, 1, 1), {"law": "isotropic"}, 0.25),
]


def bytes_of(path):
    return sum(os.path.getsize(os.path.join(d, f)) for d, _, fs in os.walk(path) for f in fs)


def audited(name):
    p = subprocess.run([exe, "check", os.path.join(work, name, "inclusions.json")],
                       capture_output=True, text=True)
    return p.returncode == 0


def outer_fraction(report):
    return sum(p["volume_fraction"] for p in report["phases"] if p["kind"] != "matrix")


def run(name, scene):
    rc, wall, peak, rep = generate(exe, scene, work, name)
    out = {"rc": rc, "wall": wall, "peak": peak, "vf": rep["volume_fraction"],
           "outer": outer_fraction(rep), "bytes": bytes_of(os.path.join(work, name)),
           "audit": audited(name), "status": rep["status"]}
    shutil.rmtree(os.path.join(work, name), ignore_errors=True)
    return out


lines = ["# Coated and continuous fibres", "",
         "Machine: %s. `/usr/bin/python3 samples/bench_coated.py %s --seeds %s`; every RVE "
         "audited by `rvegen check`; wall time and peak memory of the whole command (GNU time), "
         "default outputs." % (machine(), build, ",".join(map(str, seeds))), "",
         "## The coated scenes of the issue and their uncoated twins", "",
         "Plain twin: the same cores uncoated. Outer twin: uncoated inclusions of the coated "
         "ones' outer size asked for the coated scene's outer volume fraction. Per seed: exit "
         "code, volume fraction of the cores (coated) or of the inclusions, wall s.", "",
         "| scene | seed | coated: exit, vf, outer vf, wall s, MB, bytes | plain twin: exit, "
         "wall s, bytes | outer twin: exit, vf, wall s | wall / outer twin | bytes / plain twin "
         "| audits |",
         "|---|---|---|---|---|---|---|---|"]
worst_time, worst_bytes = 0.0, 0.0
for (title, r, aspect, box, law, vf) in (ROWS if "rows" in parts else []):
    through = aspect is None
    for seed in seeds:
        c = run("c", fibre(r, vf, T, aspect, box, law, seed, through))
        p = run("p", fibre(r, vf, 0.0, aspect, box, law, seed, through))
        # Outer twin: radius r + t; finite fibres half length h + t (aspect (a r + t) / (r + t)).
        oa = None if through else (aspect * r + T) / (r + T)
        o = run("o", fibre(r + T, c["outer"], 0.0, oa, box, law, seed, through))
        tr, br = c["wall"] / o["wall"], c["bytes"] / p["bytes"]
        worst_time, worst_bytes = max(worst_time, tr), max(worst_bytes, br)
        lines.append("| %s | %d | %d, %.4f, %.4f, %.2f, %.0f, %d | %d, %.2f, %d | %d, %.4f, %.2f "
                     "| %.2f | %.2f | %s |"
                     % (title, seed, c["rc"], c["vf"], c["outer"], c["wall"], c["peak"],
                        c["bytes"], p["rc"], p["wall"], p["bytes"], o["rc"], o["vf"], o["wall"],
                        tr, br, "ok" if c["audit"] and p["audit"] and o["audit"] else "FAILED"))
        print(lines[-1], flush=True)
lines += ["", "Largest ratios: wall time %.2f of the outer twin's, bytes %.2f of the plain "
          "twin's." % (worst_time, worst_bytes), ""]

# Continuous fibres: 500 of mean radius 0.01; the box's section holds them at the target.
N = 100 if quick else 500
R = 0.01


def continuous(vf, scatter, coated, seed, target=None, seconds=600, extra=None):
    radius = R if scatter == 0.0 else {"law": "normal", "mean": R, "std": scatter * R}
    mean_r2 = R * R * (1.0 + scatter * scatter)
    side = math.sqrt(N * math.pi * mean_r2 / vf)
    s = fibre(radius, target or vf, 0.05 * R if coated else 0.0, None, (side, side, 4 * R),
              None, seed, True)
    s["md"] = {"max_seconds": seconds}
    s["outputs"] = ["inclusions"]
    s.update(extra or {})
    return s


lines += ["## Continuous fibres (%d fibres, `\"length\": \"through\"`)" % N, "",
          "Interphase: 5 % of the mean radius. Per target: the runs that reached it, and the "
          "longest and mean wall time (s). Highest: a target above reach, 0.90 (coated: 0.82 "
          "of cores, 0.90-0.91 with the shells) with 60 s: the volume fraction of the cores "
          "reached (mean over seeds, min-max).", "",
          "| fibres | 0.60 | 0.65 | 0.70 | highest reached |", "|---|---|---|---|---|"]
points = {}
for scatter in ((0.0, 0.08) if "continuous" in parts else ()):
    for coated in (False, True):
        label = "%s%s" % ("monodisperse" if scatter == 0.0 else "8 % scatter",
                          ", interphase" if coated else "")
        cells = []
        for vf in (0.60, 0.65, 0.70):
            runs = [run("u", continuous(vf, scatter, coated, seed)) for seed in seeds]
            for x in runs:
                points.setdefault(label, []).append((x["wall"], x["vf"]))
            ok = [x for x in runs if x["rc"] == 0 and x["audit"]]
            cells.append("%d/%d, longest %.2f, mean %.2f" % (
                len(ok), len(runs), max(x["wall"] for x in runs),
                sum(x["wall"] for x in runs) / len(runs)))
        top = 0.82 if coated else 0.90
        best = [run("h", continuous(0.70, scatter, coated, seed, top, 60)) for seed in seeds]
        reached = [x["vf"] for x in best]
        for x in best:
            points.setdefault(label, []).append((x["wall"], x["vf"]))
        cells.append("%.4f (%.4f-%.4f), longest %.1f s%s" % (
            sum(reached) / len(reached), min(reached), max(reached),
            max(x["wall"] for x in best), "" if all(x["audit"] for x in best) else " AUDIT FAILED"))
        lines.append("| %s | %s |" % (label, " | ".join(cells)))
        print(lines[-1], flush=True)

# Transverse isotropy of the effective properties (FFT, one voxel along the fibres).
res = 256 if quick else 1024
iso = ["# Transverse isotropy of continuous fibres", "",
       "Machine: %s. `/usr/bin/python3 samples/bench_coated.py %s --parts isotropy --seeds %s`: "
       "FFT on %d x %d x 1 (one voxel along the fibres), %d fibres."
       % (machine(), build, ",".join(map(str, seeds)), res, res, N), "",
       "Matrix k 1, E 3.5, nu 0.35; fibres k 10, E 72, nu 0.22; interphase k 2, E 10, nu 0.3. "
       "Signed relative differences (k11 - k22) / k11, (C11 - C22) / C11 and "
       "(C66 - (C11 - C12)) / C66 (Mandel: C66 = 2 G12, so transverse isotropy is C66 = C11 - C12). "
       "Plain fibres are kept 0.1 radius apart (`min_gap`: touching fibres share voxels); coated "
       "fibres' cores are kept apart by their shells.", "",
       "| fibres | vf | seed | k11 | k22 | k33 | C11 | C22 | C12 | C66 | k | C11-C22 | C66 "
       "| wall s |",
       "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
summary = []
mats = {"matrix": {"conductivity": 1, "young": 3.5, "poisson": 0.35},
        "fibres": {"conductivity": 10, "young": 72, "poisson": 0.22},
        "fibres.coating": {"conductivity": 2, "young": 10, "poisson": 0.3}}
configs = ((0.0, False, 0.60, 0.1 * R), (0.0, False, 0.70, 0.1 * R), (0.08, True, 0.60, 0.0),
           (0.08, True, 0.70, 0.0))
for scatter, coated, vf, gap in (configs if "isotropy" in parts else ()):
    m = dict(mats)
    if not coated:
        del m["fibres.coating"]
    label = "8 % scatter, interphase" if coated else "monodisperse, gap 0.1 r"
    devs = []
    for seed in seeds:
        s = continuous(vf, scatter, coated, seed, extra={
            "voxels": {"resolution": [res, res, 1]}, "materials": m, "min_gap": gap,
            "homogenization": {"physics": ["conductivity", "elasticity"]},
            "outputs": ["inclusions"]})
        rc, wall, peak, rep = generate(exe, s, work, "fft")
        e = rep["effective"]
        k = e["conductivity"]["tensor"]
        C = e["stiffness"]["tensor"]
        d = ((k[0][0] - k[1][1]) / k[0][0], (C[0][0] - C[1][1]) / C[0][0],
             (C[5][5] - (C[0][0] - C[0][1])) / C[5][5])
        devs.append(d)
        iso.append("| %s | %.2f | %d | %.4f | %.4f | %.4f | %.3f | %.3f | %.3f | %.3f | %+.2f %% "
                   "| %+.2f %% | %+.2f %% | %.1f |"
                   % (label, vf, seed, k[0][0], k[1][1], k[2][2], C[0][0], C[1][1], C[0][1],
                      C[5][5], 100 * d[0], 100 * d[1], 100 * d[2], wall))
        print(iso[-1], flush=True)
    n = len(devs)
    summary.append("| %s | %.2f | %s | %s | %s |" % (label, vf, *(
        "mean %+.2f %%, largest %.2f %%" % (100 * sum(x[c] for x in devs) / n,
                                           100 * max(abs(x[c]) for x in devs))
        for c in range(3))))
if summary:
    iso += ["", "Over the seeds (mean of the signed difference, largest absolute one):", "",
            "| fibres | vf | k11 - k22 | C11 - C22 | C66 - (C11 - C12) |", "|---|---|---|---|---|"]
    iso += summary
    with open(os.path.join(charts, "continuous_isotropy_table.md"), "w") as f:
        f.write("\n".join(iso) + "\n")
    print("\n".join(iso))

if "rows" in parts or "continuous" in parts:
    with open(os.path.join(charts, "coated_table.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
if points:
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for label, pts in points.items():
        ax.scatter([p[0] for p in pts], [p[1] for p in pts], label=label, s=14)
    ax.set_xscale("log")
    ax.set_xlabel("wall time of the whole command (s)")
    ax.set_ylabel("fibre volume fraction reached")
    ax.set_title("Continuous fibres, %d per RVE, seeds %s" % (N, ",".join(map(str, seeds))))
    ax.axhline(0.82, color="grey", lw=0.8, ls="--")
    ax.text(ax.get_xlim()[0], 0.823, " random disk jamming (about 0.82)", fontsize=8, color="grey")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(charts, "continuous_fibres.png"), dpi=110)
print("\n".join(lines))
shutil.rmtree(work, ignore_errors=True)
