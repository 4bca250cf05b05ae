// Private to the MatrixTree::Filters module (not wrapped, not installed): the settings checks the
// ray casters' RequestData make before any work, one function per setting group, each returning
// "" when the values are usable and otherwise the reason with the valid range (for
// vtkErrorMacro). The Python front end (python/matrixtree/_checks.py) applies the same limits.
#ifndef vtkMatrixTreeChecks_h
#define vtkMatrixTreeChecks_h

#include "vtkType.h"

#include <cmath>
#include <sstream>
#include <string>

namespace vtkMatrixTreeChecks
{
/** Largest image side either ray caster renders. */
constexpr int kMaxImageSide = 16384;
/** Most samples a volume ray takes across the volume's diagonal: with the default 512 x 512
 * image a render at this bound marches ~2.7e11 samples (hours), far past any useful setting. */
constexpr double kMaxSamplesPerRay = 1 << 20;

/** Width and height each in [1, kMaxImageSide]. */
inline std::string ImageSize(const int size[2])
{
  if (size[0] >= 1 && size[1] >= 1 && size[0] <= kMaxImageSide && size[1] <= kMaxImageSide)
  {
    return "";
  }
  std::ostringstream os;
  os << "ImageSize " << size[0] << " x " << size[1] << ": each side must be in [1, " << kMaxImageSide << "]";
  return os.str();
}

/** A pinhole camera: finite position and focal point, apart. */
inline std::string Camera(const double position[3], const double focalPoint[3])
{
  double d2 = 0;
  for (int a = 0; a < 3; ++a)
  {
    if (!std::isfinite(position[a]) || !std::isfinite(focalPoint[a]))
    {
      return "the camera's Position and FocalPoint must be finite";
    }
    d2 += (focalPoint[a] - position[a]) * (focalPoint[a] - position[a]);
  }
  return d2 > 0 ? "" : "the camera's Position equals its FocalPoint: there is no view direction";
}

/**
 * The volume caster's inputs and settings: one scalar per point, a sample distance > 0 giving at
 * most kMaxSamplesPerRay samples across the volume's diagonal, an early-termination threshold in
 * [0, 1] and an opacity unit distance > 0 (NaN passes the setters' clamps; it is refused here).
 */
inline std::string VolumeSettings(vtkIdType scalars, const int dims[3], const double spacing[3],
  double sampleDistance, double earlyTermination, double unitDistance)
{
  std::ostringstream os;
  const vtkIdType points = static_cast<vtkIdType>(dims[0]) * dims[1] * dims[2];
  if (scalars != points)
  {
    os << "The input scalars hold " << scalars << " values for " << dims[0] << "x" << dims[1] << "x" << dims[2]
       << " = " << points << " points: one per point is needed";
    return os.str();
  }
  double diagonal2 = 0;
  for (int a = 0; a < 3; ++a)
  {
    diagonal2 += std::pow((dims[a] - 1) * spacing[a], 2);
  }
  const double diagonal = std::sqrt(diagonal2);
  if (!(sampleDistance > 0) || !std::isfinite(sampleDistance) || diagonal / sampleDistance > kMaxSamplesPerRay)
  {
    os << "SampleDistance " << sampleDistance << " must be finite and > 0, and at least the volume's diagonal "
       << diagonal << " / 2^20 = " << diagonal / kMaxSamplesPerRay << " (at most 2^20 samples per ray)";
    return os.str();
  }
  if (!(earlyTermination >= 0 && earlyTermination <= 1))
  {
    os << "EarlyTerminationThreshold " << earlyTermination << " must be in [0, 1]";
    return os.str();
  }
  if (!(unitDistance > 0) || !std::isfinite(unitDistance))
  {
    os << "ScalarOpacityUnitDistance " << unitDistance << " must be finite and > 0";
    return os.str();
  }
  return "";
}
}

#endif
