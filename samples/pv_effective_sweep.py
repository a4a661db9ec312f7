"""Sweep the spheres' volume fraction from pvpython and chart the effective moduli against the
Hashin-Shtrikman bounds.

usage: pvpython samples/pv_effective_sweep.py [--values 0.1,0.2,0.3,0.4,0.5] [--resolution 48]
                                              [--out effective_sweep] [--chart]

Spheres only (the default scene's fibres and grains switched off), glass in epoxy (E 70 / 3,
nu 0.2 / 0.35). For each volume fraction the RVE Generator packs the RVE, the RVE Effective
Properties filter computes the stiffness on its Voxels output (laminate voxels), and the
isotropic projection (bulk and shear moduli) is tabulated with the bounds the filter states:
printed, written as OUT.csv and, with --chart, drawn as OUT.png. Runs without a display.
"""
import argparse
import csv
import json
import os
import sys
import time

from paraview import servermanager
from paraview.simple import OutputPort

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rvegen_paraview import load_rvegen, statistics_rows  # noqa: E402

parser = argparse.ArgumentParser()
parser.add_argument("--values", default="0.1,0.2,0.3,0.4,0.5")
parser.add_argument("--resolution", type=int, default=48)
parser.add_argument("--out", default="effective_sweep")
parser.add_argument("--chart", action="store_true")
args = parser.parse_args()
load_rvegen(globals())  # defines RVEGenerator, RVEEffectiveProperties, ... here

gen = RVEGenerator(FibreVolumeFraction=0.0, EllipsoidVolumeFraction=0.0, SphereRadius=0.08,
                   Resolution=[args.resolution] * 3)
materials = {"matrix": {"young": 3, "poisson": 0.35}, "spheres": {"young": 70, "poisson": 0.2}}
eff = RVEEffectiveProperties(Input=OutputPort(gen, 1), Materials=json.dumps(materials), Physics=1)
header = ["volume_fraction", "seconds", "bulk", "bulk_hs_lower", "bulk_hs_upper", "shear",
          "shear_hs_lower", "shear_hs_upper"]
rows = []
for value in [float(v) for v in args.values.split(",")]:
    gen.SphereVolumeFraction = value
    t0 = time.time()
    table = statistics_rows(servermanager.Fetch(eff))
    seconds = time.time() - t0
    get = {(q, n): v for q, n, i, v in table}
    if ("isotropic_projection", "bulk") not in get:
        sys.exit("no result for volume fraction %s" % value)
    rows.append([value, round(seconds, 2)] + [get[k] for k in (
        ("isotropic_projection", "bulk"), ("bulk_bound", "hs_lower"), ("bulk_bound", "hs_upper"),
        ("isotropic_projection", "shear"), ("shear_bound", "hs_lower"),
        ("shear_bound", "hs_upper"))])
print("\t".join(header))
for r in rows:
    print("\t".join("%.5g" % x for x in r))
with open(args.out + ".csv", "w", newline="") as f:
    csv.writer(f).writerows([header] + rows)
print("wrote", args.out + ".csv")
if args.chart:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    phi = [r[0] for r in rows]
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for a, (name, c) in zip(ax, (("bulk modulus", 2), ("shear modulus", 5))):
        a.fill_between(phi, [r[c + 1] for r in rows], [r[c + 2] for r in rows], alpha=0.25,
                       label="Hashin-Shtrikman bounds")
        a.plot(phi, [r[c] for r in rows], "o-", label="RVE Effective Properties")
        a.set_xlabel("sphere volume fraction")
        a.set_ylabel(name)
        a.legend()
    fig.suptitle("Glass spheres in epoxy, %d^3 voxels, laminate voxels (pvpython)" % args.resolution)
    fig.tight_layout()
    fig.savefig(args.out + ".png", dpi=90)
    print("wrote", args.out + ".png")
