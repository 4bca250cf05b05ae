// Fuzz harness: the cell builder the locator uses (CellSet, MatrixTreeBuilder<CellSet>::build<6>
// with the quantized leaf boxes, paper §5.1) and the point queries' leaf search, over random and
// degenerate cells.
//
// A case is up to 30 cells: well-shaped ones (tetrahedra, and hexahedra, wedges and pyramids
// with corners jittered by up to 20% of their size: warped faces) on points of their own, and
// cells of any linear type over random points of a shared pool of up to 40 (coincident points,
// self-intersecting shapes), now and then a cell of a random type and size (cells without points
// included) or an index out of range; coordinates in one of mfuzz::Input's modes; build options;
// 16 query points (on node boundaries, at cell vertices, uniform). Invariants:
//   - CellSet and the builder accept the case or throw std::invalid_argument / std::length_error;
//   - the engine's cell evaluation (mtree::vtk91::evaluateLinearCell) runs on every evaluable cell;
//   - the locator's candidate set is conservative: every cell whose bounds hold a query point
//     (with the bounding-box overlap; with the exact test, every well-shaped cell the engine
//     finds the point inside) is a reference of the leaf holding the point, and its quantized
//     leaf box (6 bytes) passes the byte test vtkMatrixTreeLocator's FindCell applies (ByteBoxTest:
//     with q the point in the leaf's 0..255 frame, lo <= floor(q) and hi >= ceil(q) per axis).
//     The separating-axis test assumes a cell's faces bound it, which a self-intersecting cell's
//     do not: such cells are checked with the bounding-box overlap only.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

#include "fuzz_input.h"
#include "mtree/vtk91/cell_eval.h"
#include "mtree/cells/cells.h"
#include "mtree/cells/leaf_boxes.h"
#include "mtree/core/builder.h"

using namespace mtree;

namespace {
struct Shape {
  uint8_t type;
  int points;
};
// VTK type codes and point counts of the linear cells the locator meets.
const Shape kShapes[] = {{10, 4}, {12, 8}, {13, 6}, {14, 5}, {11, 8}, {5, 3}, {9, 4}, {7, 5}, {3, 2}, {1, 1}};
// Unit templates of the volume cells in VTK's point order: tetrahedron, hexahedron, wedge, pyramid.
const double kTet[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
const double kHex[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
const double kWedge[6][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {0, 1, 1}};
const double kPyramid[5][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5, 0.5, 1}};
struct Template {
  uint8_t type;
  int points;
  const double (*at)[3];
  double jitter;  // of the size; 0 for the tetrahedron (any tetrahedron is well-shaped)
};
const Template kTemplates[] = {{10, 4, kTet, 0.0}, {12, 8, kHex, 0.2}, {13, 6, kWedge, 0.2}, {14, 5, kPyramid, 0.2}};
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  mfuzz::Input in(data, size);
  BuildOptions opt = mfuzz::treeOptions(in);
  opt.maxCandidates = 1 + in.below(16);
  opt.threads = 1 + int(in.below(2));

  const mfuzz::Input::Mode mode = in.mode();
  const uint32_t pool = 1 + in.below(40), nc = in.below(31);
  std::vector<double> pts(3 * size_t(pool));
  for (double& v : pts) v = in.coordinate(mode);
  std::vector<uint32_t> offsets{0}, conn;
  std::vector<uint8_t> types;
  std::vector<bool> wellShaped;
  for (uint32_t c = 0; c < nc; ++c) {
    if (in.flag()) {  // a well-shaped cell on points of its own
      const Template& t = kTemplates[in.below(4)];
      const double size = mode == mfuzz::Input::kSmallIntegers ? 1.0 : in.uniform(0.05, 1.0);
      double origin[3];
      for (double& o : origin) o = mode == mfuzz::Input::kSmallIntegers ? double(int(in.below(4)) - 2) : in.uniform(-1, 1);
      for (int k = 0; k < t.points; ++k) {
        conn.push_back(uint32_t(pts.size() / 3));
        for (int a = 0; a < 3; ++a) pts.push_back(origin[a] + size * (t.at[k][a] + t.jitter * in.uniform(-1, 1)));
      }
      types.push_back(t.type);
      wellShaped.push_back(true);
    } else {
      Shape s = kShapes[in.below(sizeof kShapes / sizeof kShapes[0])];
      if (in.below(32) == 0) s = Shape{uint8_t(in.below(80)), int(in.below(11))};  // any type, any size
      for (int k = 0; k < s.points; ++k) conn.push_back(in.below(pool + (in.below(64) == 0 ? 3 : 0)));
      types.push_back(s.type);
      wellShaped.push_back(false);
    }
    offsets.push_back(uint32_t(conn.size()));
  }
  const uint32_t np = uint32_t(pts.size() / 3);

  CellSet cells;
  MatrixTree tree;
  LargeVector<uint8_t> boxes;
  try {
    cells = CellSet(pts, offsets, conn, types, opt.threads);
    MatrixTreeBuilder<CellSet>::build<6>(cells, opt, tree, nullptr, &boxes, LeafBoxQuantizer());
  } catch (const std::invalid_argument&) {
    return 0;
  } catch (const std::length_error&) {
    return 0;
  }
  if (tree.empty()) return 0;

  const Box root = tree.rootBox();
  for (int q = 0; q < 16 && !in.empty(); ++q) {
    Vec3 x;
    const uint32_t how = in.below(3);
    for (int a = 0; a < 3; ++a) {
      const double w = root.hi[a] - root.lo[a];
      x[a] = how == 0   ? root.lo[a] + w * double(in.below(9)) / 8  // node boundaries
             : how == 1 ? pts[3 * size_t(in.below(np)) + size_t(a)]  // a vertex
                        : in.uniform(root.lo[a], root.hi[a]);
    }
    const NodeRef leaf = tree.leafHolding(x);
    for (size_t c = 0; c < cells.size(); ++c) {
      if (!cells.exactBounds(c).contains(x)) continue;
      const int64_t n = cells.numCellPoints(c);
      bool mustFind = opt.overlap == OverlapMode::BoundingBox;
      if (vtk91::cellEvaluable(cells.type(c), n)) {
        double cp[3 * CellSet::kMaxLocalPoints], pc[3], w[CellSet::kMaxLocalPoints];
        for (int64_t k = 0; k < n; ++k) {
          const Vec3 p = cells.cellPoint(c, k);
          cp[3 * k] = p.x;
          cp[3 * k + 1] = p.y;
          cp[3 * k + 2] = p.z;
        }
        const double xx[3] = {x.x, x.y, x.z};
        const bool inside = vtk91::evaluateLinearCell(cells.type(c), cp, xx, pc, w) == vtk91::PointInCell::kInside;
        mustFind |= inside && wellShaped[c];
      }
      if (!mustFind) continue;
      if (!leaf.exists) mfuzz::fail("a point inside a cell's bounds lies in no leaf");
      const uint32_t* ids = tree.primitiveIndices().data();
      uint32_t k = leaf.range.begin;
      while (k < leaf.range.end && ids[k] != c) ++k;
      if (k == leaf.range.end) mfuzz::fail("a cell holding the point is not a reference of the point's leaf");
      const Box lb = tree.nodeBox(leaf.level, leaf.c);
      const uint8_t* b = boxes.data() + 6 * size_t(k);
      for (int a = 0; a < 3; ++a) {
        const double qa = std::min(255.0, std::max(0.0, (x[a] - lb.lo[a]) * detail::leafBoxScale(lb.lo[a], lb.hi[a])));
        if (!(b[2 * a] <= std::floor(qa) && b[2 * a + 1] >= std::ceil(qa))) {
          std::fprintf(stderr, "cell %zu axis %d: box bytes [%d, %d], point at %.17g\n", c, a, b[2 * a], b[2 * a + 1], qa);
          mfuzz::fail("the quantized leaf box of a cell holding the point rejects it");
        }
      }
    }
  }
  return 0;
}
