// What VTK 9.1's volume cells do with a hit on one of their faces, recomputed without VTK:
// - how vtkQuad::IntersectWithLine splits a quad into the two triangles it tests (face_hit.h
//   explains why 9.1 always takes the diagonal 0-2);
// - how vtkHexahedron, vtkWedge and vtkTetra::IntersectWithLine map the face's parametric
//   coordinates (r, s, and a triangle's third) to the cell's, for a hit they found on that face
//   (tests/python/test_locator.py::test_ray_hit_values_are_vtks_own checks the mapping against
//   the library through the locator).
#pragma once

#include <cstdint>

#include "mtree/cells/cells.h"
#include "mtree/cells/segment_filter.h"

namespace mtree {
namespace vtk91 {

/// The split of the VTK with this major and minor version where known (9.1: kDiagonal02), else
/// kUnknown (warped quad faces are then left to VTK).
constexpr QuadSplit quadSplitOfVtk(int major, int minor) {
  return major == 9 && minor == 1 ? QuadSplit::kDiagonal02 : QuadSplit::kUnknown;
}

/// Whether faceHitPcoords maps hits on the faces of this cell type.
constexpr bool faceHitMapped(uint8_t type) { return type == kHexahedron || type == kWedge || type == kTetra; }

/// The cell's pcoords of a hit on face `face` (the cell topology's numbering, VTK's) at the face's
/// pcoords pc (r, s; pc[2] a triangle's third), as VTK 9.1 writes them:
///   hexahedron  face 0 (0, r, 0), 1 (1, r, 0), 2 (r, 0, s), 3 (r, 1, s), 4 (r, s, 0), 5 (r, s, 1);
///   wedge       face 0 (r, s, 0), 1 (r, s, 1), 2 (s, 0, r), 3 (1 - s, s, r), 4 (0, s, r);
///   tetrahedron face 0 (r, s, 0), 1 (0, s, 0), 2 (r, 0, 0), 3 (r, s, third).
/// type must satisfy faceHitMapped.
inline void faceHitPcoords(uint8_t type, int face, const double pc[3], double out[3]) {
  const double r = pc[0], s = pc[1];
  if (type == kHexahedron) {
    switch (face) {
      case 0: out[0] = 0.0, out[1] = r, out[2] = 0.0; break;
      case 1: out[0] = 1.0, out[1] = r, out[2] = 0.0; break;
      case 2: out[0] = r, out[1] = 0.0, out[2] = s; break;
      case 3: out[0] = r, out[1] = 1.0, out[2] = s; break;
      case 4: out[0] = r, out[1] = s, out[2] = 0.0; break;
      default: out[0] = r, out[1] = s, out[2] = 1.0; break;
    }
  } else if (type == kTetra) {
    switch (face) {
      case 0: out[0] = r, out[1] = s, out[2] = 0.0; break;
      case 1: out[0] = 0.0, out[1] = s, out[2] = 0.0; break;
      case 2: out[0] = r, out[1] = 0.0, out[2] = 0.0; break;
      default: out[0] = r, out[1] = s, out[2] = pc[2]; break;
    }
  } else {
    switch (face) {
      case 0: out[0] = r, out[1] = s, out[2] = 0.0; break;
      case 1: out[0] = r, out[1] = s, out[2] = 1.0; break;
      case 2: out[0] = s, out[1] = 0.0, out[2] = r; break;
      case 3: out[0] = 1.0 - s, out[1] = s, out[2] = r; break;
      default: out[0] = 0.0, out[1] = s, out[2] = r; break;
    }
  }
}

}  // namespace vtk91
}  // namespace mtree
