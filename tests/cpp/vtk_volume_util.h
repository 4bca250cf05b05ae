// The volume scenes of python/matrixtree/volume.py in C++, for the tests and benchmarks that drive
// vtkMatrixTreeVolumeRayCaster with its C++-only settings (test_volume_filter.cpp,
// bench/cpp/volume_ab.cxx): a volume file read into one-component scalars, the default transfer
// functions and the framing camera, each computed as the Python function of the same name.
#pragma once

#include <vtkAlgorithm.h>
#include <vtkCamera.h>
#include <vtkColorTransferFunction.h>
#include <vtkDataArray.h>
#include <vtkImageData.h>
#include <vtkMetaImageReader.h>
#include <vtkNIFTIImageReader.h>
#include <vtkNew.h>
#include <vtkPiecewiseFunction.h>
#include <vtkPointData.h>
#include <vtkSLCReader.h>
#include <vtkSmartPointer.h>
#include <vtkStructuredPoints.h>
#include <vtkStructuredPointsReader.h>
#include <vtkXMLImageDataReader.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace mtest {

/// A reader of type R for `path`.
template <class R>
vtkSmartPointer<vtkAlgorithm> fileReader(const std::string& path) {
  auto r = vtkSmartPointer<R>::New();
  r->SetFileName(path.c_str());
  return r;
}

/// matrixtree.read_volume: .mhd/.mha, .nii/.nii.gz, .slc, .vti or legacy .vtk; the first
/// component of multi-component scalars. Throws std::runtime_error when there are no scalars.
inline vtkSmartPointer<vtkImageData> readVolume(const std::string& path) {
  auto endsWith = [&](const std::string& e) {
    return path.size() >= e.size() && path.compare(path.size() - e.size(), e.size(), e) == 0;
  };
  vtkSmartPointer<vtkAlgorithm> reader;
  if (endsWith(".mhd") || endsWith(".mha")) reader = fileReader<vtkMetaImageReader>(path);
  else if (endsWith(".nii") || endsWith(".nii.gz")) reader = fileReader<vtkNIFTIImageReader>(path);
  else if (endsWith(".slc")) reader = fileReader<vtkSLCReader>(path);
  else if (endsWith(".vti")) reader = fileReader<vtkXMLImageDataReader>(path);
  else if (endsWith(".vtk")) reader = fileReader<vtkStructuredPointsReader>(path);
  else throw std::runtime_error("unknown volume format: " + path);
  reader->Update();
  auto out = vtkSmartPointer<vtkImageData>::New();
  out->ShallowCopy(vtkImageData::SafeDownCast(reader->GetOutputDataObject(0)));
  vtkDataArray* s = out->GetPointData()->GetScalars();
  if (!s) throw std::runtime_error(path + " holds no point scalars");
  if (s->GetNumberOfComponents() > 1) {
    vtkSmartPointer<vtkDataArray> first = vtkSmartPointer<vtkDataArray>::Take(s->NewInstance());
    first->SetNumberOfComponents(1);
    first->SetNumberOfTuples(s->GetNumberOfTuples());
    first->CopyComponent(0, s, 0);
    first->SetName(s->GetName() ? s->GetName() : "scalars");
    out->GetPointData()->SetScalars(first);
  }
  return out;
}

/// numpy.percentile(v, q) with its default linear interpolation between the sorted values
/// (the two order statistics it needs, by selection; v is reordered).
inline double percentile(std::vector<double>& v, double q) {
  const double x = q / 100.0 * double(v.size() - 1);
  const size_t i = static_cast<size_t>(std::floor(x));
  std::nth_element(v.begin(), v.begin() + i, v.end());
  const double vi = v[i];
  const double vj = i + 1 < v.size() ? *std::min_element(v.begin() + i + 1, v.end()) : vi;
  return vi + (vj - vi) * (x - double(i));
}

/// matrixtree.default_transfer_functions: transparent up to the 60th percentile of the finite
/// scalars, opacity rising linearly to maxOpacity at the maximum, colour from dark red through
/// orange to white.
inline void defaultTransferFunctions(vtkImageData* image, vtkColorTransferFunction* ctf, vtkPiecewiseFunction* otf,
                                     double maxOpacity = 0.25) {
  vtkDataArray* s = image->GetPointData()->GetScalars();
  std::vector<double> v;
  v.reserve(size_t(s->GetNumberOfTuples()));
  for (vtkIdType i = 0; i < s->GetNumberOfTuples(); ++i) {
    const double x = s->GetComponent(i, 0);
    if (std::isfinite(x)) v.push_back(x);
  }
  if (v.empty()) throw std::runtime_error("the volume has no finite scalar");
  const double lo = *std::min_element(v.begin(), v.end());
  double hi = *std::max_element(v.begin(), v.end());
  if (hi <= lo) hi = lo + 1.0;
  double t = percentile(v, 60);
  t = std::min(std::max(t, lo), lo + 0.9 * (hi - lo));
  otf->RemoveAllPoints();
  otf->AddPoint(lo, 0.0);
  otf->AddPoint(t, 0.0);
  otf->AddPoint(hi, maxOpacity);
  ctf->RemoveAllPoints();
  ctf->AddRGBPoint(lo, 0.0, 0.0, 0.0);
  ctf->AddRGBPoint(t, 0.55, 0.1, 0.05);
  ctf->AddRGBPoint(t + 0.5 * (hi - t), 1.0, 0.6, 0.2);
  ctf->AddRGBPoint(hi, 1.0, 1.0, 0.95);
}

/// matrixtree.frame_camera: a perspective camera framing the volume's bounds from the -y side,
/// turned by azimuth and elevation (degrees).
inline vtkSmartPointer<vtkCamera> frameCamera(vtkImageData* image, double azimuth = 30.0, double elevation = 20.0,
                                              double viewAngle = 30.0) {
  double b[6];
  image->GetBounds(b);
  const double c[3] = {(b[0] + b[1]) / 2, (b[2] + b[3]) / 2, (b[4] + b[5]) / 2};
  const double ex = b[1] - b[0], ey = b[3] - b[2], ez = b[5] - b[4];
  double radius = 0.5 * std::sqrt(ex * ex + ey * ey + ez * ez);
  if (radius == 0) radius = 1.0;
  auto cam = vtkSmartPointer<vtkCamera>::New();
  cam->SetFocalPoint(c[0], c[1], c[2]);
  cam->SetPosition(c[0], c[1] - 1.0, c[2]);
  cam->SetViewUp(0, 0, 1);
  cam->SetViewAngle(viewAngle);
  cam->Azimuth(azimuth);
  cam->Elevation(elevation);
  cam->OrthogonalizeViewUp();
  const double dist = radius / std::sin(viewAngle * 3.14159265358979323846 / 180.0 / 2);
  double d[3];
  cam->GetDirectionOfProjection(d);
  cam->SetPosition(c[0] - d[0] * dist, c[1] - d[1] * dist, c[2] - d[2] * dist);
  return cam;
}

}  // namespace mtest
