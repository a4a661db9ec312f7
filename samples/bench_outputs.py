#!/usr/bin/python3
"""End-to-end cost of `rvegen generate` as a user feels it: periodic monodisperse spheres at
volume fraction 0.60, voxels 64^3, every voxel file (--outputs inclusions,voxels,h5,amitex,levelsets:
inclusions as glyph points, voxels, rve.h5, material.vtk, level sets; no mesh; what the default
wrote until it became one compressed voxel file), for N = 1e3 .. 1e5 (add --million for 1e6). For each N: the
packing time from report.json, the whole command's wall time and peak memory (GNU time), and the
ratio wall / packing; every result audited by `rvegen check`. Prints a table (also written to
samples/charts/outputs_table.md) and draws samples/charts/outputs_scaling.png.

usage: /usr/bin/python3 samples/bench_outputs.py [BUILD_DIR] [--million]
"""
import json
import math
import os
import platform
import subprocess
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

args = [a for a in sys.argv[1:] if not a.startswith("--")]
build = args[0] if args else "build"
exe = os.path.join(build, "bin", "rvegen")
work = tempfile.mkdtemp(prefix="rvegen-outputs-")
charts = os.path.join("samples", "charts")
os.makedirs(charts, exist_ok=True)
sizes = [1000, 10000, 100000] + ([1000000] if "--million" in sys.argv else [])

rows = []
for n in sizes:
    phi = 0.60
    r = (phi * 3.0 / (4.0 * math.pi * n)) ** (1.0 / 3.0)
    scene = {"box": {"size": [1, 1, 1]}, "seed": 1,
             "families": [{"shape": "sphere", "radius": r, "volume_fraction": phi}],
             "md": {"max_seconds": 3600}}
    path = os.path.join(work, "s%d.json" % n)
    out = os.path.join(work, "rve%d" % n)
    with open(path, "w") as f:
        json.dump(scene, f)
    timed = subprocess.run(["/usr/bin/time", "-f", "%e %M", exe, "generate", "-q", path, "-o", out,
                            "--outputs", "inclusions,voxels,h5,amitex,levelsets"],
                           capture_output=True, text=True)
    wall, kb = timed.stderr.strip().splitlines()[-1].split()
    with open(os.path.join(out, "report.json")) as f:
        report = json.load(f)
    audit = subprocess.run([exe, "check", os.path.join(out, "inclusions.json")],
                           capture_output=True).returncode
    packing = report["timings"]["packing"]
    size_mb = sum(os.path.getsize(os.path.join(out, f)) for f in os.listdir(out)) / 2**20
    rows.append({"n": n, "rc": timed.returncode, "vf": report["volume_fraction"],
                 "packing": packing, "wall": float(wall), "peak_mb": int(kb) / 1024.0,
                 "files_mb": size_mb, "audit": "ok" if audit == 0 else "FAILED"})
    print("N=%d done: %.1f s wall" % (n, float(wall)), file=sys.stderr)

lines = ["| N | exit | volume fraction | packing (s) | whole run (s) | whole / packing | peak memory (MB) "
         "| files (MB) | audit |", "|---|---|---|---|---|---|---|---|---|"]
for r in rows:
    lines.append("| %d | %d | %.4f | %.1f | %.1f | %.2f | %.0f | %.0f | %s |" % (
        r["n"], r["rc"], r["vf"], r["packing"], r["wall"], r["wall"] / r["packing"], r["peak_mb"],
        r["files_mb"], r["audit"]))
lines.append("")
lines.append("%s, %d cores, `/usr/bin/python3 samples/bench_outputs.py %s`" % (
    platform.processor() or platform.machine(), os.cpu_count(), build))
table = "\n".join(lines)
print(table)
with open(os.path.join(charts, "outputs_table.md"), "w") as f:
    f.write(table + "\n")

fig, ax = plt.subplots(1, 2, figsize=(10, 4))
ns = [r["n"] for r in rows]
ax[0].loglog(ns, [r["packing"] for r in rows], "o-", label="packing")
ax[0].loglog(ns, [r["wall"] for r in rows], "s-", label="whole run (wall)")
ax[0].set_xlabel("spheres")
ax[0].set_ylabel("seconds")
ax[0].legend()
ax[0].grid(True, which="both", alpha=0.3)
ax[1].loglog(ns, [r["peak_mb"] for r in rows], "o-", color="C2")
ax[1].set_xlabel("spheres")
ax[1].set_ylabel("peak memory (MB)")
ax[1].grid(True, which="both", alpha=0.3)
fig.suptitle("rvegen generate, spheres at 0.60, voxels 64^3, every voxel file")
fig.tight_layout()
fig.savefig(os.path.join(charts, "outputs_scaling.png"), dpi=110)
print("wrote", os.path.join(charts, "outputs_scaling.png"))
