#!/usr/bin/python3
"""Voxel and level-set benchmarks: accuracy against time, as tables and charts.

usage: /usr/bin/python3 samples/bench_voxels.py BUILD_DIR [--quick]

Runs BUILD_DIR/bin/rvegen_bench_voxels and writes
  samples/charts/voxels_table.md          the tables below, as measured
  samples/charts/voxels_error.png         |volume fraction error| against resolution
  samples/charts/voxels_time_error.png    time against error (centre sampling, partial volume)
  samples/charts/levelsets.png            level sets: sparse/dense memory and volume error
                                          against voxel size, with build time
"""
import os
import platform
import subprocess
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

build = sys.argv[1]
quick = "--quick" in sys.argv
here = os.path.dirname(os.path.abspath(__file__))
charts = os.path.join(here, "charts")
os.makedirs(charts, exist_ok=True)
exe = os.path.join(build, "bin", "rvegen_bench_voxels")


def run(args):
    out = subprocess.run([exe] + args, check=True, capture_output=True, text=True).stdout
    return [line.split("\t") for line in out.strip().splitlines()]


res = [24, 32, 48, 64] if quick else [24, 32, 48, 64, 96, 128, 192, 256, 384]
rows = run(["default"] + [str(r) for r in res])
big = [] if quick else run(["spheres10k", "512", "--threads", "1"]) + run(["spheres10k", "512", "--threads", "2"])
ls_n = [32, 64, 128] if quick else [64, 96, 128, 192, 256, 384, 512]
ls_rows = run(["--levelsets", os.path.join(here, "scenes", "modified.json")] + [str(n) for n in ls_n])

lines = ["Machine: %s, %d cores (%s). Command: `/usr/bin/python3 samples/bench_voxels.py build`."
         % (platform.node(), os.cpu_count(), platform.processor() or platform.machine()), "",
         "Default scene (946 inclusions, analytic volume fraction of the cores in the last column"
         " but two), 2 threads:", "",
         "| resolution | method | seconds | volume fraction | analytic | abs. error |",
         "|---:|---|---:|---:|---:|---:|"]
for r in rows:
    lines.append("| %s^3 | %s | %s | %s | %s | %s |" % (r[2], r[3], r[4], r[5], r[6], r[7]))
if big:
    lines += ["", "10,000 inclusions (default mix, 35 %), 512^3:", "",
              "| threads | method | seconds | abs. error |", "|---:|---|---:|---:|"]
    for r in big:
        lines.append("| %s | %s | %s | %s |" % (r[8], r[3], r[4], r[7]))
lines += ["", "Level sets of samples/scenes/modified.json (coated spheres, wavy fibres, deformed"
          " ellipsoids; 3 grids), voxel size = box / N, 2 threads:", "",
          "| N | seconds | sparse MB | dense MB | sparse / dense | volume error |",
          "|---:|---:|---:|---:|---:|---:|"]
for r in ls_rows:
    lines.append("| %s | %s | %.1f | %.1f | %s | %s |"
                 % (r[0], r[1], int(r[3]) / 1e6, int(r[4]) / 1e6, r[5], r[6]))
text = "\n".join(lines) + "\n"
print(text)
if not quick:
    with open(os.path.join(charts, "voxels_table.md"), "w") as f:
        f.write(text)

suffix = "_quick" if quick else ""
fig, ax = plt.subplots(figsize=(6, 4))
for method, marker in (("centre", "o"), ("partial", "s")):
    sel = [r for r in rows if r[3] == method]
    ax.loglog([int(r[2]) for r in sel], [max(float(r[7]), 1e-9) for r in sel], marker=marker,
              label={"centre": "centre sampling", "partial": "partial volume"}[method])
ax.axhline(0.005, color="grey", ls=":", lw=1)
ax.axhline(0.002, color="grey", ls="--", lw=1)
ax.set_xlabel("voxels per box edge")
ax.set_ylabel("|volume fraction - analytic|")
ax.set_title("Voxel accuracy, default scene (targets: 0.005 at 64, 0.002 at 128)")
ax.legend()
fig.tight_layout()
fig.savefig(os.path.join(charts, "voxels_error%s.png" % suffix), dpi=120)

fig, ax = plt.subplots(figsize=(6, 4))
for method, marker in (("centre", "o"), ("partial", "s")):
    sel = [r for r in rows if r[3] == method]
    ax.loglog([float(r[4]) for r in sel], [max(float(r[7]), 1e-9) for r in sel], marker=marker,
              label={"centre": "centre sampling", "partial": "partial volume"}[method])
    for r in sel:
        ax.annotate(r[2], (float(r[4]), max(float(r[7]), 1e-9)), fontsize=7)
ax.set_xlabel("seconds (2 threads)")
ax.set_ylabel("|volume fraction - analytic|")
ax.set_title("Voxelization: time against accuracy (labels = resolution)")
ax.legend()
fig.tight_layout()
fig.savefig(os.path.join(charts, "voxels_time_error%s.png" % suffix), dpi=120)

fig, ax1 = plt.subplots(figsize=(6, 4))
n = [int(r[0]) for r in ls_rows]
ax1.loglog(n, [float(r[5]) for r in ls_rows], "o-", label="sparse / dense memory")
ax1.loglog(n, [max(float(r[6]), 1e-9) for r in ls_rows], "s-", label="volume error (box fraction)")
ax1.set_xlabel("voxels per box edge (level-set voxel size = box / N)")
ax1.legend(loc="lower left")
ax2 = ax1.twinx()
ax2.loglog(n, [float(r[1]) for r in ls_rows], "^--", color="grey", label="build seconds")
ax2.set_ylabel("build seconds")
ax2.legend(loc="upper right")
ax1.set_title("Level sets: memory and accuracy against voxel size")
fig.tight_layout()
fig.savefig(os.path.join(charts, "levelsets%s.png" % suffix), dpi=120)
