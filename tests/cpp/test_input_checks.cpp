// Bad input at the C++ boundaries, each a reported error with its reason instead of a crash, a
// hang or a wrong answer (docs/reliability.md lists them):
//   engine      TriangleMesh and CellSet refuse coordinates beyond +-1e30 and point sets
//               spanning less than 1e-30 (mtree/core/coordinate_range.h), and accept the ends
//               of that range;
//   volume      vtkMatrixTreeVolumeRayCaster refuses fewer scalars than points (a heap overflow
//               in BlockSparseVolume::build before), a sample distance <= 0 or giving more than
//               2^20 samples per ray (a render of hours before), NaN thresholds, oversized images;
//   surface     vtkMatrixTreeRayCaster refuses oversized images and a camera without a view
//               direction; vtkMatrixTree refuses coordinates out of range;
//   locator     FindCell puts a point near (not on) a line cell of a 3-D grid in no cell
//               (vtkCellLocator's answer), and FindClosestPoint of a non-finite point finds no cell.
// Under ASan (scripts/sanitize.sh) the volume cases are the regression tests of the overflow.
#include <gtest/gtest.h>

#include <vtkCellArray.h>
#include <vtkCellLocator.h>
#include <vtkDoubleArray.h>
#include <vtkFloatArray.h>
#include <vtkGenericCell.h>
#include <vtkIdTypeArray.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>
#include <vtkUnstructuredGrid.h>

#include "vtkMatrixTree.h"
#include "vtkMatrixTreeLocator.h"
#include "vtkMatrixTreeRayCaster.h"
#include "vtkMatrixTreeVolumeRayCaster.h"

#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "mtree/cells/cells.h"
#include "mtree/core/primitives.h"
#include "vtk_test_util.h"

namespace {

using mtest::ErrorCatcher;

// The message of the std::invalid_argument `f` throws ("" if it throws none).
template <class F>
std::string invalidArgument(F&& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

std::vector<double> scaledTriangle(double s, double offset = 0) {
  return {offset, offset, offset, offset + s, offset, offset, offset, offset + s, offset};
}

TEST(CoordinateRange, TriangleMeshRefusesCoordinatesBeyond1e30) {
  for (double s : {1e31, 1e39, 1e100, 1e300}) {
    const std::string why = invalidArgument([&] { mtree::TriangleMesh(scaledTriangle(s), {0, 1, 2}); });
    EXPECT_NE(why.find("beyond the supported range [-1e30, 1e30]"), std::string::npos) << s << ": " << why;
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> p = scaledTriangle(1);
  p[4] = nan;
  EXPECT_NE(invalidArgument([&] { mtree::TriangleMesh(p, {0, 1, 2}); }).find("point 1 has the coordinate nan (non-finite"),
            std::string::npos);
  EXPECT_EQ(invalidArgument([&] { mtree::TriangleMesh(scaledTriangle(1e30), {0, 1, 2}); }), "");
  EXPECT_EQ(invalidArgument([&] { mtree::TriangleMesh(scaledTriangle(-1e30), {0, 1, 2}); }), "");
}

TEST(CoordinateRange, TriangleMeshRefusesExtentsBelow1e30) {
  for (double s : {1e-31, 1e-100, 1e-160, 1e-300, 4e-320}) {
    const std::string why = invalidArgument([&] { mtree::TriangleMesh(scaledTriangle(s), {0, 1, 2}); });
    EXPECT_NE(why.find("at least 1e-30 is supported"), std::string::npos) << s << ": " << why;
  }
  EXPECT_EQ(invalidArgument([&] { mtree::TriangleMesh(scaledTriangle(1e-30), {0, 1, 2}); }), "");
  // A single point (all vertices equal) spans nothing: allowed (a degenerate mesh, every ray misses);
  // so does a triangle too small to tell its vertices apart at its position (0.5 + 1e-31 == 0.5).
  EXPECT_EQ(invalidArgument([&] { mtree::TriangleMesh(scaledTriangle(0, 3), {0, 1, 2}); }), "");
  EXPECT_EQ(invalidArgument([&] { mtree::TriangleMesh(scaledTriangle(1e-31, 0.5), {0, 1, 2}); }), "");
  mtree::TriangleMesh m(scaledTriangle(1), {0, 1, 2});
  EXPECT_NE(invalidArgument([&] { m.setPoints(scaledTriangle(1e40)); }).find("TriangleMesh::setPoints"),
            std::string::npos);
}

TEST(CoordinateRange, CellSetRefusesTheSameRange) {
  const std::vector<uint32_t> off = {0, 4}, conn = {0, 1, 2, 3};
  const std::vector<uint8_t> types = {10};  // VTK_TETRA
  auto tet = [](double s) {
    return std::vector<double>{0, 0, 0, s, 0, 0, 0, s, 0, 0, 0, s};
  };
  EXPECT_NE(invalidArgument([&] { mtree::CellSet(tet(1e39), off, conn, types); }).find("CellSet: point 1"),
            std::string::npos);
  EXPECT_NE(invalidArgument([&] { mtree::CellSet(tet(1e-200), off, conn, types); }).find("span only"),
            std::string::npos);
  EXPECT_EQ(invalidArgument([&] { mtree::CellSet(tet(1e25), off, conn, types); }), "");
}

// A closed latitude-longitude sphere of radius `scale` (double points): 16 x 8 quads as triangles.
vtkSmartPointer<vtkPolyData> sphere(double scale) {
  auto pd = vtkSmartPointer<vtkPolyData>::New();
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToDouble();
  const int nu = 16, nv = 8;
  for (int j = 0; j <= nv; ++j)
    for (int i = 0; i < nu; ++i) {
      const double th = M_PI * j / nv, ph = 2 * M_PI * i / nu;
      pts->InsertNextPoint(scale * std::sin(th) * std::cos(ph), scale * std::sin(th) * std::sin(ph),
                           scale * std::cos(th));
    }
  vtkNew<vtkCellArray> tris;
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      const vtkIdType a = j * nu + i, b = j * nu + (i + 1) % nu, c = a + nu, d = b + nu;
      const vtkIdType t0[3] = {a, c, b}, t1[3] = {b, c, d};
      tris->InsertNextCell(3, t0);
      tris->InsertNextCell(3, t1);
    }
  pd->SetPoints(pts);
  pd->SetPolys(tris);
  return pd;
}

TEST(VtkMatrixTree, BuildRefusesCoordinatesOutOfRangeWithTheReason) {
  for (double scale : {1e100, 1e-160}) {
    vtkNew<vtkMatrixTree> tree;
    vtkNew<ErrorCatcher> errors;
    tree->AddObserver(vtkCommand::ErrorEvent, errors);
    tree->SetDataSet(sphere(scale));
    EXPECT_FALSE(tree->Build()) << scale;
    EXPECT_NE(errors->message.find(scale > 1 ? "beyond the supported range" : "span only"), std::string::npos)
        << errors->message;
  }
}

vtkSmartPointer<vtkImageData> image(int n, vtkIdType scalars) {
  auto im = vtkSmartPointer<vtkImageData>::New();
  im->SetDimensions(n, n, n);
  vtkNew<vtkFloatArray> a;
  a->SetNumberOfTuples(scalars);
  for (vtkIdType i = 0; i < scalars; ++i) a->SetValue(i, static_cast<float>(i % 7));
  im->GetPointData()->SetScalars(a);
  return im;
}

// Renders `im` with `set` applied to the caster; returns the error message ("" if none) and
// the seconds it took.
template <class F>
std::string renderVolume(vtkImageData* im, F&& set, double* seconds = nullptr) {
  vtkNew<vtkMatrixTreeVolumeRayCaster> caster;
  vtkNew<ErrorCatcher> errors;
  caster->AddObserver(vtkCommand::ErrorEvent, errors);
  caster->SetInputData(im);
  caster->SetImageSize(8, 8);
  set(caster.Get());
  const auto t0 = std::chrono::steady_clock::now();
  caster->Update();
  if (seconds) *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return errors->count ? errors->message : "";
}

TEST(VolumeRayCaster, FewerScalarsThanPointsIsAnError) {
  for (int n : {4, 64}) {
    const std::string why = renderVolume(image(n, 10), [](vtkMatrixTreeVolumeRayCaster*) {});
    const std::string points = std::to_string(n * n * n);
    EXPECT_NE(why.find("The input scalars hold 10 values for " + std::to_string(n) + "x" + std::to_string(n) + "x" +
                       std::to_string(n) + " = " + points + " points"),
              std::string::npos)
        << why;
  }
  EXPECT_EQ(renderVolume(image(4, 64), [](vtkMatrixTreeVolumeRayCaster*) {}), "");
}

TEST(VolumeRayCaster, SampleDistanceIsKeptAndCheckedNotClamped) {
  for (double sd : {0.0, -1.0, 1e-9, std::numeric_limits<double>::quiet_NaN()}) {
    double seconds = 0;
    vtkNew<vtkMatrixTreeVolumeRayCaster> probe;
    probe->SetSampleDistance(sd);
    if (!std::isnan(sd)) {
      EXPECT_EQ(probe->GetSampleDistance(), sd);
    }
    const std::string why =
        renderVolume(image(4, 64), [sd](vtkMatrixTreeVolumeRayCaster* c) { c->SetSampleDistance(sd); }, &seconds);
    EXPECT_NE(why.find("must be finite and > 0, and at least the volume's diagonal"), std::string::npos) << sd << ": "
                                                                                                         << why;
    EXPECT_LT(seconds, 1.0) << sd;
  }
  // 2^20 samples across the diagonal is the limit: just above it renders.
  const double diagonal = std::sqrt(3.0) * 3;
  EXPECT_EQ(renderVolume(image(4, 64),
                         [&](vtkMatrixTreeVolumeRayCaster* c) {
                           c->SetSampleDistance(1.0001 * diagonal / (1 << 20));
                           c->SetImageSize(2, 2);
                         }),
            "");
}

TEST(VolumeRayCaster, NanThresholdsAndOversizedImagesAreErrors) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(renderVolume(image(4, 64), [&](vtkMatrixTreeVolumeRayCaster* c) { c->SetEarlyTerminationThreshold(nan); })
                .find("EarlyTerminationThreshold nan must be in [0, 1]"),
            std::string::npos);
  EXPECT_NE(renderVolume(image(4, 64), [&](vtkMatrixTreeVolumeRayCaster* c) { c->SetScalarOpacityUnitDistance(nan); })
                .find("ScalarOpacityUnitDistance nan must be finite and > 0"),
            std::string::npos);
  EXPECT_NE(renderVolume(image(4, 64), [](vtkMatrixTreeVolumeRayCaster* c) { c->SetImageSize(100000, 8); })
                .find("ImageSize 100000 x 8: each side must be in [1, 16384]"),
            std::string::npos);
}

// Renders a sphere with `set` applied; returns the error message ("" if none).
template <class F>
std::string renderSurface(F&& set) {
  vtkNew<vtkMatrixTreeRayCaster> caster;
  vtkNew<ErrorCatcher> errors;
  caster->AddObserver(vtkCommand::ErrorEvent, errors);
  caster->SetInputData(sphere(1));
  caster->SetImageSize(8, 8);
  set(caster.Get());
  caster->Update();
  return errors->count ? errors->message : "";
}

TEST(RayCaster, OversizedImagesAndCamerasWithoutAViewDirectionAreErrors) {
  EXPECT_NE(renderSurface([](vtkMatrixTreeRayCaster* c) { c->SetImageSize(100000, 100000); })
                .find("ImageSize 100000 x 100000: each side must be in [1, 16384]"),
            std::string::npos);
  EXPECT_NE(renderSurface([](vtkMatrixTreeRayCaster* c) { c->SetImageSize(0, 8); }).find("ImageSize 0 x 8"),
            std::string::npos);
  EXPECT_NE(renderSurface([](vtkMatrixTreeRayCaster* c) {
              c->AutoCameraOff();
              c->SetPosition(1, 2, 3);
              c->SetFocalPoint(1, 2, 3);
            }).find("Position equals its FocalPoint"),
            std::string::npos);
  EXPECT_NE(renderSurface([](vtkMatrixTreeRayCaster* c) {
              c->AutoCameraOff();
              c->SetPosition(std::numeric_limits<double>::quiet_NaN(), 0, 3);
            }).find("must be finite"),
            std::string::npos);
  EXPECT_EQ(renderSurface([](vtkMatrixTreeRayCaster* c) {
              c->AutoCameraOff();
              c->SetPosition(0, 0, 3);
              c->SetFocalPoint(0, 0, 0);
            }),
            "");
}

// A tetrahedron and a line (2,0,0)-(3,0,0) in one grid.
vtkSmartPointer<vtkUnstructuredGrid> tetAndLine() {
  auto g = vtkSmartPointer<vtkUnstructuredGrid>::New();
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToDouble();
  const double xyz[6][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {2, 0, 0}, {3, 0, 0}};
  for (const auto& p : xyz) pts->InsertNextPoint(p);
  g->SetPoints(pts);
  const vtkIdType tet[4] = {0, 1, 2, 3}, line[2] = {4, 5};
  g->InsertNextCell(VTK_TETRA, 4, tet);
  g->InsertNextCell(VTK_LINE, 2, line);
  return g;
}

TEST(Locator, PointsNearALineCellAreInNoCellAsInVtkCellLocator) {
  auto g = tetAndLine();
  vtkNew<vtkMatrixTreeLocator> ours;
  ours->SetDataSet(g);
  ours->BuildLocator();
  vtkNew<vtkCellLocator> ref;
  ref->SetDataSet(g);
  ref->BuildLocator();
  vtkNew<vtkGenericCell> cell;
  double pc[3], w[8];
  for (double d : {0.0, 1e-12, 1e-6, 1e-3, 0.01}) {
    double x[3] = {2.5, d, 0};
    const vtkIdType want = ref->FindCell(x, 0.0, cell, pc, w);
    EXPECT_EQ(want, d == 0 ? 1 : -1) << d;
    EXPECT_EQ(ours->FindCell(x, 0.0, cell, pc, w), want) << d;
  }
  double inside[3] = {0.2, 0.2, 0.2};
  EXPECT_EQ(ours->FindCell(inside, 0.0, cell, pc, w), 0);
}

TEST(Locator, NonFinitePointsHaveNoClosestPoint) {
  vtkNew<vtkMatrixTreeLocator> loc;
  loc->SetDataSet(tetAndLine());
  loc->BuildLocator();
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  vtkNew<vtkGenericCell> cell;
  for (const auto& q : {std::vector<double>{0, inf, 0}, {nan, 0, 0}, {-inf, 1, 1}}) {
    double cp[3] = {7, 7, 7}, d2 = 0;
    vtkIdType id = 5;
    int sub = 0;
    loc->FindClosestPoint(q.data(), cp, cell, id, sub, d2);
    EXPECT_EQ(id, -1);
  }
  double x[3] = {0.2, 0.2, 0.2}, cp[3], d2 = 1;
  vtkIdType id = -1;
  int sub = 0;
  loc->FindClosestPoint(x, cp, cell, id, sub, d2);
  EXPECT_EQ(id, 0);
  EXPECT_EQ(d2, 0.0);

  // The batched FindClosestPoints: the same answers, with its documented NaN point and inf d2.
  vtkNew<vtkPoints> pts;
  pts->InsertNextPoint(0, inf, 0);
  pts->InsertNextPoint(nan, 0, 0);
  pts->InsertNextPoint(-inf, 1, 1);
  pts->InsertNextPoint(x);
  vtkNew<vtkDoubleArray> cps, d2s;
  vtkNew<vtkIdTypeArray> ids;
  loc->FindClosestPoints(pts, cps, ids, d2s);
  ASSERT_EQ(ids->GetNumberOfTuples(), 4);
  for (vtkIdType i = 0; i < 3; ++i) {
    EXPECT_EQ(ids->GetValue(i), -1) << "point " << i;
    EXPECT_TRUE(std::isinf(d2s->GetValue(i))) << "point " << i;
    for (int k = 0; k < 3; ++k) EXPECT_TRUE(std::isnan(cps->GetComponent(i, k))) << "point " << i;
  }
  EXPECT_EQ(ids->GetValue(3), 0);
  EXPECT_EQ(d2s->GetValue(3), 0.0);
}

}  // namespace
