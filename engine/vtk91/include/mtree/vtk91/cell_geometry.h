// Where a point or a segment lies relative to one cell of VTK's linear types, decided by the
// engine alone: the cell tests of the VTK-free cell locator (cell_locator.h), which serves the
// Python package where no VTK C++ library is at hand (pip's VTK wheels ship none).
//
// The conventions are VTK's vtkCell::EvaluatePosition and IntersectWithLine: point order,
// parametric coordinates, interpolation functions, and the acceptance rule of each type:
//   vertex        inside when x is the point (dist2 == 0);
//   line          inside when x projects onto the segment (0 <= t <= 1), dist2 to the line;
//   triangle      inside when x projects into the triangle (barycentrics in [0, 1]), dist2 to
//                 the plane;
//   quad          Newton on the projection (20 steps, converged below 1e-4), inside in
//                 [-0.001, 1.001]; pixel: pcoords in [0, 1];
//   polygon       inside when the projection lies in the polygon; weights 1 / distance^2
//                 (vtkPolygon's default interpolation);
//   strip, polyline, polyvertex   the best of their triangles, segments or points;
//   tetrahedron   barycentrics in [-0.001, 1.001];  voxel  pcoords in [0, 1];
//   hexahedron, wedge, pyramid   VTK's Newton iteration (cell_eval.h's step), inside in
//                 [-1e-6, 1 + 1e-6] (hexahedron) or [-0.001, 1.001] (wedge: and r + s <= 1.001).
// The linear volume cells are first asked of cell_eval.h, which repeats VTK 9.1's arithmetic and
// answers where a different rounding could not change the answer (then pcoords and weights are
// VTK's bit for bit); the rest are decided here with the same rules in plain arithmetic, so a
// point within round-off of a boundary may go to the neighbour that VTK would not pick.
//
// Closest points are exact for cells with planar faces: x itself inside a volume cell, else the
// nearest point of the cell's triangulated boundary (VTK's hexahedron clamps pcoords instead,
// which is exact for parallelepipeds only).
//
// Segments follow vtkCell::IntersectWithLine with tolerance tol: a face (triangle, the
// triangles (0, 1, 2), (2, 3, 0) of a quad, as VTK 9.1 splits it, a polygon's plane) is hit
// where the segment crosses its plane within tol of it; a vertex where the segment passes within
// tol of it on every axis (VTK's); a line where the closest approach of the two segments is
// within tol (VTK measures from the ends of the segments differently when their infinite lines
// meet outside them). Volume cells are hit on their boundary faces, the first crossing first: a
// warped quad face at the nearer of its two triangles (VTK 9.1: the first triangle hit), a voxel
// too (VTK's voxel answers t = 0 for a segment starting inside it).
#pragma once

#include <cstdint>
#include <limits>

#include "mtree/cells/cells.h"  // cellTypeName
#include "mtree/core/geometry.h"

namespace mtree {

/// One point against one cell, as vtkCell::EvaluatePosition reports it.
struct CellPoint {
  /// 1: x is in the cell (VTK's 1); 0: it is not; -1: the cell is degenerate there (a zero
  /// determinant, Newton diverged or did not converge: VTK's -1).
  int status = 0;
  double pcoords[3] = {0, 0, 0};
  /// With closest points asked for: the point of the cell nearest x and |x - closest|^2 (for a
  /// point inside a 2-D cell's outline, its projection and the squared distance to the plane).
  /// Inside points always get them; otherwise, without closest points, dist2 stays infinite.
  Vec3 closest;
  double dist2 = std::numeric_limits<double>::infinity();
};

/// Whether the engine evaluates cells of this VTK type with this many points (every linear type,
/// vertex to pyramid; not the quadratic, higher-order or polyhedral ones).
bool cellTypeSupported(uint8_t type, int64_t numPoints);
/// 0, 1, 2 or 3 for the linear types; -1 for the others.
int cellDimension(uint8_t type);

/// Evaluates x against the cell of `type` with `n` points `pts` (3 doubles each, VTK's order).
/// weights: n entries, written when status is 1 (zeros beside the sub-cell of a strip, polyline
/// or polyvertex). wantClosest: also fill closest and dist2 (otherwise only inside points get
/// them, as x or its projection). The type must be supported (cellTypeSupported).
CellPoint evaluateCellPoint(uint8_t type, const double* pts, int n, const double x[3], double* weights,
                            bool wantClosest);

/// The first point, t in [0, 1] along p1 -> p2, where the segment meets the cell within `tol`
/// (VTK's IntersectWithLine; see the header comment). False if it does not.
bool intersectCellSegment(uint8_t type, const double* pts, int n, Vec3 p1, Vec3 p2, double tol, double& t,
                          Vec3& x);

/// The closest point to x on the triangle abc (Ericson, Real-Time Collision Detection 5.1.5).
Vec3 closestPointOnTriangle(Vec3 x, Vec3 a, Vec3 b, Vec3 c);
/// The closest point to x on the segment ab; t its parameter in [0, 1].
Vec3 closestPointOnSegment(Vec3 x, Vec3 a, Vec3 b, double& t);

}  // namespace mtree
