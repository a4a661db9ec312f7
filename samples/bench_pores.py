"""Pores in the FFT solver: insulating (or empty) spheres at 0.25 (radius 0.1, unit box, seed 3)
in a matrix of conductivity 1 (Young's modulus 1, Poisson 0.3), each voxel rule at several
resolutions: the effective value, the iterations (the most of the load cases) and whether the
solve reached its tolerance (1e-6, at most 3,000 iterations), and the value plain voxels
extrapolate to (first order, from their two finest grids) as the reference. Prints a table
(also written to samples/charts/pores_table.md).

usage: /usr/bin/python3 samples/bench_pores.py [BUILD_DIR] [--res 32,64,96]
       [--physics conductivity,elasticity]
"""
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_util import generate, machine, option  # noqa: E402


resolutions = option("--res", [32, 64, 96], int)
physics = option("--physics", ["conductivity", "elasticity"], str)
build = sys.argv[1] if len(sys.argv) > 1 else "build"
exe = os.path.abspath(os.path.join(build, "bin", "rvegen"))
work = tempfile.mkdtemp(prefix="rvegen-pores-")
rules = ["laminate", "plain", "voigt", "reuss"]


def scene(phys, rule, res):
    return {"box": {"size": [1, 1, 1]}, "seed": 3,
            "families": [{"name": "pores", "shape": "sphere", "radius": 0.1,
                          "volume_fraction": 0.25}],
            "materials": {"matrix": {"conductivity": 1, "young": 1, "poisson": 0.3},
                          "pores": {"conductivity": 0, "young": 0, "poisson": 0.3}},
            "voxels": {"resolution": res},
            "homogenization": {"physics": [phys], "voxel_rule": rule, "max_iterations": 3000},
            "outputs": ["inclusions"]}


def value(phys, effective):
    if phys == "conductivity":
        c = effective["conductivity"]
        return [c["mean_of_diagonal"]], c
    s = effective["stiffness"]
    return [s["isotropic_projection"]["bulk"], s["isotropic_projection"]["shear"]], s


lines = ["Machine: %s" % machine(), "",
         "| physics | rule | voxels | value (k, or bulk and shear) | iterations | converged "
         "| wall s |", "|---|---|---|---|---|---|---|"]
print("\n".join(lines), flush=True)
for phys in physics:
    plain = {}
    for rule in rules:
        for res in resolutions:
            rc, wall, peak, rep = generate(exe, scene(phys, rule, res), work,
                                           "%s_%s_%d" % (phys, rule, res))
            v, r = value(phys, rep["effective"])
            if rule == "plain":
                plain[res] = v
            line = "| %s | %s | %d^3 | %s | %d | %s | %.1f |" % (
                phys, rule, res, ", ".join("%.4f" % x for x in v), max(r["iterations"]),
                "yes" if r["converged"] else "no (exit %d)" % rc, wall)
            lines.append(line)
            print(line, flush=True)
    if len(plain) >= 2:
        a, b = sorted(plain)[-2:]
        ref = [vb + (vb - va) / (b / a - 1.0) for va, vb in zip(plain[a], plain[b])]
        line = "| %s | plain, extrapolated from %d^3 and %d^3 | - | %s | - | - | - |" % (
            phys, a, b, ", ".join("%.4f" % x for x in ref))
        lines.append(line)
        print(line, flush=True)

charts = os.path.join("samples", "charts")
os.makedirs(charts, exist_ok=True)
with open(os.path.join(charts, "pores_table.md"), "w") as f:
    f.write("\n".join(lines) + "\n")
