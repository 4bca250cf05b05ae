// Concurrent use of built trees, the cases the thread-safety notes promise (vtkMatrixTreeLocator.h:
// "after the locator is built, FindCell(x, tol2, cell, ...) ... may be called concurrently"; the
// engine's trees are read-only once built): 4 std::threads querying one tree at once, and the
// OpenMP-parallel batch queries and renders, each against the serial answers. In the normal build
// these check the answers; scripts/sanitize.sh tsan runs them under ThreadSanitizer (with LLVM's
// OpenMP runtime and its Archer tool, which tell TSan about OpenMP's synchronisation), where any
// data race in the queries or in the parallel build, render and batch loops is a report.
#include <gtest/gtest.h>

#include <vtkDataSetTriangleFilter.h>
#include <vtkDoubleArray.h>
#include <vtkGenericCell.h>
#include <vtkIdTypeArray.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkImageData.h>
#include <vtkUnstructuredGrid.h>

#include "vtkMatrixTreeLocator.h"

#include <thread>
#include <vector>

#include "mtree/core/builder.h"
#include "mtree/rays/raycast.h"
#include "mtree/volume/volume.h"
#include "test_util.h"

namespace {

constexpr int kThreads = 4;

// Runs f(t) on kThreads std::threads at once.
template <class F>
void onThreads(F&& f) {
  std::vector<std::thread> pool;
  for (int t = 0; t < kThreads; ++t) pool.emplace_back([&f, t] { f(t); });
  for (auto& th : pool) th.join();
}

TEST(Concurrency, RayQueriesFromThreadsEqualSerial) {
  const mtree::TriangleMesh mesh = mtest::makeIcosphere(4);
  for (mtree::TreeKind kind : {mtree::TreeKind::Octree, mtree::TreeKind::RegularKd}) {
    const mtree::MatrixTree tree = mtest::buildTree(mesh, mtest::options(kind, 0, 8, 2));  // a 2-thread build
    const std::vector<mtest::Ray> rays = mtest::aimedRays(mesh, 400, 17);
    std::vector<mtree::RayHit> serial(rays.size());
    for (size_t i = 0; i < rays.size(); ++i)
      mtree::intersectFirst(tree, mesh, rays[i].o, rays[i].d, rays[i].tmin, rays[i].tmax, serial[i]);
    std::vector<std::vector<mtree::RayHit>> got(kThreads, std::vector<mtree::RayHit>(rays.size()));
    onThreads([&](int t) {
      for (size_t i = 0; i < rays.size(); ++i)  // every thread all rays: the most overlap
        mtree::intersectFirst(tree, mesh, rays[i].o, rays[i].d, rays[i].tmin, rays[i].tmax, got[t][i]);
    });
    for (int t = 0; t < kThreads; ++t)
      for (size_t i = 0; i < rays.size(); ++i) {
        ASSERT_EQ(got[t][i].prim, serial[i].prim) << "thread " << t << " ray " << i;
        ASSERT_EQ(got[t][i].t, serial[i].t) << "thread " << t << " ray " << i;
      }
  }
}

vtkSmartPointer<vtkUnstructuredGrid> tetGrid() {
  vtkNew<vtkImageData> image;  // 8^3 voxels over [-10, 10]^3, each split into tetrahedra
  image->SetDimensions(9, 9, 9);
  image->SetOrigin(-10, -10, -10);
  image->SetSpacing(2.5, 2.5, 2.5);
  vtkNew<vtkDataSetTriangleFilter> tets;
  tets->SetInputData(image);
  tets->Update();
  return tets->GetOutput();
}

TEST(Concurrency, LocatorFindCellFromThreadsAndFindCellsEqualSerial) {
  auto grid = tetGrid();
  vtkNew<vtkMatrixTreeLocator> loc;
  loc->SetDataSet(grid);
  loc->SetNumberOfThreads(2);
  loc->BuildLocator();
  mtest::Rng rng(5);
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToDouble();
  for (int i = 0; i < 2000; ++i) {
    double x[3];
    for (double& c : x) c = rng.uniform(-11, 11);
    pts->InsertNextPoint(x);
  }
  std::vector<vtkIdType> serial(2000);
  {
    vtkNew<vtkGenericCell> cell;
    double pc[3], w[8];
    for (vtkIdType i = 0; i < 2000; ++i) serial[i] = loc->FindCell(pts->GetPoint(i), 0.0, cell, pc, w);
  }
  std::vector<std::vector<vtkIdType>> got(kThreads, std::vector<vtkIdType>(2000));
  onThreads([&](int t) {
    vtkNew<vtkGenericCell> cell;  // one per thread, as the thread-safety note asks
    double pc[3], w[8], x[3];
    for (vtkIdType i = 0; i < 2000; ++i) {
      pts->GetData()->GetTuple(i, x);
      got[t][i] = loc->FindCell(x, 0.0, cell, pc, w);
    }
  });
  for (int t = 0; t < kThreads; ++t) EXPECT_EQ(got[t], serial) << "thread " << t;
  vtkNew<vtkIdTypeArray> ids;
  vtkNew<vtkDoubleArray> weights;
  loc->SetNumberOfThreads(kThreads);
  loc->FindCells(pts, ids, nullptr, weights);
  ASSERT_EQ(ids->GetNumberOfTuples(), 2000);
  for (vtkIdType i = 0; i < 2000; ++i) EXPECT_EQ(ids->GetValue(i), serial[i]) << i;
  int found = 0;
  for (vtkIdType id : serial) found += id >= 0;
  EXPECT_GT(found, 500);
}

TEST(Concurrency, VolumeBuildAndRenderWithThreadsEqualOneThread) {
  const int dims[3] = {21, 18, 13};
  std::vector<float> v(size_t(dims[0]) * dims[1] * dims[2]);
  for (size_t i = 0; i < v.size(); ++i) v[i] = float((i * 7919) % 251);
  std::vector<float> rgba(4 * 16);
  for (int i = 0; i < 16; ++i) {
    rgba[4 * i] = rgba[4 * i + 1] = rgba[4 * i + 2] = 1.f;
    rgba[4 * i + 3] = i < 10 ? 0.f : 0.3f;  // most cells invisible: skipping matters
  }
  const mtree::TransferTable tf(0, 250, rgba, 1.0);
  mtree::VolumeCamera cam;
  cam.position = mtree::Vec3(40, -30, 25);
  cam.focalPoint = mtree::Vec3(10, 9, 6);
  cam.viewUp = mtree::Vec3(0, 0, 1);
  cam.width = 64;
  cam.height = 48;
  std::vector<float> images[2];
  for (int k = 0; k < 2; ++k) {
    mtree::VolumeBuildOptions bo;
    bo.threads = k == 0 ? 1 : kThreads;
    mtree::BlockSparseVolume vol;
    vol.build(v.data(), dims, tf, bo);
    mtree::VolumeRenderOptions ro;
    ro.sampleDistance = 0.5;
    ro.shade = true;
    ro.threads = bo.threads;
    images[k] = mtree::renderVolume(vol, mtree::VolumeGeometry(), tf, cam, ro).rgba;
  }
  ASSERT_EQ(images[0].size(), images[1].size());
  EXPECT_TRUE(images[0] == images[1]);
  float alpha = 0;
  for (size_t i = 3; i < images[0].size(); i += 4) alpha += images[0][i];
  EXPECT_GT(alpha, 1.f);
}

}  // namespace
