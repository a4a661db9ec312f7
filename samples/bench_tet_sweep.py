#!/usr/bin/python3
"""Tetrahedral meshes of packings other than the benchmark's, looking for failures: each kind
of scene with several seeds, `"mesh_tet": {"chord_error": 0.03, "gap_elements": 1}` (the other
settings at their defaults), whole command under GNU time. Kinds:

  coated:     coated spheres (radius 0.07, shells 0.01) at 0.35, box 0.5, min_gap 0.005;
  ellipsoids: ellipsoids of 0.1 x 0.07 x 0.05 at 0.4, unit box, min_gap 0.005;
  mix:        spheres (radius 0.06) at 0.2 with fibres (radius 0.02, L/D 8) at 0.12, box 0.8,
              min_gap 0.004;
  fibres:     isotropic fibres (radius 0.0117, L/D 10) at 0.2, box 0.6, min_gap 0.002.

Prints one row per run: exit code, wall seconds, peak MiB, elements, least dihedral angle,
elements under 5 degrees and the attempts that failed before the mesh was made, with their
messages (from report.json), or the error's last line; writes the table to
samples/charts/tet_sweep_table.md.

usage: /usr/bin/python3 samples/bench_tet_sweep.py [BUILD_DIR] [--seeds 11,12,13]
                                                   [--kinds coated,ellipsoids,mix,fibres]
                                                   [--name tet_sweep]
(--name: the table's file name, samples/charts/NAME_table.md)
"""
import json
import os
import shutil
import sys
import tempfile

from bench_util import machine, timed

args = sys.argv[1:]
seeds, kinds = [11, 12, 13], ["ellipsoids", "mix", "fibres", "coated"]
name_out = "tet_sweep"
for flag in ("--seeds", "--kinds", "--name"):
    if flag in args:
        i = args.index(flag)
        values = args[i + 1].split(",")
        if flag == "--seeds":
            seeds = [int(v) for v in values]
        elif flag == "--name":
            name_out = args[i + 1]
        else:
            kinds = values
        args = args[:i] + args[i + 2:]
build = args[0] if args else "build"
exe = os.path.join(build, "bin", "rvegen")
here = os.path.dirname(os.path.abspath(__file__))


def scene(kind, seed):
    families = {
        "coated": ([0.5] * 3, 0.005, [{"name": "cs", "shape": "sphere", "radius": 0.07,
                                       "volume_fraction": 0.35,
                                       "coating": {"thickness": 0.01}}]),
        "ellipsoids": ([1.0] * 3, 0.005, [{"name": "el", "shape": "ellipsoid",
                                           "semi_axes": [0.1, 0.07, 0.05],
                                           "volume_fraction": 0.4}]),
        "mix": ([0.8] * 3, 0.004, [{"name": "sp", "shape": "sphere", "radius": 0.06,
                                    "volume_fraction": 0.2},
                                   {"name": "fi", "shape": "cylinder", "radius": 0.02,
                                    "aspect_ratio": 8, "volume_fraction": 0.12}]),
        "fibres": ([0.6] * 3, 0.002, [{"name": "fi", "shape": "cylinder", "radius": 0.0117,
                                       "aspect_ratio": 10, "volume_fraction": 0.2}]),
    }
    box, gap, fams = families[kind]
    return {"box": {"size": box}, "seed": seed, "min_gap": gap, "families": fams,
            "outputs": ["inclusions", "mesh_tet"],
            "mesh_tet": {"chord_error": 0.03, "gap_elements": 1}}


work = tempfile.mkdtemp(prefix="rvegen-tet-sweep-")
rows = []
print("kind\tseed\texit\twall_s\tpeak_MiB\telements\tleast_deg\tunder_5\tretries\tnote",
      flush=True)
try:
    for seed in seeds:
        for kind in kinds:
            name = "%s_%d" % (kind, seed)
            path, out = os.path.join(work, name + ".json"), os.path.join(work, name)
            with open(path, "w") as f:
                json.dump(scene(kind, seed), f)
            rc, wall, peak, err = timed([exe, "generate", "-q", path, "-o", out])
            elements = least = under = note = ""
            retries = ""
            try:
                with open(os.path.join(out, "report.json")) as f:
                    mesh = json.load(f)["mesh_tet"]
                elements = mesh["tetrahedra"]
                least = "%.2f" % mesh["min_dihedral_degrees"]["min"]
                under = mesh["min_dihedral_degrees"]["below_5_degrees"]
                retries = len(mesh.get("retries", []))
                # Each retry: the start of the message and what followed it.
                note = " / ".join(r[:70] + " ... " + r.rsplit("; ", 1)[-1]
                                  for r in mesh.get("retries", []))
            except (OSError, KeyError):
                lines = [ln for ln in err.splitlines()
                         if ln.strip() and not ln.startswith("Command exited")]
                note = lines[-1][:160] if lines else ""
            row = (kind, seed, rc, "%.1f" % wall, "%.0f" % peak, elements, least, under, retries,
                   note)
            rows.append(row)
            print("\t".join(str(v) for v in row), flush=True)
            shutil.rmtree(out, ignore_errors=True)
finally:
    shutil.rmtree(work, ignore_errors=True)

with open(os.path.join(here, "charts", name_out + "_table.md"), "w") as f:
    f.write("Machine: %s\n\n" % machine())
    f.write("| kind | seed | exit | wall s | peak MiB | elements | least degrees | under 5 | "
            "retries | note |\n|---|---|---|---|---|---|---|---|---|---|\n")
    for row in rows:
        f.write("| " + " | ".join(str(v) for v in row) + " |\n")
