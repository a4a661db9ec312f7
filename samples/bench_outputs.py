#!/usr/bin/python3
"""End-to-end cost of `rvegen generate` as a user feels it: periodic monodisperse spheres at
volume fraction 0.60, voxels 64^3, N = 1e3 .. 1e5 (add --million for 1e6), each with two output
sets:
  default  the default outputs: inclusions, voxels (voxels.vti), levelsets (none for spheres) and
           statistics (g(r) and nearest-neighbour distances in report.json);
  lean     the inclusion files only, no statistics (--outputs inclusions).
For each run: the packing time and the statistics time from report.json, the whole command's wall
time and peak memory (GNU time), the bytes written; every result audited by `rvegen check`.
Prints a table (also written to samples/charts/outputs_table.md) and draws
samples/charts/outputs_scaling.png.

usage: /usr/bin/python3 samples/bench_outputs.py [BUILD_DIR] [--million]
"""
import json
import math
import os
import subprocess
import sys
import tempfile

import matplotlib

from bench_util import machine, timed

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

args = [a for a in sys.argv[1:] if not a.startswith("--")]
build = args[0] if args else "build"
exe = os.path.join(build, "bin", "rvegen")
work = tempfile.mkdtemp(prefix="rvegen-outputs-")
charts = os.path.join("samples", "charts")
os.makedirs(charts, exist_ok=True)
sizes = [1000, 10000, 100000] + ([1000000] if "--million" in sys.argv else [])
configs = [("default", "inclusions,voxels,levelsets,statistics"), ("lean", "inclusions")]

rows = []
for n in sizes:
    phi = 0.60
    r = (phi * 3.0 / (4.0 * math.pi * n)) ** (1.0 / 3.0)
    scene = {"box": {"size": [1, 1, 1]}, "seed": 1,
             "families": [{"shape": "sphere", "radius": r, "volume_fraction": phi}],
             "md": {"max_seconds": 3600}}
    path = os.path.join(work, "s%d.json" % n)
    with open(path, "w") as f:
        json.dump(scene, f)
    for name, outputs in configs:
        out = os.path.join(work, "rve%d_%s" % (n, name))
        rc, wall, peak, err = timed([exe, "generate", "-q", path, "-o", out, "--outputs", outputs])
        if rc != 0:
            raise SystemExit("rvegen generate failed (exit %d): %s" % (rc, err[-500:]))
        with open(os.path.join(out, "report.json")) as f:
            report = json.load(f)
        audit = subprocess.run([exe, "check", os.path.join(out, "inclusions.json")],
                               capture_output=True).returncode
        size_mb = sum(os.path.getsize(os.path.join(out, f)) for f in os.listdir(out)) / 2**20
        rows.append({"n": n, "config": name, "rc": rc, "vf": report["volume_fraction"],
                     "packing": report["timings"]["packing"],
                     "statistics": report["timings"].get("statistics", 0.0), "wall": wall,
                     "peak_mb": peak, "files_mb": size_mb,
                     "audit": "ok" if audit == 0 else "FAILED"})
        print("N=%d %s: %.1f s wall, %.0f MiB" % (n, name, wall, peak), file=sys.stderr, flush=True)

lines = ["%s; `/usr/bin/python3 samples/bench_outputs.py %s`, runs in turn, whole command by GNU "
         "time." % (machine(), " ".join(sys.argv[1:])), "",
         "| N | outputs | exit | volume fraction | packing (s) | statistics (s) | whole run (s) "
         "| whole / packing | peak memory (MiB) | files (MiB) | audit |",
         "|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
for r in rows:
    lines.append("| %d | %s | %d | %.4f | %.1f | %.1f | %.1f | %.2f | %.0f | %.0f | %s |" % (
        r["n"], r["config"], r["rc"], r["vf"], r["packing"], r["statistics"], r["wall"],
        r["wall"] / r["packing"], r["peak_mb"], r["files_mb"], r["audit"]))
lines += ["", "default: --outputs " + configs[0][1] + " (the default); lean: --outputs " +
          configs[1][1] + " (no statistics)."]
table = "\n".join(lines)
print(table)
with open(os.path.join(charts, "outputs_table.md"), "w") as f:
    f.write(table + "\n")

fig, ax = plt.subplots(1, 2, figsize=(10, 4))
for k, (name, _) in enumerate(configs):
    sel = [r for r in rows if r["config"] == name]
    ns = [r["n"] for r in sel]
    if k == 0:
        ax[0].loglog(ns, [r["packing"] for r in sel], "o--", color="grey", label="packing")
    ax[0].loglog(ns, [r["wall"] for r in sel], "s-", color="C%d" % k,
                 label="whole run, %s outputs" % name)
    ax[1].loglog(ns, [r["peak_mb"] for r in sel], "o-", color="C%d" % k, label=name + " outputs")
ax[0].set_xlabel("spheres")
ax[0].set_ylabel("seconds")
ax[0].legend()
ax[0].grid(True, which="both", alpha=0.3)
ax[1].set_xlabel("spheres")
ax[1].set_ylabel("peak memory (MiB)")
ax[1].legend()
ax[1].grid(True, which="both", alpha=0.3)
fig.suptitle("rvegen generate, spheres at 0.60, voxels 64^3")
fig.tight_layout()
fig.savefig(os.path.join(charts, "outputs_scaling.png"), dpi=110)
print("wrote", os.path.join(charts, "outputs_scaling.png"))
