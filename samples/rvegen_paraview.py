"""Loads the RVEGen ParaView plugin for the sample scripts.

The plugin is looked up in $RVEGEN_PLUGIN, then in the install tree samples/quickstart.sh makes
(install/lib/paraview-<major>.<minor>/plugins/RVEGen/RVEGen.so, for the running ParaView's
version), then in build/test-install.
"""
import os

from paraview import servermanager
from paraview.simple import LoadPlugin

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
_PM = servermanager.vtkSMProxyManager
SUBDIR = os.path.join("lib", "paraview-%d.%d" % (_PM.GetVersionMajor(), _PM.GetVersionMinor()),
                      "plugins", "RVEGen", "RVEGen.so")
CANDIDATES = [
    os.environ.get("RVEGEN_PLUGIN", ""),
    os.path.join(ROOT, "install", SUBDIR),
    os.path.join(ROOT, "build", "test-install", SUBDIR),
]


def load_rvegen(namespace):
    """Loads the plugin into `namespace` (pass globals()); raises when it cannot be found."""
    for path in CANDIDATES:
        if path and os.path.exists(path):
            LoadPlugin(path, ns=namespace)
            return path
    raise RuntimeError("RVEGen plugin not found: run samples/quickstart.sh or set RVEGEN_PLUGIN")


def statistics_rows(table):
    """The rows of an RVE Statistics table as (quantity, name, index, value) tuples."""
    return [(table.GetValue(r, 0).ToString(), table.GetValue(r, 1).ToString(),
             table.GetValue(r, 2).ToInt(), table.GetValue(r, 3).ToDouble())
            for r in range(table.GetNumberOfRows())]
