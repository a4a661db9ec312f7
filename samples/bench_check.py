#!/usr/bin/python3
"""`rvegen check` and the audit at scale, whole command (GNU time):

  * check of periodic simple-cubic lattices of spheres (radius 0.45 of the spacing), 125,000 and
    1,000,000 spheres (the file is written here);
  * generate of the 100:1 bidisperse mixture (one sphere of radius 0.3 at 0.11 of the box, about
    88,000 of radius 0.003 at 0.01) with md.max_seconds 10: packing, audit and whole command.

Prints a table and writes samples/charts/check_table.md.

usage: /usr/bin/python3 samples/bench_check.py [BUILD_DIR]
"""
import os
import sys
import tempfile

from bench_util import generate, machine, timed

build = sys.argv[1] if len(sys.argv) > 1 else "build"
exe = os.path.join(build, "bin", "rvegen")
work = tempfile.mkdtemp(prefix="rvegen-check-")
here = os.path.dirname(os.path.abspath(__file__))


def lattice(m, path):
    h = 1.0 / m
    with open(path, "w") as f:
        f.write('{"format": "rvegen.inclusions/1", "box": {"origin": [0, 0, 0], "size": [1, 1, 1], '
                '"periodic": true}, "family_names": ["spheres"], "inclusions": [')
        k = 0
        for z in range(m):
            for y in range(m):
                for x in range(m):
                    f.write('%s{"id": %d, "family": 0, "shape": "sphere", "center": [%r, %r, %r], '
                            '"radius": %r}' % ("," if k else "", k, (x + .5) * h, (y + .5) * h,
                                               (z + .5) * h, 0.45 * h))
                    k += 1
        f.write("]}")


lines = ["%s; `/usr/bin/python3 samples/bench_check.py`, whole command by GNU time." % machine(), "",
         "| case | inclusions | exit | wall s | peak MiB | note |", "|---|---:|---:|---:|---:|---|"]
for m in (50, 100):
    path = os.path.join(work, "lattice%d.json" % m)
    lattice(m, path)
    rc, wall, peak, err = timed([exe, "check", path])
    lines.append("| check, lattice | %d | %d | %.2f | %.0f | %.0f MB file |" % (
        m ** 3, rc, wall, peak, os.path.getsize(path) / 1e6))
    print(lines[-1], flush=True)
    os.remove(path)

scene = {"box": {"size": [1, 1, 1]}, "seed": 1, "md": {"max_seconds": 10},
         "families": [{"shape": "sphere", "radius": 0.3, "volume_fraction": 0.11},
                      {"shape": "sphere", "radius": 0.003, "volume_fraction": 0.01}]}
rc, wall, peak, r = generate(exe, scene, work, "bidisperse")
lines.append("| generate, 100:1 mixture, budget 10 s | %d | %d | %.2f | %.0f | packing %.2f s, audit "
             "%.2f s |" % (r["count"], rc, wall, peak, r["timings"]["packing"],
                           r["timings"]["audit"]))
print(lines[-1], flush=True)
text = "\n".join(lines)
print(text)
with open(os.path.join(here, "charts", "check_table.md"), "w") as f:
    f.write(text + "\n")
