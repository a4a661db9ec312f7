#!/usr/bin/python3
"""Runs the pair-test benchmark, prints a table and draws samples/charts/pair_throughput.png.

usage: /usr/bin/python3 samples/bench_pairs.py [BUILD_DIR]
"""
import json
import os
import platform
import subprocess
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

build = sys.argv[1] if len(sys.argv) > 1 else "build"
exe = os.path.join(build, "bin", "rvegen_bench_pairs")
out = subprocess.run([exe, "--benchmark_format=json", "--benchmark_min_time=0.5"],
                     check=True, capture_output=True, text=True).stdout
data = json.loads(out)
names = {0: "sphere", 1: "cylinder", 2: "ellipsoid"}
rows = []
for b in data["benchmarks"]:
    parts = dict(p.split(":") for p in b["name"].split("/")[1:])
    label = "%s-%s" % (names[int(parts["a"])], names[int(parts["b"])])
    rows.append((label, b["items_per_second"], b["cpu_time"]))
print("machine: %s, %s CPUs (%s)" % (platform.node(), os.cpu_count(), data["context"].get("mhz_per_cpu", "?")))
print("%-22s %16s %12s" % ("pair", "tests/second", "ns/test"))
for label, ips, ns in rows:
    print("%-22s %16.0f %12.1f" % (label, ips, ns))
fig, ax = plt.subplots(figsize=(7, 3.5))
ax.barh([r[0] for r in rows], [r[1] for r in rows], color="#4477aa")
ax.set_xscale("log")
ax.set_xlabel("exact pair tests per second (near-contact pairs, one core)")
ax.set_title("rvegen pair tests")
fig.tight_layout()
os.makedirs("samples/charts", exist_ok=True)
fig.savefig("samples/charts/pair_throughput.png", dpi=120)
print("wrote samples/charts/pair_throughput.png")
