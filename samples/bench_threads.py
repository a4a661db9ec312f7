#!/usr/bin/python3
"""Packing on one core against two: `rvegen generate --threads 1` and `--threads 2` run in turn
on the same scene, whole command under GNU time, and the inclusion lists compared byte for byte.
Scenes: 100,000 spheres at 0.60; 2,500 isotropic fibres of L/D 20 at 0.22; the Figure 5 sample
(samples/scenes/figure5.json, coated wavy fibres and deformed grains, its default outputs).
Prints a table, the Amdahl limit of each scene from its measured speed-up, and writes
samples/charts/threads_table.md.

usage: /usr/bin/python3 samples/bench_threads.py [BUILD_DIR] [--repeat N]
  --repeat N: each scene N times, 1 and 2 threads in turn; the table gives the least wall time
  of each (this machine's times vary by 10-20 % from run to run), and the range.
"""
import filecmp
import json
import os
import shutil
import sys
import tempfile

from bench_util import machine, timed

args = sys.argv[1:]
repeat = 1
if "--repeat" in args:
    i = args.index("--repeat")
    repeat = int(args[i + 1])
    args = args[:i] + args[i + 2:]
build = args[0] if args else "build"
exe = os.path.join(build, "bin", "rvegen")
here = os.path.dirname(os.path.abspath(__file__))
work = tempfile.mkdtemp(prefix="rvegen-threads-")
scenes = [
    ("100,000 spheres at 0.60", {
        "box": {"size": [1, 1, 1]}, "seed": 1, "outputs": ["inclusions"],
        "families": [{"shape": "sphere", "radius": 0.01127, "volume_fraction": 0.60}]}),
    ("2,500 fibres L/D 20 at 0.22", {
        "box": {"size": [1, 1, 1]}, "seed": 1, "outputs": ["inclusions"],
        "families": [{"shape": "cylinder", "radius": 0.00888, "aspect_ratio": 20,
                      "volume_fraction": 0.22, "orientation": {"law": "isotropic"}}]}),
    ("Figure 5 sample", os.path.join(here, "scenes", "figure5.json")),
]
rows = []
for name, scene in scenes:
    if isinstance(scene, str):
        path = scene
    else:
        path = os.path.join(work, "scene%d.json" % len(rows))
        with open(path, "w") as f:
            json.dump(scene, f)
    res = {}
    walls = {1: [], 2: []}
    for rep_k in range(repeat):
        for t in (1, 2):
            out = os.path.join(work, "out%d_%d" % (len(rows), t))
            shutil.rmtree(out, ignore_errors=True)
            rc, wall, peak, err = timed([exe, "generate", "-q", path, "-o", out, "--threads",
                                         str(t)])
            if rc != 0:
                raise SystemExit("%s, %d thread(s): exit %d: %s" % (name, t, rc, err[-400:]))
            walls[t].append(wall)
            res[t] = (min(walls[t]), max(peak, res[t][1] if t in res else 0.0), out)
    spread = "%.1f-%.1f / %.1f-%.1f s" % (min(walls[1]), max(walls[1]), min(walls[2]),
                                          max(walls[2]))
    same = filecmp.cmp(os.path.join(res[1][2], "inclusions.json"),
                       os.path.join(res[2][2], "inclusions.json"), shallow=False)
    ratio = res[2][0] / res[1][0]
    # Amdahl from the measured ratio on 2 cores: ratio = s + (1 - s) / 2, so the serial share
    # s = 2 ratio - 1, and 16 cores give at most s + (1 - s) / 16 of the one-core time.
    serial = max(0.0, 2.0 * ratio - 1.0)
    at16 = serial + (1.0 - serial) / 16.0
    rows.append((name, res[1][0], res[2][0], ratio, res[1][1], res[2][1], same, serial, at16,
                 spread))
lines = ["%s; `/usr/bin/python3 samples/bench_threads.py%s`, whole command by GNU time, "
         "`--threads 1` then `--threads 2` on the same scene%s." % (
             machine(), " --repeat %d" % repeat if repeat > 1 else "",
             ", %d times: the least wall time of each" % repeat if repeat > 1 else ""), "",
         "| scene | 1 thread | 2 threads | ratio | runs (1 / 2 threads) | peak 1 / 2 | "
         "inclusions.json | serial share (Amdahl) | 16 cores, at best |",
         "|---|---:|---:|---:|---|---|---|---:|---:|"]
for r in rows:
    lines.append("| %s | %.1f s | %.1f s | %.2f | %s | %.0f / %.0f MiB | %s | %.0f %% | %.2f x one "
                 "core |" % (r[0], r[1], r[2], r[3], r[9], r[4], r[5],
                             "identical" if r[6] else "DIFFERENT", 100 * r[7], r[8]))
text = "\n".join(lines) + "\n"
print(text)
with open(os.path.join(here, "charts", "threads_table.md"), "w") as f:
    f.write(text)
