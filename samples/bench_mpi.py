"""Time the voxel image of a scene under pvbatch, with as many MPI ranks as it is started with.

usage: [mpirun -np N] pvbatch samples/bench_mpi.py PLUGIN.so SCENE.json [THREADS]

The packing is computed first (the same on every rank, cached by the source); then only the
voxel port is updated at the scene's resolution, each rank voxelizing its own slab. Prints:
ranks  threads_per_rank (0: all)  packing_seconds  voxel_seconds
"""
import sys
import time

from paraview.simple import *  # noqa: F401,F403
from paraview import servermanager

plugin, scene = sys.argv[1:3]
LoadPlugin(plugin, ns=globals())
ranks = servermanager.vtkProcessModule.GetProcessModule().GetNumberOfLocalPartitions()
threads = int(sys.argv[3]) if len(sys.argv) > 3 else 0
gen = RVEGenerator(SceneFile=scene, Threads=threads)
# Filters on one port each: updating one asks the source for that port only.
surfaces = PassArrays(Input=OutputPort(gen, 0))
voxels = PassArrays(Input=OutputPort(gen, 1))
t0 = time.time()
UpdatePipeline(proxy=surfaces)  # packing (the same on every rank) + surfaces
t1 = time.time()
UpdatePipeline(proxy=voxels)  # voxels: each rank its slab
t2 = time.time()
print("%d\t%d\t%.2f\t%.2f" % (ranks, threads, t1 - t0, t2 - t1))
