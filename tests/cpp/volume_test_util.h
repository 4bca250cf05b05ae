// Shared by the volume test suites (CPU and OpenCL): a ramp transfer table, a look-at camera and
// a real volume read as floats.
#pragma once

#include <cmath>
#include <string>
#include <vector>

#include <vtkDataArray.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkStructuredPointsReader.h>

#include "mtree/volume/volume.h"
#include "test_util.h"

namespace mtest {

/// Build options that keep float input in Float32 blocks even where its values are all
/// integers or the table allows quantising them (VolumeBuildOptions::compactIntegralFloat and
/// quantizeFloat off): for tests of the float layout.
inline mtree::VolumeBuildOptions floatBlocks() {
  mtree::VolumeBuildOptions o;
  o.compactIntegralFloat = false;
  o.quantizeFloat = false;
  return o;
}

/// Transparent below `threshold` (fraction of [lo, hi]), a colour and opacity ramp above.
inline mtree::TransferTable rampTable(double lo, double hi, double threshold, float maxAlpha, int n = 1024) {
  std::vector<float> rgba;
  for (int i = 0; i < n; ++i) {
    const double s = double(i) / (n - 1);
    const double a = s <= threshold ? 0.0 : maxAlpha * (s - threshold) / (1 - threshold);
    rgba.insert(rgba.end(), {float(s), float(0.5 * s + 0.2), float(1 - s), float(a)});
  }
  return mtree::TransferTable(lo, hi, rgba, 1.0);
}

/// A perspective camera at `pos` looking at `focal`, w x h pixels, vertical view angle `angle`
/// degrees; view up +y, or +x when looking almost along y.
inline mtree::VolumeCamera lookAt(mtree::Vec3 pos, mtree::Vec3 focal, int w = 1, int h = 1, double angle = 30) {
  mtree::VolumeCamera c;
  c.position = pos;
  c.focalPoint = focal;
  c.viewUp = std::fabs(mtree::normalized(focal - pos).y) > 0.9 ? mtree::Vec3(1, 0, 0) : mtree::Vec3(0, 1, 0);
  c.viewAngle = angle;
  c.width = w;
  c.height = h;
  return c;
}

/// A volume of the shared data folder with its scalars as floats (any input type), its
/// dimensions, scalar range and geometry.
struct FloatVolume {
  std::vector<float> v;
  int dims[3] = {0, 0, 0};
  double range[2] = {0, 0};
  mtree::VolumeGeometry geo;
};

/// Reads a legacy-VTK volume (e.g. "volumes/ironProt.vtk"); false if it has no point scalars.
inline bool readFloatVolume(const std::string& rel, FloatVolume& out) {
  vtkNew<vtkStructuredPointsReader> r;
  r->SetFileName(dataPath(rel).c_str());
  r->Update();
  vtkImageData* im = r->GetOutput();
  vtkDataArray* s = im->GetPointData()->GetScalars();
  if (!s) return false;
  im->GetDimensions(out.dims);
  out.v.resize(size_t(s->GetNumberOfTuples()));
  for (vtkIdType i = 0; i < s->GetNumberOfTuples(); ++i) out.v[size_t(i)] = float(s->GetTuple1(i));
  s->GetRange(out.range);
  im->GetSpacing(out.geo.spacing);
  im->GetOrigin(out.geo.origin);
  return true;
}

}  // namespace mtest
