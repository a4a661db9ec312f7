#!/usr/bin/python3
"""Bytes written by `rvegen generate` for the default scene at 512^3 voxels, as a user feels it:
the default outputs (inclusions, compressed voxels.vti, level sets) against every voxel file
(--outputs inclusions,voxels,h5,amitex,levelsets: the image three times, as the default was
before), with the whole command's wall time and peak memory (GNU time). Prints a table and
writes it to samples/charts/output_size_table.md.

usage: /usr/bin/python3 samples/bench_output_size.py [BUILD_DIR] [RESOLUTION]
"""
import json
import os
import platform
import subprocess
import sys
import tempfile

build = sys.argv[1] if len(sys.argv) > 1 else "build"
res = int(sys.argv[2]) if len(sys.argv) > 2 else 512
exe = os.path.join(build, "bin", "rvegen")
work = tempfile.mkdtemp(prefix="rvegen-size-")
scene = json.loads(subprocess.run([exe, "default-scene"], check=True, capture_output=True,
                                  text=True).stdout)
scene["voxels"]["resolution"] = [res, res, res]
path = os.path.join(work, "scene.json")
with open(path, "w") as f:
    json.dump(scene, f)

rows = []
for label, extra in (("default outputs", []),
                     ("every voxel file", ["--outputs", "inclusions,voxels,h5,amitex,levelsets"])):
    out = os.path.join(work, label.replace(" ", "_"))
    t = subprocess.run(["/usr/bin/time", "-f", "%e %M", exe, "generate", "-q", path, "-o", out] + extra,
                       capture_output=True, text=True)
    if t.returncode != 0:
        sys.exit("rvegen failed: " + t.stderr)
    wall, peak_kb = t.stderr.strip().splitlines()[-1].split()
    files = sorted(os.listdir(out))
    size = sum(os.path.getsize(os.path.join(out, n)) for n in files)
    rows.append((label, size, float(wall), int(peak_kb) / 1024.0, " ".join(files)))

cpu = platform.processor() or platform.machine()
lines = ["Default scene (946 inclusions) at %d^3 voxels, whole command, %s, %d cores:" %
         (res, cpu, os.cpu_count()), "",
         "| outputs | bytes written | wall (s) | peak memory (MiB) | files |",
         "|---|---|---|---|---|"]
for label, size, wall, peak, files in rows:
    lines.append("| %s | %.1f MB | %.1f | %.0f | %s |" % (label, size / 1e6, wall, peak, files))
lines.append("")
lines.append("default / every voxel file: %.3f of the bytes" % (rows[0][1] / rows[1][1]))
text = "\n".join(lines)
print(text)
os.makedirs(os.path.join("samples", "charts"), exist_ok=True)
with open(os.path.join("samples", "charts", "output_size_table.md"), "w") as f:
    f.write(text + "\n")
