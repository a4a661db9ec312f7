#!/usr/bin/python3
"""Distributed cost against the number of MPI ranks: runs samples/bench_mpi.py under
`mpirun -np N pvbatch --symmetric` (rank 0 packs and broadcasts, every rank voxelizes its slab)
for N = 1, 2, 4 (oversubscribed beyond the cores), times the whole command, prints a table (also
samples/charts/mpi_ranks.md) and draws samples/charts/mpi_ranks.png.

usage: /usr/bin/python3 samples/bench_mpi_ranks.py PLUGIN.so [SCENE.json]
"""
import os
import platform
import subprocess
import sys
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

plugin = sys.argv[1]
scene = sys.argv[2] if len(sys.argv) > 2 else os.path.join("samples", "scenes", "mix10k.json")
bench = os.path.join(os.path.dirname(os.path.abspath(__file__)), "bench_mpi.py")
charts = os.path.join("samples", "charts")
os.makedirs(charts, exist_ok=True)
rows = []
for ranks in (1, 2, 4):
    threads = 0 if ranks == 1 else 1
    cmd = ["mpirun", "--allow-run-as-root", "--oversubscribe", "-np", str(ranks), "pvbatch"]
    if ranks > 1:
        cmd.append("--symmetric")
    cmd += [bench, plugin, scene, str(threads)]
    t0 = time.time()
    run = subprocess.run(cmd, capture_output=True, text=True, check=True)
    wall = time.time() - t0
    lines = [ln.split("\t") for ln in run.stdout.splitlines() if ln.count("\t") == 3]
    packing = max(float(f[2]) for f in lines)
    voxels = max(float(f[3]) for f in lines)
    rows.append((ranks, threads, packing, voxels, wall))
    print("ranks %d done: %.1f s" % (ranks, wall), file=sys.stderr)

table = ["| ranks | threads per rank (0: all) | packing (s) | voxel port (s, slowest rank) | whole command (s) |",
         "|---|---|---|---|---|"]
table += ["| %d | %d | %.1f | %.1f | %.1f |" % r for r in rows]
text = "\n".join(table) + "\n\n%s, %d cores, `%s`\n" % (
    platform.machine(), os.cpu_count(), " ".join(["samples/bench_mpi_ranks.py"] + sys.argv[1:]))
print(text)
with open(os.path.join(charts, "mpi_ranks.md"), "w") as f:
    f.write(text)
fig, ax = plt.subplots(figsize=(6, 4))
x = [r[0] for r in rows]
ax.plot(x, [r[2] for r in rows], "o-", label="packing (rank 0)")
ax.plot(x, [r[3] for r in rows], "s-", label="voxel port")
ax.plot(x, [r[4] for r in rows], "^-", label="whole command")
ax.set_xticks(x)
ax.set_xlabel("MPI ranks (pvbatch --symmetric; %d cores)" % os.cpu_count())
ax.set_ylabel("seconds")
ax.set_title(os.path.basename(scene))
ax.grid(alpha=0.3)
ax.legend()
fig.tight_layout()
fig.savefig(os.path.join(charts, "mpi_ranks.png"), dpi=110)
print("wrote samples/charts/mpi_ranks.png")
