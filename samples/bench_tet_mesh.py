#!/usr/bin/python3
"""Tetrahedral mesh benchmarks (`--outputs mesh_tet`): whole-command wall time and peak memory
(/usr/bin/time), elements, elements per second, element quality and phase volumes, for

  1. spheres of radius 0.1 in a periodic box of 0.6 (the analyst's sample without its rods),
     volume fraction 0.15 to 0.64 (asked; the packer stops where min_gap jams it) against
     min_gap 0.005, 0.01, 0.03: failures where they happen;
  2. a short-fibre scene: 40 fibres of L/D 10 at 0.25 in the unit box, orientation tensor
     diag(0.7, 0.25, 0.05), min_gap 0.005, meshed, then run by CalculiX (the conductivity deck,
     fibres 10 times the matrix) against rvegen's FFT value on laminate voxels at 128^3;
  3. the default scene (946 inclusions: spheres, fibres of radius 0.02, ellipsoids; min_gap 0):
     the memory estimate at the default chord error, and the mesh at coarser ones;
  4. with --large: the aim of 2 minutes and 4 GB for the whole command, on the default scene
     as it is (min_gap 0, chord error 0.03) and on 2,484 fibres of L/D 10 at 0.25 in the
     unit box (radius 0.0117, orientation tensor diag(0.7, 0.25, 0.05), min_gap 0.002, chord
     error 0.1, optimiser threshold 0.15), 10-node elements with one and with half an element
     across the gaps (about 7 minutes; its table also in samples/charts/tet_mesh_large_table.md).

Prints the tables (also written to samples/charts/tet_mesh_table.md) and draws
samples/charts/tet_mesh_sweep.png (time and least dihedral angle against the volume fraction,
one curve per min_gap).

usage: /usr/bin/python3 samples/bench_tet_mesh.py [BUILD_DIR] [--quick] [--no-ccx] [--no-spheres]
                                                  [--no-fibres] [--no-default] [--large]
"""
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_util import generate, machine, timed  # noqa: E402

args = [a for a in sys.argv[1:] if not a.startswith("--")]
quick = "--quick" in sys.argv
build = args[0] if args else "build"
exe = os.path.abspath(os.path.join(build, "bin", "rvegen"))
here = os.path.dirname(os.path.abspath(__file__))
work = tempfile.mkdtemp(prefix="rvegen-tet-")
charts = os.path.join(here, "charts")
os.makedirs(charts, exist_ok=True)
lines = ["Machine: %s. `%s`." % (machine(), " ".join(["samples/bench_tet_mesh.py"] + sys.argv[1:])),
         ""]


def say(text=""):
    print(text)
    sys.stdout.flush()
    lines.append(text)


def mesh_row(report):
    m = report["mesh_tet"]
    worst = max(abs(p["relative_error"]) for p in m["phases"] if p["exact_volume"] > 0)
    q = m["min_dihedral_degrees"]
    return m["tetrahedra"], q["min"], q["below_5_degrees"], worst, m.get("merged_nodes", 0)


def least_gap(out):
    """The least surface gap between two spheres of an RVE (periodic images included)."""
    with open(os.path.join(out, "inclusions.json")) as f:
        incs = json.load(f)
    size = incs["box"]["size"]
    balls = [(i["center"], i["radius"]) for i in incs["inclusions"]]
    least = math.inf
    for a in range(len(balls)):
        for b in range(a + 1, len(balls)):
            d = [balls[b][0][k] - balls[a][0][k] for k in range(3)]
            d = [x - size[k] * round(x / size[k]) for k, x in enumerate(d)]
            least = min(least, math.sqrt(sum(x * x for x in d)) - balls[a][1] - balls[b][1])
    return least


def phase_errors(report):
    """Each phase's volume error in the mesh, as a table cell."""
    return ", ".join("%s %+.2f %%" % (p["name"], 100 * p["relative_error"])
                     for p in report["mesh_tet"]["phases"])


def clearance(report):
    """The cell's move and its least face and edge clearances, as a table cell."""
    m = report["mesh_tet"]
    moved = any(abs(x) > 0 for x in m["cell_origin"])
    return "%s %.2f / %.2f" % ("moved" if moved else "box", m["face_clearance"],
                               m["edge_clearance"])


def spheres_part():
    """1. Spheres: volume fraction against min_gap."""
    fractions = [0.15, 0.35] if quick else [0.15, 0.25, 0.35, 0.45, 0.55, 0.64]
    # min_gap 0: the packer's own gaps, down to where the spheres all but touch (pinch points).
    gaps = [0.01, 0.03] if quick else [0.0, 0.005, 0.01, 0.03]
    say("## Spheres of radius 0.1, box 0.6: volume fraction against min_gap")
    say()
    say("| volume fraction | min_gap | spheres | exit | wall s | peak MiB | tetrahedra | estimated "
        "| tets/s | least angle | under 5 deg | worst volume error | cell, clearance face / edge "
        "| least gap / radius |")
    say("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    sweep = {}
    for gap in gaps:
        for vf in fractions:
            scene = {"box": {"size": [0.6, 0.6, 0.6]}, "seed": 5, "min_gap": gap,
                     "md": {"max_seconds": 60},
                     "families": [{"name": "spheres", "shape": "sphere", "radius": 0.1,
                                   "volume_fraction": vf}],
                     "outputs": ["inclusions", "mesh_tet"]}
            name = "s_%g_%g" % (vf, gap)
            path = os.path.join(work, name + ".json")
            with open(path, "w") as f:
                json.dump(scene, f)
            rc, wall, peak, err = timed([exe, "generate", "-q", path, "-o", os.path.join(work, name)])
            count = round(vf * 0.216 / (4 / 3 * math.pi * 1e-3))
            reached = os.path.exists(os.path.join(work, name, "report.json"))
            if rc != 0 and not (rc == 3 and reached):  # 3: the packing stopped short, RVE written
                why = [ln for ln in err.strip().splitlines() if ln.startswith("rvegen:")]
                say("| %.2f | %g | %d | %d | %.1f | %.0f | failed: %s | | | | | | | |"
                    % (vf, gap, count, rc, wall, peak, (why or ["?"])[-1][:120]))
                continue
            with open(os.path.join(work, name, "report.json")) as f:
                report = json.load(f)
            tets, least, below, worst, merged = mesh_row(report)
            sweep.setdefault(gap, []).append((vf, wall, least, tets))
            got = report["volume_fraction"]
            estimated = report["mesh_tet"]["estimated_tetrahedra"]
            say("| %.2f%s | %g | %d | %d | %.1f | %.0f | %d | %d (%+.0f %%) | %.0f | %.2f | %d | %.3f %% "
                "| %s | %.4f |"
                % (vf, " (packed %.3f)" % got if rc == 3 else "", gap, count, rc, wall, peak, tets,
                   estimated, 100 * (estimated / tets - 1), tets / wall, least, below, 100 * worst,
                   clearance(report), least_gap(os.path.join(work, name)) / 0.1))
            shutil.rmtree(os.path.join(work, name), ignore_errors=True)

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
    for gap, rows in sorted(sweep.items()):
        a1.plot([r[0] for r in rows], [r[1] for r in rows], "o-", label="min_gap %g" % gap)
        a2.plot([r[0] for r in rows], [r[2] for r in rows], "o-", label="min_gap %g" % gap)
    a1.set_xlabel("volume fraction of spheres")
    a1.set_ylabel("whole command, s")
    a1.set_title("Tetrahedral mesh: wall time")
    a2.axhline(5.0, color="grey", ls="--", lw=1)
    a2.set_xlabel("volume fraction of spheres")
    a2.set_ylabel("least dihedral angle, degrees")
    a2.set_title("Element quality (5 degrees dashed)")
    for a in (a1, a2):
        a.grid(alpha=0.3)
        a.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(charts, "tet_mesh_sweep.png"), dpi=110)


if "--no-spheres" not in sys.argv:
    spheres_part()



def fibres_part():
    """2. Short fibres, meshed and run by CalculiX."""
    n = 12 if quick else 40
    r = (0.25 / (2.0 * math.pi * 10 * n)) ** (1.0 / 3.0)
    fibres = {"box": {"size": [1, 1, 1]}, "seed": 1, "min_gap": 0.005, "md": {"max_seconds": 120},
              "families": [{"name": "fibres", "shape": "cylinder", "radius": r, "aspect_ratio": 10,
                            "count": n,
                            "orientation": {"law": "tensor",
                                            "a2": [[0.7, 0, 0], [0, 0.25, 0], [0, 0, 0.05]]}}],
              "voxels": {"resolution": 64 if quick else 128},
              "materials": {"matrix": {"conductivity": 1}, "fibres": {"conductivity": 10}},
              "homogenization": {"physics": ["conductivity"], "tolerance": 1e-8},
              "outputs": ["inclusions", "mesh_tet"]}
    say()
    say("## %d fibres of L/D 10 (radius %.4f) at 0.25, tensor orientation, min_gap 0.005" % (n, r))
    say()
    rc, wall, peak, report = generate(exe, fibres, work, "fibres")
    if rc != 0:
        say("rvegen generate: exit %d" % rc)
    else:
        tets, least, below, worst, merged = mesh_row(report)
        fft = report["effective"]["conductivity"]["tensor"]
        say("rvegen generate (packing, mesh, FFT at %d^3): %.1f s, %.0f MiB; %d tetrahedra, "
            "least angle %.2f deg, %d under 5 deg, worst phase volume error %.3f %%, %d nodes merged"
            % (fibres["voxels"]["resolution"], wall, peak, tets, least, below, 100 * worst, merged))
        if "--no-ccx" not in sys.argv and shutil.which("ccx"):
            run = os.path.join(work, "fibres_run")
            shutil.copytree(os.path.join(work, "fibres"), run)
            p = subprocess.run(["/usr/bin/time", "-f", "TIME %e %M", "ccx", "-i",
                                "run_tet_conductivity"], cwd=run, capture_output=True, text=True)
            t = [ln for ln in p.stderr.splitlines() if ln.startswith("TIME ")][-1].split()
            warned = [ln for ln in p.stdout.splitlines() if "*WARNING" in ln or "*ERROR" in ln]
            eff = json.loads(subprocess.run([sys.executable, os.path.join(here, "ccx_effective.py"),
                                             run, "run_tet_conductivity"], check=True,
                                            capture_output=True, text=True).stdout)["conductivity"]
            say("CalculiX (conductivity deck): exit %d, %.1f s, %.0f MiB, %d warnings or errors"
                % (p.returncode, float(t[1]), int(t[2]) / 1024, len(warned)))
            say()
            say("| | k11 | k22 | k33 |")
            say("|---|---|---|---|")
            say("| CalculiX, tetrahedra | %.4f | %.4f | %.4f |" % (eff[0][0], eff[1][1], eff[2][2]))
            say("| FFT, laminate voxels | %.4f | %.4f | %.4f |" % (fft[0][0], fft[1][1], fft[2][2]))
            say("| difference | %+.2f %% | %+.2f %% | %+.2f %% |"
                % tuple(100 * (eff[i][i] / fft[i][i] - 1) for i in range(3)))
        shutil.rmtree(os.path.join(work, "fibres"), ignore_errors=True)

if "--no-fibres" not in sys.argv:
    fibres_part()


# 3. The default scene: the estimate at the default chord error, then meshes at coarser ones.
def default_part():
    say()
    say("## The default scene (946 inclusions, min_gap 0)")
    say()
    rc, wall, peak, err = timed([exe, "generate", "-q", "--outputs", "mesh_tet", "--max-memory",
                                 "4G", "-o", os.path.join(work, "default")])
    why = [ln for ln in err.strip().splitlines() if ln.startswith("rvegen:")]
    say("Default chord error 0.003, `--max-memory 4G`: exit %d after %.1f s: %s"
        % (rc, wall, (why or ["?"])[-1]))
    say()
    say("| chord error | exit | wall s | peak MiB | tetrahedra | tets/s | least angle | under 5 deg "
        "| volume error per phase | cell, clearance face / edge |")
    say("|---|---|---|---|---|---|---|---|---|---|")
    for chord in ([0.03] if quick else [0.03, 0.01]):
        scene = json.loads(subprocess.run([exe, "default-scene"], check=True, capture_output=True,
                                          text=True).stdout)
        scene["mesh_tet"] = {"chord_error": chord}
        scene["outputs"] = ["mesh_tet"]
        try:
            rc, wall, peak, report = generate(exe, scene, work, "default_%g" % chord)
        except SystemExit as e:
            say("| %g | failed: %s | | | | | | | | |" % (chord, str(e)[-200:].replace("\n", " ")))
            continue
        if rc != 0:
            say("| %g | %d | %.1f | %.0f | failed | | | | | |" % (chord, rc, wall, peak))
            continue
        tets, least, below, worst, merged = mesh_row(report)
        errors = phase_errors(report)
        say("| %g | %d | %.1f | %.0f | %d | %.0f | %.2f | %d | %s | %s |"
            % (chord, rc, wall, peak, tets, tets / wall, least, below, errors, clearance(report)))
        shutil.rmtree(os.path.join(work, "default_%g" % chord), ignore_errors=True)


if "--no-default" not in sys.argv:
    default_part()


def large_part():
    """4. The two scenes of the aim (2 minutes, 4 GB), one and half an element across the gaps."""
    default = json.loads(subprocess.run([exe, "default-scene"], check=True, capture_output=True,
                                        text=True).stdout)
    default["outputs"] = ["mesh_tet"]
    for key in ("voxels", "homogenization"):
        default.pop(key, None)
    fibres = {"box": {"size": [1, 1, 1]}, "seed": 1, "min_gap": 0.002,
              "families": [{"name": "fibres", "shape": "cylinder", "radius": 0.0117,
                            "aspect_ratio": 10, "volume_fraction": 0.25,
                            "orientation": {"law": "tensor",
                                            "a2": [[0.7, 0, 0], [0, 0.25, 0], [0, 0, 0.05]]}}],
              "outputs": ["mesh_tet"]}
    cases = [("default scene (`min_gap` 0)", "default", default,
              {"chord_error": 0.03, "order": 2}),
             ("2,484 fibres", "fibres", fibres,
              {"chord_error": 0.1, "order": 2, "optimize_threshold": 0.15})]
    first = len(lines)
    say()
    say("## The aim: 2 minutes and 4 GB for the whole command (10-node elements)")
    say()
    say("| scene | across the gaps | exit | wall s | peak MiB | tetrahedra | tets/s | least angle "
        "| under 5 deg | volume error per phase |")
    say("|---|---|---|---|---|---|---|---|---|---|")
    for title, name, scene, mesh in cases:
        for across in (1, 0.5):
            scene["mesh_tet"] = dict(mesh, gap_elements=across)
            tag = "%s_%g" % (name, across)
            rc, wall, peak, report = generate(exe, scene, work, tag)
            if rc != 0:
                say("| %s | %g | %d | %.1f | %.0f | failed | | | | |"
                    % (title, across, rc, wall, peak))
                continue
            tets, least, below, worst, merged = mesh_row(report)
            errors = phase_errors(report)
            say("| %s | %g | %d | %.1f | %.0f | %d | %.0f | %.2f | %d | %s |"
                % (title, across, rc, wall, peak, tets, tets / wall, least, below, errors))
            shutil.rmtree(os.path.join(work, tag), ignore_errors=True)
    with open(os.path.join(charts, "tet_mesh_large_table.md"), "w") as f:
        f.write("Machine: %s.\n\n" % machine())
        f.write("\n".join(lines[first + 1:]) + "\n")


if "--large" in sys.argv:
    large_part()

if not all(flag in sys.argv for flag in ("--no-spheres", "--no-fibres", "--no-default")):
    with open(os.path.join(charts, "tet_mesh_table.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
shutil.rmtree(work, ignore_errors=True)
