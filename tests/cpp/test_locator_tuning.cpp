// vtkMatrixTreeLocator's alternative implementations (vtkMatrixTreeLocatorTuning, C++ only)
// against each other: the default and the alternative give the same answers.
//   BuildSort             COUNTING and RADIX build the same tree and leaf boxes: the same counts
//                         and memory, the same FindCells (ids, pcoords, weights) and first hits,
//                         with 1 and 2 build threads; the phases name the sort's steps; a change
//                         is a build setting (a rebuild), clamped, copied by CopySettings.
//   RayStepTable          the step-table walk and the mask walk give the same first hits (cell,
//                         t, x, pcoords, subId bit for bit), hit lists and cells along the
//                         segment; a query setting (no rebuild).
//   EngineCellEvaluation  FindCell and FindCells with the engine's copy of VTK 9.1's
//                         EvaluatePosition against the same locator handing every candidate to
//                         VTK: on all seven CFD grids the same cell, pcoords and weights bit for
//                         bit and the generic cell filled as vtkDataSet::GetCell fills it, for
//                         random points and the hard ones (vertices, edge midpoints, face centres,
//                         points moved towards faces and vertices by factors around VTK's
//                         tolerances, NaN); copied and printed.
//   CellStorage           the cell arrays read in place (32- and 64-bit), copied, and the
//                         automatic choice, against the copy path of integer points: the same
//                         tree and answers to every query; in place holds at least the copy's 4
//                         bytes per connectivity entry less.
// And the query statistics (vtkMatrixTreeLocatorQueryStatistics): none in a default build; in a
// build configured with -DMATRIXTREE_QUERY_STATS=ON they agree with what the queries returned.
#include <gtest/gtest.h>

#include <vtkAppendFilter.h>
#include <vtkCell.h>
#include <vtkCellArray.h>
#include <vtkDataArray.h>
#include <vtkDoubleArray.h>
#include <vtkFloatArray.h>
#include <vtkGenericCell.h>
#include <vtkIdList.h>
#include <vtkIdTypeArray.h>
#include <vtkIntArray.h>
#include <vtkNew.h>
#include <vtkPLYReader.h>
#include <vtkPointSet.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>
#include <vtkTriangleFilter.h>
#include <vtkUnstructuredGrid.h>
#ifdef MATRIXTREE_HAVE_EXODUS
#include <vtkCompositeDataIterator.h>
#include <vtkExodusIIReader.h>
#include <vtkMultiBlockDataSet.h>
#endif

#include "vtkMatrixTreeLocator.h"
#include "vtkMatrixTreeLocatorTuning.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "test_util.h"
#include "vtk_grid_util.h"

namespace {

using Tuning = vtkMatrixTreeLocatorTuning;

// ---------------------------------------------------------------------------------------------
// Data and helpers
// ---------------------------------------------------------------------------------------------

/// A CFD grid by its path under the data folder: SU2 and VTU as the other tests read them,
/// Exodus II through vtkExodusIIReader (every element block, merged, as matrixtree.read_grid).
vtkSmartPointer<vtkUnstructuredGrid> readAnyGrid(const std::string& rel) {
#ifdef MATRIXTREE_HAVE_EXODUS
  if (rel.size() > 4 && rel.compare(rel.size() - 4, 4, ".ex2") == 0) {
    vtkNew<vtkExodusIIReader> r;
    r->SetFileName(mtest::dataPath(rel).c_str());
    r->UpdateInformation();
    for (int i = 0; i < r->GetNumberOfObjects(vtkExodusIIReader::ELEM_BLOCK); ++i)
      r->SetObjectStatus(vtkExodusIIReader::ELEM_BLOCK, i, 1);
    r->Update();
    vtkNew<vtkAppendFilter> app;
    app->MergePointsOn();
    vtkSmartPointer<vtkCompositeDataIterator> it = vtkSmartPointer<vtkCompositeDataIterator>::Take(
        vtkMultiBlockDataSet::SafeDownCast(r->GetOutput())->NewIterator());
    for (it->InitTraversal(); !it->IsDoneWithTraversal(); it->GoToNextItem()) app->AddInputData(it->GetCurrentDataObject());
    app->Update();
    auto out = vtkSmartPointer<vtkUnstructuredGrid>::New();
    out->ShallowCopy(app->GetOutput());
    return out;
  }
#endif
  return mtest::readGrid(rel);
}

/// A PLY surface as triangle polydata (matrixtree.read_mesh: vtkTriangleFilter without vertices and lines).
vtkSmartPointer<vtkPolyData> readMesh(const std::string& rel) {
  vtkNew<vtkPLYReader> r;
  r->SetFileName(mtest::dataPath(rel).c_str());
  vtkNew<vtkTriangleFilter> tri;
  tri->SetInputConnection(r->GetOutputPort());
  tri->PassVertsOff();
  tri->PassLinesOff();
  tri->Update();
  auto out = vtkSmartPointer<vtkPolyData>::New();
  out->ShallowCopy(tri->GetOutput());
  return out;
}

vtkSmartPointer<vtkMatrixTreeLocator> makeLocator(vtkDataSet* ds, const Tuning& tuning = Tuning(), int threads = 0,
                                                  int treeType = vtkMatrixTreeLocator::OCTREE) {
  auto loc = vtkSmartPointer<vtkMatrixTreeLocator>::New();
  loc->SetDataSet(ds);
  loc->SetTreeType(treeType);
  loc->SetNumberOfThreads(threads);
  loc->SetTuning(tuning);
  loc->BuildLocator();
  return loc;
}

std::array<double, 6> bounds(vtkDataSet* ds) {
  std::array<double, 6> b;
  ds->GetBounds(b.data());
  return b;
}

/// n points uniform in the data set's bounds grown by `grow` of their extent per side.
std::vector<std::array<double, 3>> randomPoints(vtkDataSet* ds, int n, uint64_t seed, double grow = 0.05) {
  const auto b = bounds(ds);
  mtest::Rng rng(seed);
  std::vector<std::array<double, 3>> out(static_cast<size_t>(n));
  for (auto& p : out)
    for (int a = 0; a < 3; ++a) {
      const double e = b[2 * a + 1] - b[2 * a];
      p[a] = b[2 * a] - grow * e + rng.uniform() * e * (1 + 2 * grow);
    }
  return out;
}

vtkSmartPointer<vtkPoints> asPoints(const std::vector<std::array<double, 3>>& pts) {
  auto p = vtkSmartPointer<vtkPoints>::New();
  p->SetDataTypeToDouble();
  p->SetNumberOfPoints(static_cast<vtkIdType>(pts.size()));
  for (size_t i = 0; i < pts.size(); ++i) p->SetPoint(static_cast<vtkIdType>(i), pts[i].data());
  return p;
}

template <class T>
std::vector<T> values(vtkDataArray* a) {
  std::vector<T> out(static_cast<size_t>(a->GetNumberOfValues()));
  for (size_t i = 0; i < out.size(); ++i) out[i] = static_cast<T>(a->GetVariantValue(static_cast<vtkIdType>(i)).ToDouble());
  return out;
}

std::vector<double> doubles(vtkDoubleArray* a) {
  return std::vector<double>(a->GetPointer(0), a->GetPointer(0) + a->GetNumberOfValues());
}

std::vector<vtkIdType> ids(vtkIdTypeArray* a) {
  return std::vector<vtkIdType>(a->GetPointer(0), a->GetPointer(0) + a->GetNumberOfValues());
}

std::vector<vtkIdType> ids(vtkIdList* l) {
  return std::vector<vtkIdType>(l->GetPointer(0), l->GetPointer(0) + l->GetNumberOfIds());
}

/// The bytes of a double sequence: equal means equal bit for bit.
bool sameBits(const double* a, const double* b, size_t n) { return std::memcmp(a, b, n * sizeof(double)) == 0; }

struct FirstHit {
  int hit = 0;
  double t = 0, x[3] = {0, 0, 0}, pc[3] = {0, 0, 0};
  int sub = 0;
  vtkIdType cell = -1;
  bool operator==(const FirstHit& o) const {
    return hit == o.hit && sameBits(&t, &o.t, 1) && sameBits(x, o.x, 3) && sameBits(pc, o.pc, 3) && sub == o.sub &&
           cell == o.cell;
  }
};

FirstHit firstHit(vtkMatrixTreeLocator* loc, const double p1[3], const double p2[3], double tol, vtkGenericCell* gc) {
  FirstHit h;
  h.hit = loc->IntersectWithLine(p1, p2, tol, h.t, h.x, h.pc, h.sub, h.cell, gc);
  return h;
}

// ---------------------------------------------------------------------------------------------
// BuildSort
// ---------------------------------------------------------------------------------------------

class BuildSorts : public ::testing::TestWithParam<std::string> {};

TEST_P(BuildSorts, GiveTheSameLocator) {
  vtkSmartPointer<vtkUnstructuredGrid> ds = readAnyGrid(GetParam());
  ASSERT_TRUE(ds);
  vtkSmartPointer<vtkPoints> pts = asPoints(randomPoints(ds, 20000, 5));
  const auto b = bounds(ds);
  struct Answers {
    int height;
    vtkIdType leaves, refs, bytes;
    std::vector<vtkIdType> ids;
    std::vector<double> pc, w;
    std::vector<FirstHit> hits;
  };
  std::vector<Answers> all;
  vtkNew<vtkGenericCell> gc;
  for (int sort : {Tuning::RADIX, Tuning::COUNTING}) {
    for (int threads : {1, 2}) {
      Tuning tuning;
      tuning.BuildSort = sort;
      auto loc = makeLocator(ds, tuning, threads);
      const std::string phases = loc->GetBuildPhases();
      EXPECT_EQ(phases.find("refdata") != std::string::npos, sort == Tuning::RADIX) << phases;
      EXPECT_EQ(phases.find("scatter") != std::string::npos, sort == Tuning::COUNTING) << phases;
      vtkNew<vtkIdTypeArray> cellIds;
      vtkNew<vtkDoubleArray> pc, w;
      loc->FindCells(pts, cellIds, pc, w);
      Answers a{loc->GetTreeHeight(), loc->GetNumberOfLeaves(), loc->GetNumberOfReferences(), loc->GetMemorySize(),
                ids(cellIds), doubles(pc), doubles(w), {}};
      for (int i = 0; i < 20; ++i) {
        const double p1[3] = {b[0], b[2], b[4]};
        double p2[3];
        for (int k = 0; k < 3; ++k) p2[k] = b[2 * k + 1] - i * 0.01 * (b[2 * k + 1] - b[2 * k]);
        a.hits.push_back(firstHit(loc, p1, p2, 0.0, gc));
      }
      all.push_back(std::move(a));
    }
  }
  for (size_t k = 1; k < all.size(); ++k) {
    SCOPED_TRACE("build " + std::to_string(k));
    EXPECT_EQ(all[k].height, all[0].height);
    EXPECT_EQ(all[k].leaves, all[0].leaves);
    EXPECT_EQ(all[k].refs, all[0].refs);
    EXPECT_EQ(all[k].bytes, all[0].bytes);
    EXPECT_EQ(all[k].ids, all[0].ids);
    EXPECT_TRUE(all[k].pc.size() == all[0].pc.size() && sameBits(all[k].pc.data(), all[0].pc.data(), all[0].pc.size()));
    EXPECT_TRUE(all[k].w.size() == all[0].w.size() && sameBits(all[k].w.data(), all[0].w.data(), all[0].w.size()));
    EXPECT_TRUE(all[k].hits == all[0].hits);
  }
  EXPECT_GT(std::count_if(all[0].ids.begin(), all[0].ids.end(), [](vtkIdType c) { return c >= 0; }), 1000);
}

INSTANTIATE_TEST_SUITE_P(Grids, BuildSorts,
                         ::testing::Values("cfd/pipe_flow_tets.vtu", "cfd/brick_pyra.su2", "cfd/brick_hex.su2"),
                         [](const auto& info) { return mtest::meshTag(info.param); });

TEST(LocatorTuning, BuildSortIsAClampedCopiedBuildSetting) {
  vtkNew<vtkMatrixTreeLocator> loc;
  EXPECT_EQ(loc->GetTuning().BuildSort, Tuning::COUNTING);
  Tuning t = loc->GetTuning();
  t.BuildSort = Tuning::RADIX;
  loc->SetTuning(t);
  EXPECT_EQ(loc->GetTuning().BuildSort, Tuning::RADIX);
  t.BuildSort = 9;
  loc->SetTuning(t);
  EXPECT_EQ(loc->GetTuning().BuildSort, Tuning::COUNTING) << "clamped";
  vtkNew<vtkMatrixTreeLocator> other;
  t.BuildSort = Tuning::RADIX;
  other->SetTuning(t);
  loc->CopySettings(other);
  EXPECT_EQ(loc->GetTuning().BuildSort, Tuning::RADIX);
  vtkSmartPointer<vtkUnstructuredGrid> ds = readAnyGrid("cfd/brick_hex.su2");
  ASSERT_TRUE(ds);
  loc->SetDataSet(ds);
  loc->BuildLocator();
  const vtkMTimeType t0 = loc->GetBuildTime();
  t.BuildSort = Tuning::COUNTING;
  loc->SetTuning(t);
  loc->BuildLocator();
  EXPECT_GT(loc->GetBuildTime(), t0) << "a build setting: the next build is a rebuild";
}

// ---------------------------------------------------------------------------------------------
// Query statistics
// ---------------------------------------------------------------------------------------------

TEST(LocatorQueryStatistics, CountWhatTheQueriesDid) {
  using Stats = vtkMatrixTreeLocatorQueryStatistics;
  std::vector<std::string> names;
  for (int i = 0; i < Stats::GetNumber(); ++i) names.push_back(Stats::GetName(i));
  EXPECT_EQ(Stats::GetName(-1), nullptr);
  EXPECT_EQ(Stats::GetName(Stats::GetNumber()), nullptr);
  if (!Stats::Enabled()) {
    EXPECT_TRUE(names.empty());
    EXPECT_EQ(Stats::Get(0), 0u);
    return;
  }
  vtkSmartPointer<vtkUnstructuredGrid> ds = readAnyGrid("cfd/brick_tets.su2");
  ASSERT_TRUE(ds);
  auto loc = makeLocator(ds);
  Stats::Reset();
  vtkNew<vtkGenericCell> gc;
  double pc[3], w[8];
  const auto pts = randomPoints(ds, 2000, 5, 0.2);
  long found = 0;
  for (auto p : pts) found += loc->FindCell(p.data(), 0.0, gc, pc, w) >= 0 ? 1 : 0;
  mtest::Rng rng(6);
  long hits = 0;
  for (int i = 0; i < 500; ++i) {
    const std::array<double, 3>& a = pts[static_cast<size_t>(i)];
    double b[3];
    for (int k = 0; k < 3; ++k) b[k] = pts[static_cast<size_t>(500 + i)][k] + rng.uniform(-1, 1);
    hits += firstHit(loc, a.data(), b, 0.0, gc).hit;
  }
  std::map<std::string, uint64_t> s;
  for (int i = 0; i < Stats::GetNumber(); ++i) s[names[static_cast<size_t>(i)]] = Stats::Get(i);
  EXPECT_EQ(s["findcell_queries"], pts.size());
  EXPECT_EQ(s["findcell_found"], static_cast<uint64_t>(found));
  EXPECT_GT(found, 0);
  EXPECT_LE(s["findcell_found"], s["findcell_evaluations"]);
  EXPECT_LE(s["findcell_evaluations"], s["findcell_box_passes"]);
  EXPECT_LE(s["findcell_box_passes"], s["findcell_references"]);
  EXPECT_LE(s["findcell_leaf_scans"], s["findcell_queries"]);
  EXPECT_EQ(s["ray_queries"], 500u);
  EXPECT_EQ(s["ray_hits"], static_cast<uint64_t>(hits));
  EXPECT_GT(hits, 0);
  EXPECT_LE(s["ray_leaves"], s["ray_steps"]);
  EXPECT_LE(s["ray_steps"], s["ray_node_visits"]);
  EXPECT_LE(s["ray_candidates"], s["ray_references"]);
  EXPECT_LE(s["ray_proved_misses"] + s["ray_certain_hits"] + s["ray_mailbox_repeats"], s["ray_cell_tests"]);
  Stats::Reset();
  for (int i = 0; i < Stats::GetNumber(); ++i) EXPECT_EQ(Stats::Get(i), 0u) << names[static_cast<size_t>(i)];
}

// ---------------------------------------------------------------------------------------------
// RayStepTable
// ---------------------------------------------------------------------------------------------

struct MeshCase {
  std::string mesh;
  int treeType;
};

class StepTable : public ::testing::TestWithParam<MeshCase> {};

TEST_P(StepTable, WalkGivesTheSameAnswers) {
  vtkSmartPointer<vtkPolyData> mesh = readMesh(GetParam().mesh);
  ASSERT_GT(mesh->GetNumberOfPolys(), 0);
  auto loc = makeLocator(mesh, Tuning(), 0, GetParam().treeType);
  EXPECT_TRUE(loc->GetTuning().RayStepTable) << "on by default";
  const vtkMTimeType built = loc->GetBuildTime();
  const auto b = bounds(mesh);
  const double diag = std::sqrt((b[1] - b[0]) * (b[1] - b[0]) + (b[3] - b[2]) * (b[3] - b[2]) + (b[5] - b[4]) * (b[5] - b[4]));
  mtest::Rng rng(11);
  vtkNew<vtkGenericCell> gc;
  int hits = 0;
  for (int i = 0; i < 3000; ++i) {
    double p1[3], p2[3];
    for (int a = 0; a < 3; ++a) p1[a] = b[2 * a] + rng.uniform() * (b[2 * a + 1] - b[2 * a]);
    mtree::Vec3 u = rng.direction();
    if (i % 5 == 0) {
      double v[3] = {u.x, u.y, u.z};
      v[rng.below(3)] = 0.0;  // parallel to an axis plane
      u = mtree::normalized(mtree::Vec3(v[0], v[1], v[2]));
    }
    for (int a = 0; a < 3; ++a) p2[a] = p1[a] + u[a] * 0.4 * diag;
    struct Res {
      FirstHit first;
      int n = 0;
      std::vector<double> points;
      std::vector<vtkIdType> hitIds, along;
    } res[2];
    for (int on = 1; on >= 0; --on) {
      Tuning t = loc->GetTuning();
      t.RayStepTable = on != 0;
      loc->SetTuning(t);
      Res& r = res[1 - on];
      r.first = firstHit(loc, p1, p2, 0.0, gc);
      if (i % 10 == 0) {
        vtkNew<vtkPoints> pts;
        vtkNew<vtkIdList> hitIds, along;
        r.n = loc->IntersectWithLine(p1, p2, pts, hitIds);
        for (vtkIdType k = 0; k < pts->GetNumberOfPoints(); ++k)
          for (int a = 0; a < 3; ++a) r.points.push_back(pts->GetPoint(k)[a]);
        r.hitIds = ids(hitIds);
        loc->FindCellsAlongLine(p1, p2, 0.0, along);
        r.along = ids(along);
      }
    }
    ASSERT_TRUE(res[0].first == res[1].first) << "segment " << i << ": table cell " << res[0].first.cell << ", masks "
                                              << res[1].first.cell;
    ASSERT_EQ(res[0].n, res[1].n) << "segment " << i;
    ASSERT_TRUE(res[0].points.size() == res[1].points.size() &&
                sameBits(res[0].points.data(), res[1].points.data(), res[0].points.size()))
        << "segment " << i;
    ASSERT_EQ(res[0].hitIds, res[1].hitIds) << "segment " << i;
    ASSERT_EQ(res[0].along, res[1].along) << "segment " << i;
    hits += res[0].first.hit;
  }
  EXPECT_GT(hits, 300);
  EXPECT_EQ(loc->GetBuildTime(), built) << "a query setting: no rebuild";
}

INSTANTIATE_TEST_SUITE_P(Meshes, StepTable,
                         ::testing::Values(MeshCase{"meshes/bunny.ply", vtkMatrixTreeLocator::OCTREE},
                                           MeshCase{"meshes/lucy.ply", vtkMatrixTreeLocator::OCTREE},
                                           MeshCase{"meshes/horse.ply", vtkMatrixTreeLocator::KDTREE}),
                         [](const auto& info) {
                           return mtest::meshTag(info.param.mesh) + (info.param.treeType ? "_kdtree" : "_octree");
                         });

// ---------------------------------------------------------------------------------------------
// EngineCellEvaluation
// ---------------------------------------------------------------------------------------------

/// Points where the answer is delicate: grid vertices, cell centres, edge midpoints, face centres,
/// and points moved from a cell's centre towards (and past) a vertex or a face centre by factors
/// around VTK's tolerances; plus random points in the grid's box grown by 10%.
std::vector<std::array<double, 3>> hardPoints(vtkDataSet* ds, int nCells, uint64_t seed) {
  mtest::Rng rng(seed);
  std::vector<std::array<double, 3>> out;
  const double factors[] = {0.5, 0.999, 0.999999, 1.0, 1.000001, 1.0005, 1.001, 1.0015, 1.01, 1.3};
  auto point = [&](vtkIdType i) {
    std::array<double, 3> p;
    ds->GetPoint(i, p.data());
    return p;
  };
  for (int i = 0; i < nCells; ++i) out.push_back(point(rng.below(static_cast<uint32_t>(ds->GetNumberOfPoints()))));
  auto toward = [&](const std::array<double, 3>& c, const std::array<double, 3>& q) {
    for (double f : factors) out.push_back({c[0] + f * (q[0] - c[0]), c[1] + f * (q[1] - c[1]), c[2] + f * (q[2] - c[2])});
  };
  auto mean = [&](vtkIdList* idl) {
    std::array<double, 3> m = {0, 0, 0};
    for (vtkIdType k = 0; k < idl->GetNumberOfIds(); ++k) {
      const auto p = point(idl->GetId(k));
      for (int a = 0; a < 3; ++a) m[a] += p[a] / idl->GetNumberOfIds();
    }
    return m;
  };
  vtkNew<vtkGenericCell> cell;
  for (int i = 0; i < nCells; ++i) {
    ds->GetCell(rng.below(static_cast<uint32_t>(ds->GetNumberOfCells())), cell);
    const auto centre = mean(cell->GetPointIds());
    out.push_back(centre);
    const auto p0 = point(cell->GetPointId(0)), p1 = point(cell->GetPointId(1));
    out.push_back({0.5 * (p0[0] + p1[0]), 0.5 * (p0[1] + p1[1]), 0.5 * (p0[2] + p1[2])});
    for (int f = 0; f < cell->GetNumberOfFaces(); ++f) toward(centre, mean(cell->GetFace(f)->GetPointIds()));
    toward(centre, point(cell->GetPointId(static_cast<int>(rng.below(static_cast<uint32_t>(cell->GetNumberOfPoints()))))));
  }
  const auto grown = randomPoints(ds, 20 * nCells, seed + 1, 0.1);
  out.insert(out.end(), grown.begin(), grown.end());
  return out;
}

class EngineCellEvaluation : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
#ifndef MATRIXTREE_HAVE_EXODUS
    if (GetParam().size() > 4 && GetParam().compare(GetParam().size() - 4, 4, ".ex2") == 0)
      GTEST_SKIP() << "VTK's Exodus reader is not available to this build";
#endif
    ds_ = readAnyGrid(GetParam());
    ASSERT_TRUE(ds_) << GetParam();
  }
  vtkSmartPointer<vtkUnstructuredGrid> ds_;
};

TEST_P(EngineCellEvaluation, FindCellEqualsVtkEvaluation) {
  vtkUnstructuredGrid* ds = ds_;
  auto loc = makeLocator(ds);
  vtkNew<vtkGenericCell> gcEngine, gcVtk, ref;
  const std::string name = GetParam();
  const auto points = hardPoints(ds, 300, mtest::seedFor(name));
  Tuning engine, vtk;
  vtk.EngineCellEvaluation = false;
  size_t found = 0;
  for (auto x : points) {
    double pcE[3] = {0, 0, 0}, wE[8] = {0}, pcV[3] = {0, 0, 0}, wV[8] = {0};
    loc->SetTuning(engine);
    const vtkIdType a = loc->FindCell(x.data(), 0.0, gcEngine, pcE, wE);
    loc->SetTuning(vtk);
    const vtkIdType b = loc->FindCell(x.data(), 0.0, gcVtk, pcV, wV);
    ASSERT_EQ(a, b) << name << ": x = " << x[0] << " " << x[1] << " " << x[2];
    if (a < 0) continue;
    ++found;
    const vtkIdType n = gcVtk->GetNumberOfPoints();
    ASSERT_TRUE(sameBits(pcE, pcV, 3)) << name << ": pcoords differ at cell " << a;
    ASSERT_TRUE(sameBits(wE, wV, static_cast<size_t>(n))) << name << ": weights differ at cell " << a;
    // The cell handed back is the found cell as GetCell gives it (callers read its point ids).
    ds->GetCell(a, ref);
    ASSERT_EQ(gcEngine->GetCellType(), ref->GetCellType());
    ASSERT_EQ(gcEngine->GetNumberOfPoints(), n);
    for (vtkIdType k = 0; k < n; ++k) {
      ASSERT_EQ(gcEngine->GetPointId(static_cast<int>(k)), ref->GetPointId(static_cast<int>(k)));
      ASSERT_TRUE(sameBits(gcEngine->GetPoints()->GetPoint(k), ref->GetPoints()->GetPoint(k), 3));
    }
  }
  EXPECT_GT(found, points.size() / 4);
  // NaN and infinite coordinates: no cell, no crash, either way.
  const double inf = std::numeric_limits<double>::infinity();
  for (std::array<double, 3> x : {std::array<double, 3>{std::nan(""), 0.0, 0.0}, std::array<double, 3>{inf, inf, inf}}) {
    for (const Tuning& t : {engine, vtk}) {
      loc->SetTuning(t);
      double pc[3], w[8];
      EXPECT_EQ(loc->FindCell(x.data(), 0.0, gcEngine, pc, w), -1);
    }
  }
}

TEST_P(EngineCellEvaluation, FindCellsEqualsVtkEvaluation) {
  // The batched FindCells (OpenMP, every thread with its own cell) gives the same arrays.
  vtkSmartPointer<vtkPoints> pts = asPoints(hardPoints(ds_, 2000, 7));
  std::vector<vtkIdType> cellIds[2];
  std::vector<double> pc[2], w[2];
  for (int engine = 0; engine < 2; ++engine) {
    Tuning t;
    t.EngineCellEvaluation = engine != 0;
    auto loc = makeLocator(ds_, t);
    vtkNew<vtkIdTypeArray> c;
    vtkNew<vtkDoubleArray> p, ww;
    loc->FindCells(pts, c, p, ww);
    cellIds[engine] = ids(c);
    pc[engine] = doubles(p);
    w[engine] = doubles(ww);
  }
  EXPECT_EQ(cellIds[0], cellIds[1]);
  ASSERT_EQ(pc[0].size(), pc[1].size());
  EXPECT_TRUE(sameBits(pc[0].data(), pc[1].data(), pc[0].size()));
  ASSERT_EQ(w[0].size(), w[1].size());
  EXPECT_TRUE(sameBits(w[0].data(), w[1].data(), w[0].size()));
  EXPECT_GT(std::count_if(cellIds[1].begin(), cellIds[1].end(), [](vtkIdType c) { return c >= 0; }),
            pts->GetNumberOfPoints() / 4);
}

INSTANTIATE_TEST_SUITE_P(Grids, EngineCellEvaluation,
                         ::testing::Values("cfd/pipe_flow_tets.vtu", "cfd/pipe_lumen_tets.vtu", "cfd/brick_tets.su2",
                                           "cfd/brick_pyra.su2", "cfd/brick_prism.su2", "cfd/brick_hex.su2",
                                           "cfd/disk_out_ref.ex2"),
                         [](const auto& info) { return mtest::meshTag(info.param); });

TEST(LocatorTuning, TuningIsCopiedAndPrinted) {
  vtkNew<vtkMatrixTreeLocator> a, b;
  EXPECT_TRUE(a->GetTuning().EngineCellEvaluation);
  Tuning t;
  t.EngineCellEvaluation = false;
  a->SetTuning(t);
  b->CopySettings(a);
  EXPECT_FALSE(b->GetTuning().EngineCellEvaluation);
  std::ostringstream os;
  b->Print(os);
  EXPECT_NE(os.str().find("EngineCellEvaluation: Off"), std::string::npos) << os.str();
}

// ---------------------------------------------------------------------------------------------
// CellStorage
// ---------------------------------------------------------------------------------------------

/// The bunny's first 20000 triangles, every third grown into a quad (the point mirrored across
/// edge b-c) and every seventh other into a pentagon slightly off its plane: triangles, quads and
/// polygons in one polygon-only polydata with float points.
vtkSmartPointer<vtkPolyData> mixedPolygons() {
  vtkSmartPointer<vtkPolyData> mesh = readMesh("meshes/bunny.ply");
  vtkNew<vtkFloatArray> xyz;
  xyz->SetNumberOfComponents(3);
  for (vtkIdType i = 0; i < mesh->GetNumberOfPoints(); ++i) {
    double p[3];
    mesh->GetPoint(i, p);
    xyz->InsertNextTuple(p);
  }
  auto point = [&](vtkIdType i) {
    std::array<double, 3> p;
    mesh->GetPoint(i, p.data());
    return p;
  };
  vtkNew<vtkCellArray> polys;
  vtkIdType next = mesh->GetNumberOfPoints();
  vtkNew<vtkIdList> tri;
  for (vtkIdType t = 0; t < std::min<vtkIdType>(20000, mesh->GetNumberOfCells()); ++t) {
    mesh->GetCellPoints(t, tri);
    const vtkIdType a = tri->GetId(0), b = tri->GetId(1), c = tri->GetId(2);
    const auto pa = point(a), pb = point(b), pc = point(c);
    if (t % 3 == 0) {
      const double m[3] = {pb[0] + pc[0] - pa[0], pb[1] + pc[1] - pa[1], pb[2] + pc[2] - pa[2]};
      xyz->InsertNextTuple(m);
      const vtkIdType q[4] = {a, b, next++, c};
      polys->InsertNextCell(4, q);
    } else if (t % 7 == 0) {
      double centre[3], e1[3], e2[3];
      for (int k = 0; k < 3; ++k) {
        centre[k] = (pa[k] + pb[k] + pc[k]) / 3;
        e1[k] = pb[k] + 0.3 * (pb[k] - centre[k]);
        e2[k] = pc[k] + 0.3 * (pc[k] - centre[k]) + 1e-4;
      }
      xyz->InsertNextTuple(e1);
      xyz->InsertNextTuple(e2);
      const vtkIdType q[5] = {a, b, next, next + 1, c};
      next += 2;
      polys->InsertNextCell(5, q);
    } else {
      const vtkIdType q[3] = {a, b, c};
      polys->InsertNextCell(3, q);
    }
  }
  auto out = vtkSmartPointer<vtkPolyData>::New();
  vtkNew<vtkPoints> p;
  p->SetData(xyz);
  out->SetPoints(p);
  out->SetPolys(polys);
  return out;
}

vtkSmartPointer<vtkUnstructuredGrid> asGrid(vtkPolyData* pd) {
  vtkNew<vtkAppendFilter> app;
  app->AddInputData(pd);
  app->Update();
  auto out = vtkSmartPointer<vtkUnstructuredGrid>::New();
  out->ShallowCopy(app->GetOutput());
  return out;
}

vtkCellArray* cellArray(vtkDataSet* ds) {
  if (auto* ug = vtkUnstructuredGrid::SafeDownCast(ds)) return ug->GetCells();
  return vtkPolyData::SafeDownCast(ds)->GetPolys();
}

/// A copy of ds with its cell arrays in 32- or 64-bit storage and its points as int32 (read
/// through a copy by the locator) or float64 (read in place, as the cell arrays); ds's
/// coordinates must be integers.
vtkSmartPointer<vtkDataSet> sameCells(vtkDataSet* ds, int bits, bool intPoints) {
  vtkSmartPointer<vtkDataSet> out = vtkSmartPointer<vtkDataSet>::Take(ds->NewInstance());
  out->DeepCopy(ds);
  vtkCellArray* ca = cellArray(out);
  if (bits == 32) {
    ca->ConvertTo32BitStorage();
  } else {
    ca->ConvertTo64BitStorage();
  }
  EXPECT_EQ(ca->IsStorage64Bit(), bits == 64);
  vtkSmartPointer<vtkDataArray> xyz;
  if (intPoints) {
    xyz = vtkSmartPointer<vtkIntArray>::New();
  } else {
    xyz = vtkSmartPointer<vtkDoubleArray>::New();
  }
  xyz->SetNumberOfComponents(3);
  xyz->SetNumberOfTuples(ds->GetNumberOfPoints());
  for (vtkIdType i = 0; i < ds->GetNumberOfPoints(); ++i) xyz->SetTuple(i, ds->GetPoint(i));
  vtkNew<vtkPoints> p;
  p->SetData(xyz);
  vtkPointSet::SafeDownCast(out)->SetPoints(p);
  return out;
}

/// Grids with integer coordinates: brick_hex in units of 1e-3 (hexahedra only), the mixed
/// polygons scaled by 1e4 as polydata and as an unstructured grid.
std::vector<vtkSmartPointer<vtkDataSet>> integerGrids() {
  std::vector<vtkSmartPointer<vtkDataSet>> out;
  const std::pair<vtkSmartPointer<vtkDataSet>, double> sources[] = {{readAnyGrid("cfd/brick_hex.su2"), 1000.0},
                                                                   {mixedPolygons(), 1e4}};
  for (const auto& src : sources) {
    vtkSmartPointer<vtkDataSet> g = vtkSmartPointer<vtkDataSet>::Take(src.first->NewInstance());
    g->DeepCopy(src.first);
    vtkNew<vtkDoubleArray> xyz;
    xyz->SetNumberOfComponents(3);
    xyz->SetNumberOfTuples(g->GetNumberOfPoints());
    for (vtkIdType i = 0; i < g->GetNumberOfPoints(); ++i) {
      double p[3];
      src.first->GetPoint(i, p);
      for (double& v : p) v = std::nearbyint(v * src.second);
      xyz->SetTuple(i, p);
    }
    vtkNew<vtkPoints> p;
    p->SetData(xyz);
    vtkPointSet::SafeDownCast(g)->SetPoints(p);
    out.push_back(g);
  }
  out.push_back(asGrid(vtkPolyData::SafeDownCast(out[1])));
  return out;
}

/// FindCells, IntersectSegments (tolerance 0 and > 0), FindClosestPoint and FindCellsWithinBounds
/// of loc on seeded probes of ds, every answer as doubles.
std::vector<std::vector<double>> answers(vtkMatrixTreeLocator* loc, vtkDataSet* ds, uint64_t seed) {
  std::vector<std::array<double, 3>> x = randomPoints(ds, 3000, seed, 0.0);
  vtkNew<vtkGenericCell> gc;
  for (vtkIdType c = 0; c < ds->GetNumberOfCells(); c += 13) {
    ds->GetCell(c, gc);
    std::array<double, 3> m = {0, 0, 0};
    for (vtkIdType k = 0; k < gc->GetNumberOfPoints(); ++k)
      for (int a = 0; a < 3; ++a) m[a] += gc->GetPoints()->GetPoint(k)[a] / gc->GetNumberOfPoints();
    x.push_back(m);
  }
  const auto b = bounds(ds);
  const double diag = std::sqrt((b[1] - b[0]) * (b[1] - b[0]) + (b[3] - b[2]) * (b[3] - b[2]) + (b[5] - b[4]) * (b[5] - b[4]));
  std::vector<std::vector<double>> out;
  vtkNew<vtkIdTypeArray> cellIds;
  vtkNew<vtkDoubleArray> pc, w;
  loc->FindCells(asPoints(x), cellIds, pc, w);
  out.push_back(values<double>(cellIds));
  out.push_back(doubles(pc));
  out.push_back(doubles(w));
  mtest::Rng rng(seed + 1);
  vtkNew<vtkDoubleArray> a1, a2;
  a1->SetNumberOfComponents(3);
  a2->SetNumberOfComponents(3);
  for (size_t i = 0; i < 1500; ++i) {
    const mtree::Vec3 u = rng.direction();
    const double q[3] = {x[i][0] + 0.2 * diag * u.x, x[i][1] + 0.2 * diag * u.y, x[i][2] + 0.2 * diag * u.z};
    a1->InsertNextTuple(x[i].data());
    a2->InsertNextTuple(q);
  }
  for (double tol : {0.0, 1e-3 * diag}) {
    vtkNew<vtkDoubleArray> t;
    vtkNew<vtkIdTypeArray> c;
    loc->IntersectSegments(a1, a2, tol, t, c);
    out.push_back(doubles(t));
    out.push_back(values<double>(c));
  }
  for (size_t i = 0; i < 200; ++i) {
    double cp[3], d2;
    vtkIdType cid;
    int sub;
    loc->FindClosestPoint(x[i].data(), cp, gc, cid, sub, d2);
    out.push_back({cp[0], cp[1], cp[2], static_cast<double>(cid), d2});
    vtkNew<vtkIdList> lst;
    const double r = 0.03 * diag;
    double bb[6] = {x[i][0] - r, x[i][0] + r, x[i][1] - r, x[i][1] + r, x[i][2] - r, x[i][2] + r};
    loc->FindCellsWithinBounds(bb, lst);
    const auto l = ids(lst);
    out.emplace_back(l.begin(), l.end());
  }
  return out;
}

class CellStorage : public ::testing::TestWithParam<int> {};

TEST_P(CellStorage, ArraysReadInPlaceGiveTheCopyPathsAnswers) {
  const int which = GetParam();
  vtkSmartPointer<vtkDataSet> ds = integerGrids()[static_cast<size_t>(which)];
  vtkSmartPointer<vtkDataSet> refDs = sameCells(ds, 64, true);
  auto ref = makeLocator(refDs, Tuning(), 1);
  const auto refAnswers = answers(ref, refDs, static_cast<uint64_t>(which));
  vtkIdType inPlaceBytes = -1;
  const std::pair<int, int> cases[] = {{32, Tuning::CELLS_IN_PLACE},
                                       {64, Tuning::CELLS_IN_PLACE},
                                       {64, Tuning::CELLS_COPIED},
                                       {64, Tuning::CELLS_AUTOMATIC}};
  for (const auto& c : cases) {
    SCOPED_TRACE(std::to_string(c.first) + "-bit, storage " + std::to_string(c.second));
    vtkSmartPointer<vtkDataSet> v = sameCells(ds, c.first, false);
    Tuning t;
    t.CellStorage = c.second;
    auto loc = makeLocator(v, t, 1);
    EXPECT_EQ(loc->GetTreeHeight(), ref->GetTreeHeight());
    EXPECT_EQ(loc->GetNumberOfLeaves(), ref->GetNumberOfLeaves());
    EXPECT_EQ(loc->GetNumberOfReferences(), ref->GetNumberOfReferences());
    vtkCellArray* conn = cellArray(v);
    const vtkIdType nids = conn->GetNumberOfConnectivityIds();
    // Automatic: in place where the cells average more than 5 points (brick_hex), else copied.
    const bool inPlace = c.second == Tuning::CELLS_IN_PLACE ||
                         (c.second == Tuning::CELLS_AUTOMATIC && nids > 5 * conn->GetNumberOfCells());
    if (c.second == Tuning::CELLS_AUTOMATIC) {
      EXPECT_EQ(inPlace, which == 0);
    }
    if (inPlace) {
      EXPECT_LE(loc->GetMemorySize(), ref->GetMemorySize() - 4 * nids);
      inPlaceBytes = loc->GetMemorySize();
    } else {  // the copy of the ids, not of the points
      ASSERT_GE(inPlaceBytes, 0);
      EXPECT_LE(inPlaceBytes + 4 * nids, loc->GetMemorySize());
      EXPECT_LT(loc->GetMemorySize(), ref->GetMemorySize());
    }
    const auto got = answers(loc, v, static_cast<uint64_t>(which));
    ASSERT_EQ(got.size(), refAnswers.size());
    for (size_t k = 0; k < got.size(); ++k) {
      ASSERT_EQ(got[k].size(), refAnswers[k].size()) << "answer " << k;
      ASSERT_TRUE(sameBits(got[k].data(), refAnswers[k].data(), got[k].size())) << "answer " << k;
    }
  }
}

std::string integerGridName(const ::testing::TestParamInfo<int>& info) {
  static const char* const names[] = {"brick_hex_mm", "mixed_polygons", "mixed_polygons_grid"};
  return names[info.param];
}

INSTANTIATE_TEST_SUITE_P(Grids, CellStorage, ::testing::Values(0, 1, 2), integerGridName);

}  // namespace
