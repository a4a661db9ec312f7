#!/usr/bin/python3
"""Dense monodisperse sphere targets with default settings, seed by seed.

10,000 spheres in a unit box asked for 0.636 and 0.645 (no "md" settings), seeds 1-8: the exit
code, status, volume fraction reached and the wall time of the whole `rvegen generate` command
(outputs: the inclusion files). Prints the table and writes samples/charts/dense_spheres_table.md.

usage: /usr/bin/python3 samples/bench_dense_spheres.py [BUILD_DIR]
"""
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time

build = sys.argv[1] if len(sys.argv) > 1 else "build"
exe = os.path.join(build, "bin", "rvegen")
here = os.path.dirname(os.path.abspath(__file__))
work = tempfile.mkdtemp(prefix="rvegen-dense-")
lines = ["10,000 spheres, default settings, `rvegen generate` wall time (inclusion files written); "
         "%s, %d cores." % (platform.processor() or platform.machine(), os.cpu_count()), "",
         "| target | seed | exit | status | volume fraction | seconds |", "|---|---:|---:|---|---:|---:|"]
summary = []
for target in (0.636, 0.645):
    reached = 0
    for seed in range(1, 9):
        scene = {"box": {"size": [1, 1, 1]}, "seed": seed,
                 "families": [{"shape": "sphere", "volume_fraction": target, "count": 10000}],
                 "outputs": ["inclusions"]}
        path = os.path.join(work, "s.json")
        with open(path, "w") as f:
            json.dump(scene, f)
        out = os.path.join(work, "rve")
        t = time.time()
        rc = subprocess.run([exe, "generate", "-q", path, "-o", out]).returncode
        wall = time.time() - t
        with open(os.path.join(out, "report.json")) as f:
            report = json.load(f)
        reached += rc == 0
        lines.append("| %.3f | %d | %d | %s | %.4f | %.1f |" % (target, seed, rc, report["status"],
                                                             report["volume_fraction"], wall))
        print(lines[-1], flush=True)
    summary.append("%.3f: %d of 8 seeds" % (target, reached))
peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
lines += ["", "Reached: " + "; ".join(summary) + ". Largest peak memory of a run: %.0f MiB." % peak]
text = "\n".join(lines)
print(text)
with open(os.path.join(here, "charts", "dense_spheres_table.md"), "w") as f:
    f.write(text + "\n")
