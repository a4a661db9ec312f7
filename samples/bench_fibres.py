#!/usr/bin/python3
"""Short-fibre benchmarks: packs the fibre scenes of the density table with `rvegen generate`
(periodic unit box, about 2,500 fibres, a time budget of 120 s each), audits every result with
`rvegen check`, prints a table (also written to samples/charts/fibres_table.md) and draws three
charts in samples/charts/:

  fibres_time.png      volume fraction reached against time, one curve per orientation law
  fibres_jamming.png   volume fraction reached against L/D (isotropic, planar, aligned), with
                       the random-contact line phi = 5 / (L/D)
  fibres_tensor.png    orientation tensor components asked for against obtained

Wall time and peak memory are those of the whole command (/usr/bin/time). Two runs go side by
side (one per core; the packer is single-threaded).

usage: /usr/bin/python3 samples/bench_fibres.py [BUILD_DIR] [--quick]
"""
import concurrent.futures
import json
import math
import os
import platform
import re
import subprocess
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

args = [a for a in sys.argv[1:] if not a.startswith("--")]
quick = "--quick" in sys.argv
build = args[0] if args else "build"
exe = os.path.abspath(os.path.join(build, "bin", "rvegen"))
work = tempfile.mkdtemp(prefix="rvegen-fibres-")
charts = os.path.join("samples", "charts")
os.makedirs(charts, exist_ok=True)
budget = 10 if quick else 120
count = 600 if quick else 2500

LAWS = {
    "aligned": {"law": "aligned", "axis": [1, 0, 0]},
    "planar": {"law": "planar", "normal": [0, 0, 1]},
    "diag(0.7,0.25,0.05)": {"law": "tensor", "a2": [[0.7, 0, 0], [0, 0.25, 0], [0, 0, 0.05]]},
    "isotropic": {"law": "isotropic"},
    "vMF kappa 3": {"law": "von_mises_fisher", "axis": [1, 0, 0], "kappa": 3},
}


def fibres(law, vf, a, n=count, seed=1, seconds=budget):
    """n fibres of aspect a (L/D) filling vf of the unit box: the radius follows."""
    r = (vf / (2.0 * math.pi * a * n)) ** (1.0 / 3.0)
    return {"box": {"size": [1, 1, 1], "periodic": True}, "seed": seed,
            "md": {"max_seconds": seconds},
            "families": [{"name": "fibres", "shape": "cylinder", "radius": r, "aspect_ratio": a,
                          "volume_fraction": vf, "orientation": LAWS[law]}],
            "voxels": {"resolution": 16}}


def run(name, scene):
    """Packs a scene; returns its report, the audit's verdict, wall time, peak memory and the
    progress curve (seconds, valid volume fraction)."""
    path = os.path.join(work, name + ".json")
    out = os.path.join(work, name)
    with open(path, "w") as f:
        json.dump(scene, f)
    p = subprocess.run(["/usr/bin/time", "-f", "TIME %e %M", exe, "generate", path, "-o", out],
                       capture_output=True, text=True)
    if p.returncode not in (0, 3):
        raise SystemExit("rvegen generate failed on %s (exit %d): %s" %
                         (name, p.returncode, p.stderr[-500:]))
    wall, peak = [float(x) for x in p.stderr.strip().splitlines()[-1].split()[1:]]
    curve = [(float(m.group(1)), float(m.group(2))) for m in
             re.finditer(r"md: ([0-9.]+) s, step \d+, volume fraction ([0-9.]+) valid",
                         p.stderr)]
    with open(os.path.join(out, "report.json")) as f:
        report = json.load(f)
    audit = subprocess.run([exe, "check", os.path.join(out, "inclusions.json")],
                           capture_output=True, text=True)
    report["overlaps"] = 0 if audit.returncode == 0 else (audit.stdout + audit.stderr).strip()
    report["wall"], report["peak_mb"], report["curve"] = wall, peak / 1024.0, curve
    return report


def run_all(jobs):
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        futures = {name: pool.submit(run, name, scene) for name, scene in jobs}
        return {name: f.result() for name, f in futures.items()}


# The density table of the short-fibre issue.
TABLE = [("aligned", 20, 0.60), ("planar", 20, 0.28), ("diag(0.7,0.25,0.05)", 20, 0.25),
         ("isotropic", 20, 0.22), ("isotropic", 10, 0.40), ("diag(0.7,0.25,0.05)", 40, 0.14),
         ("vMF kappa 3", 20, 0.20)]
results = run_all([("t%d" % i, fibres(law, vf, a)) for i, (law, a, vf) in enumerate(TABLE)])

lines = ["| orientation | L/D | fibres | target | reached | status | overlaps | A2 error (max) |"
         " packing s | wall s | peak MB |",
         "|---|---|---|---|---|---|---|---|---|---|---|"]
for i, (law, a, vf) in enumerate(TABLE):
    r = results["t%d" % i]
    f = r["families"][0]
    lines.append("| %s | %g | %d | %.2f | %.4f | %s | %s | %.1e | %.1f | %.1f | %.0f |" % (
        law, a, f["count"], vf, f["volume_fraction"], r["stop_reason"], r["overlaps"],
        f["orientation_tensor_error"], r["packing_seconds"], r["wall"], r["peak_mb"]))
machine = "%s, %d cores, %s" % (platform.processor() or platform.machine(), os.cpu_count(),
                                platform.platform())
table = "\n".join(lines)
print(table)
print("machine:", machine)
if not quick:
    with open(os.path.join(charts, "fibres_table.md"), "w") as f:
        f.write(table + "\n\nmachine: " + machine + "\n")

# Volume fraction against time, per law (the table's L/D 20 runs).
plt.figure(figsize=(6, 4))
for i, (law, a, vf) in enumerate(TABLE):
    if a != 20:
        continue
    c = results["t%d" % i]["curve"]
    if c:
        plt.plot([t for t, _ in c], [v for _, v in c], label="%s (target %.2f)" % (law, vf))
plt.xlabel("seconds")
plt.ylabel("valid volume fraction")
plt.title("Fibres, L/D 20: volume fraction reached against time")
plt.legend(fontsize=7)
plt.grid(alpha=0.3)
plt.tight_layout()
plt.savefig(os.path.join(charts, "fibres_time.png"), dpi=110)

# Orientation tensor asked for against obtained.
plt.figure(figsize=(4.5, 4.5))
for i, (law, a, vf) in enumerate(TABLE):
    f = results["t%d" % i]["families"][0]
    got = [x for row in f["orientation_tensor"] for x in row]
    want = [x for row in f["target_orientation_tensor"] for x in row]
    plt.scatter(want, got, s=14, label="%s, L/D %g" % (law, a))
plt.plot([-0.1, 1], [-0.1, 1], "k--", lw=0.8)
plt.xlabel("A2 component asked for")
plt.ylabel("A2 component of the RVE")
plt.legend(fontsize=6)
plt.tight_layout()
plt.savefig(os.path.join(charts, "fibres_tensor.png"), dpi=110)

# Jamming fraction against L/D: targets above reach, a shorter budget.
ratios = [5, 10, 20] if quick else [5, 10, 20, 40]
jam_laws = {"isotropic": lambda a: min(0.6, 8.0 / a), "planar": lambda a: min(0.65, 10.0 / a),
            "aligned": lambda a: 0.8}
jobs = [("j-%s-%d" % (law, a), fibres(law, f(a), a, n=count // 2, seconds=budget // 3))
        for law, f in jam_laws.items() for a in ratios]
jam = run_all(jobs)
plt.figure(figsize=(6, 4))
print("\n| orientation | L/D | reached (budget %d s) |" % (budget // 3))
print("|---|---|---|")
for law in jam_laws:
    ys = [jam["j-%s-%d" % (law, a)]["volume_fraction"] for a in ratios]
    for a, y in zip(ratios, ys):
        print("| %s | %d | %.4f |" % (law, a, y))
    plt.plot(ratios, ys, "o-", label=law)
xs = [r / 10.0 for r in range(40, 420)]
plt.plot(xs, [min(0.9, 5.0 / x) for x in xs], "k--", lw=0.8, label="phi = 5 / (L/D)")
plt.xscale("log")
plt.xlabel("L/D")
plt.ylabel("volume fraction reached")
plt.title("Fibres: densest valid packing within %d s" % (budget // 3))
plt.legend(fontsize=7)
plt.grid(alpha=0.3)
plt.tight_layout()
plt.savefig(os.path.join(charts, "fibres_jamming.png"), dpi=110)
print("charts in", charts)
