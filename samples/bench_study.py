#!/usr/bin/python3
"""A full representativity study (`rvegen study`), whole command under GNU time: short fibres of
L/D 10 at 0.20 (isotropic, conductivity 10 in a matrix of 1), box edges 1, 1.5 and 2 times
0.6, 10 realizations each, effective conductivity by FFT at a voxel size of 0.01. Prints the
table, writes samples/charts/study_table.md and the chart samples/charts/study_fibres.png.

usage: /usr/bin/python3 samples/bench_study.py [BUILD_DIR] [--jobs N] [--mpi N]
  --mpi N: the study under `mpirun -np N` (the realizations shared out among N ranks); the
  table then goes to samples/charts/study_table_mpi.md and no chart is drawn.
"""
import json
import os
import subprocess
import sys
import tempfile

from bench_util import machine, timed

args = [a for a in sys.argv[1:]]
jobs = []
if "--jobs" in args:
    i = args.index("--jobs")
    jobs = ["--jobs", args[i + 1]]
    args = args[:i] + args[i + 2:]
launcher = []
if "--mpi" in args:
    i = args.index("--mpi")
    launcher = ["mpirun", "--allow-run-as-root", "--oversubscribe", "-np", args[i + 1]]
    args = args[:i] + args[i + 2:]
build = args[0] if args else "build"
exe = os.path.join(build, "bin", "rvegen")
here = os.path.dirname(os.path.abspath(__file__))
work = tempfile.mkdtemp(prefix="rvegen-study-")
with open(os.path.join(here, "fibres_study.json")) as f:
    scene = json.load(f)  # the README's study scene
path = os.path.join(work, "fibres.json")
with open(path, "w") as f:
    json.dump(scene, f)
out = os.path.join(work, "study")
rc, wall, peak, err = timed(launcher + [exe, "study", path, "-o", out, "--sizes", "1,1.5,2",
                             "--realizations", "10", "--target-error", "0.01", "-q"] + jobs)
if rc != 0:
    raise SystemExit("rvegen study failed (exit %d): %s" % (rc, err[-800:]))
with open(os.path.join(out, "study.json")) as f:
    study = json.load(f)
opts = jobs + (["--mpi", launcher[-1]] if launcher else [])
lines = ["%s; `/usr/bin/python3 samples/bench_study.py%s`, whole command by GNU time: %.0f s, "
         "peak %.0f MiB%s." % (machine(), " " + " ".join(opts) if opts else "", wall, peak,
                                " (the largest process)" if launcher else ""), "",
         "Scene: isotropic fibres L/D 10 at 0.20 (conductivity 10, matrix 1), box 0.6 x "
         "{1, 1.5, 2}, 10 realizations per size, voxel size 0.01.", "",
         "| property | size | n | mean | sd | 95 % CI of the mean | relative error | "
         "realizations for 1 % |", "|---|---:|---:|---:|---:|---|---:|---:|"]
recs = []
for name in ("conductivity.mean", "conductivity.k11", "volume_fraction.fibres",
             "voxel_fraction.fibres", "nearest_neighbour.mean"):
    p = study["properties"].get(name)
    if not p:
        continue
    for r in p["per_size"]:
        lines.append("| %s | %g | %d | %.5g | %.3g | [%.5g, %.5g] | %.2g | %d |"
                     % (name, r["size"], r["n"], r["mean"], r["sd"], r["ci95"][0], r["ci95"][1],
                        r["relative_error"], r["realizations_needed"]))
    law, rec = p["variance_law"], p["recommended"]
    recs.append("| %s | %s | %s | %s | %s |" % (
        name, "exact" if law["exact"] else ("%.3g" % law["alpha"] if "alpha" in law else "-"),
        "%.3g" % law["integral_range"] if "integral_range" in law else "-",
        "%.3g (edge x%.2f)" % (rec["volume"], rec["size"]) if rec.get("volume") else "-",
        rec["basis"]))
lines += ["", "| property | fitted alpha | integral range | recommended volume for 1 %, "
          "10 realizations | basis |", "|---|---:|---:|---|---|"] + recs
text = "\n".join(lines) + "\n"
print(text)
with open(os.path.join(here, "charts", "study_table_mpi.md" if launcher else "study_table.md"),
          "w") as f:
    f.write(text)
if not launcher:
    subprocess.run(["/usr/bin/python3", os.path.join(here, "plot_study.py"), out,
                    "conductivity.mean", "nearest_neighbour.mean", "-o",
                    os.path.join(here, "charts", "study_fibres.png")], check=True)
