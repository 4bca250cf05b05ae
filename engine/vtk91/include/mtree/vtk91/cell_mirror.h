// VTK 9.1's vtkCell::EvaluatePosition and vtkCell::IntersectWithLine, transcribed without VTK:
// for every cell type listed by mirrorCovers (every linear type; the quadratic tetrahedron,
// hexahedron, wedge and pyramid and the triquadratic hexahedron), the same branches, the same helper cells (a
// hexahedron's faces as vtkQuad, a quad's triangles as vtkTriangle, a triangle's edges as
// vtkLine), the same constants and the operations in VTK's order, so that return value, t, x,
// pcoords, weights, closest point and dist2 are VTK 9.1's bit for bit in a build without FMA
// contraction (the project's: CMakeLists.txt sets no -march). tests/cpp/test_cell_mirror
// compares every output with the VTK it links, on random, degenerate and boundary cases.
//
// What it is for: the one cell decision of both locators. vtkMatrixTreeLocator asks its fast,
// margin-guarded verdicts first (cell_eval.h, face_hit.h) and VTK's own cell where they leave
// the answer open; the VTK-free locator (cell_locator.h) asks the same fast verdicts and then
// this transcription, which gives the answer VTK would have given.
//
// Not transcribed, with what is done instead (documented in docs/guide.md, tested):
//   - vtkPolygon::PointInPolygon fires rays in random directions (vtkMath::Random, a global
//     generator) and votes; here the rays are a fixed sequence, so the answer is VTK's wherever
//     VTK's own votes agree (every point not within round-off of an edge or a vertex);
//   - types mirrorCovers rejects (the other quadratic and biquadratic types, Lagrange and Bezier
//     cells, polyhedra, convex point sets): the VTK-free locator refuses them at build time with
//     a message naming the first such cell; vtkMatrixTreeLocator asks VTK's own cell for them.
#pragma once

#include <cstdint>

namespace mtree {
namespace vtk91 {

/// One cell as a vtkCell holds it: its VTK type, n points (3 doubles each, in VTK's order) and
/// their point ids (only vtkQuad::IntersectWithLine reads them, to break a tie between its
/// diagonals; nullptr means the ids a cell's constructor gives, all 0).
struct MirrorCell {
  uint8_t type = 0;
  int n = 0;
  const double* pts = nullptr;
  const int64_t* ids = nullptr;
};

/// Whether EvaluatePosition and IntersectWithLine are transcribed for this type with n points.
bool mirrorCovers(uint8_t type, int64_t n);

/// vtkCell::EvaluatePosition(x, closest, subId, pcoords, dist2, weights) of VTK 9.1: 1 inside,
/// 0 outside, -1 degenerate or not converged. closest may be null, as in VTK's FindCell (dist2
/// is then left as VTK leaves it: not always written). weights: room for c.n values.
int evaluatePosition(const MirrorCell& c, const double x[3], double* closest, int& subId, double pcoords[3],
                     double& dist2, double* weights);

/// vtkCell::IntersectWithLine(p1, p2, tol, t, x, pcoords, subId) of VTK 9.1: 1 on a hit.
int intersectWithLine(const MirrorCell& c, const double p1[3], const double p2[3], double tol, double& t,
                      double x[3], double pcoords[3], int& subId);

/// The face of a hexahedron, wedge, pyramid or tetrahedron (cellTopology's numbering, VTK's)
/// tested alone as the cell's IntersectWithLine tests it (vtkQuad or vtkTriangle with the
/// face's points and constructor ids), the hit's pcoords mapped to the cell's as VTK maps them.
/// For a segment whose first hit is certain to lie on that face (segment_filter.h), this is
/// the cell's answer. 1 on a hit.
int intersectFace(const MirrorCell& c, int face, const double p1[3], const double p2[3], double tol, double& t,
                  double x[3], double pcoords[3], int& subId);

}  // namespace vtk91
}  // namespace mtree
