"""pvpython test: the RVE Generator reports its progress and stops on abort.

1. A packing of the default scene: ProgressEvent values rise (never fall) from below 1 to 1,
   with values strictly between 0 and 1 on the way (packing, then each output).
2. A packing that would take minutes (12,000 spheres asked for 0.64 with a 120 s budget): an
   observer sets AbortExecute once the progress passes 5 %; the update must return within a
   second of it, with status "aborted" and empty outputs.
3. The source is usable afterwards: a smaller target on the same source packs, status "ok", and
   updating again with the aborted scene's properties (the proxy marked modified) packs again
   (nothing stale was cached).

usage: pvpython test_progress.py PLUGIN.so
"""
import sys
import time

from paraview.simple import *  # noqa: F401,F403
from paraview import servermanager

plugin = sys.argv[1]
failures = []


def check(cond, msg):
    if not cond:
        failures.append(msg)
        print("FAIL:", msg)


LoadPlugin(plugin, ns=globals())

# 1. Progress of a whole update (packing and every output port).
gen = RVEGenerator()
alg = gen.GetClientSideObject()
values = []
tag = alg.AddObserver("ProgressEvent", lambda obj, ev: values.append(obj.GetProgress()))
gen.UpdatePipeline()
alg.RemoveObserver(tag)
print("progress values: %d, first %s, last %s" % (len(values), values[:3], values[-3:]))
check(len(values) >= 5, "only %d progress events" % len(values))
check(values and values[-1] == 1.0, "progress does not end at 1: %s" % values[-1:])
inner = [v for v in values if 0.0 < v < 1.0]
check(len(inner) >= 3, "fewer than 3 progress values strictly between 0 and 1: %s" % inner)
# Within one execution the values never fall (each port's execution starts again at 0).
runs, run = [], []
for v in values:
    if run and v == 0.0:
        runs.append(run)
        run = []
    run.append(v)
runs.append(run)
for r in runs:
    check(all(a <= b for a, b in zip(r, r[1:])), "progress falls within an execution: %s" % r)
gen.UpdatePropertyInformation()
check(str(gen.GetPropertyValue("Status")) == "ok", "default scene status %s" % gen.GetPropertyValue("Status"))

# The RVE Voxelize filter reports its slabs too.
vox = RVEVoxelize(Input=OutputPort(gen, 0), Resolution=[48, 48, 48])
vvalues = []
tag = vox.GetClientSideObject().AddObserver("ProgressEvent", lambda o, e: vvalues.append(o.GetProgress()))
vox.UpdatePipeline()
check(len([v for v in vvalues if 0.0 < v < 1.0]) >= 3 and vvalues[-1] == 1.0,
      "RVE Voxelize progress: %s" % vvalues)

# 2. Abort a long packing from a progress observer.
big = RVEGenerator(SphereVolumeFraction=0.64, SphereRadius=0.0268, FibreVolumeFraction=0.0,
                   EllipsoidVolumeFraction=0.0, TimeBudget=120.0, Resolution=[16, 16, 16])
balg = big.GetClientSideObject()
state = {"abort_at": None, "max_after": 0.0, "events_after": 0}


def on_progress(obj, ev):
    p = obj.GetProgress()
    if state["abort_at"] is None and p > 0.05:
        state["abort_at"] = time.monotonic()
        obj.SetAbortExecute(1)
    elif state["abort_at"] is not None:
        state["events_after"] += 1


tag = balg.AddObserver("ProgressEvent", on_progress)
t0 = time.monotonic()
big.UpdatePipeline()
t1 = time.monotonic()
balg.RemoveObserver(tag)
check(state["abort_at"] is not None, "progress never passed 5 %")
if state["abort_at"] is not None:
    stop = t1 - state["abort_at"]
    print("aborted %.2f s into the packing; the update returned %.3f s after the abort" %
          (state["abort_at"] - t0, stop))
    check(stop < 1.0, "the update returned %.2f s after the abort" % stop)
big.UpdatePropertyInformation()
check(str(big.GetPropertyValue("Status")) == "aborted",
      "status after abort: %s" % big.GetPropertyValue("Status"))
# (The output as it stands: fetching it would update the source, which packs again.)
points = balg.GetOutputDataObject(0)
check(points.GetNumberOfPoints() == 0, "aborted Inclusions output has %d points" % points.GetNumberOfPoints())

# 3. Usable afterwards: a reachable target packs on the same source...
big.SphereVolumeFraction = 0.3
big.UpdatePipeline()
big.UpdatePropertyInformation()
check(str(big.GetPropertyValue("Status")) == "ok", "status after re-run: %s" % big.GetPropertyValue("Status"))
points = servermanager.Fetch(big, idx=0)
check(points.GetNumberOfPoints() > 0, "re-run gives no inclusions")
runs_before = big.GetPropertyValue("PackingRuns")
# ... and an update with the same properties as an aborted one packs again.
big.SphereVolumeFraction = 0.64
big.TimeBudget = 5.0
once = []


def abort_once(obj, ev):
    if not once and 0.01 < obj.GetProgress() < 1.0:
        once.append(1)
        obj.SetAbortExecute(1)


tag = balg.AddObserver("ProgressEvent", abort_once)
big.UpdatePipeline()
balg.RemoveObserver(tag)
big.UpdatePropertyInformation()
check(str(big.GetPropertyValue("Status")) == "aborted", "second abort: %s" % big.GetPropertyValue("Status"))
# Same properties: ParaView's proxy updates only what it knows changed, so pvpython marks the
# source modified (as the GUI's Apply after a property change); the VTK source must then pack
# again rather than keep the aborted state.
big.MarkModified(big)
big.UpdatePipeline()
big.UpdatePropertyInformation()
status = str(big.GetPropertyValue("Status"))
check(status in ("ok", "target_not_reached"), "update after abort gives status %s" % status)
check(big.GetPropertyValue("PackingRuns") >= runs_before + 1, "update after abort did not pack")
points = servermanager.Fetch(big, idx=0)
check(points.GetNumberOfPoints() > 0, "update after abort gives no inclusions")

if failures:
    print("%d failure(s)" % len(failures))
    sys.exit(1)
print("progress and abort: all checks passed")
