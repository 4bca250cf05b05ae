// segmentMayHitCell (engine/include/mtree/cells/segment_filter.h) against VTK itself: whenever the
// filter rejects a (segment, cell) pair, VTK's own vtkCell::IntersectWithLine with the same
// tolerance must report no hit at t <= tMax. Checked on the real CFD grids (tetrahedra,
// pyramids + tetrahedra, hexahedra, prisms) and a real surface (triangles), for random segments
// and the hard ones — segments through cell vertices, along cell edges, lying in a face's plane,
// starting on a face — at tolerances 0, 1e-9 and 1e-4 of the grid's diagonal; and on extreme
// coordinates (1e12 offset, 1e-12 scale), flat tetrahedra, zero-length and non-finite segments.
// And tetraFirstHitIfCertain / convexFirstHitIfCertain (firstHitIfCertain): whenever it answers,
// VTK's own IntersectWithLine of the cell (vtkTetra, vtkHexahedron, vtkWedge, vtkPyramid) at
// tol 0 reports a hit at the same t (1e-9), and it answers for most hits on the tetrahedral
// grids and the brick's hexahedra and prisms; single hexahedra, wedges and pyramids (axis-aligned,
// sheared, warped, tangled) at extreme coordinates, with segments through their vertices, along
// edges and through their quads' diagonals, check the same.
// Where convexFirstHitIfCertain proves a miss instead (the segment outside one of a planar
// convex cell's face planes by its margin everywhere), VTK must report no hit at all.
// The filter must also earn its keep: on the grids it rejects most of the cells whose bounding
// box the segment crosses (a count, not a timing).
#include <gtest/gtest.h>

#include <vtkCellArray.h>
#include <vtkGenericCell.h>
#include <vtkIdList.h>
#include <vtkNew.h>
#include <vtkPLYReader.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkQuad.h>
#include <vtkSmartPointer.h>
#include <vtkTetra.h>
#include <vtkTriangle.h>
#include <vtkUnstructuredGrid.h>
#include <vtkVersion.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "mtree/cells/segment_filter.h"
#include "mtree/vtk91/face_hit.h"
#include "test_util.h"
#include "vtk_grid_util.h"

namespace {

/// The engine's copy of a dataset's cells (the same conversion the locator makes).
mtree::CellSet toCellSet(vtkDataSet* ds) {
  const vtkIdType np = ds->GetNumberOfPoints(), nc = ds->GetNumberOfCells();
  std::vector<double> pts(3 * static_cast<size_t>(np));
  for (vtkIdType i = 0; i < np; ++i) ds->GetPoint(i, &pts[3 * static_cast<size_t>(i)]);
  std::vector<uint32_t> offsets(static_cast<size_t>(nc) + 1, 0), conn;
  std::vector<uint8_t> types(static_cast<size_t>(nc));
  vtkNew<vtkIdList> ids;
  for (vtkIdType c = 0; c < nc; ++c) {
    types[static_cast<size_t>(c)] = static_cast<uint8_t>(ds->GetCellType(c));
    ds->GetCellPoints(c, ids);
    for (vtkIdType k = 0; k < ids->GetNumberOfIds(); ++k) conn.push_back(static_cast<uint32_t>(ids->GetId(k)));
    offsets[static_cast<size_t>(c) + 1] = static_cast<uint32_t>(conn.size());
  }
  return mtree::CellSet(std::move(pts), std::move(offsets), std::move(conn), std::move(types), 1);
}

struct Tally {
  long long boxHits = 0, rejected = 0, trueHits = 0;  // trueHits: kept, and hit by VTK
  long long tetHits = 0, certain = 0;  // tetrahedra hit by VTK at tol 0; of those decided by tetraFirstHitIfCertain
  long long polyHits = 0, polyCertain = 0;  // the same for hexahedra, wedges and pyramids (convexFirstHitIfCertain)
  long long polyMisses = 0;  // pairs convexFirstHitIfCertain proves missed (decideCell's kMiss beyond segmentMayHitCell)
  long long memoDecided = 0;  // decideCell calls that found the cell's ConvexShapeMemo byte set
  std::vector<uint8_t> memo;  // one ConvexShapeMemo byte per cell, shared by every segment of the test
  long long misses() const { return boxHits - trueHits; }
};

/// Checks every cell whose bounds (grown by tol) the segment crosses: a rejection must agree
/// with VTK. tMax is 1 and, for half the calls, the parameter of a random point on the segment.
void checkSegment(vtkDataSet* ds, const mtree::CellSet& cells, const double p1[3], const double p2[3], double tol,
                  double tMax, vtkGenericCell* cell, Tally& tally) {
  const mtree::SegmentFrame frame{mtree::Vec3(p1), mtree::Vec3(p2), tol, mtest::kVtkQuadSplit};
  const mtree::Vec3 o(p1), d = mtree::Vec3(p2) - o;
  for (size_t c = 0; c < cells.size(); ++c) {
    mtree::Box b = cells.exactBounds(c);
    b.lo = b.lo - mtree::Vec3(tol, tol, tol);
    b.hi = b.hi + mtree::Vec3(tol, tol, tol);
    double t0 = 0, t1 = 1;
    if (!mtree::rayBox(o, d, b, t0, t1)) continue;
    ++tally.boxHits;
    // VTK's own answer for this pair: the reference for every check below.
    ds->GetCell(static_cast<vtkIdType>(c), cell);
    double t = 0, x[3], pc[3];
    int sub = 0;
    double q1[3] = {p1[0], p1[1], p1[2]}, q2[3] = {p2[0], p2[1], p2[2]};
    const bool hit = cell->IntersectWithLine(q1, q2, tol, t, x, pc, sub) != 0;
    double tc = 0;
    int face = -1;
    bool provedMiss = false;
    const bool certain = mtree::firstHitIfCertain(frame, cells, c, tc, &face, &provedMiss);
    if (provedMiss) {
      // A proved miss must be VTK's: no hit at all.
      ++tally.polyMisses;
      ASSERT_FALSE(certain);
      ASSERT_FALSE(hit) << "cell " << c << " (type " << int(cells.type(c)) << ") proved missed is hit by VTK at t="
                        << t << ", segment (" << p1[0] << "," << p1[1] << "," << p1[2] << ")->(" << p2[0] << ","
                        << p2[1] << "," << p2[2] << ")";
    }
    const bool isTet = cells.type(c) == mtree::kTetra;
    const bool isPoly = cells.type(c) >= mtree::kHexahedron && cells.type(c) <= mtree::kPyramid;
    if (tol == 0 && isTet && hit) ++tally.tetHits;
    if (tol == 0 && isPoly && hit) ++tally.polyHits;
    if (certain) {
      // A certain hit must be VTK's: a hit, at the same t.
      ++(isTet ? tally.certain : tally.polyCertain);
      ASSERT_TRUE(isTet || isPoly) << "certain hit of cell " << c << " of type " << int(cells.type(c));
      ASSERT_TRUE(hit) << "certain hit of cell " << c << " (type " << int(cells.type(c)) << ") at t=" << tc
                       << " is not hit by VTK";
      ASSERT_NEAR(t, tc, 1e-9 * std::max(1.0, std::fabs(t))) << "cell " << c << " type " << int(cells.type(c));
    }
    const bool may = mtree::segmentMayHitCell(frame, cells, c, tMax);
    // The locator's one-pass decision gives the same answers as the two calls.
    double td = -1;
    int fd = -1;
    const mtree::CellVerdict verdict = mtree::decideCell(frame, cells, c, tMax, true, td, &fd);
    ASSERT_EQ(verdict == mtree::CellVerdict::kMiss, !may || provedMiss) << "cell " << c;
    // With the per-cell shape memo (the locator's): the same verdict, t and face, whether the
    // byte was already set by an earlier segment or is set by this call.
    if (tally.memo.size() != cells.size()) tally.memo.assign(cells.size(), 0);
    tally.memoDecided += tally.memo[c] != 0;
    double tm = -1;
    int fm = -1;
    const mtree::CellVerdict vm = mtree::decideCell(frame, cells, c, tMax, true, tm, &fm, tally.memo.data());
    ASSERT_EQ(vm, verdict) << "cell " << c << " memo " << int(tally.memo[c]);
    if (verdict == mtree::CellVerdict::kCertain) {
      ASSERT_EQ(tm, td) << "cell " << c;
      ASSERT_EQ(fm, fd) << "cell " << c;
    }
    if (may) {
      ASSERT_EQ(verdict == mtree::CellVerdict::kCertain, certain) << "cell " << c;
      if (certain) {
        ASSERT_EQ(td, tc) << "cell " << c;
      }
    }
    if (certain && tc < tMax * (1 - 1e-9)) {
      ASSERT_TRUE(may) << "a certain hit before tMax was rejected: tet " << c;
    }
    if (may) {
      if (hit && t <= tMax) ++tally.trueHits;
      continue;
    }
    ++tally.rejected;
    ASSERT_FALSE(hit && t <= tMax) << "rejected cell " << c << " (type " << int(cells.type(c)) << ") is hit by VTK at t="
                                   << t << " <= tMax=" << tMax << ", tol=" << tol << ", segment (" << p1[0] << ","
                                   << p1[1] << "," << p1[2] << ")->(" << p2[0] << "," << p2[1] << "," << p2[2] << ")";
  }
}

/// Segments through the diagonals of a random cell's quad faces: where VTK's split of the quad
/// into two triangles decides, a certain hit must not be claimed unless VTK agrees.
void diagonalSegments(vtkDataSet* ds, const mtree::CellSet& cells, int count, std::mt19937_64& rng,
                      vtkGenericCell* cell, Tally& tally) {
  std::uniform_real_distribution<double> U(0, 1);
  for (int i = 0; i < count; ++i) {
    const size_t c = static_cast<size_t>(U(rng) * cells.size()) % cells.size();
    const mtree::CellTopology* topo = mtree::cellTopology(cells.type(c));
    if (!topo || cells.numCellPoints(c) != topo->numPoints) continue;
    int f = static_cast<int>(U(rng) * topo->numFaces) % topo->numFaces;
    if (topo->faceSize[f] != 4) continue;
    const int* v = topo->face[f];
    const int k = i % 2;
    const mtree::Vec3 a = cells.cellPoint(c, v[k]), b = cells.cellPoint(c, v[k + 2]);
    const double s = (i % 3 == 0) ? 0.5 : U(rng);
    const mtree::Vec3 x = a + (b - a) * s;  // on the diagonal
    mtree::Vec3 cen(0, 0, 0);
    for (int j = 0; j < topo->numPoints; ++j) cen = cen + cells.cellPoint(c, j);
    cen = cen * (1.0 / topo->numPoints);
    // From the cell's centroid (inside: the hit is the exit through x) or from outside towards it.
    const mtree::Vec3 from = (i % 4 < 2) ? cen : x + (x - cen) * 1.5;
    const mtree::Vec3 to = (i % 4 < 2) ? x + (x - cen) * 0.5 : cen;
    const double p1[3] = {from.x, from.y, from.z}, p2[3] = {to.x, to.y, to.z};
    checkSegment(ds, cells, p1, p2, 0.0, 1.0, cell, tally);
    if (::testing::Test::HasFatalFailure()) return;
  }
}

/// Random and adversarial segments over a dataset.
void runDataset(vtkDataSet* ds, int nRandom, int nHard, Tally& tally) {
  const mtree::CellSet cells = toCellSet(ds);
  double bb[6];
  ds->GetBounds(bb);
  const double diag = std::sqrt((bb[1] - bb[0]) * (bb[1] - bb[0]) + (bb[3] - bb[2]) * (bb[3] - bb[2]) +
                                (bb[5] - bb[4]) * (bb[5] - bb[4]));
  std::mt19937_64 rng(20261121);
  std::uniform_real_distribution<double> U(0, 1);
  vtkNew<vtkGenericCell> cell;
  const double tols[3] = {0.0, 1e-9 * diag, 1e-4 * diag};
  auto randomDir = [&](double len, double out[3]) {
    double n2 = 0;
    do {
      for (int a = 0; a < 3; ++a) out[a] = 2 * U(rng) - 1;
      n2 = out[0] * out[0] + out[1] * out[1] + out[2] * out[2];
    } while (n2 < 1e-6 || n2 > 1);
    for (int a = 0; a < 3; ++a) out[a] *= len / std::sqrt(n2);
  };
  for (int i = 0; i < nRandom; ++i) {
    double p1[3], p2[3], dir[3];
    for (int a = 0; a < 3; ++a) p1[a] = bb[2 * a] + U(rng) * (bb[2 * a + 1] - bb[2 * a]);
    randomDir(0.05 * diag, dir);
    for (int a = 0; a < 3; ++a) p2[a] = p1[a] + dir[a];
    const double tMax = (i % 2) ? 1.0 : U(rng);
    checkSegment(ds, cells, p1, p2, tols[i % 3], tMax, cell, tally);
    if (::testing::Test::HasFatalFailure()) return;
  }
  // Hard segments built from a random cell: through a vertex, along an edge, in a face's plane,
  // from a face centroid.
  vtkNew<vtkIdList> ids;
  for (int i = 0; i < nHard; ++i) {
    const vtkIdType c = static_cast<vtkIdType>(U(rng) * ds->GetNumberOfCells()) % ds->GetNumberOfCells();
    ds->GetCellPoints(c, ids);
    const vtkIdType n = ids->GetNumberOfIds();
    if (n < 3) continue;
    double v0[3], v1[3], v2[3], p1[3], p2[3], dir[3];
    ds->GetPoint(ids->GetId(0), v0);
    ds->GetPoint(ids->GetId(1), v1);
    ds->GetPoint(ids->GetId(2), v2);
    const int kind = i % 4;
    randomDir(0.02 * diag, dir);
    for (int a = 0; a < 3; ++a) {
      if (kind == 0) {  // through vertex 0
        p1[a] = v0[a] - dir[a];
        p2[a] = v0[a] + dir[a];
      } else if (kind == 1) {  // along the edge 0-1, overshooting both ends
        p1[a] = v0[a] - 0.5 * (v1[a] - v0[a]);
        p2[a] = v1[a] + 0.5 * (v1[a] - v0[a]);
      } else if (kind == 2) {  // in the plane of points 0, 1, 2, through their centroid
        const double cen = (v0[a] + v1[a] + v2[a]) / 3;
        p1[a] = cen - (v1[a] - v0[a]) - 0.3 * (v2[a] - v0[a]);
        p2[a] = cen + (v1[a] - v0[a]) + 0.3 * (v2[a] - v0[a]);
      } else {  // from the centroid of points 0, 1, 2, outwards in a random direction
        p1[a] = (v0[a] + v1[a] + v2[a]) / 3;
        p2[a] = p1[a] + dir[a];
      }
    }
    checkSegment(ds, cells, p1, p2, tols[(i / 4) % 3], (i % 3) ? 1.0 : 0.5, cell, tally);
    if (::testing::Test::HasFatalFailure()) return;
  }
  diagonalSegments(ds, cells, nHard / 2, rng, cell, tally);
}

struct GridCase {
  const char* path;
  double minRejectedFraction;  // of the candidates VTK misses
  double polyCertainFraction = 0;  // of the hexahedra/wedges/pyramids hit at tol 0
};

class SegmentFilterGrid : public ::testing::TestWithParam<GridCase> {};

TEST_P(SegmentFilterGrid, RejectionsAgreeWithVtk) {
  const GridCase gc = GetParam();
  auto g = mtest::readGrid(gc.path);
  ASSERT_TRUE(g) << "cannot read " << gc.path;
  const bool big = g->GetNumberOfCells() > 100000;
  Tally tally;
  runDataset(g, big ? 90 : 300, big ? 120 : 400, tally);
  if (HasFatalFailure()) return;
  std::printf("%s: %lld box candidates, %lld VTK misses at t <= tMax, %lld rejected; %lld tets hit at tol 0, %lld of "
              "them certain without VTK; %lld hexahedra/wedges/pyramids hit, %lld certain; %lld proved missed by "
              "their face planes\n",
              gc.path, tally.boxHits, tally.misses(), tally.rejected, tally.tetHits, tally.certain, tally.polyHits,
              tally.polyCertain, tally.polyMisses);
  // On the tetrahedral grids a good share of the hits is decided without VTK, even with two
  // thirds of these segments made to pass through vertices and along edges.
  if (tally.tetHits > 100) {
    EXPECT_GT(tally.certain, 0.25 * tally.tetHits);
  }
  // The brick's hexahedra and prisms have planar faces: most of their hits are certain too.
  if (tally.polyHits > 100 && gc.polyCertainFraction > 0) {
    EXPECT_GT(tally.polyCertain, gc.polyCertainFraction * tally.polyHits);
    // And the shape memo was met set (the check above compared its verdicts on those calls).
    EXPECT_GT(tally.memoDecided, 0);
  }
  ASSERT_GT(tally.boxHits, 1000);
  // Worth calling: on tetrahedra most of the candidates VTK would miss are proved missed. The
  // brick's hexahedra are axis-aligned (the box is the hull) and its prisms half so: there only
  // the tMax bound and the slanted faces reject.
  EXPECT_GT(tally.rejected, gc.minRejectedFraction * tally.misses());
}

INSTANTIATE_TEST_SUITE_P(Grids, SegmentFilterGrid,
                         ::testing::Values(GridCase{"cfd/brick_tets.su2", 0.85}, GridCase{"cfd/brick_pyra.su2", 0.85},
                                           GridCase{"cfd/brick_hex.su2", 0.5, 0.25}, GridCase{"cfd/brick_prism.su2", 0.4, 0.25},
                                           GridCase{"cfd/pipe_flow_tets.vtu", 0.85}),
                         [](const ::testing::TestParamInfo<GridCase>& info) {
                           std::string name = info.param.path;
                           name = name.substr(name.find('/') + 1);
                           return name.substr(0, name.find('.'));
                         });

/// A hexahedral grid of n^3 unit cells whose points are moved by up to `jitter` (of a cell) along
/// each axis: every face is warped, by about the jitter, as the faces of real hexahedral meshes
/// are (disk_out_ref's: 1e-8 to 1e-3 of a cell).
vtkSmartPointer<vtkUnstructuredGrid> jitteredHexGrid(int n, double jitter, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(-1, 1);
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToDouble();
  for (int k = 0; k <= n; ++k)
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i)
        pts->InsertNextPoint(i + jitter * U(rng), j + jitter * U(rng), k + jitter * U(rng));
  auto g = vtkSmartPointer<vtkUnstructuredGrid>::New();
  g->SetPoints(pts);
  auto id = [n](int i, int j, int k) { return static_cast<vtkIdType>((k * (n + 1) + j) * (n + 1) + i); };
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const vtkIdType c[8] = {id(i, j, k),         id(i + 1, j, k),         id(i + 1, j + 1, k),
                                id(i, j + 1, k),     id(i, j, k + 1),         id(i + 1, j, k + 1),
                                id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)};
        g->InsertNextCell(12, 8, c);
      }
  return g;
}

// Warped hexahedra: within kMaxFaceWarp (over the crossings' |cos|) the hits are certain, at
// VTK's t (the plane of the triangle of vtkQuad's split that holds the hit, not the face's
// plane, which is up to the warp off); beyond it VTK decides. checkSegment checks every verdict
// against VTK's own vtkHexahedron.
TEST(SegmentFilter, WarpedHexahedraCertainHitsAreVtks) {
  long long planarCertain = -1;  // with no jitter (first): the share the warped grids must keep
  for (const double jitter : {0.0, 1e-7, 1e-5, 1e-3}) {
    SCOPED_TRACE("jitter " + std::to_string(jitter));
    auto g = jitteredHexGrid(8, jitter, 5);
    Tally tally;
    runDataset(g, 300, 400, tally);
    if (HasFatalFailure()) return;
    std::printf("hexahedra jittered by %g: %lld hit at tol 0, %lld certain; %lld proved missed by their face planes\n",
                jitter, tally.polyHits, tally.polyCertain, tally.polyMisses);
    ASSERT_GT(tally.polyHits, 200);
    if (jitter == 0.0) {
      planarCertain = tally.polyCertain;
      ASSERT_GT(planarCertain, 50);
    } else if (jitter <= 1e-5) {
      EXPECT_GT(tally.polyCertain, 0.9 * planarCertain);
      EXPECT_GT(tally.memoDecided, 0);
    } else {
      EXPECT_LT(tally.polyCertain, 0.05 * tally.polyHits);
    }
  }
}

TEST(SegmentFilter, SurfaceTrianglesAgreeWithVtk) {
  vtkNew<vtkPLYReader> r;
  const std::string path = mtest::dataPath("meshes/bunny.ply");
  r->SetFileName(path.c_str());
  r->Update();
  vtkPolyData* pd = r->GetOutput();
  ASSERT_GT(pd->GetNumberOfCells(), 1000) << path;
  Tally tally;
  runDataset(pd, 150, 300, tally);
  if (HasFatalFailure()) return;
  std::printf("bunny: %lld box candidates, %lld VTK misses at t <= tMax, %lld rejected\n", tally.boxHits,
              tally.misses(), tally.rejected);
  ASSERT_GT(tally.boxHits, 1000);
  // Segments lying in a triangle's plane (a third of the hard ones) cross the plane test's slab:
  // those misses stay with VTK.
  EXPECT_GT(tally.rejected, 0.5 * tally.misses());
}

/// One tetrahedron scaled by s and moved by off, against VTK's vtkTetra on segments through
/// its vertices, edges and faces.
void checkScaledTet(double s, double off, Tally& tally) {
  vtkNew<vtkUnstructuredGrid> g;
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToDouble();
  const double v[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.2, 0.3, 1}};
  for (const auto& p : v) pts->InsertNextPoint(off + s * p[0], off + s * p[1], off + s * p[2]);
  g->SetPoints(pts);
  const vtkIdType ids[4] = {0, 1, 2, 3};
  g->InsertNextCell(10, 4, ids);
  const mtree::CellSet cells = toCellSet(g);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> U(-0.5, 1.5);
  vtkNew<vtkGenericCell> cell;
  for (int i = 0; i < 4000; ++i) {
    double p1[3], p2[3];
    for (int a = 0; a < 3; ++a) {
      p1[a] = off + s * U(rng);
      p2[a] = off + s * U(rng);
    }
    if (i % 5 == 0)  // through a vertex
      for (int a = 0; a < 3; ++a) p2[a] = 2 * (off + s * v[i % 4][a]) - p1[a];
    const double tol = (i % 3 == 0) ? 0.0 : (i % 3 == 1 ? 1e-9 * s : 1e-3 * s);
    checkSegment(g, cells, p1, p2, tol, 1.0, cell, tally);
    if (::testing::Test::HasFatalFailure()) return;
  }
}

TEST(SegmentFilter, ExtremeCoordinates) {
  for (double s : {1.0, 1e-12, 1e12})
    for (double off : {0.0, 1e12, -3e6}) {
      if (s == 1e-12 && off != 0.0) continue;  // a 1e-12 cell at 1e12 has no representable interior
      Tally tally;
      SCOPED_TRACE("scale " + std::to_string(s) + " offset " + std::to_string(off));
      checkScaledTet(s, off * (s >= 1 ? 1 : s), tally);
      if (HasFatalFailure()) return;
      EXPECT_GT(tally.rejected, 100) << "scale " << s << " offset " << off;
    }
}

/// One hexahedron, wedge or pyramid (VTK type and point order) scaled by s and moved by off,
/// against VTK's own cell on random segments, segments through its vertices and from inside,
/// and segments through its quads' diagonals.
void checkScaledCell(int type, const std::vector<std::array<double, 3>>& v, double s, double off, Tally& tally) {
  vtkNew<vtkUnstructuredGrid> g;
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToDouble();
  for (const auto& p : v) pts->InsertNextPoint(off + s * p[0], off + s * p[1], off + s * p[2]);
  g->SetPoints(pts);
  std::vector<vtkIdType> ids(v.size());
  for (size_t k = 0; k < v.size(); ++k) ids[k] = static_cast<vtkIdType>(k);
  g->InsertNextCell(type, static_cast<vtkIdType>(ids.size()), ids.data());
  const mtree::CellSet cells = toCellSet(g);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> U(-0.5, 1.5);
  vtkNew<vtkGenericCell> cell;
  for (int i = 0; i < 3000; ++i) {
    double p1[3], p2[3];
    for (int a = 0; a < 3; ++a) {
      p1[a] = off + s * U(rng);
      p2[a] = off + s * U(rng);
    }
    if (i % 5 == 0)  // through a vertex
      for (int a = 0; a < 3; ++a) p2[a] = 2 * (off + s * v[i % v.size()][a]) - p1[a];
    if (i % 7 == 0)  // from inside (near the centroid)
      for (int a = 0; a < 3; ++a) {
        double cen = 0;
        for (const auto& p : v) cen += p[a];
        p1[a] = off + s * (cen / v.size() + 0.05 * (U(rng) - 0.5));
      }
    const double tol = (i % 4 == 3) ? 1e-9 * s : 0.0;
    checkSegment(g, cells, p1, p2, tol, 1.0, cell, tally);
    if (::testing::Test::HasFatalFailure()) return;
  }
  diagonalSegments(g, cells, 400, rng, cell, tally);
}

TEST(SegmentFilter, ConvexCellsCertainHitsAreVtks) {
  using P = std::vector<std::array<double, 3>>;
  const P cube = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  P sheared = cube, warped = cube, tangled = cube, bent = cube, twisted = cube;
  for (auto& p : sheared) p[0] += 0.3 * p[2], p[1] += 0.2 * p[2] + 0.1 * p[0];
  warped[6][2] += 0.1;  // non-planar faces, far beyond kMaxFaceWarp: VTK must decide
  std::swap(tangled[6], tangled[7]);
  // Warped as real meshes are (disk_out_ref's faces, 1e-8 to 1e-3 of the cell): within
  // kMaxFaceWarp the test answers, and must still give VTK's t (the plane of the triangle of
  // vtkQuad's split that holds the hit).
  bent[6][2] += 3e-6;
  for (auto& p : twisted) p[0] += 2e-5 * p[1] * p[2], p[1] -= 1e-5 * p[0] * p[2];
  const P wedge = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.1, 0, 1}, {1.1, 0, 1}, {0.1, 1, 1}};
  P wedgeBent = wedge;
  wedgeBent[4][1] += 4e-6;
  const P pyramid = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.4, 0.5, 1}};
  P pyramidBent = pyramid;
  pyramidBent[2][2] += 5e-6;
  const struct {
    const char* name;
    int type;
    const P* pts;
    bool planar;  // certain hits expected (planar, or warped within the limit)
  } cases[] = {{"cube", 12, &cube, true},          {"sheared", 12, &sheared, true}, {"warped", 12, &warped, false},
               {"tangled", 12, &tangled, false},   {"wedge", 13, &wedge, true},     {"pyramid", 14, &pyramid, true},
               {"bent", 12, &bent, true},          {"twisted", 12, &twisted, true}, {"wedge bent", 13, &wedgeBent, true},
               {"pyramid bent", 14, &pyramidBent, true}};
  for (const auto& cs : cases)
    for (double s : {1.0, 1e-12, 1e12})
      for (double off : {0.0, 1e12, -3e6}) {
        if (s == 1e-12 && off != 0.0) continue;
        SCOPED_TRACE(std::string(cs.name) + " scale " + std::to_string(s) + " offset " + std::to_string(off));
        Tally tally;
        checkScaledCell(cs.type, *cs.pts, s, off * (s >= 1 ? 1 : s), tally);
        if (HasFatalFailure()) return;
        if (!cs.planar) {
          EXPECT_EQ(tally.polyCertain, 0);
        } else if (off == 0.0) {
          EXPECT_GT(tally.polyCertain, 0.25 * tally.polyHits) << tally.polyHits;
          EXPECT_GT(tally.memoDecided, 0);
        }
      }
}

// The ConvexShapeMemo byte decideCell leaves for a cell: kPlanarConvex with the faces whose
// normals point inwards for planar convex cells (a cube's points in VTK's order, then mirrored,
// which turns every face's winding), kWarpedConvex with the cube's flips for a slightly warped
// cube (within kMaxFaceWarp: still certain), kNotConvex for a tangled or flat cell, nothing for
// one warped beyond the limit (checked in full each time); and the verdicts with the memo set
// are those without (checkScaledCell above, on many segments).
TEST(SegmentFilter, ConvexShapeMemoStates) {
  using Memo = mtree::ConvexShapeMemo;
  using P = std::vector<std::array<double, 3>>;
  const P cube = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  P mirrored = cube, warped = cube, tangled = cube, flat = cube, bent = cube;
  for (auto& p : mirrored) p[2] = -p[2];
  warped[6][2] += 0.1;
  bent[6][2] += 3e-6;
  std::swap(tangled[6], tangled[7]);
  for (auto& p : flat) p[2] *= 1e-5;
  const struct {
    const char* name;
    const P* pts;
    int expect;  // -1: kUnknown, 0: kNotConvex, 1: kPlanarConvex, 2: kWarpedConvex
  } cases[] = {{"cube", &cube, 1},       {"mirrored", &mirrored, 1}, {"warped", &warped, -1},
               {"tangled", &tangled, 0}, {"flat", &flat, 0},         {"bent", &bent, 2}};
  uint8_t flipsCube = 0xff, flipsMirrored = 0xff;
  for (const auto& cs : cases) {
    SCOPED_TRACE(cs.name);
    std::vector<double> pts;
    for (const auto& p : *cs.pts) pts.insert(pts.end(), p.begin(), p.end());
    const mtree::CellSet cells(std::move(pts), std::vector<uint32_t>{0, 8}, std::vector<uint32_t>{0, 1, 2, 3, 4, 5, 6, 7},
                               std::vector<uint8_t>{mtree::kHexahedron}, 1);
    // A segment through the cell's middle: every check runs.
    const mtree::SegmentFrame frame{mtree::Vec3(-0.5, 0.41, 0.37 * (*cs.pts)[4][2]),
                                    mtree::Vec3(1.5, 0.53, 0.61 * (*cs.pts)[4][2]), 0.0, mtest::kVtkQuadSplit};
    uint8_t memo = 0;
    double t = -1, tm = -1;
    const mtree::CellVerdict v = mtree::decideCell(frame, cells, 0, 1.0, true, t);
    const mtree::CellVerdict first = mtree::decideCell(frame, cells, 0, 1.0, true, tm, nullptr, &memo);
    const uint8_t after = memo;
    const mtree::CellVerdict second = mtree::decideCell(frame, cells, 0, 1.0, true, tm, nullptr, &memo);
    EXPECT_EQ(first, v);
    EXPECT_EQ(second, v);
    EXPECT_EQ(memo, after);
    if (cs.expect == 2) {
      ASSERT_EQ(after & ~Memo::kFlipsMask, Memo::kWarpedConvex) << int(after);
      EXPECT_EQ(v, mtree::CellVerdict::kCertain);
      EXPECT_EQ(tm, t);
      EXPECT_EQ(after & Memo::kFlipsMask, flipsCube);  // listed after the cube
    } else if (cs.expect == 1) {
      ASSERT_TRUE(Memo::planar(after)) << int(after);
      EXPECT_EQ(v, mtree::CellVerdict::kCertain);
      EXPECT_EQ(tm, t);
      (cs.pts == &cube ? flipsCube : flipsMirrored) = after & Memo::kFlipsMask;
    } else {
      EXPECT_EQ(after, cs.expect == 0 ? Memo::kNotConvex : Memo::kUnknown);
      EXPECT_NE(v, mtree::CellVerdict::kCertain);
    }
  }
  // Mirroring turns every face inside out: the flips are complements over the six faces.
  EXPECT_EQ(flipsCube ^ flipsMirrored, 0x3f);
}

// tetraCertainHitFace: where it names a face, vtkTetra::IntersectWithLine at tol 0 finds its hit
// on that face alone: the same t and x as vtkTriangle's test of the face (its points in
// vtkTetra's order), and the tetrahedron's pcoords are the face's mapped as VTK 9.1 maps them.
// Random tetrahedra (some thin), segments from inside and outside, a third of them nearly
// parallel to a face (the cases the steepness conditions exclude), at extreme coordinates.
TEST(SegmentFilter, TetraCertainFaceIsVtks) {
  static constexpr int kFaces[4][3] = {{0, 1, 3}, {1, 2, 3}, {2, 0, 3}, {0, 2, 1}};
  std::mt19937_64 rng(41);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  vtkNew<vtkTetra> tet;
  vtkNew<vtkTriangle> tri;
  int faced = 0, certain = 0;
  for (double scale : {1.0, 1e-9, 1e9})
    for (double off : {0.0, 1e3, -1e8})
      for (int it = 0; it < 3000; ++it) {
        double v[4][3];
        for (auto& p : v)
          for (double& c : p) c = U(rng);
        if (it % 5 == 0)
          for (double& c : v[3]) c = 0.02 * c;  // thin
        for (auto& p : v)
          for (double& c : p) c = c * scale + off;
        std::vector<double> pts(&v[0][0], &v[0][0] + 12);
        std::vector<uint32_t> offsets = {0, 4}, conn = {0, 1, 2, 3};
        std::vector<uint8_t> types = {VTK_TETRA};
        const mtree::CellSet cells(std::move(pts), std::move(offsets), std::move(conn), std::move(types), 1);
        double a[3], b[3], dir[3];
        const double w[4] = {std::fabs(U(rng)), std::fabs(U(rng)), std::fabs(U(rng)), std::fabs(U(rng))};
        const double ws = w[0] + w[1] + w[2] + w[3];
        for (int k = 0; k < 3; ++k) {
          a[k] = (v[0][k] * w[0] + v[1][k] * w[1] + v[2][k] * w[2] + v[3][k] * w[3]) / ws;  // inside
          if (it % 2) a[k] += 0.8 * scale * U(rng);  // or not
          dir[k] = U(rng) * scale;
        }
        if (it % 3 == 0) {
          // Nearly parallel to face f: its edge direction plus a small normal component.
          const int* f = kFaces[it % 4];
          const double e1[3] = {v[f[1]][0] - v[f[0]][0], v[f[1]][1] - v[f[0]][1], v[f[1]][2] - v[f[0]][2]};
          const double e2[3] = {v[f[2]][0] - v[f[0]][0], v[f[2]][1] - v[f[0]][1], v[f[2]][2] - v[f[0]][2]};
          const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
          const double eps = (it % 9 == 0) ? 1e-3 : ((it % 9 == 3) ? 0.04 : 0.3);
          const double nn = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
          const double en = std::sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]);
          for (int k = 0; k < 3; ++k) dir[k] = e1[k] / en + eps * n[k] / nn * U(rng);
          for (int k = 0; k < 3; ++k) dir[k] *= scale;
        }
        for (int k = 0; k < 3; ++k) b[k] = a[k] + 2.0 * dir[k];
        const mtree::SegmentFrame frame(mtree::Vec3(a), mtree::Vec3(b), 0.0);
        double tc;
        if (!mtree::tetraFirstHitIfCertain(frame, cells, 0, tc)) continue;
        ++certain;
        const int face = mtree::tetraCertainHitFace(frame, cells, 0);
        if (face < 0) continue;
        ++faced;
        for (int k = 0; k < 4; ++k) tet->GetPoints()->SetPoint(k, v[k]);
        for (int k = 0; k < 3; ++k) tri->GetPoints()->SetPoint(k, v[kFaces[face][k]]);
        double t1, x1[3], pc1[3], t2, x2[3], pc2[3];
        int s1, s2;
        ASSERT_TRUE(tet->IntersectWithLine(a, b, 0.0, t1, x1, pc1, s1)) << it;
        ASSERT_TRUE(tri->IntersectWithLine(a, b, 0.0, t2, x2, pc2, s2)) << it;
        ASSERT_EQ(t1, t2) << it << " face " << face;
        for (int k = 0; k < 3; ++k) ASSERT_EQ(x1[k], x2[k]) << it;
        const double mapped[4][3] = {{pc2[0], pc2[1], 0.0}, {0.0, pc2[1], 0.0}, {pc2[0], 0.0, 0.0}, {pc2[0], pc2[1], pc2[2]}};
        for (int k = 0; k < 3; ++k) ASSERT_EQ(pc1[k], mapped[face][k]) << it << " face " << face;
        ASSERT_EQ(s1, s2);
      }
  EXPECT_GT(faced, certain / 2) << certain;
  EXPECT_GT(certain, 3000);
}

// mtree::vtk91 (vtk_face_hit.h) recomputes VTK 9.1's vtkTriangle and vtkQuad IntersectWithLine at
// tol 0: wherever it answers, VTK's own call (a fresh cell, as vtkMatrixTreeCellBridge::CertainFaceHit uses)
// must give the same verdict and, on a hit, the same t, x, pcoords and subId to the bit. Random
// triangles (some thin, some nearly edge-on to the segment) and quads (planar, warped,
// axis-aligned squares, long rectangles), at scales 1e-9 ... 1e9 and offsets up to 1e8, with
// segments through the inside, past the edges and diagonals, and ending short of the plane.
TEST(SegmentFilter, Vtk91FaceTestIsVtks) {
  if (!(VTK_MAJOR_VERSION == 9 && VTK_MINOR_VERSION == 1)) GTEST_SKIP() << "the recomputation is VTK 9.1's";
  std::mt19937_64 rng(97);
  std::uniform_real_distribution<double> U(-1.0, 1.0), U01(0.0, 1.0);
  long long hits = 0, misses = 0, asked = 0, total = 0;
  for (double scale : {1.0, 1e-9, 1e9})
    for (double off : {0.0, 1e3, -1e8})
      for (int it = 0; it < 4000; ++it) {
        // Cells smaller than 1e-9 of their offset sit at the coordinates' round-off, where VTK is
        // asked about most of them: they are checked, not counted.
        const bool resolved = off == 0.0 || scale > 1e-9 * std::fabs(off);
        const bool isQuad = it % 2 == 1;
        const int n = isQuad ? 4 : 3;
        double v[4][3];
        const int shape = (it / 2) % 5;
        if (isQuad && shape == 0) {  // an axis-aligned square (equal diagonals)
          const double a = 0.5 + U01(rng);
          const double sq[4][3] = {{0, 0, 0}, {a, 0, 0}, {a, a, 0}, {0, a, 0}};
          for (int k = 0; k < 4; ++k)
            for (int c = 0; c < 3; ++c) v[k][c] = sq[k][(c + it) % 3];
        } else if (isQuad) {  // a parallelogram, then warped (or not), or a long rectangle
          double o[3], e1[3], e2[3];
          for (int c = 0; c < 3; ++c) o[c] = U(rng), e1[c] = U(rng), e2[c] = U(rng);
          if (shape == 4)
            for (double& c : e2) c *= 0.01;
          for (int c = 0; c < 3; ++c) {
            v[0][c] = o[c];
            v[1][c] = o[c] + e1[c];
            v[2][c] = o[c] + e1[c] + e2[c];
            v[3][c] = o[c] + e2[c];
          }
          if (shape == 2 || shape == 3) {
            const double w = shape == 2 ? 1e-6 : 0.05;
            for (double& c : v[2]) c += w * U(rng);
          }
        } else {
          for (int k = 0; k < 3; ++k)
            for (double& c : v[k]) c = U(rng);
          if (shape == 1)
            for (int c = 0; c < 3; ++c) v[2][c] = 0.5 * (v[0][c] + v[1][c]) + 1e-3 * U(rng);  // thin
        }
        for (int k = 0; k < n; ++k)
          for (double& c : v[k]) c = c * scale + off;
        // A target point: inside (random barycentric of the points), beyond an edge, or on a
        // diagonal (quads); the segment through it from a random start, ending past it or short.
        double w[4] = {U01(rng), U01(rng), U01(rng), isQuad ? U01(rng) : 0.0};
        const int pick = it % 7;
        if (pick == 5) w[it % n] = -0.02 * U01(rng);  // just outside
        if (pick == 6 && isQuad) w[1] = w[3] = 0.0;  // on the diagonal 0-2
        double ws = 0;
        for (int k = 0; k < n; ++k) ws += w[k];
        double target[3] = {0, 0, 0}, a[3], b[3];
        for (int c = 0; c < 3; ++c) {
          for (int k = 0; k < n; ++k) target[c] += v[k][c] * w[k] / ws;
        }
        double dir[3];
        for (int c = 0; c < 3; ++c) dir[c] = U(rng) * scale;
        if (it % 11 == 0) {  // nearly in the plane: along an edge with a small normal part
          for (int c = 0; c < 3; ++c) dir[c] = (v[1][c] - v[0][c]) + 1e-4 * U(rng) * scale;
        }
        const double reach = (it % 13 == 0) ? 0.8 : 1.7;  // short: the plane lies past p2
        for (int c = 0; c < 3; ++c) {
          a[c] = target[c] - dir[c];
          b[c] = a[c] + reach * dir[c];
        }
        vtkSmartPointer<vtkCell> cell;
        if (isQuad) cell = vtkSmartPointer<vtkQuad>::New();
        else cell = vtkSmartPointer<vtkTriangle>::New();
        for (int k = 0; k < n; ++k) cell->GetPoints()->SetPoint(k, v[k]);
        double t = 0, x[3] = {0, 0, 0}, pc[3] = {0, 0, 0};
        int sub = -1;
        const int vtkHit = cell->IntersectWithLine(a, b, 0.0, t, x, pc, sub);
        mtree::vtk91::LineHit h;
        const mtree::vtk91::FaceHit ours =
            isQuad ? mtree::vtk91::quadLineHit(v, a, b, h) : mtree::vtk91::triangleLineHit(v[0], v[1], v[2], a, b, h);
        total += resolved;
        if (ours == mtree::vtk91::FaceHit::kAskVtk) {
          asked += resolved;
          continue;
        }
        if (ours == mtree::vtk91::FaceHit::kMiss) {
          misses += resolved;
          ASSERT_EQ(vtkHit, 0) << "it " << it << " scale " << scale << " off " << off;
          continue;
        }
        hits += resolved;
        ASSERT_EQ(vtkHit, 1) << "it " << it << " scale " << scale << " off " << off;
        ASSERT_EQ(h.t, t) << it;
        for (int c = 0; c < 3; ++c) {
          ASSERT_EQ(h.x[c], x[c]) << it << " x" << c;
          ASSERT_EQ(h.pcoords[c], pc[c]) << it << " pcoords" << c << " quad " << isQuad << " shape " << shape;
        }
        ASSERT_EQ(sub, 0);
      }
  // Both verdicts are exercised, and VTK is asked only about the few on a quad's diagonal, near
  // an edge, edge-on or degenerate.
  EXPECT_GT(hits, total / 4) << total;
  EXPECT_GT(misses, total / 10) << total;
  EXPECT_LT(asked, total / 20) << total;
}

TEST(SegmentFilter, DegenerateInputNeverRejects) {
  // A flat tetrahedron (all four points in z = 0): the face planes are unreliable, so only the
  // ray frame may reject, and a segment through its plane must not be rejected.
  std::vector<double> pts = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0.3, 0.3, 0};
  const mtree::CellSet flat(pts, std::vector<uint32_t>{0, 4}, std::vector<uint32_t>{0, 1, 2, 3},
                            std::vector<uint8_t>{10}, 1);
  const mtree::SegmentFrame down(mtree::Vec3(0.2, 0.2, 1), mtree::Vec3(0.2, 0.2, -1), 0.0);
  EXPECT_TRUE(mtree::segmentMayHitCell(down, flat, 0, 1.0));
  const mtree::SegmentFrame away(mtree::Vec3(5, 5, 1), mtree::Vec3(5, 5, -1), 0.0);
  EXPECT_FALSE(mtree::segmentMayHitCell(away, flat, 0, 1.0));
  // Zero-length, non-finite segments and a non-finite or negative tolerance: never rejected.
  const double nan = std::nan("");
  const mtree::SegmentFrame zero(mtree::Vec3(5, 5, 5), mtree::Vec3(5, 5, 5), 0.0);
  const mtree::SegmentFrame bad(mtree::Vec3(nan, 0, 0), mtree::Vec3(5, 5, 5), 0.0);
  const mtree::SegmentFrame badTol(mtree::Vec3(5, 5, 1), mtree::Vec3(5, 5, -1), nan);
  const mtree::SegmentFrame negTol(mtree::Vec3(5, 5, 1), mtree::Vec3(5, 5, -1), -1.0);
  for (const auto* f : {&zero, &bad, &badTol, &negTol}) {
    EXPECT_FALSE(f->valid);
    EXPECT_TRUE(mtree::segmentMayHitCell(*f, flat, 0, 1.0));
  }
  // A quadratic tetrahedron (type 24) may bulge past its nodes: never rejected.
  std::vector<double> qp(30, 0.0);
  for (int k = 0; k < 10; ++k) qp[3 * k] = k;
  std::vector<uint32_t> qc(10);
  for (uint32_t k = 0; k < 10; ++k) qc[k] = k;
  const mtree::CellSet quad(qp, std::vector<uint32_t>{0, 10}, qc, std::vector<uint8_t>{24}, 1);
  EXPECT_TRUE(mtree::segmentMayHitCell(away, quad, 0, 1.0));
}

}  // namespace
