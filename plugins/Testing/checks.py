"""Comparisons shared by the pvpython tests."""
from vtkmodules.vtkImagingCore import vtkImageDifference
from vtkmodules.vtkIOImage import vtkPNGReader


def image_error(png, baseline):
    """Thresholded error of vtkImageDifference between two PNG files (0 = same picture)."""
    a = vtkPNGReader()
    a.SetFileName(png)
    b = vtkPNGReader()
    b.SetFileName(baseline)
    cmp = vtkImageDifference()
    cmp.SetInputConnection(a.GetOutputPort())
    cmp.SetImageConnection(b.GetOutputPort())
    cmp.Update()
    return cmp.GetThresholdedError()


def differing_values(a, b):
    """Number of tuples where two VTK arrays of the same length hold different values."""
    return sum(1 for i in range(a.GetNumberOfTuples()) if a.GetValue(i) != b.GetValue(i))
