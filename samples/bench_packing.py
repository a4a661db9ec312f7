#!/usr/bin/python3
"""Packing benchmarks: runs `rvegen generate` on the scenes of the packing targets, audits
every result with `rvegen check`, prints a table (also written to
samples/charts/packing_table.md: the packing time from report.json, and the whole command's wall
time and peak memory by GNU time) and draws three charts in samples/charts/:

  packing_rsa_vs_md.png      time against volume fraction reached, RSA and MD (RSA's wall)
  packing_scaling.png        time against number of spheres (MD, volume fraction 0.60)
  packing_aspect_ratio.png   volume fraction reached (jammed) against cylinder aspect ratio

usage: /usr/bin/python3 samples/bench_packing.py [BUILD_DIR] [--quick]
"""
import json
import os
import subprocess
import sys
import tempfile

from bench_util import machine, timed

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

args = [a for a in sys.argv[1:] if not a.startswith("--")]
quick = "--quick" in sys.argv
build = args[0] if args else "build"
exe = os.path.join(build, "bin", "rvegen")
work = tempfile.mkdtemp(prefix="rvegen-bench-")
charts = os.path.join("samples", "charts")
os.makedirs(charts, exist_ok=True)


def run(name, scene):
    """Packs a scene; returns the report plus the audit's verdict."""
    path = os.path.join(work, name + ".json")
    out = os.path.join(work, name)
    scene.setdefault("voxels", {"resolution": 8})
    with open(path, "w") as f:
        json.dump(scene, f)
    rc, wall, peak, err = timed([exe, "generate", path, "-o", out, "--quiet"])
    if rc not in (0, 3):
        raise SystemExit("rvegen generate failed on %s (exit %d): %s" % (name, rc, err[-500:]))
    with open(os.path.join(out, "report.json")) as f:
        report = json.load(f)
    report["wall"], report["peak"] = wall, peak
    audit = subprocess.run([exe, "check", os.path.join(out, "inclusions.json")],
                           capture_output=True, text=True)
    report["overlaps"] = 0 if audit.returncode == 0 else audit.stdout.strip().splitlines()[-1]
    return report


def spheres(n, vf, method="md", seed=1, md=None):
    s = {"box": {"size": [1, 1, 1]}, "seed": seed, "method": method,
         "families": [{"shape": "sphere", "volume_fraction": vf, "count": n}]}
    if md:
        s["md"] = md
    return s


def mix(a, vf_total, n_total=2000):
    """Spheres and cylinders of aspect ratio a, half and half by volume, equal inclusion volume."""
    return {"box": {"size": [1, 1, 1]}, "seed": 1, "families": [
        {"shape": "sphere", "volume_fraction": vf_total / 2, "count": n_total // 2},
        {"shape": "cylinder", "aspect_ratio": a, "volume_fraction": vf_total / 2,
         "count": n_total // 2}]}


# --- Targets ------------------------------------------------------------------------------
n10k = 2000 if quick else 10000
targets = [
    ("%d spheres, 0.60" % n10k, spheres(n10k, 0.60), 0.60),
    ("%d spheres, 0.63" % n10k, spheres(n10k, 0.63), 0.63),
    ("%d spheres, 0.636, default settings" % n10k, spheres(n10k, 0.636), 0.636),
    ("%d spheres, 0.645, default settings" % n10k, spheres(n10k, 0.645), 0.645),
    ("%d spheres, highest (target 0.66), default settings" % n10k, spheres(n10k, 0.66), None),
    ("%d spheres, highest (target 0.66), tuned: pressure 0.2, patience 300" % n10k,
     spheres(n10k, 0.66, md={"pressure": 0.2, "patience": 300}), None),
    ("spheres + cylinders a=2, 0.60", mix(2, 0.60), 0.60),
    ("spheres + cylinders a=5, 0.55", mix(5, 0.55), 0.55),
    ("ellipsoids 3:2:1 isotropic, 0.60",
     {"box": {"size": [1, 1, 1]}, "seed": 1, "families": [
         {"shape": "ellipsoid", "axis_ratios": [3, 2, 1], "volume_fraction": 0.60,
          "count": 3000}]}, 0.60),
    ("lognormal radii std/mean 0.3, 0.62",
     {"box": {"size": [1, 1, 1]}, "seed": 1, "families": [
         {"shape": "sphere", "radius": {"law": "lognormal", "mean": 0.02, "std": 0.006},
          "volume_fraction": 0.62}]}, 0.62),
]
if not quick:
    targets.append(("100000 spheres, 0.60", spheres(100000, 0.60), 0.60))

rows = []
for i, (label, scene, want) in enumerate(targets):
    r = run("target%d" % i, scene)
    rows.append((label, r["count"], r["volume_fraction"], r["packing_seconds"], r["wall"],
                 r["peak"], r.get("steps", 0), r["status"], r["overlaps"], want))
    print("%-52s %7d  vf %.4f  %7.2f s  wall %7.2f s  %5.0f MiB  %6d steps  %-18s overlaps %s"
          % rows[-1][:9], flush=True)

# --- RSA against MD: time against volume fraction reached ---------------------------------
n_cmp = 2000
curve = {"rsa": [], "md": []}
for vf in [0.1, 0.2, 0.3, 0.35, 0.4, 0.45, 0.5, 0.55, 0.6, 0.63]:
    for method in ("rsa", "md"):
        if method == "rsa" and vf > 0.45:
            continue  # far past the wall: RSA stops at the same place
        r = run("%s_%g" % (method, vf), spheres(n_cmp, vf, method))
        curve[method].append((vf, r["volume_fraction"], r["packing_seconds"], r["status"]))
        print("%s target %.2f: reached %.4f in %.2f s (%s)" % (method, vf, r["volume_fraction"],
                                                           r["packing_seconds"], r["status"]),
              flush=True)

# --- Time against N -------------------------------------------------------------------------
scaling = []
for n in ([1000, 3000, 10000] if quick else [1000, 3000, 10000, 30000, 100000]):
    r = run("n%d" % n, spheres(n, 0.60))
    scaling.append((n, r["packing_seconds"], r["status"]))
    print("N = %d: %.2f s (%s)" % (n, r["packing_seconds"], r["status"]), flush=True)

# --- Volume fraction reached against aspect ratio ---------------------------------------------
aspect = []
for a in ([1, 2, 5] if quick else [0.5, 1, 2, 3, 5, 10, 20]):
    scene = {"box": {"size": [1, 1, 1]}, "seed": 1, "md": {"max_seconds": 90},
             "families": [{"shape": "cylinder", "aspect_ratio": a, "volume_fraction": 0.8,
                           "count": 1000}]}
    r = run("a%g" % a, scene)
    aspect.append((a, r["volume_fraction"], r["packing_seconds"], r["stop_reason"]))
    print("a = %g: %.4f in %.2f s (%s)" % aspect[-1], flush=True)

# --- Table and charts -------------------------------------------------------------------------
lines = ["Measured on %s with `/usr/bin/python3 %s`, runs in turn; packing seconds from "
         "report.json, wall time and peak memory of the whole `rvegen generate` command (GNU time)."
         % (machine(), " ".join(["samples/bench_packing.py"] + sys.argv[1:])),
         "", "| scene | inclusions | volume fraction reached | packing s | wall s | peak MiB | steps "
         "| status | overlaps |", "|---|---:|---:|---:|---:|---:|---:|---|---:|"]
for label, n, vf, sec, wall, peak, steps, status, ov, want in rows:
    lines.append("| %s | %d | %.4f | %.2f | %.2f | %.0f | %d | %s | %s |"
                 % (label, n, vf, sec, wall, peak, steps, status, ov))
table = "\n".join(lines) + "\n"
print(table)
with open(os.path.join(charts, "packing_table.md"), "w") as f:
    f.write(table)

fig, ax = plt.subplots(figsize=(6.5, 4))
for method, colour in (("rsa", "#cc6677"), ("md", "#4477aa")):
    pts = curve[method]
    ax.plot([p[1] for p in pts], [p[2] for p in pts], "o-", color=colour, label=method.upper())
    for p in pts:
        if p[3] != "ok":
            ax.plot(p[1], p[2], "x", color="black", ms=9)
ax.set_yscale("log")
ax.set_xlabel("volume fraction reached (%d monodisperse spheres)" % n_cmp)
ax.set_ylabel("packing time (s)")
ax.set_title("RSA stalls, MD goes on (x: target not reached)")
ax.legend()
fig.tight_layout()
fig.savefig(os.path.join(charts, "packing_rsa_vs_md.png"), dpi=120)

fig, ax = plt.subplots(figsize=(6.5, 4))
ns = [p[0] for p in scaling]
ts = [p[1] for p in scaling]
ax.loglog(ns, ts, "o-", color="#4477aa", label="MD, volume fraction 0.60")
ax.loglog(ns, [ts[0] * n / ns[0] for n in ns], "--", color="grey", label="linear in N")
ax.set_xlabel("number of spheres")
ax.set_ylabel("packing time (s)")
ax.legend()
fig.tight_layout()
fig.savefig(os.path.join(charts, "packing_scaling.png"), dpi=120)

fig, ax = plt.subplots(figsize=(6.5, 4))
ax.semilogx([p[0] for p in aspect], [p[1] for p in aspect], "o-", color="#4477aa")
ax.set_xlabel("cylinder aspect ratio a = half length / radius (isotropic)")
ax.set_ylabel("volume fraction at jamming")
ax.set_title("MD, 1000 cylinders, target 0.8 (beyond reach)")
fig.tight_layout()
fig.savefig(os.path.join(charts, "packing_aspect_ratio.png"), dpi=120)
print("wrote charts to", charts)
