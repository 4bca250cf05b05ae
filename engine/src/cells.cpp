#include "mtree/cells.h"

namespace mtree {

namespace {
CellTopology makeTopology(int numPoints, std::initializer_list<std::initializer_list<int>> faces,
                          std::initializer_list<std::pair<int, int>> edges) {
  CellTopology t;
  t.numPoints = numPoints;
  for (const auto& f : faces) {
    int k = 0;
    for (int v : f) t.face[t.numFaces][k++] = v;
    t.faceSize[t.numFaces++] = k;
  }
  for (const auto& e : edges) {
    t.edge[t.numEdges][0] = e.first;
    t.edge[t.numEdges][1] = e.second;
    ++t.numEdges;
  }
  return t;
}
}  // namespace

const CellTopology* cellTopology(uint8_t type) {
  // Point orderings are VTK's (vtkTetra, vtkHexahedron, vtkWedge, vtkPyramid, vtkTriangle, vtkQuad).
  static const CellTopology tri = makeTopology(3, {{0, 1, 2}}, {{0, 1}, {1, 2}, {2, 0}});
  static const CellTopology quad = makeTopology(4, {{0, 1, 2, 3}}, {{0, 1}, {1, 2}, {2, 3}, {3, 0}});
  static const CellTopology tet =
      makeTopology(4, {{0, 1, 3}, {1, 2, 3}, {2, 0, 3}, {0, 2, 1}}, {{0, 1}, {1, 2}, {2, 0}, {0, 3}, {1, 3}, {2, 3}});
  static const CellTopology hex = makeTopology(
      8, {{0, 4, 7, 3}, {1, 2, 6, 5}, {0, 1, 5, 4}, {3, 7, 6, 2}, {0, 3, 2, 1}, {4, 5, 6, 7}},
      {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6}, {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}});
  static const CellTopology wedge =
      makeTopology(6, {{0, 1, 2}, {3, 5, 4}, {0, 3, 4, 1}, {1, 4, 5, 2}, {2, 5, 3, 0}},
                   {{0, 1}, {1, 2}, {2, 0}, {3, 4}, {4, 5}, {5, 3}, {0, 3}, {1, 4}, {2, 5}});
  static const CellTopology pyramid =
      makeTopology(5, {{0, 3, 2, 1}, {0, 1, 4}, {1, 2, 4}, {2, 3, 4}, {3, 0, 4}},
                   {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {0, 4}, {1, 4}, {2, 4}, {3, 4}});
  switch (type) {
    case kTriangle: return &tri;
    case kQuad: return &quad;
    case kTetra: return &tet;
    case kHexahedron: return &hex;
    case kWedge: return &wedge;
    case kPyramid: return &pyramid;
    default: return nullptr;  // voxels and pixels are their bounding box; others are padded
  }
}

}  // namespace mtree
