"""Is my RVE big enough? A representativity study run from pvpython, its charts in ParaView.

usage: pvpython --force-offscreen-rendering samples/pv_study.py [SCENE.json] [-o DIR]
           [--sizes 1,1.5,2] [--realizations 10] [--target-error 0.01] [--property NAME]
           [--rvegen PATH]

Runs `rvegen study` on the scene (default samples/fibres_study.json; a study already in DIR is
resumed, so only missing realizations are computed), then reads its report, study.csv, in
ParaView and draws two line charts of one property (default conductivity.mean when the study
has it): the mean against the box edge with its 95 % confidence interval, and the variance
between realizations against the volume on log axes with the fitted law K V^-alpha. The charts
are saved as DIR/pv_study_mean.png and DIR/pv_study_variance.png, the charted table as
DIR/pv_study_chart.csv, and the recommended size is printed. Saving a picture needs a display:
run it under xvfb-run on a machine without one.

The rvegen program is --rvegen, else $RVEGEN, else install/bin/rvegen or build/bin/rvegen of
this checkout, else the one on PATH. Under MPI the study itself runs distributed with
`mpirun -np N rvegen study ...`; this script then charts its result (give the same -o).
"""
import argparse
import json
import os
import shutil
import subprocess
import sys

from paraview.simple import (CreateView, CSVReader, GetActiveViewOrCreate, ProgrammableFilter,
                             SaveData, SaveScreenshot, Show)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def find_rvegen(given):
    for path in (given, os.environ.get("RVEGEN", ""), os.path.join(ROOT, "install", "bin", "rvegen"),
                 os.path.join(ROOT, "build", "bin", "rvegen"), shutil.which("rvegen") or ""):
        if path and os.access(path, os.X_OK):
            return path
    raise SystemExit("rvegen not found: build it (samples/quickstart.sh), or give --rvegen PATH")


parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
parser.add_argument("scene", nargs="?", default=os.path.join(ROOT, "samples", "fibres_study.json"))
parser.add_argument("-o", "--out", default="pv_study")
parser.add_argument("--sizes", default="1,1.5,2")
parser.add_argument("--realizations", type=int, default=10)
parser.add_argument("--target-error", default="0.01")
parser.add_argument("--property", default="")
parser.add_argument("--rvegen", default="")
args = parser.parse_args()

# 1. The study: the command line does it (resumable, realizations on every core).
cmd = [find_rvegen(args.rvegen), "study", args.scene, "-o", args.out, "--sizes", args.sizes,
       "--realizations", str(args.realizations), "--target-error", args.target_error]
print(" ".join(cmd), flush=True)
rc = subprocess.call(cmd)
if rc not in (0, 3):  # 3: some realizations did not reach their target (left out, counted)
    raise SystemExit("rvegen study failed with exit %d" % rc)
with open(os.path.join(args.out, "study.json")) as f:
    study = json.load(f)
props = study["properties"]
name = args.property or ("conductivity.mean" if "conductivity.mean" in props else next(iter(props)))
if name not in props:
    raise SystemExit("no property %s in the study (it has: %s)" % (name, ", ".join(props)))

# 2. The report in ParaView: study.csv as a table, the property's rows as chart columns, the
#    fitted variance law beside the measured variance.
law = props[name]["variance_law"]
reader = CSVReader(FileName=[os.path.abspath(os.path.join(args.out, "study.csv"))])
rows = ProgrammableFilter(Input=reader, OutputDataSetType="vtkTable")
rows.Script = """
import math
from vtkmodules.vtkCommonCore import vtkDoubleArray
name, K, alpha = %r, %r, %r
t = self.GetInput()
out = self.GetOutput()
col = lambda c: t.GetColumnByName(c)
cols = {c: vtkDoubleArray() for c in ("size", "volume", "mean", "ci95_low", "ci95_high",
                                      "variance", "variance_law")}
for c, a in cols.items():
    a.SetName(c)
for r in range(t.GetNumberOfRows()):
    if col("property").GetValue(r) != name:
        continue
    sd = float(col("sd").GetValue(r))
    v = float(col("volume").GetValue(r))
    for c in ("size", "volume", "mean", "ci95_low", "ci95_high"):
        cols[c].InsertNextValue(float(col(c).GetValue(r)))
    cols["variance"].InsertNextValue(sd * sd)
    cols["variance_law"].InsertNextValue(K * v ** -alpha if K else float("nan"))
for a in cols.values():
    out.AddColumn(a)
""" % (name, law.get("K", 0.0), law.get("alpha", 0.0))
rows.UpdatePipeline()
SaveData(os.path.join(args.out, "pv_study_chart.csv"), proxy=rows)

mean_view = CreateView("XYChartView")
mean_view.ViewSize = [800, 500]
mean_view.ChartTitle = "%s: mean and 95 %% confidence interval (n = %d)" % (
    name, study["realizations"])
mean_view.BottomAxisTitle = "box edge (multiple of the scene's box)"
mean_view.LeftAxisTitle = name
d = Show(rows, mean_view)
d.UseIndexForXAxis = 0
d.XArrayName = "size"
d.SeriesVisibility = ["mean", "ci95_low", "ci95_high"]
d.SeriesLineStyle = ["mean", "1", "ci95_low", "2", "ci95_high", "2"]
d.SeriesMarkerStyle = ["mean", "4"]
d.SeriesMarkerSize = ["mean", "8"]
SaveScreenshot(os.path.join(args.out, "pv_study_mean.png"), mean_view, ImageResolution=[800, 500])

var_view = CreateView("XYChartView")
var_view.ViewSize = [800, 500]
var_view.ChartTitle = "variance between realizations, law K V^-alpha (alpha %.2f)" % law.get(
    "alpha", float("nan"))
var_view.BottomAxisTitle = "volume V"
var_view.LeftAxisTitle = "variance"
var_view.BottomAxisLogScale = 1
var_view.LeftAxisLogScale = 1
d = Show(rows, var_view)
d.UseIndexForXAxis = 0
d.XArrayName = "volume"
d.SeriesVisibility = ["variance", "variance_law"]
d.SeriesLineStyle = ["variance", "0", "variance_law", "1"]
d.SeriesMarkerStyle = ["variance", "4"]
d.SeriesMarkerSize = ["variance", "10"]
SaveScreenshot(os.path.join(args.out, "pv_study_variance.png"), var_view,
               ImageResolution=[800, 500])

# 3. The answer.
rec = props[name]["recommended"]
print("%s: recommended box edge x%s of the scene's (volume %s) for a relative error %s of the "
      "mean over %d realizations; basis: %s" % (name, rec.get("size"), rec.get("volume"),
                                                 study["target_error"], rec["realizations"],
                                                 rec["basis"]))
print("wrote %s/pv_study_mean.png, pv_study_variance.png and pv_study_chart.csv" % args.out)
