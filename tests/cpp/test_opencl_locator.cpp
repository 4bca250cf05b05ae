// vtkMatrixTreeLocator::FindCells with Backend OPENCL against Backend CPU (the reference): on the
// real CFD grids (tetrahedra; tetrahedra + pyramids; hexahedra; prisms), 10^5 seeded points in
// and around the bounds plus the hard cases — points on shared faces and at cell vertices (where
// several cells contain the point and the first in the leaf's order must win) and points at
// VTK's tolerance boundary (barycentric -1e-3, where the device must leave the call to the host)
// — the cell ids are identical and pcoords/weights equal to 1e-12. Also: the device copy is kept
// until a rebuild, float points, and an error (no crash, no fallback) when the selector matches
// no device. Device tests skip, with the reason, when there is no OpenCL device.
#include <gtest/gtest.h>

#include <vtkCellArray.h>
#include <vtkCommand.h>
#include <vtkDoubleArray.h>
#include <vtkFloatArray.h>
#include <vtkGenericCell.h>
#include <vtkIdList.h>
#include <vtkIdTypeArray.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkSmartPointer.h>
#include <vtkUnstructuredGrid.h>
#include <vtkXMLUnstructuredGridReader.h>

#include "vtkMatrixTreeLocator.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "opencl_test_util.h"
#include "vtk_grid_util.h"
#include "vtk_test_util.h"
#include "test_util.h"

namespace {

using mtest::ErrorCatcher;
using mtest::readGrid;

/// 10^5 seeded points in the bounds grown by 5% per side, then the hard cases: for seeded
/// cells, the centroid of a face (a shared face: two cells contain it), a vertex (many do) and,
/// for tetrahedra, the point at barycentric -1e-3 beyond a face (VTK's tolerance boundary).
vtkSmartPointer<vtkPoints> queryPoints(vtkUnstructuredGrid* g, uint64_t seed, size_t random, size_t special) {
  mtest::Rng rng(seed);
  double b[6];
  g->GetBounds(b);
  auto pts = vtkSmartPointer<vtkPoints>::New();
  pts->SetDataTypeToDouble();
  for (size_t i = 0; i < random; ++i) {
    double x[3];
    for (int a = 0; a < 3; ++a) {
      const double e = b[2 * a + 1] - b[2 * a];
      x[a] = rng.uniform(b[2 * a] - 0.05 * e, b[2 * a + 1] + 0.05 * e);
    }
    pts->InsertNextPoint(x);
  }
  vtkNew<vtkIdList> ids;
  const uint32_t nc = static_cast<uint32_t>(g->GetNumberOfCells());
  for (size_t i = 0; i < special; ++i) {
    const vtkIdType c = rng.below(nc);
    g->GetCellPoints(c, ids);
    double p[8][3];
    const int np = static_cast<int>(std::min<vtkIdType>(8, ids->GetNumberOfIds()));
    for (int k = 0; k < np; ++k) g->GetPoint(ids->GetId(k), p[k]);
    double x[3];
    switch (i % 3) {
      case 0:  // centroid of the first three points: on a face of a tetrahedron, wedge or pyramid
        for (int a = 0; a < 3; ++a) x[a] = (p[0][a] + p[1][a] + p[2][a]) / 3.0;
        break;
      case 1:  // a vertex
        for (int a = 0; a < 3; ++a) x[a] = p[rng.below(static_cast<uint32_t>(np))][a];
        break;
      default:  // barycentric (-1e-3, ...) in a tetrahedron: right at VTK's tolerance
        if (g->GetCellType(c) == VTK_TETRA) {
          const double w0 = -1e-3, w1 = 0.3, w2 = 0.4, w3 = 1.0 - w0 - w1 - w2;
          for (int a = 0; a < 3; ++a) x[a] = w0 * p[0][a] + w1 * p[1][a] + w2 * p[2][a] + w3 * p[3][a];
        } else {
          for (int a = 0; a < 3; ++a) x[a] = 0.5 * (p[0][a] + p[np - 1][a]);
        }
    }
    pts->InsertNextPoint(x);
  }
  // Non-finite points: no cell on either backend.
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  pts->InsertNextPoint(nan, 0, 0);
  pts->InsertNextPoint(inf, inf, inf);
  return pts;
}

struct Answers {
  vtkNew<vtkIdTypeArray> ids;
  vtkNew<vtkDoubleArray> pcoords, weights;
  double ms = 0;
};

void findCells(vtkMatrixTreeLocator* loc, vtkPoints* pts, Answers& out, bool params = true) {
  const auto t0 = std::chrono::steady_clock::now();
  loc->FindCells(pts, out.ids, params ? out.pcoords.Get() : nullptr, params ? out.weights.Get() : nullptr);
  out.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

/// Same ids, pcoords and weights within tol.
void expectSame(const Answers& cpu, const Answers& dev, const std::string& what, double tol = 1e-12) {
  ASSERT_EQ(cpu.ids->GetNumberOfTuples(), dev.ids->GetNumberOfTuples()) << what;
  const vtkIdType n = cpu.ids->GetNumberOfTuples();
  vtkIdType diff = 0, firstDiff = -1;
  for (vtkIdType i = 0; i < n; ++i)
    if (cpu.ids->GetValue(i) != dev.ids->GetValue(i) && diff++ == 0) firstDiff = i;
  EXPECT_EQ(diff, 0) << what << ": first at point " << firstDiff << ": cpu " << cpu.ids->GetValue(firstDiff)
                     << ", opencl " << dev.ids->GetValue(firstDiff);
  if (dev.pcoords->GetNumberOfTuples() == 0) return;
  ASSERT_EQ(cpu.pcoords->GetNumberOfValues(), dev.pcoords->GetNumberOfValues()) << what;
  ASSERT_EQ(cpu.weights->GetNumberOfValues(), dev.weights->GetNumberOfValues()) << what;
  double dp = 0, dw = 0;
  for (vtkIdType k = 0; k < cpu.pcoords->GetNumberOfValues(); ++k)
    dp = std::max(dp, std::fabs(cpu.pcoords->GetValue(k) - dev.pcoords->GetValue(k)));
  for (vtkIdType k = 0; k < cpu.weights->GetNumberOfValues(); ++k)
    dw = std::max(dw, std::fabs(cpu.weights->GetValue(k) - dev.weights->GetValue(k)));
  EXPECT_LE(dp, tol) << what;
  EXPECT_LE(dw, tol) << what;
}

class OpenCLLocatorGrid : public ::testing::TestWithParam<const char*> {};

TEST_P(OpenCLLocatorGrid, FindCellsEqualsCpu) {
  REQUIRE_DEVICE(ctx);
  const std::string rel = GetParam();
  auto g = readGrid(rel);
  ASSERT_TRUE(g) << "cannot read " << mtest::dataPath(rel);
  vtkNew<vtkMatrixTreeLocator> cpu, dev;
  cpu->SetDataSet(g);
  cpu->BuildLocator();
  dev->SetDataSet(g);
  dev->SetBackendToOpenCL();
  EXPECT_STREQ(dev->GetBackendAsString(), "opencl");
  dev->BuildLocator();
  auto pts = queryPoints(g, mtest::seedFor(rel), 100000, 6000);
  const vtkIdType n = pts->GetNumberOfPoints();
  Answers a, b, bWarm, bIds;
  findCells(cpu, pts, a);
  findCells(dev, pts, b);  // first call: upload (and, once per process, the kernel compile)
  const std::string firstPhases = dev->GetLastFindCellsPhases();
  findCells(dev, pts, bWarm);
  const std::string warmPhases = dev->GetLastFindCellsPhases();
  EXPECT_EQ(dev->GetNumberOfOpenCLUploads(), 1);
  EXPECT_EQ(dev->GetLastNumberOfUnconfirmedCells(), 0);
  const vtkIdType resumes = dev->GetLastNumberOfHostResumes();
  findCells(dev, pts, bIds, false);  // ids only: the device's "found" is not re-checked by VTK
  ASSERT_EQ(a.ids->GetNumberOfTuples(), n);
  vtkIdType found = 0;
  for (vtkIdType i = 0; i < n; ++i) found += a.ids->GetValue(i) >= 0;
  EXPECT_GT(found, n / 10) << "the points should hit the grid";
  EXPECT_EQ(a.ids->GetValue(n - 1), -1);
  expectSame(a, b, rel + " (first call)");
  expectSame(a, bWarm, rel + " (device copy reused)");
  expectSame(a, bIds, rel + " (ids only)");
  std::printf("[ opencl   ] %s: %lld cells, %lld points, %lld found, %lld finished on the host; CPU %.1f ms, "
              "OpenCL first %.1f ms, warm %.1f ms (%s; first: %s), ids only %.1f ms\n",
              rel.c_str(), static_cast<long long>(g->GetNumberOfCells()), static_cast<long long>(n),
              static_cast<long long>(found), static_cast<long long>(resumes), a.ms, b.ms, bWarm.ms, warmPhases.c_str(),
              firstPhases.c_str(), bIds.ms);
  if (g->IsHomogeneous() && g->GetCellType(0) == VTK_TETRA) {
    // Tetrahedra are decided on the device, except right at the tolerance boundary.
    EXPECT_LT(resumes, n / 20);
    EXPECT_GT(resumes, 0) << "the points at barycentric -1e-3 should reach the host";
  }
}

INSTANTIATE_TEST_SUITE_P(CfdGrids, OpenCLLocatorGrid,
                         ::testing::Values("cfd/pipe_flow_tets.vtu", "cfd/brick_pyra.su2", "cfd/brick_hex.su2",
                                           "cfd/brick_prism.su2"),
                         [](const ::testing::TestParamInfo<const char*>& info) {
                           std::string s = info.param;
                           s = s.substr(s.find('/') + 1);
                           for (char& c : s)
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           return s;
                         });

TEST(OpenCLLocator, KdTreeFloatPointsAndRebuild) {
  REQUIRE_DEVICE(ctx);
  auto g = readGrid("cfd/pipe_lumen_tets.vtu");
  ASSERT_TRUE(g);
  vtkNew<vtkMatrixTreeLocator> cpu, dev;
  for (vtkMatrixTreeLocator* l : {cpu.Get(), dev.Get()}) {
    l->SetTreeTypeToKdTree();
    l->SetDataSet(g);
  }
  dev->SetBackendToOpenCL();
  // Float points: the device gets them as doubles, converted as GetPoint does.
  auto dbl = queryPoints(g, 77, 20000, 3000);
  vtkNew<vtkPoints> flt;
  flt->SetDataTypeToFloat();
  flt->SetNumberOfPoints(dbl->GetNumberOfPoints());
  for (vtkIdType i = 0; i < dbl->GetNumberOfPoints(); ++i) flt->SetPoint(i, dbl->GetPoint(i));
  Answers a, b;
  findCells(cpu, flt, a);
  findCells(dev, flt, b);
  expectSame(a, b, "pipe_lumen kd-tree, float points");
  EXPECT_EQ(dev->GetNumberOfOpenCLUploads(), 1);
  // A new height rebuilds the tree: the next FindCells uploads again, and still agrees.
  cpu->SetHeight(cpu->GetTreeHeight() - 1);
  dev->SetHeight(dev->GetTreeHeight() - 1);
  Answers c, d;
  findCells(cpu, flt, c);
  findCells(dev, flt, d);
  expectSame(c, d, "pipe_lumen kd-tree, rebuilt one level shallower");
  EXPECT_EQ(dev->GetNumberOfOpenCLUploads(), 2);
  // Back to the CPU backend: same answers, nothing uploaded.
  dev->SetBackendToCPU();
  Answers e;
  findCells(dev, flt, e);
  expectSame(c, e, "back on the CPU backend");
  EXPECT_EQ(dev->GetNumberOfOpenCLUploads(), 2);
}

TEST(OpenCLLocator, NoMatchingDeviceIsAnErrorNotACrash) {
  // Runs with or without a device: a selector that matches none fails as a machine without
  // OpenCL does (and a build without OpenCL fails the same way, from the engine's stubs).
  auto g = readGrid("cfd/pipe_flow_tets.vtu");
  ASSERT_TRUE(g);
  vtkNew<vtkMatrixTreeLocator> loc;
  vtkNew<ErrorCatcher> errors;
  loc->AddObserver(vtkCommand::ErrorEvent, errors);
  loc->SetDataSet(g);
  loc->SetBackendToOpenCL();
  loc->SetOpenCLDevice("no-such-opencl-device-xyz");
  auto pts = queryPoints(g, 3, 1000, 0);
  Answers a;
  findCells(loc, pts, a);
  EXPECT_EQ(a.ids->GetNumberOfTuples(), 0);
  EXPECT_EQ(a.pcoords->GetNumberOfTuples(), 0);
  EXPECT_EQ(a.weights->GetNumberOfTuples(), 0);
  EXPECT_GE(errors->count, 1);
  EXPECT_NE(errors->message.find("opencl backend"), std::string::npos) << errors->message;
  EXPECT_EQ(loc->GetNumberOfOpenCLUploads(), 0);
  std::printf("[ opencl   ] expected error: %s\n", errors->message.c_str());
  // The one-point call stays on the CPU and works.
  double x[3];
  pts->GetPoint(0, x);
  vtkNew<vtkGenericCell> cell;
  double pc[3], w[8];
  const int before = errors->count;
  loc->FindCell(x, 0.0, cell, pc, w);
  EXPECT_EQ(errors->count, before);
  // And the CPU backend answers the batch.
  loc->SetBackendToCPU();
  findCells(loc, pts, a);
  EXPECT_EQ(a.ids->GetNumberOfTuples(), pts->GetNumberOfPoints());
  EXPECT_EQ(errors->count, before);
}

}  // namespace
