"""Sweep a parameter of the RVE Generator from pvpython and tabulate the statistics.

usage: pvpython samples/pv_sweep.py [--property SphereVolumeFraction] [--values 0.1,0.2,0.3]
                                    [--out sweep.csv]

For each value the generator packs the RVE again (other properties: the default scene); the
RVE Statistics filter gives the volume fraction per phase, the counts and the nearest-neighbour
distances, printed as a table and written as CSV. Runs without a display.
"""
import argparse
import csv
import os
import sys
import time

from paraview import servermanager


sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rvegen_paraview import load_rvegen, statistics_rows  # noqa: E402

parser = argparse.ArgumentParser()
parser.add_argument("--property", default="SphereVolumeFraction")
parser.add_argument("--values", default="0.1,0.2,0.3,0.4")
parser.add_argument("--out", default="sweep.csv")
args = parser.parse_args()
load_rvegen(globals())  # defines RVEGenerator, RVEStatistics, RVEVoxelize here

gen = RVEGenerator()
stats = RVEStatistics(Input=gen)
header = ["value", "seconds", "total_volume_fraction", "count", "nn_mean", "nn_min"]
rows = []
for value in [float(v) for v in args.values.split(",")]:
    setattr(gen, args.property, value)
    t0 = time.time()
    table = statistics_rows(servermanager.Fetch(stats))
    seconds = time.time() - t0
    vf = sum(v for q, n, i, v in table if q == "volume_fraction" and n != "matrix")
    count = sum(int(v) for q, n, i, v in table if q == "count")
    nn = {n: v for q, n, i, v in table if q == "nearest_neighbour_distance"}
    rows.append([value, round(seconds, 3), round(vf, 5), count, round(nn.get("mean", 0), 5),
                 round(nn.get("min", 0), 5)])
print("%s sweep" % args.property)
print("\t".join(header))
for r in rows:
    print("\t".join(str(x) for x in r))
with open(args.out, "w", newline="") as f:
    csv.writer(f).writerows([header] + rows)
print("wrote", args.out)
