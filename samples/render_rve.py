"""Renders an RVE written by `rvegen generate` to a PNG (headless under xvfb-run).

usage: pvpython --force-offscreen-rendering samples/render_rve.py RVE_DIR [OUT.png]
"""
import os
import sys

from paraview.simple import XMLImageDataReader

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rve_view import save_rve_dir_picture  # noqa: E402

rve = sys.argv[1]
# Next to the RVE directory, never inside it (rvegen generate refuses a directory holding files
# it did not write).
out = sys.argv[2] if len(sys.argv) > 2 else os.path.normpath(rve) + "_rve.png"
voxels = XMLImageDataReader(FileName=[os.path.join(rve, "voxels.vti")])
save_rve_dir_picture(rve, voxels, out, 800)
print("wrote", out)
sys.stdout.flush()
os._exit(0)  # no GL teardown at exit (GLXBadContext, sometimes an abort, under Xvfb)
