#!/usr/bin/python3
"""Modified shapes packed by their own shape: the density table of the modified-shapes issue, the
densest packing of deformed spheres against the deformation amplitude, and of wavy fibres
against the wave amplitude.

Runs `rvegen generate` (periodic unit box, 120 s budget each), audits every result with
`rvegen check`, prints a table (also written to samples/charts/deformed_table.md) and draws
samples/charts/deformed_density.png: the volume fraction reached (targets above jamming) against
the amplitude, for this build (deformed spheres kept apart by their certified support
functions) and, with --baseline BIN, for another rvegen binary (for example one built from an
earlier commit, which packed them by the ball deform_scale (1 + amplitude)); and
samples/charts/wavy_density.png, the same for wavy fibres (chains of straight pieces against the
envelope cylinder of radius r + A, 60 s budget).

Wall time and peak memory are those of the whole command (/usr/bin/time). Two runs go side by
side (one per core).

With --table only the density table runs (printed, charts and table file left as they are).

usage: /usr/bin/python3 samples/bench_deformed.py [BUILD_DIR] [--baseline BIN] [--quick] [--table]
"""
import concurrent.futures
import json
import os
import platform
import subprocess
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

argv = sys.argv[1:]
baseline = None
if "--baseline" in argv:
    k = argv.index("--baseline")
    baseline = os.path.abspath(argv[k + 1])
    del argv[k:k + 2]
quick = "--quick" in argv
table_only = "--table" in argv
args = [a for a in argv if not a.startswith("--")]
build = args[0] if args else "build"
exe = os.path.abspath(os.path.join(build, "bin", "rvegen"))
work = tempfile.mkdtemp(prefix="rvegen-deformed-")
charts = os.path.join("samples", "charts")
os.makedirs(charts, exist_ok=True)
budget = 20 if quick else 120
radius = 0.08 if quick else 0.05  # about 1,000 grains at 0.5 (quick: 250)


def grains(vf, amplitude, smoothness=1.0, seconds=budget, seed=1):
    return {"box": {"size": [1, 1, 1]}, "seed": seed, "md": {"max_seconds": seconds},
            "families": [{"name": "grains", "shape": "sphere", "radius": radius,
                          "volume_fraction": vf,
                          "deformation": {"amplitude": amplitude, "smoothness": smoothness}}],
            "voxels": {"resolution": 64}}


def wavy(vf, coated=False, seconds=budget, amplitude=0.02):
    # a = 8 (L/D 4), amplitude = radius, wavelength 5 diameters; r = 0.02.
    f = {"name": "wavy fibres", "shape": "cylinder", "radius": 0.02, "aspect_ratio": 8,
         "volume_fraction": vf, "waviness": {"amplitude": amplitude, "wavelength": 0.2}}
    if coated:
        f["coating"] = {"thickness": 0.005}
    return {"box": {"size": [1, 1, 1]}, "seed": 1, "md": {"max_seconds": seconds},
            "families": [f], "voxels": {"resolution": 64}}


def figure5(seconds=budget):
    s = wavy(0.20, coated=True, seconds=seconds)
    s["families"].append({"name": "grains", "shape": "sphere", "radius": 0.05,
                          "volume_fraction": 0.15,
                          "deformation": {"amplitude": 0.1, "smoothness": 1}})
    return s


def curved(vf, seconds=budget):
    # a = 20 (L/D 10), r = 0.01, radius of curvature 10 fibre lengths, planar-random (normal z).
    return {"box": {"size": [1, 1, 1]}, "seed": 1, "md": {"max_seconds": seconds},
            "families": [{"name": "curved fibres", "shape": "cylinder", "radius": 0.01,
                          "aspect_ratio": 20, "volume_fraction": vf,
                          "curvature": {"radius": 4.0},
                          "orientation": {"law": "planar", "normal": [0, 0, 1]}}],
            "voxels": {"resolution": 64}}


def run(binary, name, scene):
    """Generates a scene; returns exit code, reached fraction, audit verdict, times, memory."""
    path = os.path.join(work, name + ".json")
    out = os.path.join(work, name)
    with open(path, "w") as f:
        json.dump(scene, f)
    p = subprocess.run(["/usr/bin/time", "-f", "TIME %e %M", binary, "generate", "-q", path,
                        "-o", out], capture_output=True, text=True)
    wall, peak = [float(x) for x in p.stderr.strip().splitlines()[-1].split()[1:]]
    r = {"exit": p.returncode, "wall": wall, "peak_mb": peak / 1024.0, "vf": None,
         "packing": None, "audit": "-", "why": ""}
    if p.returncode in (0, 3):
        with open(os.path.join(out, "report.json")) as f:
            rep = json.load(f)
        r["vf"] = rep["volume_fraction"]
        r["packing"] = rep["packing_seconds"]
        r["stop"] = rep["stop_reason"]
        audit = subprocess.run([binary, "check", os.path.join(out, "inclusions.json")],
                               capture_output=True, text=True)
        r["audit"] = "ok" if audit.returncode == 0 else "FAILED"
    else:
        r["why"] = p.stderr.strip().splitlines()[0][:140] if p.stderr.strip() else ""
    return r


def run_all(jobs):
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        futures = {name: pool.submit(run, b, name, scene) for b, name, scene in jobs}
        return {name: f.result() for name, f in futures.items()}


def comparison(what, method, xs, res, mine, theirs):
    """Table rows: reached fraction (exit, audit, wall) of this build and of the baseline."""
    def cell(r):
        return " %.4f (%d, %s, %.1f) |" % (r["vf"] or 0, r["exit"], r["audit"], r["wall"])
    rows = ["", "| %s | reached, %s (exit, audit, wall s) |" % (what, method) +
            (" reached, baseline (exit, audit, wall s) |" if baseline else ""),
            "|---|---|" + ("---|" if baseline else "")]
    for x in xs:
        row = "| %g |" % x + cell(res["%s-%g" % (mine, x)])
        if baseline:
            row += cell(res["%s-%g" % (theirs, x)])
        rows.append(row)
    return rows


# The density table.
TABLE = [("wavy fibres a 8, amplitude = radius, wavelength 5 D", 0.30, wavy(0.30)),
         ("Figure 5: coated wavy fibres 0.20 + deformed spheres 0.15", 0.35, figure5()),
         ("deformed spheres, amplitude 0.2, smoothness 1", 0.50, grains(0.50, 0.2)),
         ("curved fibres a 20, radius of curvature 10 L, planar-random", 0.20, curved(0.20))]
res = run_all([(exe, "t%d" % i, s) for i, (_, _, s) in enumerate(TABLE)])
lines = ["| scene | target | exit | reached | audit | packing s | wall s | peak MB |",
         "|---|---|---|---|---|---|---|---|"]
for i, (name, target, _) in enumerate(TABLE):
    r = res["t%d" % i]
    if r["vf"] is None:
        lines.append("| %s | %.2f | %d | refused: %s | - | - | %.1f | %.0f |" %
                     (name, target, r["exit"], r["why"].replace("|", "/"), r["wall"],
                      r["peak_mb"]))
    else:
        lines.append("| %s | %.2f | %d | %.4f | %s | %.1f | %.1f | %.0f |" %
                     (name, target, r["exit"], r["vf"], r["audit"], r["packing"], r["wall"],
                      r["peak_mb"]))
if table_only:
    print("\n".join(lines))
    sys.exit(0)

# Densest packing against amplitude: targets above jamming. A binary that packs by the ball
# (1 + e) refuses targets whose balls would fill more than 0.7405: it gets 0.70 / (1 + e)^3.
amps = [0.05, 0.1, 0.2, 0.3] if quick else [0.05, 0.1, 0.2, 0.3, 0.4]
jobs = [(exe, "s-%g" % e, grains(0.66, e)) for e in amps]
if baseline:
    jobs += [(baseline, "b-%g" % e, grains(round(0.70 / (1 + e) ** 3, 4), e)) for e in amps]
jam = run_all(jobs)
lines += comparison("amplitude", "support", amps, jam, "s", "b")
# Wavy fibres against amplitude / radius: targets above jamming. Envelopes above 0.9069 of the
# box are refused: a fibre packed by its envelope (the baseline; this build below A = 0.75 r)
# gets 0.85 / (1 + A / r)^2, a chain 0.45.
ratios = [0.25, 0.5, 1.0]
jobs = [(exe, "w-%g" % q, wavy(0.45 if q >= 0.75 else round(0.85 / (1 + q) ** 2, 4),
                               seconds=budget // 2, amplitude=0.02 * q)) for q in ratios]
if baseline:
    jobs += [(baseline, "wb-%g" % q,
              wavy(round(0.85 / (1 + q) ** 2, 4), seconds=budget // 2, amplitude=0.02 * q))
             for q in ratios]
wj = run_all(jobs)
lines += comparison("wave amplitude / radius", "this build (chains from 0.75)", ratios, wj, "w",
                    "wb")


def chart(xs, res, mine, theirs, labels, xlabel, ylabel, title, top, name):
    """Reached fraction against xs: this build, and the baseline when there is one."""
    plt.figure(figsize=(6, 4))
    plt.plot(xs, [res["%s-%g" % (mine, x)]["vf"] for x in xs], "o-", label=labels[0])
    if baseline:
        plt.plot(xs, [res["%s-%g" % (theirs, x)]["vf"] for x in xs], "s--", label=labels[1])
    plt.xlabel(xlabel)
    plt.ylabel(ylabel)
    plt.title(title)
    plt.ylim(0, top)
    plt.legend(fontsize=8)
    plt.grid(alpha=0.3)
    plt.tight_layout()
    plt.savefig(os.path.join(charts, name), dpi=110)


chart(amps, jam, "s", "b", ["support functions (this build)",
                            "ball deform_scale (1 + amplitude) (baseline)"],
      "deformation amplitude (smoothness 1)", "volume fraction reached (target above jamming)",
      "Deformed spheres: densest valid packing", 0.7, "deformed_density.png")
chart(ratios, wj, "w", "wb", ["this build (chains from A = 0.75 r)",
                              "envelope cylinder r + A (baseline)"],
      "wave amplitude / fibre radius (L/D 4, wavelength 5 D)",
      "volume fraction reached in %d s" % (budget // 2), "Wavy fibres: densest valid packing",
      0.5, "wavy_density.png")
machine = "%s, %d cores, %s" % (platform.processor() or platform.machine(), os.cpu_count(),
                                platform.platform())
table = "\n".join(lines)
print(table)
print("machine:", machine)
if not quick:
    with open(os.path.join(charts, "deformed_table.md"), "w") as f:
        f.write(table + "\n\nmachine: " + machine + "\n")

print("charts in", charts)
