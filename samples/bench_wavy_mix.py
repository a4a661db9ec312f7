#!/usr/bin/python3
"""Dense wavy-fibre mixtures against the wave count and the box size: coated wavy fibres (L/D 8,
radius 0.02, amplitude = radius, shell 0.005) at 0.20 with deformed grains (radius 0.05,
amplitude 0.1) at 0.15, target 0.35, in periodic boxes of side 0.6, 1.0 and 1.2, 120 s budget.

Runs `rvegen generate --outputs inclusions` (all cores) for each wave count (1 to 4 wavelengths
per fibre), box side, grain smoothness and seed, timed as a whole command (/usr/bin/time), prints
a table (also written to samples/charts/wavy_mix_table.md) and draws
samples/charts/wavy_mix.png: the volume fraction reached against the waves per fibre, one line
per box side, with the wall time.

usage: /usr/bin/python3 samples/bench_wavy_mix.py [BUILD_DIR] [--waves 1,2,3,4]
       [--boxes 0.6,1.0,1.2] [--smoothness 1,3] [--seeds 1,2,3,4,5] [--budget 120]
       [--name wavy_mix]   (the table and chart's file names: samples/charts/NAME_table.md, NAME.png)
       [--shake X]   (md.shake of the scenes; by default the packer's own)
       [--steps N]   (md.max_steps of the scenes: a fixed amount of work, to time the steps)
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
print(header)
for w in waves:
    for side in boxes:
        for smooth in smoothness:
            for seed in seeds:
                name = "w%d_s%g_b%g_%d" % (w, smooth, side, seed)
                rc, wall, peak, rep = generate(exe, scene(w, smooth, side, seed), work, name,
                                               ["--outputs", "inclusions"])
                row = (w, smooth, side, seed, rep["count"], rep["volume_fraction"],
                       rep["status"], wall, peak)
                rows.append(row)
                line = "| %d | %g | %g | %d | %s | %.4f | %s | %.1f | %.0f |" % row
                print(line, flush=True)

reached = [r for r in rows if r[6] == "ok"]
summary = "%d of %d runs reached 0.35 within %g s" % (len(reached), len(rows), budget)
print(summary)
with open(os.path.join(charts, name_out + "_table.md"), "w") as f:
    f.write("Machine: %s. `samples/bench_wavy_mix.py` (target 0.35, budget %g s, all cores%s).\n\n"
            % (machine(), budget, ("" if shake is None else ", md.shake %g" % shake)
               + ("" if steps is None else ", md.max_steps %d" % steps)))
    f.write(header + "\n")
    for r in rows:
        f.write("| %d | %g | %g | %d | %s | %.4f | %s | %.1f | %.0f |\n" % r)
    f.write("\n%s.\n" % summary)

fig, (ax, at) = plt.subplots(1, 2, figsize=(10, 4))
for side in boxes:
    xs = [w for w in waves]
    mean_vf = []
    mean_t = []
    for w in waves:
        sel = [r for r in rows if r[0] == w and r[2] == side]
        mean_vf.append(sum(r[5] for r in sel) / max(1, len(sel)))
        mean_t.append(sum(r[7] for r in sel) / max(1, len(sel)))
    ax.plot(xs, mean_vf, "o-", label="box %g" % side)
    at.plot(xs, mean_t, "o-", label="box %g" % side)
ax.axhline(0.35, color="k", lw=0.8, ls="--")
ax.set_xlabel("wavelengths per fibre")
ax.set_ylabel("volume fraction reached (mean over runs)")
ax.set_xticks(waves)
ax.legend()
at.axhline(budget, color="k", lw=0.8, ls="--")
at.set_xlabel("wavelengths per fibre")
at.set_ylabel("wall s (mean over runs)")
at.set_xticks(waves)
at.legend()
fig.suptitle("Coated wavy fibres 0.20 + deformed grains 0.15, target 0.35")
fig.tight_layout()
fig.savefig(os.path.join(charts, name_out + ".png"), dpi=110)
print("wrote samples/charts/%s_table.md and samples/charts/%s.png" % (name_out, name_out))
