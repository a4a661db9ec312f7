#!/usr/bin/python3
"""Dense monodisperse sphere targets with default settings, seed by seed.

10,000 spheres in a unit box asked for 0.636 and 0.645 (no "md" settings), seeds 1-8: the exit
code, status, volume fraction reached and the wall time of the whole `rvegen generate` command
(outputs: the inclusion files) and its peak memory (GNU time). Prints the table and writes samples/charts/dense_spheres_table.md.

usage: /usr/bin/python3 samples/bench_dense_spheres.py [BUILD_DIR]
"""
import os
import sys
import tempfile

from bench_util import generate, machine

build = sys.argv[1] if len(sys.argv) > 1 else "build"
exe = os.path.join(build, "bin", "rvegen")
here = os.path.dirname(os.path.abspath(__file__))
work = tempfile.mkdtemp(prefix="rvegen-dense-")
lines = ["10,000 spheres, default settings, whole `rvegen generate` command (inclusion files "
         "written), runs in turn; %s; `/usr/bin/python3 samples/bench_dense_spheres.py`." % machine(),
         "", "| target | seed | exit | status | volume fraction | wall s | peak MiB |",
         "|---|---:|---:|---|---:|---:|---:|"]
summary = []
for target in (0.636, 0.645):
    reached = 0
    for seed in range(1, 9):
        scene = {"box": {"size": [1, 1, 1]}, "seed": seed,
                 "families": [{"shape": "sphere", "volume_fraction": target, "count": 10000}],
                 "outputs": ["inclusions"]}
        rc, wall, peak, report = generate(exe, scene, work, "rve")
        reached += rc == 0
        lines.append("| %.3f | %d | %d | %s | %.4f | %.1f | %.0f |" % (
            target, seed, rc, report["status"], report["volume_fraction"], wall, peak))
        print(lines[-1], flush=True)
    summary.append("%.3f: %d of 8 seeds" % (target, reached))
lines += ["", "Reached: " + "; ".join(summary) + "."]
text = "\n".join(lines)
print(text)
with open(os.path.join(here, "charts", "dense_spheres_table.md"), "w") as f:
    f.write(text + "\n")
