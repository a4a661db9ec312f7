"""Generate an RVE with the ParaView plugin and save pictures, headless.

usage: xvfb-run -a -s "-screen 0 1280x1024x24" pvpython --force-offscreen-rendering \\
         samples/pv_generate.py [SCENE.json|default] [OUT_DIR]

With "default" (or nothing) the generator's properties give the default scene. Writes OUT_DIR/rve_3d.png (the
inclusions coloured by family) and OUT_DIR/rve_slice.png (a slice of the voxel image by phase).
"""
import os
import sys

from paraview.simple import ColorBy, CreateView, OutputPort, SaveScreenshot, Show, Slice

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rve_view import save_rve_picture  # noqa: E402
from rvegen_paraview import load_rvegen  # noqa: E402

scene = sys.argv[1] if len(sys.argv) > 1 and sys.argv[1] != "default" else ""
out = sys.argv[2] if len(sys.argv) > 2 else "rve_pictures"
os.makedirs(out, exist_ok=True)
load_rvegen(globals())  # defines RVEGenerator here
gen = RVEGenerator(SceneFile=scene)  # noqa: F821
save_rve_picture(OutputPort(gen, 0), OutputPort(gen, 1), os.path.join(out, "rve_3d.png"), 600)
cut = Slice(Input=OutputPort(gen, 1))
cut.SliceType.Normal = [0, 0, 1]
view = CreateView("RenderView")
view.OrientationAxesVisibility = 0
ColorBy(Show(cut, view), ("CELLS", "phase"))
view.ResetCamera()
SaveScreenshot(os.path.join(out, "rve_slice.png"), view, ImageResolution=[600, 600])
print("wrote", out)
sys.stdout.flush()
os._exit(0)  # no GL teardown at exit (GLXBadContext under Xvfb)
