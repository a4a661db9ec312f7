#include "vtkRVEStatistics.h"

#include "rvegen/io/report.hpp"
#include "rvegen/model/stats.hpp"
#include "vtkDoubleArray.h"
#include "vtkInformation.h"
#include "vtkInformationVector.h"
#include "vtkObjectFactory.h"
#include "vtkRVECommon.h"
#include "vtkTable.h"

vtkStandardNewMacro(vtkRVEStatistics);

int vtkRVEStatistics::FillInputPortInformation(int, vtkInformation* info) {
  info->Set(vtkAlgorithm::INPUT_REQUIRED_DATA_TYPE(), "vtkDataObject");
  return 1;
}

int vtkRVEStatistics::RequestData(vtkInformation*, vtkInformationVector** in,
                                  vtkInformationVector* out) {
  vtkDataObject* input = in[0]->GetInformationObject(0)->Get(vtkDataObject::DATA_OBJECT());
  vtkTable* table = vtkTable::GetData(out);
  rvegen::InclusionSet set;
  std::string error;
  if (!RVEInclusionsFromFieldData(input, &set, &error)) {
    vtkErrorMacro(<< error);
    return 0;
  }
  RVELongTable rows;
  const std::vector<rvegen::Phase> phases = rvegen::phase_table(set);
  const std::vector<double> vf = rvegen::phase_volume_fractions(set, phases);
  for (const auto& p : phases) rows.Row("volume_fraction", p.name, p.label, vf[p.label]);
  for (const auto& p : phases) {
    if (p.kind != rvegen::PhaseKind::kCore) continue;
    const int f = p.family;
    int count = 0;
    double diameter = 0.0;
    bool spheres = true;
    for (const auto& inc : set.inclusions) {
      if (inc.family != f) continue;
      ++count;
      diameter += 2.0 * inc.shape.radius;
      spheres = spheres && inc.shape.kind == rvegen::ShapeKind::Sphere;
    }
    rows.Row("count", p.name, f, count);
    if (count == 0) continue;
    if (!spheres) {
      const rvegen::Mat3 a = rvegen::orientation_tensor(set, f);
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) rows.Row("orientation_tensor", p.name, 3 * i + j, a(i, j));
      }
    } else if (count > 1) {
      const rvegen::RadialDistribution g =
          rvegen::radial_distribution(set, f, 50, 5.0 * diameter / count);
      for (size_t k = 0; k < g.r.size(); ++k) {
        rows.Row("r", p.name, static_cast<int>(k), g.r[k]);
        rows.Row("g_r", p.name, static_cast<int>(k), g.g[k]);
      }
    }
  }
  const rvegen::Summary nn = rvegen::nearest_neighbour_distances(set);
  if (nn.n > 0) {
    rows.Row("nearest_neighbour_distance", "mean", 0, nn.mean);
    rows.Row("nearest_neighbour_distance", "std", 1, nn.std);
    rows.Row("nearest_neighbour_distance", "min", 2, nn.min);
    rows.Row("nearest_neighbour_distance", "max", 3, nn.max);
  }
  rows.AddTo(table);
  return 1;
}
