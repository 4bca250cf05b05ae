// Paired comparison of two vtkMatrixTreeVolumeRayCaster developer settings
// (vtkMatrixTreeVolumeTuning: C++ only, not wrapped), in one process.
//
//   volume_ab VOLUME [A [B [ROUNDS [W H [THREADS [OUT.json]]]]]]
//
// A and B: comma-separated settings applied in order to the production path ("default" or ""
// for none): skip=0|1 (empty-space skipping), dense=0|1 (allocate every block), simd=0|1 (the
// AVX2 marcher where the CPU has it; 0: the SSE2 marcher), e.g. `volume_ab head.mhd default
// simd=0`. Defaults: A "default", B "skip=0", 15 rounds, 512 x 512 pixels, all threads.
//
// The scene is bench/volume.py's: matrixtree.default_transfer_functions, frame_camera, sample
// distance half the smallest spacing (tests/cpp/vtk_volume_util.h computes them as Python does).
// Each configuration has its own filter, classified before the timing starts; A and B then
// alternate, ROUNDS times, each frame timed by the renderer (GetLastRenderTime, the marching
// alone), so load from other processes hits both alike. Each round gives one ratio B/A; the
// table shows A's and B's median times and the median ratio with its quartiles. The images and
// samples are compared too: every setting gives the production image (skipping and the SSE2
// marcher bit for bit, dense storage within 1e-6) from the same samples.
//
// Prints a table; OUT.json (optional) gets one object.
#include "vtkMatrixTreeVolumeRayCaster.h"
#include "vtkMatrixTreeVolumeTuning.h"
#include "vtk_volume_util.h"

#include "vtkCamera.h"
#include "vtkColorTransferFunction.h"
#include "vtkFloatArray.h"
#include "vtkImageData.h"
#include "vtkNew.h"
#include "vtkPiecewiseFunction.h"
#include "vtkPointData.h"
#include "vtkSmartPointer.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace
{

vtkMatrixTreeVolumeTuning ParseTuning(const std::string& spec)
{
  vtkMatrixTreeVolumeTuning t;
  std::stringstream in(spec == "default" ? std::string() : spec);
  std::string item;
  while (std::getline(in, item, ','))
  {
    const size_t eq = item.find('=');
    const std::string key = item.substr(0, eq);
    const std::string value = eq == std::string::npos ? "" : item.substr(eq + 1);
    if (value != "0" && value != "1")
    {
      throw std::invalid_argument("setting '" + item + "': expected key=0 or key=1");
    }
    const bool on = value == "1";
    if (key == "skip")
    {
      t.EmptySpaceSkipping = on;
    }
    else if (key == "dense")
    {
      t.DenseStorage = on;
    }
    else if (key == "simd")
    {
      t.Vectorized = on;
    }
    else
    {
      throw std::invalid_argument("unknown setting '" + key + "' (skip, dense, simd)");
    }
  }
  return t;
}

double Median(std::vector<double> v)
{
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double Quantile(std::vector<double> v, double q)
{
  std::sort(v.begin(), v.end());
  const double x = q * double(v.size() - 1);
  const size_t i = static_cast<size_t>(x);
  const size_t j = std::min(i + 1, v.size() - 1);
  return v[i] + (v[j] - v[i]) * (x - double(i));
}

struct Frame
{
  double ms = 0;
  std::vector<float> rgba;
  vtkIdType samples = 0, skips = 0;
};

Frame Render(vtkMatrixTreeVolumeRayCaster* c)
{
  c->Modified();
  c->Update();
  vtkFloatArray* a = vtkFloatArray::SafeDownCast(c->GetOutput()->GetPointData()->GetArray("RGBAFloat"));
  if (!a)
  {
    throw std::runtime_error("the volume ray caster failed (see the VTK error above)");
  }
  Frame f;
  f.ms = c->GetLastRenderTime();
  f.rgba.assign(a->GetPointer(0), a->GetPointer(0) + 4 * a->GetNumberOfTuples());
  f.samples = c->GetNumberOfSamples();
  f.skips = c->GetNumberOfSkips();
  return f;
}

} // namespace

int main(int argc, char** argv)
{
  if (argc < 2)
  {
    std::fprintf(stderr, "usage: %s VOLUME [A [B [ROUNDS [W H [THREADS [OUT.json]]]]]]\n", argv[0]);
    return 2;
  }
  try
  {
    const std::string path = argv[1];
    const std::string specA = argc > 2 ? argv[2] : "default", specB = argc > 3 ? argv[3] : "skip=0";
    const int rounds = argc > 4 ? std::max(1, std::atoi(argv[4])) : 15;
    const int w = argc > 6 ? std::atoi(argv[5]) : 512, h = argc > 6 ? std::atoi(argv[6]) : 512;
    const int threads = argc > 7 ? std::atoi(argv[7]) : 0;
    const std::string json = argc > 8 ? argv[8] : "";
    const vtkMatrixTreeVolumeTuning tuning[2] = { ParseTuning(specA), ParseTuning(specB) };

    const vtkSmartPointer<vtkImageData> image = mtest::readVolume(path);
    vtkNew<vtkColorTransferFunction> ctf;
    vtkNew<vtkPiecewiseFunction> otf;
    mtest::defaultTransferFunctions(image, ctf, otf);
    const vtkSmartPointer<vtkCamera> camera = mtest::frameCamera(image);
    double sp[3];
    image->GetSpacing(sp);
    for (double& s : sp)
    {
      s = std::fabs(s);
    }
    vtkNew<vtkMatrixTreeVolumeRayCaster> casters[2];
    for (int k = 0; k < 2; ++k)
    {
      vtkMatrixTreeVolumeRayCaster* c = casters[k];
      c->SetInputData(image);
      c->SetColorTransferFunction(ctf);
      c->SetScalarOpacity(otf);
      c->SetScalarOpacityUnitDistance((sp[0] + sp[1] + sp[2]) / 3);
      c->SetImageSize(w, h);
      c->SetCamera(camera);
      c->SetSampleDistance(0.5 * std::min({ sp[0], sp[1], sp[2] }));
      c->SetNumberOfThreads(threads);
      c->SetTuning(tuning[k]);
      Render(c); // classification and a warm-up frame
    }

    std::vector<double> ms[2], ratio;
    Frame last[2];
    for (int r = 0; r < rounds; ++r)
    {
      for (int k = 0; k < 2; ++k)
      {
        last[k] = Render(casters[k]);
        ms[k].push_back(last[k].ms);
      }
      ratio.push_back(last[1].ms / last[0].ms);
    }
    double maxDiff = 0;
    for (size_t i = 0; i < last[0].rgba.size(); ++i)
    {
      maxDiff = std::max(maxDiff, std::fabs(double(last[0].rgba[i]) - double(last[1].rgba[i])));
    }
    // The samples taken are the same whatever the setting; skipped nodes only with skipping on.
    const bool sameSamples = last[0].samples == last[1].samples;
    const std::string name = path.substr(path.find_last_of('/') + 1);
    std::printf("%-26s %-22s %-22s %9s %9s %7s %15s %10s %6s\n", "volume", "A", "B", "A ms", "B ms", "B/A",
      "B/A quartiles", "max_diff", "samples");
    std::printf("%-26s %-22s %-22s %9.2f %9.2f %7.3f   %5.3f..%5.3f %10.3g %6s\n", name.c_str(), specA.c_str(),
      specB.c_str(), Median(ms[0]), Median(ms[1]), Median(ratio), Quantile(ratio, 0.25), Quantile(ratio, 0.75), maxDiff,
      sameSamples ? "same" : "differ");
    if (!json.empty())
    {
      std::ofstream out(json);
      out << "{\"volume\": \"" << name << "\", \"a\": \"" << specA << "\", \"b\": \"" << specB
          << "\", \"rounds\": " << rounds << ", \"width\": " << w << ", \"height\": " << h
          << ", \"a_ms\": " << Median(ms[0]) << ", \"b_ms\": " << Median(ms[1]) << ", \"ratio\": " << Median(ratio)
          << ", \"ratio_q1\": " << Quantile(ratio, 0.25) << ", \"ratio_q3\": " << Quantile(ratio, 0.75)
          << ", \"max_diff\": " << maxDiff << ", \"same_samples\": " << (sameSamples ? "true" : "false") << ", \"a_skips\": " << last[0].skips
          << ", \"b_skips\": " << last[1].skips << "}\n";
    }
    return 0;
  }
  catch (const std::exception& e)
  {
    std::fprintf(stderr, "volume_ab: %s\n", e.what());
    return 1;
  }
}
