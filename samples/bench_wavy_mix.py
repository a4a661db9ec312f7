#!/usr/bin/python3
"""Dense wavy-fibre mixtures against the wave count and the box size: coated wavy fibres (L/D 8,
radius 0.02, amplitude = radius, shell 0.005) at 0.20 with deformed grains (radius 0.05,
amplitude 0.1) at 0.15, target 0.35, in periodic boxes of side 0.6, 1.0 and 1.2, 120 s budget.

Runs `rvegen generate --outputs inclusions` (all cores) for each wave count (1 to 4 wavelengths
per fibre), box side, grain smoothness and seed, timed as a whole command (/usr/bin/time), prints
a table (also written to samples/charts/wavy_mix_table.md) and draws
samples/charts/wavy_mix.png: the volume fraction reached against the waves per fibre, every run
a point and one line through each box side's means, with the wall time. The table ends with a
summary per wave count and box (runs, how many reached 0.35, the least reached, the longest).

usage: /usr/bin/python3 samples/bench_wavy_mix.py [BUILD_DIR] [--waves 1,2,3,4]
       [--boxes 0.6,1.0,1.2] [--smoothness 1,3] [--seeds 1,2,3,4,5] [--budget 120]
       [--name wavy_mix]   (the table and chart's file names: samples/charts/NAME_table.md, NAME.png)
       [--shake X]   (md.shake of the scenes; by default the packer's own)
       [--steps N]   (md.max_steps of the scenes: a fixed amount of work, to time the steps)
       [--tables A.md,B.md]   (runs nothing: the rows of earlier tables of this script, joined
                               into one table and chart)
"""
import os
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_util import generate, machine, option  # noqa: E402


waves = option("--waves", [1, 2, 3, 4], int)
boxes = option("--boxes", [0.6, 1.0, 1.2])
smoothness = option("--smoothness", [1.0, 3.0])
seeds = option("--seeds", [1, 2, 3, 4, 5], int)
budget = option("--budget", [120.0])[0]
name_out = option("--name", ["wavy_mix"], str)[0]
shake = option("--shake", [None])[0]
steps = option("--steps", [None], int)[0]
tables = option("--tables", [], str)
build = sys.argv[1] if len(sys.argv) > 1 else "build"
exe = os.path.abspath(os.path.join(build, "bin", "rvegen"))
work = tempfile.mkdtemp(prefix="rvegen-wavy-mix-")
charts = os.path.join("samples", "charts")
os.makedirs(charts, exist_ok=True)


def scene(n_waves, smooth, side, seed):
    length = 8 * 2 * 0.02
    md = {"max_seconds": budget}
    if shake is not None:
        md["shake"] = shake
    if steps is not None:
        md["max_steps"] = steps
    return {"box": {"size": [side] * 3}, "seed": seed, "md": md,
            "families": [
                {"name": "wavy fibres", "shape": "cylinder", "radius": 0.02, "aspect_ratio": 8,
                 "volume_fraction": 0.20,
                 "waviness": {"amplitude": 0.02, "wavelength": length / n_waves},
                 "coating": {"thickness": 0.005}},
                {"name": "grains", "shape": "sphere", "radius": 0.05, "volume_fraction": 0.15,
                 "deformation": {"amplitude": 0.1, "smoothness": smooth}}]}


rows = []
header = ("| waves per fibre | grain smoothness | box | seed | inclusions | reached | status | wall s "
          "| peak MiB |\n|---|---|---|---|---|---|---|---|---|")
ROW = "| %d | %g | %g | %d | %s | %.4f | %s | %.1f | %.0f |"  # a run, as printed and written
print(header)


def table_rows(path):
    """The runs of a table this script wrote."""
    out = []
    for line in open(path):
        f = [x.strip() for x in line.strip().strip("|").split("|")]
        if len(f) == 9 and f[0].isdigit():
            out.append((int(f[0]), float(f[1]), float(f[2]), int(f[3]), f[4], float(f[5]), f[6],
                        float(f[7]), float(f[8])))
    return out


for t in tables:
    rows += table_rows(t)
if tables:
    waves = sorted({r[0] for r in rows})
    boxes = sorted({r[2] for r in rows})
    for r in rows:
        print(ROW % r)
for w in waves if not tables else []:
    for side in boxes:
        for smooth in smoothness:
            for seed in seeds:
                name = "w%d_s%g_b%g_%d" % (w, smooth, side, seed)
                rc, wall, peak, rep = generate(exe, scene(w, smooth, side, seed), work, name,
                                               ["--outputs", "inclusions"])
                row = (w, smooth, side, seed, rep["count"], rep["volume_fraction"],
                       rep["status"], wall, peak)
                rows.append(row)
                line = ROW % row
                print(line, flush=True)

reached = [r for r in rows if r[6] == "ok"]
summary = "%d of %d runs reached 0.35 within %g s" % (len(reached), len(rows), budget)
print(summary)
# Per wave count and box (over the smoothnesses and seeds): how many reached, the least density,
# the longest run.
cells = ("| waves per fibre | box | runs | reached 0.35 | least reached | longest wall s |\n"
         "|---|---|---|---|---|---|\n")
for w in waves:
    for side in boxes:
        sel = [r for r in rows if r[0] == w and r[2] == side]
        if sel:
            cells += "| %d | %g | %d | %d | %.4f | %.1f |\n" % (
                w, side, len(sel), sum(r[6] == "ok" for r in sel), min(r[5] for r in sel),
                max(r[7] for r in sel))
print(cells)
with open(os.path.join(charts, name_out + "_table.md"), "w") as f:
    if tables:
        f.write("The runs of %s, joined (`samples/bench_wavy_mix.py --tables`).\n\n"
                % ", ".join("`%s`" % t for t in tables))
    else:
        f.write("Machine: %s. `samples/bench_wavy_mix.py` (target 0.35, budget %g s, all cores%s)."
                "\n\n" % (machine(), budget, ("" if shake is None else ", md.shake %g" % shake)
                           + ("" if steps is None else ", md.max_steps %d" % steps)))
    f.write(header + "\n")
    for r in rows:
        f.write(ROW % r + "\n")
    f.write("\n%s.\n\n" % summary)
    f.write(cells)

fig, (ax, at) = plt.subplots(1, 2, figsize=(10, 4))
# Every run is a point (the boxes side by side about each wave count), the line joins the boxes'
# means: a cell passes when all its points reach 0.35 within the budget.
for k, side in enumerate(boxes):
    dx = 0.12 * (k - 0.5 * (len(boxes) - 1))
    xs, mean_vf, mean_t = [], [], []
    for w in waves:
        sel = [r for r in rows if r[0] == w and r[2] == side]
        if not sel:
            continue
        xs.append(w + dx)
        mean_vf.append(sum(r[5] for r in sel) / len(sel))
        mean_t.append(sum(r[7] for r in sel) / len(sel))
        ax.plot([w + dx] * len(sel), [r[5] for r in sel], ".", color="C%d" % k, alpha=0.5)
        at.plot([w + dx] * len(sel), [r[7] for r in sel], ".", color="C%d" % k, alpha=0.5)
    ax.plot(xs, mean_vf, "o-", color="C%d" % k, label="box %g (mean, and each run)" % side)
    at.plot(xs, mean_t, "o-", color="C%d" % k, label="box %g" % side)
ax.axhline(0.35, color="k", lw=0.8, ls="--")
ax.set_ylim(min([0.32] + [r[5] - 0.002 for r in rows]), 0.355)
ax.set_xlabel("wavelengths per fibre")
ax.set_ylabel("volume fraction reached")
ax.set_xticks(waves)
ax.legend()
at.axhline(budget, color="k", lw=0.8, ls="--")
at.set_xlabel("wavelengths per fibre")
at.set_ylabel("wall s of the whole command")
at.set_xticks(waves)
at.legend()
fig.suptitle("Coated wavy fibres 0.20 + deformed grains 0.15, target 0.35")
fig.tight_layout()
fig.savefig(os.path.join(charts, name_out + ".png"), dpi=110)
print("wrote samples/charts/%s_table.md and samples/charts/%s.png" % (name_out, name_out))
