// vtkMatrixTree's tree kinds (TreeType: the matrix octree and kd-tree, the implicit general
// kd-tree and BSP tree of §4, the hybrid of §7) through the VTK classes, on the Utah hand (quads
// and triangles: the cell ids go through the triangulation):
//   IntersectRays      every kind gives the brute force's first hit (cell and t) for rays aimed
//                      at the mesh, with node visits and triangle tests counted.
//   Tuning             vtkMatrixTreeTuning's SplitTraversal (RESTART, STACK, BACKTRACK) gives
//                      the same hits bit for bit, in IntersectRays and in the ray caster's image;
//                      a query setting (no rebuild), clamped, printed.
//   Ray caster         every kind renders the octree's depth image (same hit pixels, the same
//                      depth to round-off).
//   FindLeaves         a point on a triangle lies in an existing leaf of the split trees; a point
//                      outside the root box in none.
//   Statistics         nodes, bytes, and the pointer-tree bytes of the split trees.
//   Bad settings       the hybrid on the OpenCL backend fails with an error saying so.
#include <gtest/gtest.h>

#include <vtkDoubleArray.h>
#include <vtkIdTypeArray.h>
#include <vtkImageData.h>
#include <vtkIntArray.h>
#include <vtkNew.h>
#include <vtkOBJReader.h>
#include <vtkPointData.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>

#include <cmath>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "test_util.h"
#include "vtkMatrixTree.h"
#include "vtkMatrixTreeInternals.h"
#include "vtkMatrixTreeRayCaster.h"
#include "vtkMatrixTreeTuning.h"
#include "vtk_test_util.h"

namespace {

using mtest::Ray;

const int kKinds[] = {vtkMatrixTree::OCTREE, vtkMatrixTree::KDTREE, vtkMatrixTree::IMPLICIT_KDTREE,
                      vtkMatrixTree::BSP_TREE, vtkMatrixTree::HYBRID};

vtkSmartPointer<vtkPolyData> hand() {
  vtkNew<vtkOBJReader> reader;
  reader->SetFileName(mtest::dataPath("scenes/utah_hand/hand_00.obj").c_str());
  reader->Update();
  return reader->GetOutput();
}

vtkSmartPointer<vtkMatrixTree> treeOf(vtkPolyData* mesh, int kind) {
  auto tree = vtkSmartPointer<vtkMatrixTree>::New();
  tree->SetDataSet(mesh);
  tree->SetTreeType(kind);
  EXPECT_TRUE(tree->Build()) << tree->GetTreeTypeAsString();
  return tree;
}

struct Answers {
  std::vector<double> t;
  std::vector<vtkIdType> cell;
  vtkIdType hits = 0;
};

Answers intersect(vtkMatrixTree* tree, const std::vector<Ray>& rays) {
  vtkNew<vtkDoubleArray> o, d;
  o->SetNumberOfComponents(3);
  d->SetNumberOfComponents(3);
  for (const Ray& r : rays) {
    o->InsertNextTuple3(r.o.x, r.o.y, r.o.z);
    d->InsertNextTuple3(r.d.x, r.d.y, r.d.z);
  }
  vtkNew<vtkDoubleArray> t;
  vtkNew<vtkIdTypeArray> cells;
  Answers a;
  a.hits = tree->IntersectRays(o, d, std::numeric_limits<double>::infinity(), t, cells);
  for (vtkIdType i = 0; i < t->GetNumberOfTuples(); ++i) {
    a.t.push_back(t->GetValue(i));
    a.cell.push_back(cells->GetValue(i));
  }
  return a;
}

std::vector<Ray> raysAt(const mtree::TriangleMesh& mesh, int n) {
  std::vector<Ray> rays = mtest::aimedRays(mesh, n, 0x7ee5);
  for (Ray& r : rays) {
    r.tmin = 0;
    r.tmax = std::numeric_limits<double>::infinity();
  }
  return rays;
}

vtkSmartPointer<vtkMatrixTreeRayCaster> casterOf(vtkPolyData* mesh, int kind) {
  auto caster = vtkSmartPointer<vtkMatrixTreeRayCaster>::New();
  caster->SetInputData(mesh);
  caster->SetImageSize(96, 80);
  caster->GetTree()->SetTreeType(kind);
  return caster;
}

// The caster's image with the split trees' CPU walk `traversal` (the tree is built once).
vtkSmartPointer<vtkImageData> render(vtkMatrixTreeRayCaster* caster, int traversal) {
  vtkMatrixTreeTuning tuning;
  tuning.SplitTraversal = traversal;
  caster->GetTree()->SetTuning(tuning);
  caster->Modified();
  caster->Update();
  auto img = vtkSmartPointer<vtkImageData>::New();
  img->DeepCopy(caster->GetOutput());
  return img;
}

}  // namespace

TEST(TreeKinds, IntersectRaysGivesTheBruteForceFirstHitForEveryKind) {
  vtkSmartPointer<vtkPolyData> mesh = hand();
  for (int kind : kKinds) {
    auto tree = treeOf(mesh, kind);
    const vtkMatrixTreeInternals& in = *tree->GetInternals();
    const std::vector<Ray> rays = raysAt(in.Mesh, 4000);
    const Answers a = intersect(tree, rays);
    const std::vector<mtree::RayHit> ref = mtest::BruteForce(in.Mesh).firstAll(rays);
    uint64_t mismatches = 0, hits = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
      hits += ref[i].hit();
      if (!ref[i].hit()) {
        mismatches += !(std::isinf(a.t[i]) && a.cell[i] == -1);
        continue;
      }
      const bool sameCell = a.cell[i] == in.CellOfTriangle[ref[i].prim] && a.t[i] == ref[i].t;
      const bool tie = std::fabs(a.t[i] - ref[i].t) <= 1e-6 * std::max(1.0, std::fabs(ref[i].t));
      mismatches += !(sameCell || tie);
    }
    EXPECT_EQ(mismatches, 0u) << tree->GetTreeTypeAsString();
    EXPECT_EQ(static_cast<uint64_t>(a.hits), hits) << tree->GetTreeTypeAsString();
    EXPECT_GT(hits, rays.size() / 2) << tree->GetTreeTypeAsString();
    EXPECT_GT(tree->GetLastNodeVisits(), 0) << tree->GetTreeTypeAsString();
    EXPECT_GT(tree->GetLastTriangleTests(), 0) << tree->GetTreeTypeAsString();
  }
}

TEST(TreeKinds, SplitTraversalTuningGivesTheSameHitsBitForBit) {
  vtkSmartPointer<vtkPolyData> mesh = hand();
  for (int kind : {vtkMatrixTree::IMPLICIT_KDTREE, vtkMatrixTree::BSP_TREE}) {
    auto tree = treeOf(mesh, kind);
    EXPECT_EQ(tree->GetTuning().SplitTraversal, vtkMatrixTreeTuning::STACK);
    const std::vector<Ray> rays = raysAt(tree->GetInternals()->Mesh, 2000);
    const Answers stack = intersect(tree, rays);
    const vtkIdType builds = tree->GetNumberOfBuilds();
    for (int walk : {vtkMatrixTreeTuning::RESTART, vtkMatrixTreeTuning::BACKTRACK}) {
      vtkMatrixTreeTuning tuning;
      tuning.SplitTraversal = walk;
      tree->SetTuning(tuning);
      EXPECT_EQ(tree->GetTuning(), tuning);
      ASSERT_TRUE(tree->BuildIfNeeded());
      const Answers other = intersect(tree, rays);
      EXPECT_EQ(other.cell, stack.cell) << tree->GetTreeTypeAsString() << " walk " << walk;
      EXPECT_EQ(other.t, stack.t) << tree->GetTreeTypeAsString() << " walk " << walk;
      std::ostringstream os;
      tree->PrintSelf(os, vtkIndent());
      EXPECT_NE(os.str().find(std::string("Tuning.SplitTraversal: ") +
                              mtree::splitTraversalName(static_cast<mtree::SplitTraversal>(walk))),
                std::string::npos);
    }
    EXPECT_EQ(tree->GetNumberOfBuilds(), builds);  // a query setting
    vtkMatrixTreeTuning bad;
    bad.SplitTraversal = 7;
    tree->SetTuning(bad);
    EXPECT_EQ(tree->GetTuning().SplitTraversal, vtkMatrixTreeTuning::BACKTRACK);

    // The ray caster's image: the same depth and cell ids, whatever the walk.
    auto caster = casterOf(mesh, kind);
    auto ref = render(caster, vtkMatrixTreeTuning::STACK);
    const vtkIdType casterBuilds = caster->GetTree()->GetNumberOfBuilds();
    for (int walk : {vtkMatrixTreeTuning::RESTART, vtkMatrixTreeTuning::BACKTRACK}) {
      auto img = render(caster, walk);
      EXPECT_EQ(caster->GetTree()->GetNumberOfBuilds(), casterBuilds);
      for (const char* name : {"Depth", "CellId"}) {
        vtkDataArray* a = img->GetPointData()->GetArray(name);
        vtkDataArray* b = ref->GetPointData()->GetArray(name);
        ASSERT_TRUE(a && b) << name;
        uint64_t differ = 0;
        for (vtkIdType p = 0; p < a->GetNumberOfTuples(); ++p) {
          const double x = a->GetTuple1(p), y = b->GetTuple1(p);
          differ += !(x == y || (std::isinf(x) && std::isinf(y)));
        }
        EXPECT_EQ(differ, 0u) << name << " walk " << walk;
      }
    }
  }
}

TEST(TreeKinds, RayCasterRendersTheOctreesHitsWithEveryKind) {
  vtkSmartPointer<vtkPolyData> mesh = hand();
  auto ref = render(casterOf(mesh, vtkMatrixTree::OCTREE), vtkMatrixTreeTuning::STACK);
  vtkDataArray* refDepth = ref->GetPointData()->GetArray("Depth");
  ASSERT_TRUE(refDepth);
  for (int kind : kKinds) {
    auto img = render(casterOf(mesh, kind), vtkMatrixTreeTuning::STACK);
    vtkDataArray* depth = img->GetPointData()->GetArray("Depth");
    ASSERT_TRUE(depth);
    uint64_t differ = 0, hits = 0;
    for (vtkIdType p = 0; p < depth->GetNumberOfTuples(); ++p) {
      const double x = depth->GetTuple1(p), y = refDepth->GetTuple1(p);
      hits += std::isfinite(y);
      differ += !((std::isinf(x) && std::isinf(y)) || std::fabs(x - y) <= 1e-5 * std::max(1.0, std::fabs(y)));
    }
    EXPECT_EQ(differ, 0u) << kind;
    EXPECT_GT(hits, 1000u);
  }
}

TEST(TreeKinds, FindLeavesAndStatisticsOfTheSplitTrees) {
  vtkSmartPointer<vtkPolyData> mesh = hand();
  for (int kind : kKinds) {
    auto tree = treeOf(mesh, kind);
    const std::string name = tree->GetTreeTypeAsString();
    const bool split = kind == vtkMatrixTree::IMPLICIT_KDTREE || kind == vtkMatrixTree::BSP_TREE;
    const vtkMatrixTreeInternals& in = *tree->GetInternals();
    EXPECT_GT(tree->GetNumberOfNodes(), tree->GetNumberOfLeaves()) << name;
    EXPECT_GE(tree->GetNumberOfReferences(), tree->GetNumberOfTriangles()) << name;
    EXPECT_GT(tree->GetMemorySize(), 4 * tree->GetNumberOfReferences()) << name;
    EXPECT_EQ(tree->GetPointerTreeMemorySize() > 0, split) << name;
    if (split) {
      // SahKdNode's 8 bytes a node plus the same 4-byte triangle indices.
      EXPECT_EQ(tree->GetPointerTreeMemorySize(), 8 * tree->GetNumberOfNodes() + 4 * tree->GetNumberOfReferences())
          << name;
    }
    // Points on triangles lie in existing leaves.
    mtest::Rng rng(0xf1d);
    vtkNew<vtkDoubleArray> pts;
    pts->SetNumberOfComponents(3);
    for (int i = 0; i < 2000; ++i) {
      const mtree::Vec3 p = mtest::pointOn(in.Mesh, rng.below(static_cast<uint32_t>(in.Mesh.size())), rng);
      pts->InsertNextTuple3(p.x, p.y, p.z);
    }
    double b[6];
    tree->GetRootBounds(b);
    pts->InsertNextTuple3(b[1] + (b[1] - b[0]), b[3], b[5]);
    vtkNew<vtkIntArray> res;
    tree->FindLeaves(pts, res);
    ASSERT_EQ(res->GetNumberOfTuples(), 2001);
    uint64_t missing = 0;
    for (vtkIdType i = 0; i < 2000; ++i) {
      const int level = res->GetComponent(i, 0);
      missing += !(level >= 0 && level <= tree->GetTreeHeight() && res->GetComponent(i, 4) == 1);
    }
    EXPECT_EQ(missing, 0u) << name;
    EXPECT_EQ(res->GetComponent(2000, 0), -1) << name;
  }
}

TEST(TreeKinds, HybridOnOpenCLFailsWithAClearError) {
  vtkSmartPointer<vtkPolyData> mesh = hand();
  vtkNew<vtkMatrixTree> tree;
  vtkNew<mtest::ErrorCatcher> errors;
  tree->AddObserver(vtkCommand::ErrorEvent, errors);
  tree->SetDataSet(mesh);
  tree->SetTreeTypeToHybrid();
  tree->SetBackendToOpenCL();
  EXPECT_FALSE(tree->Build());
  EXPECT_EQ(errors->count, 1);
  EXPECT_NE(errors->message.find("no OpenCL traversal"), std::string::npos) << errors->message;
  EXPECT_FALSE(tree->IsBuilt());
}
