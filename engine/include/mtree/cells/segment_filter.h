// A conservative segment-versus-cell rejection test, run before a cell is handed to VTK's own
// vtkCell::IntersectWithLine. The locator's ray queries must return VTK's answers (hit cell, t,
// x, pcoords), so VTK still decides every cell this test lets through; the test only proves,
// from the cell's points alone, that VTK cannot report a hit with t <= tMax, and so saves the
// GetCell + IntersectWithLine call (about 1 us for a tetrahedron) for most of the cells whose
// bounding box the segment crosses.
//
// Why it is safe: every linear cell type (vertex to pyramid, polygons and strips included) lies
// inside the convex hull of its points, and VTK reports a hit only where the segment passes within
// its tolerance of the cell (absolute distance; per axis for a vertex, so up to sqrt(3) tol).
// The test therefore inflates the hull by r = 2 tol + delta, where delta = 1e-3 of the cell's
// extent plus a round-off term in the coordinates' magnitude; delta covers VTK's own round-off
// and the relative tolerance vtkPolygon's point-in-polygon test applies. Two proofs of a miss:
//   1. the ray frame: with u, w unit vectors perpendicular to the segment, the hull's projection
//      onto u or w lies entirely on one side of the segment's line (further than r); or its
//      projection onto the segment direction lies beyond tMax (or before t = 0) by more than r;
//   2. tetrahedra: the segment clipped against the four inflated face planes (Cyrus-Beck) is
//      empty on [0, tMax]. For a tetrahedron this is exact up to the inflation;
//   3. triangles: both ends of the segment on [0, tMax] lie on one side of the triangle's plane,
//      further than r; or, seen along the segment, its line passes outside an edge of the
//      projected triangle by more than r.
// Axis-aligned cells (voxels, the hexahedra of a brick grid) gain little: for them the bounding
// box the caller tests first is already the hull, and only the tMax bound rejects more.
// Types outside that list (quadratic and higher-order cells, polyhedra, whose curved faces can
// leave the hull of their nodes) are never rejected.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "mtree/cells/cells.h"
#include "mtree/core/geometry.h"

namespace mtree {

/// How vtkQuad::IntersectWithLine splits a quad into the two triangles it tests, which decides
/// where a warped quad face is hit (a planar one is hit at the same point either way):
///   kUnknown     warped faces are left to VTK (the default: a VTK whose split is not known);
///   kDiagonal02  triangles (0, 1, 2) and (2, 3, 0), whatever the quad's shape (VTK 9.1's:
///                mtree::vtk91::quadSplitOfVtk).
enum class QuadSplit : uint8_t { kUnknown = 0, kDiagonal02 = 1 };

/// The segment p1 -> p2 with its frame, set up once per query.
struct SegmentFrame {
  Vec3 p1, d;         // the segment is p1 + t d, t in [0, 1]
  Vec3 u, w;          // unit vectors perpendicular to d (and to each other)
  double invLen = 0;  // 1 / |d|
  double invLen2 = 0; // 1 / |d|^2
  double tol = 0;     // VTK's tolerance (a distance)
  double mag = 0;     // largest coordinate magnitude of p1 and p2
  bool valid = false; // false: zero-length or non-finite segment, or bad tol: nothing is rejected
  QuadSplit quadSplit = QuadSplit::kUnknown;  // the VTK's, for warped quad faces (see QuadSplit)

  SegmentFrame(Vec3 a, Vec3 b, double tolerance, QuadSplit split = QuadSplit::kUnknown)
      : p1(a), d(b - a), tol(tolerance), quadSplit(split) {
    const double len2 = dot(d, d);
    if (!isFinite(a) || !isFinite(b) || !(len2 > 0) || !std::isfinite(len2) || !(tolerance >= 0) ||
        !std::isfinite(tolerance))
      return;
    invLen2 = 1.0 / len2;
    invLen = std::sqrt(invLen2);
    // u: perpendicular to d and to the coordinate axis d is least aligned with.
    const double ax = std::fabs(d.x), ay = std::fabs(d.y), az = std::fabs(d.z);
    const Vec3 e = (ax <= ay && ax <= az) ? Vec3(1, 0, 0) : (ay <= az ? Vec3(0, 1, 0) : Vec3(0, 0, 1));
    u = normalized(cross(d, e));
    w = normalized(cross(d * invLen, u));
    mag = std::max({std::fabs(a.x), std::fabs(a.y), std::fabs(a.z), std::fabs(b.x), std::fabs(b.y), std::fabs(b.z)});
    valid = isFinite(u) && isFinite(w);
  }
};

/// Whether the cell's type lies inside the convex hull of its points (VTK's linear types).
inline bool cellInsideHullOfPoints(uint8_t type) { return type >= kVertex && type <= kPyramid; }

/// segmentMayHitCell for a tetrahedron, from its four points: the Cyrus-Beck test alone (the
/// segment clipped against the four face planes pushed out by r, empty on [0, min(tMax, 1)]).
/// For a tetrahedron it decides everything the ray-frame hull test would (that test is the
/// projection of the same hull onto two axes and the segment's, grown by the same r), so the
/// points are read and the frame's products computed only once. 0: a miss, 1: VTK must decide,
/// -1: the tetrahedron is (nearly) flat, the planes decide nothing (the ray-frame test may).
inline int tetraMayHit(const SegmentFrame& f, const Vec3 v[4], double tMax) {
  if (!f.valid) return 1;
  const Vec3 lo = vmin(vmin(v[0], v[1]), vmin(v[2], v[3])), hi = vmax(vmax(v[0], v[1]), vmax(v[2], v[3]));
  const double vmag = std::max({std::fabs(lo.x), std::fabs(lo.y), std::fabs(lo.z), std::fabs(hi.x), std::fabs(hi.y),
                                std::fabs(hi.z)});
  const Vec3 ext = hi - lo;
  const double emax = std::max({ext.x, ext.y, ext.z});
  const double delta = 1e-3 * emax + 64 * std::numeric_limits<double>::epsilon() * std::max(vmag, f.mag);
  const double r = 2 * f.tol + delta;
  if (!(std::isfinite(r))) return 1;
  static constexpr int kFace[4][4] = {{0, 1, 3, 2}, {1, 2, 3, 0}, {2, 0, 3, 1}, {0, 2, 1, 3}};  // 3 on the face, then the opposite
  double tLo = 0, tHi = std::min(tMax, 1.0);
  if (!(tLo <= tHi)) return 0;
  for (const auto& fv : kFace) {
    const Vec3 o = v[fv[0]];
    Vec3 nrm = cross(v[fv[1]] - o, v[fv[2]] - o);
    const double nn = norm(nrm);
    const double side = dot(nrm, v[fv[3]] - o);
    // A flat (or nearly flat) tetrahedron has no reliable inside.
    if (!(std::fabs(side) > 1e-9 * nn * emax)) return -1;
    if (side > 0) nrm = nrm * -1.0;  // outward
    const double A = dot(nrm, f.p1 - o) - r * nn;  // <= 0: p1 inside the pushed-out plane
    const double B = dot(nrm, f.d);
    if (B == 0) {
      if (A > 0) return 0;
      continue;
    }
    const double t = -A / B;
    if (B > 0) tHi = std::min(tHi, t);
    else tLo = std::max(tLo, t);
    if (tLo > tHi) return 0;
  }
  return 1;
}

/// A cell's points in the segment's frame, for segmentMayHitCell's test and decideCell's fused
/// path (one copy of the arithmetic, so both give the same verdicts): the extents across the line
/// (a along u, b along w), along it (s, in units of t) and in space, and the largest coordinate.
struct RayFrameExtent {
  double amin = std::numeric_limits<double>::infinity(), amax = -amin;
  double bmin = amin, bmax = amax, smin = amin, smax = amax;
  Vec3 lo{amin, amin, amin}, hi{amax, amax, amax};
  double vmag = 0;
  /// Adds point v; a and b are its coordinates across the line.
  void add(const SegmentFrame& f, const Vec3& v, double& a, double& b) {
    lo = vmin(lo, v);
    hi = vmax(hi, v);
    vmag = std::max({vmag, std::fabs(v.x), std::fabs(v.y), std::fabs(v.z)});
    const Vec3 q = v - f.p1;
    a = dot(f.u, q);
    b = dot(f.w, q);
    const double s = dot(f.d, q) * f.invLen2;
    amin = std::min(amin, a), amax = std::max(amax, a);
    bmin = std::min(bmin, b), bmax = std::max(bmax, b);
    smin = std::min(smin, s), smax = std::max(smax, s);
  }
  /// The test's margin: twice the tolerance, 1e-3 of the points' extent and round-off (not finite
  /// for non-finite points: then nothing is proven).
  double radius(const SegmentFrame& f) const {
    const Vec3 ext = hi - lo;
    const double delta = 1e-3 * std::max({ext.x, ext.y, ext.z}) +
                         64 * std::numeric_limits<double>::epsilon() * std::max(vmag, f.mag);
    return 2 * f.tol + delta;
  }
  /// True when every point is more than r off the line on one side, or beyond the segment's
  /// part [0, min(tMax, 1)] by more than r: the cell cannot be hit there.
  bool outside(const SegmentFrame& f, double r, double tMax) const {
    if (amin > r || amax < -r || bmin > r || bmax < -r) return true;
    const double rs = r * f.invLen;  // r in units of t
    return smin - rs > std::min(tMax, 1.0) || smax + rs < 0;
  }
};

/// False only if vtkCell::IntersectWithLine(p1, p2, tol, t, ...) on cell c cannot return a hit
/// with t <= tMax (see the header comment). True means "ask VTK".
inline bool segmentMayHitCell(const SegmentFrame& f, const CellSet& cells, size_t c, double tMax) {
  if (!f.valid || !cellInsideHullOfPoints(cells.type(c))) return true;
  const int64_t n = cells.numCellPoints(c);
  if (n <= 0) return true;
  if (cells.type(c) == kTetra && n == 4) {
    const Vec3 v[4] = {cells.cellPoint(c, 0), cells.cellPoint(c, 1), cells.cellPoint(c, 2), cells.cellPoint(c, 3)};
    const int verdict = tetraMayHit(f, v, tMax);
    if (verdict >= 0) return verdict != 0;
    // Flat: the ray-frame test below may still prove a miss (its face planes ask VTK).
  }
  RayFrameExtent rf;
  Vec3 tet[4];
  double pa[4] = {0, 0, 0, 0}, pb[4] = {0, 0, 0, 0};  // the first points in the ray frame
  for (int64_t k = 0; k < n; ++k) {
    const Vec3 v = cells.cellPoint(c, k);
    if (k < 4) tet[k] = v;
    double a, b;
    rf.add(f, v, a, b);
    if (k < 4) pa[k] = a, pb[k] = b;
  }
  const double r = rf.radius(f);
  if (!(std::isfinite(r))) return true;
  if (rf.outside(f, r, tMax)) return false;
  const double tHiLimit = std::min(tMax, 1.0);
  const Vec3 ext = rf.hi - rf.lo;
  if (cells.type(c) == kTriangle && n == 3) {
    // Both ends on the same side of the triangle's plane, further than r: a miss.
    const Vec3 nrm = cross(tet[1] - tet[0], tet[2] - tet[0]);
    const double nn = norm(nrm);
    if (!(nn > 0)) return true;
    const double a = dot(nrm, f.p1 - tet[0]), b = a + dot(nrm, f.d) * tHiLimit, R = r * nn;
    if ((a > R && b > R) || (a < -R && b < -R)) return false;
    // Seen along the segment, the line is the origin of the (u, w) plane: outside the projected
    // triangle's edge line by more than r is further than r from the triangle. A projection of
    // (nearly) no area (the segment in the triangle's plane) is left to VTK.
    const double area = (pa[1] - pa[0]) * (pb[2] - pb[0]) - (pb[1] - pb[0]) * (pa[2] - pa[0]);
    const double e2max = std::max({(pa[1] - pa[0]) * (pa[1] - pa[0]) + (pb[1] - pb[0]) * (pb[1] - pb[0]),
                                   (pa[2] - pa[1]) * (pa[2] - pa[1]) + (pb[2] - pb[1]) * (pb[2] - pb[1]),
                                   (pa[0] - pa[2]) * (pa[0] - pa[2]) + (pb[0] - pb[2]) * (pb[0] - pb[2])});
    if (!(std::fabs(area) > 1e-6 * e2max)) return true;
    const double orient = area > 0 ? 1.0 : -1.0;
    for (int e = 0; e < 3; ++e) {
      const int i = e, j = (e + 1) % 3;
      const double ex = pa[j] - pa[i], ey = pb[j] - pb[i];
      // Signed distance of the origin to the edge line, positive inside.
      const double len = std::sqrt(ex * ex + ey * ey);
      const double inside = orient * (ex * (0 - pb[i]) - ey * (0 - pa[i]));
      if (inside < -r * len) return false;
    }
    return true;
  }
  if (cells.type(c) != kTetra || n != 4) return true;
  // Cyrus-Beck against the tetrahedron's four face planes, each pushed out by r.
  static constexpr int kFace[4][4] = {{0, 1, 3, 2}, {1, 2, 3, 0}, {2, 0, 3, 1}, {0, 2, 1, 3}};  // 3 on the face, then the opposite
  double tLo = 0, tHi = tHiLimit;
  for (const auto& fv : kFace) {
    const Vec3 o = tet[fv[0]];
    Vec3 nrm = cross(tet[fv[1]] - o, tet[fv[2]] - o);
    const double nn = norm(nrm);
    const double side = dot(nrm, tet[fv[3]] - o);
    // A flat (or nearly flat) tetrahedron has no reliable inside: keep the ray-frame verdict.
    if (!(std::fabs(side) > 1e-9 * nn * std::max({ext.x, ext.y, ext.z}))) return true;
    if (side > 0) nrm = nrm * -1.0;  // outward
    const double A = dot(nrm, f.p1 - o) - r * nn;  // <= 0: p1 inside the pushed-out plane
    const double B = dot(nrm, f.d);
    if (B == 0) {
      if (A > 0) return false;
      continue;
    }
    const double t = -A / B;
    if (B > 0) tHi = std::min(tHi, t);
    else tLo = std::max(tLo, t);
    if (tLo > tHi) return false;
  }
  return true;
}

/// The part of a certain-hit decision that tetrahedra and convex cells share. Face i's plane is
/// given by how far inside it p1 lies, l1[i] (>= 0 inside, in the cell's units), and its change
/// along d, dl[i]; m is the margin. Finds where the line enters the cell (te, through face ie)
/// and leaves it (tx, face ix), and is true only if the line is certainly inside between them:
/// no face plane parallel to it and near, and at both crossings every other face at least m
/// away, the crossing face's distance at p1 and at p2 at least m, and veto(tc, ic) false (a
/// cell's own extra test, e.g. a quad's diagonals).
/// certainCrossings' first step: the entry (te, face ie: the last plane the line enters) and the
/// exit (tx, ix: the first it leaves); false when the line is parallel to a face plane and not m
/// inside it, or the crossings are missing or out of order.
inline bool lineCrossings(const double* l1, const double* dl, int nf, double m, double& te, double& tx, int& ie,
                          int& ix) {
  te = -std::numeric_limits<double>::infinity();
  tx = std::numeric_limits<double>::infinity();
  ie = ix = -1;
  for (int i = 0; i < nf; ++i) {
    if (dl[i] == 0) {
      if (l1[i] < m) return false;  // parallel to a face plane, outside or near it
      continue;
    }
    const double ti = -l1[i] / dl[i];
    if (dl[i] > 0) {
      if (ti > te) te = ti, ie = i;
    } else if (ti < tx) {
      tx = ti, ix = i;
    }
  }
  return ie >= 0 && ix >= 0 && te < tx;
}

/// certainCrossings' second step, for lineCrossings' answer (te, ie; tx, ix): every other face
/// at least m away at both crossings, the crossing face's distance at p1 and p2 at least m, and
/// veto false. A face plane parallel to the line is among the "other" faces at both crossings,
/// so its distance is checked against this m too (lineCrossings may have run with a smaller one).
template <class Veto>
inline bool crossingsClear(const double* l1, const double* dl, int nf, double m, double te, double tx, int ie, int ix,
                           Veto&& veto, int* faces = nullptr) {
  for (const auto& [tc, ic] : {std::pair<double, int>(te, ie), std::pair<double, int>(tx, ix)}) {
    for (int j = 0; j < nf; ++j)
      if (j != ic && !(l1[j] + tc * dl[j] >= m)) return false;
    if (!(std::fabs(l1[ic]) >= m) || !(std::fabs(l1[ic] + dl[ic]) >= m)) return false;
    if (veto(tc, ic)) return false;
  }
  if (faces) faces[0] = ie, faces[1] = ix;
  return true;
}

template <class Veto>
inline bool certainCrossings(const double* l1, const double* dl, int nf, double m, double& te, double& tx,
                             Veto&& veto, int* faces = nullptr) {
  int ie, ix;
  return lineCrossings(l1, dl, nf, m, te, tx, ie, ix) && crossingsClear(l1, dl, nf, m, te, tx, ie, ix, veto, faces);
}

/// The first hit of a segment whose line enters a convex cell at te and leaves at tx: te if
/// 0 < te <= 1, else tx if te <= 0 < tx <= 1; false when neither crossing is in the segment.
inline bool firstCrossingInSegment(double te, double tx, double& t) {
  if (te > 0 && te <= 1) {
    t = te;
    return true;
  }
  if (te <= 0 && tx > 0 && tx <= 1) {
    t = tx;
    return true;
  }
  return false;
}

/// |cos| of the angle between the segment and a crossed face's normal above which the face that
/// holds a certain hit is reported (tetraCertainHit, convexFirstHitIfCertain).
constexpr double kSteepCrossing = 0.05;

/// Where vtkTetra::IntersectWithLine(p1, p2, tol = 0, ...) reports its hit, when that is
/// certain from the engine's copy of the cell. VTK's answer for a tetrahedron is the smallest t in
/// [0, 1] at which the segment crosses one of its four triangles. With barycentric coordinates
/// lambda_i affine along the line, the line is inside for t in [te, tx]; the first hit is te if
/// 0 < te <= 1, else tx if te <= 0 < tx <= 1. The answer is certain when both crossings lie
/// inside their faces by a margin (every other lambda >= m: the line then passes no edge or
/// vertex closely, so none of VTK's four triangle tests is near a decision), neither crossing is
/// near an end of the segment, and the tetrahedron is not a sliver; m covers the round-off of
/// this computation and of VTK's. Returns false when not certain (VTK must decide) or when the
/// segment misses: misses are the rejection test's business. On true, t is the hit's parameter
/// (equal to VTK's up to round-off).
inline bool tetraCertainHit(const SegmentFrame& f, const Vec3 v[4], double& t, int* face = nullptr);
inline bool tetraFirstHitIfCertain(const SegmentFrame& f, const CellSet& cells, size_t c, double& t) {
  if (!f.valid || f.tol != 0 || cells.type(c) != kTetra || cells.numCellPoints(c) != 4) return false;
  const Vec3 v[4] = {cells.cellPoint(c, 0), cells.cellPoint(c, 1), cells.cellPoint(c, 2), cells.cellPoint(c, 3)};
  return tetraCertainHit(f, v, t);
}

/// For a tetrahedron c whose hit tetraFirstHitIfCertain finds certain: tetraCertainHit's face
/// (the face that holds the hit), or -1.
inline int tetraCertainHitFace(const SegmentFrame& f, const CellSet& cells, size_t c) {
  if (!f.valid || f.tol != 0 || cells.type(c) != kTetra || cells.numCellPoints(c) != 4) return -1;
  const Vec3 v[4] = {cells.cellPoint(c, 0), cells.cellPoint(c, 1), cells.cellPoint(c, 2), cells.cellPoint(c, 3)};
  double t;
  int face = -1;
  return tetraCertainHit(f, v, t, &face) ? face : -1;
}

/// tetraFirstHitIfCertain from the tetrahedron's four points (VTK's order).
///
/// face (optional): on true, the face (vtkTetra's numbering: {0,1,3}, {1,2,3}, {2,0,3}, {0,2,1})
/// that holds the hit, or -1. It is given when the line crosses the entry and the exit face at
/// |cos| >= kSteepCrossing to their normals, the other two at |cos| >= 1e-3 (no plane nearly
/// parallel to the line, where VTK's t would be ill-conditioned), eps mag <= 1e-9 h and
/// m kSteepCrossing h >= 64 eps mag, h the smallest height. Then VTK's four triangle tests
/// accept no other face at a t up to the hit's: a face g crossed after the hit is crossed
/// m h_g / |cos_g| further along the line (at the hit g's coordinate is >= m; it changes by
/// |cos_g| / h_g per unit of length), where VTK's crossings err by about eps mag / |cos_g|; a
/// face g crossed before the entry is crossed outside the entry face's plane by at least
/// m h_g |cos_entry| / |cos_g| >= m kSteepCrossing h_g (with the exit as the hit, also before
/// t = 0 by m h_entry / |cos_entry|), far beyond the round-off of VTK's triangle test.
inline bool tetraCertainHit(const SegmentFrame& f, const Vec3 v[4], double& t, int* face) {
  if (face) *face = -1;
  if (!f.valid || f.tol != 0) return false;
  const Vec3 v0 = v[0], v1 = v[1], v2 = v[2], v3 = v[3];
  const Vec3 a = v1 - v0, b = v2 - v0, e = v3 - v0;
  const Vec3 be = cross(b, e);
  const double det = dot(a, be);  // 6 x signed volume
  const double L = std::sqrt(std::max({dot(a, a), dot(b, b), dot(e, e), dot(b - a, b - a), dot(e - a, e - a),
                                       dot(e - b, e - b)}));
  if (!(std::fabs(det) > 1e-4 * L * L * L)) return false;  // sliver or flat: VTK decides
  const double inv = 1.0 / det;
  // Barycentric coordinates (l0, l1, l2, l3) of p1 and their change along d.
  auto bary = [&](Vec3 r, double l[4]) {
    l[1] = dot(r, be) * inv;
    l[2] = dot(a, cross(r, e)) * inv;
    l[3] = dot(a, cross(b, r)) * inv;
  };
  const Vec3 r1 = f.p1 - v0;
  double l1[4], dl[4];
  bary(r1, l1);
  l1[0] = 1.0 - l1[1] - l1[2] - l1[3];
  bary(f.d, dl);  // linear part only: d is a direction
  dl[0] = -(dl[1] + dl[2] + dl[3]);
  // Round-off of these coordinates (and of VTK's) grows with the distance of p1 and p2 from the
  // cell, and with the coordinates' magnitude against the cell's size.
  const double far = (norm(r1) + norm(r1 + f.d)) / L;
  const double vmag = std::max({std::fabs(v0.x), std::fabs(v0.y), std::fabs(v0.z)});
  const double m = 1e-6 + 1e-9 * far + 1024 * std::numeric_limits<double>::epsilon() * std::max(f.mag, vmag) / L;
  // VTK's t carries an absolute error of about eps x magnitude / |d|: where that could reorder
  // two hits by more than the 1e-9 the locator treats as a tie, VTK must decide.
  if (1024 * std::numeric_limits<double>::epsilon() * std::max(f.mag, vmag) * f.invLen > 1e-10) return false;
  // Both crossings well inside their faces, and neither near t = 0 or t = 1 (in barycentric
  // terms: the face's coordinate at p1 and at p2 is not near 0). No crossing in [0, 1]: a miss,
  // left to the rejection test and VTK.
  double te, tx;
  int crossed[2];
  if (!certainCrossings(l1, dl, 4, m, te, tx, [](double, int) { return false; }, crossed) ||
      !firstCrossingInSegment(te, tx, t))
    return false;
  if (face) {
    // |grad lambda_k| = 1 / h_k; |cos_k| = |dl_k| h_k / |d|.
    const Vec3 g1 = be * inv, g2 = cross(e, a) * inv, g3 = cross(a, b) * inv;
    const Vec3 g0 = (g1 + g2 + g3) * -1.0;
    const double h[4] = {1.0 / norm(g0), 1.0 / norm(g1), 1.0 / norm(g2), 1.0 / norm(g3)};
    const double hmin = std::min({h[0], h[1], h[2], h[3]});
    double mag = f.mag;
    for (int k = 0; k < 4; ++k) mag = std::max({mag, std::fabs(v[k].x), std::fabs(v[k].y), std::fabs(v[k].z)});
    bool clear = std::isfinite(hmin) && std::numeric_limits<double>::epsilon() * mag <= 1e-9 * hmin &&
                 m * kSteepCrossing * hmin >= 64 * std::numeric_limits<double>::epsilon() * mag;
    for (int k = 0; k < 4; ++k) {
      const double cosk = std::fabs(dl[k]) * h[k] * f.invLen;
      clear = clear && cosk >= (k == crossed[0] || k == crossed[1] ? kSteepCrossing : 1e-3);
    }
    // lambda_k vanishes on the face opposite point k: faces 1, 2, 0, 3.
    static constexpr int kFaceOf[4] = {1, 2, 0, 3};
    if (clear) *face = kFaceOf[t == te ? crossed[0] : crossed[1]];
  }
  return true;
}

/// The same for a hexahedron, wedge or pyramid whose faces are planar (to round-off) and which is
/// convex: vtkHexahedron, vtkWedge and vtkPyramid report the smallest t in [0, 1] at which the
/// segment crosses one of their faces, each face a triangle or a quad that vtkQuad splits into
/// two triangles along one of its diagonals. With planar faces the line meets the convex cell's
/// boundary only where it enters (te) and leaves (tx); the hit is te if 0 < te <= 1, else tx if
/// te <= 0 < tx <= 1. It is certain when both crossings lie inside their faces by a margin (every
/// other face plane at least m L away, L the cell's bounding-box diagonal), a quad face's
/// crossing is m L away from both its diagonals (so whichever split VTK picks, one triangle
/// holds it well inside and the other well outside), neither crossing is near an end of the
/// segment, and the cell is not flat. m is tetraFirstHitIfCertain's margin. A non-convex or
/// degenerate cell, and a segment that misses: false (VTK decides).
///
/// Warped faces (f.quadSplit known; a quad's points off its plane by `warp` L, beyond round-off
/// and up to kMaxFaceWarp): VTK's two triangles of each face lie within warp L of its plane, so
/// the line meets VTK's surface only within W = warp / c of the planes' crossings along it (c the
/// smaller |cos| of the entry and exit crossings; units of L), where every distance the checks
/// use moves by at most W. The checks are then made with m + 32 W (W <= kMaxFaceWarp, else
/// false), the miss proof with m + 2 warp, and t is where the line crosses the plane of the
/// triangle of VTK's split that holds the hit (quadSplitCrossing), not the face's plane.
///
/// face (optional): on true, the face (the topology's numbering, VTK's) that holds the hit, or
/// -1. It is given only when the line crosses both the entry and the exit face at an angle:
/// |cos| of the angle between the segment and either face's normal >= kSteepCrossing. Then no
/// other face of the cell comes within m kSteepCrossing L of the line (a face j crossed at t_j
/// before the entry lies outside the entry face's plane by (te - t_j) |dl_entry| L, and
/// (te - t_j) |dl_j| >= m because the entry is m inside plane j; the same after the exit), so
/// VTK's face tests, exact containment at tol 0, reject every face but the two crossed, and the
/// other crossed face's t is not the first: VTK's hit is that face's, whatever the other faces.
///
/// miss (optional): set when the cell passes the planarity and convexity checks and the line,
/// for t in [-1e-9, 1 + 1e-9], stays outside some face plane by m L (the function then returns
/// false): every point of the segment is then m L from the convex cell and from each of its
/// faces (VTK's triangles lie within round-off, planeEps L <= m L, or the warp of those planes), so none
/// of VTK's exact (tol 0) face tests can accept a crossing: VTK reports no hit.
/// convexFirstHitIfCertain's test on the cell's points p (topo's count), their bounds lo, hi and
/// largest coordinate magnitude vmag; f valid, f.tol == 0 and miss (if given) false on entry.
/// memo (optional): the cell's ConvexShapeMemo byte (see there); the verdicts are the same with
/// or without it.
inline bool convexCertainFromPoints(const SegmentFrame& f, const CellTopology* topo, const Vec3* p, Vec3 lo, Vec3 hi,
                                    double vmag, double& t, int* face, bool* miss, uint8_t* memo = nullptr);

/// The largest warp of a quad face (its points' distance from the plane the test takes for it, in
/// units of the cell's diagonal L) for which convexCertainFromPoints still answers, and the
/// largest warp over the |cos| of the crossings (W, see there).
constexpr double kMaxFaceWarp = 1e-4;

/// The triangle of a quad's split (QuadSplit::kDiagonal02: (0, 1, 2) or (2, 3, 0)) that holds x, a
/// point near the quad and far (against its warp) from the diagonal 0-2; t where the line
/// p1 + t d crosses that triangle's plane. False for a degenerate triangle or a line parallel to it.
inline bool quadSplitCrossing(const SegmentFrame& f, const Vec3 q[4], const Vec3& x, double& t) {
  const Vec3 e = q[2] - q[0];
  const Vec3 b = dot(cross(e, x - q[0]), cross(e, q[1] - q[0])) > 0 ? q[1] : q[3];
  const Vec3 n = cross(b - q[0], e);
  const double tt = dot(n, q[0] - f.p1) / dot(n, f.d);
  if (!std::isfinite(tt)) return false;
  t = tt;
  return true;
}

/// What convexCertainFromPoints learns of a cell that does not depend on the segment, kept in one
/// byte per cell so that the next segment skips the checks: 0 (kUnknown) until a first call has
/// decided; kNotConvex for a degenerate, flat or non-convex cell (the test then always answers
/// false); kPlanarConvex | flips for a convex, non-degenerate cell whose quad faces are planar
/// within the round-off of the cell's own coordinates (64 eps vmag / L, where a call allows
/// 64 eps max(|segment|, vmag) / L, never less: planar for every segment), bit i of flips set
/// where face i's computed normal points inwards; kWarpedConvex | flips for a convex cell with
/// a face warped beyond that round-off (each call measures the warp again against its own
/// limits). A cell some quad of which is warped beyond the call's limit is left as it is.
/// Reads and writes are relaxed atomics: threads that race store the same byte.
struct ConvexShapeMemo {
  static constexpr uint8_t kUnknown = 0, kNotConvex = 0x40, kPlanarConvex = 0x80, kWarpedConvex = 0xc0,
                           kFlipsMask = 0x3f;
  /// Convex with its flips known (planar or warped); planar and convex.
  static bool convex(uint8_t m) { return (m & kPlanarConvex) != 0; }
  static bool planar(uint8_t m) { return (m & kWarpedConvex) == kPlanarConvex; }
  static uint8_t load(const uint8_t* m) { return m ? __atomic_load_n(m, __ATOMIC_RELAXED) : kUnknown; }
  static void store(uint8_t* m, uint8_t v) {
    if (m) __atomic_store_n(m, v, __ATOMIC_RELAXED);
  }
};

inline bool convexFirstHitIfCertain(const SegmentFrame& f, const CellSet& cells, size_t c, double& t,
                                    int* face = nullptr, bool* miss = nullptr) {
  if (miss) *miss = false;
  if (!f.valid || f.tol != 0) return false;
  const uint8_t type = cells.type(c);
  if (type != kHexahedron && type != kWedge && type != kPyramid) return false;
  const CellTopology* topo = cellTopology(type);
  if (!topo || cells.numCellPoints(c) != topo->numPoints) return false;
  const int n = topo->numPoints;
  Vec3 p[CellSet::kMaxLocalPoints];
  Vec3 lo(std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
          std::numeric_limits<double>::infinity());
  Vec3 hi = lo * -1.0;
  double vmag = 0;
  for (int k = 0; k < n; ++k) {
    p[k] = cells.cellPoint(c, k);
    lo = vmin(lo, p[k]);
    hi = vmax(hi, p[k]);
    vmag = std::max({vmag, std::fabs(p[k].x), std::fabs(p[k].y), std::fabs(p[k].z)});
  }
  return convexCertainFromPoints(f, topo, p, lo, hi, vmag, t, face, miss);
}

inline bool convexCertainFromPoints(const SegmentFrame& f, const CellTopology* topo, const Vec3* p, Vec3 lo, Vec3 hi,
                                    double vmag, double& t, int* face, bool* miss, uint8_t* memo) {
  using Memo = ConvexShapeMemo;
  const uint8_t known = Memo::load(memo);
  if (known == Memo::kNotConvex) return false;
  const int n = topo->numPoints;
  const double L = norm(hi - lo);
  if (!(L > 0) || !std::isfinite(L)) return false;
  constexpr double eps = std::numeric_limits<double>::epsilon();
  const double mag = std::max(f.mag, vmag);
  // As in tetraFirstHitIfCertain: VTK's t must not be able to reorder hits by more than 1e-9.
  if (1024 * eps * mag * f.invLen > 1e-10) return false;
  // Round-off of a point's distance to a face plane, in units of L.
  const double planeEps = 64 * eps * mag / L;
  const Vec3 r1 = f.p1 - lo;
  const double far = (norm(r1) + norm(r1 + f.d)) / L;
  const double m = 1e-6 + 1e-9 * far + 1024 * eps * mag / L;
  // Each face: unit outward normal nu and a point o on it; l1 = -dot(nu, p1 - o) / L is how far
  // inside the plane p1 lies (units of L), dl its change along d.
  const double invL = 1.0 / L;
  double l1[6], dl[6];
  const int nf = topo->numFaces;
  // The faces' normals and their scales first, every face's, so that the square roots and
  // divisions overlap (the checks below wait on them).
  Vec3 nrms[6];
  double scale[6];
  bool degenerate = false;
  for (int i = 0; i < nf; ++i) {
    const int* v = topo->face[i];
    nrms[i] = topo->faceSize[i] == 4 ? cross(p[v[2]] - p[v[0]], p[v[3]] - p[v[1]])
                                     : cross(p[v[1]] - p[v[0]], p[v[2]] - p[v[0]]);
    const double nn2 = dot(nrms[i], nrms[i]);
    degenerate = degenerate || !(nn2 > 1e-12 * L * L * L * L);
    // Unit normal scaled by 1 / L: dot products with it are distances in units of L.
    scale[i] = invL / std::sqrt(nn2);
  }
  if (degenerate) {  // a degenerate face
    Memo::store(memo, Memo::kNotConvex);
    return false;
  }
  // The round-off of the cell's own coordinates (planeEps with vmag alone): planar within it is
  // planar for every segment (the memo's kPlanarConvex).
  const double cellPlaneEps = 64 * eps * vmag / L;
  bool cellPlanar = true;
  // The largest distance of a quad face's point from its plane (units of L); beyond round-off
  // (planeEps) the cell is warped, and up to kMaxFaceWarp the margins below absorb it.
  double warp = 0;
  const double warpLimit = f.quadSplit == QuadSplit::kUnknown ? planeEps : std::max(planeEps, kMaxFaceWarp);
  const bool convexKnown = Memo::convex(known), planarKnown = Memo::planar(known);
  uint8_t flips = 0;
  for (int i = 0; i < nf; ++i) {
    const int* v = topo->face[i];
    const bool quad = topo->faceSize[i] == 4;
    Vec3 nrm = nrms[i] * scale[i];
    const Vec3 o = p[v[0]];
    // Planar (a quad's other points on the plane through v[0] to round-off, or within the warp
    // limit; a triangle's are by construction) and convex (every other point of the cell on one
    // side, the inner one); the topology's faces are wound outward, but a tangled cell may not
    // be: the side is taken from the cell's points. The memo's kPlanarConvex skips both checks,
    // its kWarpedConvex the second.
    if (quad && !planarKnown)
      for (int j = 1; j < 4; ++j) {
        const double off = std::fabs(dot(nrm, p[v[j]] - o));
        if (!(off <= warpLimit)) return false;  // a face too warped: VTK decides
        warp = std::max(warp, off);
        cellPlanar = cellPlanar && off <= cellPlaneEps;
      }
    if (convexKnown) {
      if ((known >> i) & 1) nrm = nrm * -1.0;
    } else {
      unsigned onFace = 0;
      for (int j = 0; j < topo->faceSize[i]; ++j) onFace |= 1u << v[j];
      double inner = 0;
      for (int k = 0; k < n; ++k) {
        if ((onFace >> k) & 1) continue;
        const double s = dot(nrm, p[k] - o);
        if (!(std::fabs(s) > 1e-3)) {  // a point (nearly) on another face's plane: flat or odd
          Memo::store(memo, Memo::kNotConvex);
          return false;
        }
        if (inner == 0) inner = s;
        else if ((s > 0) != (inner > 0)) {  // points on both sides: not convex
          Memo::store(memo, Memo::kNotConvex);
          return false;
        }
      }
      if (inner > 0) {  // outward: the cell's points lie at negative distance
        nrm = nrm * -1.0;
        flips = static_cast<uint8_t>(flips | 1u << i);
      }
    }
    l1[i] = -dot(nrm, f.p1 - o);
    dl[i] = -dot(nrm, f.d);
  }
  if (!convexKnown)
    Memo::store(memo, static_cast<uint8_t>((cellPlanar ? Memo::kPlanarConvex : Memo::kWarpedConvex) | flips));
  // Warped: VTK's triangles of a quad face lie within warp L of its plane, not within round-off.
  // (A cell the memo knows planar has warp 0 here, as it had on the call that set the memo.)
  const bool warped = warp > planeEps;
  // Where the line enters (te, face ie) and leaves (tx, ix) the cell: found once, with margin m,
  // before the miss proof only where the warp's margin needs them (1 found, 0 none, -1 not yet).
  double te = 0, tx = 0;
  int ie = -1, ix = -1, crossings = -1;
  // The miss proof's and the certain hit's margins (units of L); m for planar faces.
  double mMiss = m, mc = m;
  if (warped) {
    mMiss = m + 2 * warp;
    // Where the line crosses the entry and exit planes at |cos| c to their normals, VTK's
    // surface there lies within W = warp / c of the crossing, along the line (units of L), and
    // every other distance the checks below use moves by at most W over that stretch: they are
    // made with m + 32 W (32: the face-clear condition's kSteepCrossing 1/20 of it still exceeds
    // the warp of the faces that must stay clear).
    crossings = lineCrossings(l1, dl, nf, m, te, tx, ie, ix) ? 1 : 0;
    if (crossings) {
      const double c = std::min(std::fabs(dl[ie]), std::fabs(dl[ix])) * L * f.invLen;
      const double W = warp / c;
      mc = W <= kMaxFaceWarp ? m + 32 * W : std::numeric_limits<double>::infinity();
    }
  }
  // A quad face's crossing must also be away from both its diagonals (in its plane: distance to
  // the diagonal's line).
  auto nearDiagonal = [&](double tc, int ic) {
    if (topo->faceSize[ic] != 4) return false;
    const int* v = topo->face[ic];
    const Vec3 x = f.p1 + f.d * tc;
    for (int k = 0; k < 2; ++k) {
      const Vec3 a = p[v[k]], e = p[v[k + 2]] - a;
      const Vec3 c = cross(e, x - a);  // |c| / |e|: the distance to the diagonal's line
      if (!(dot(c, c) >= mc * mc * L * L * dot(e, e))) return true;
    }
    return false;
  };
  if (miss) {
    // Outside plane i by m where l1[i] + t dl[i] <= -m: for t <= lo_i (dl > 0), t >= hi_i
    // (dl < 0), everywhere or nowhere (dl == 0). Those sets cover [a, b] when one of them
    // does, or when the last "t <=" set reaches the first "t >=" set.
    const double a = -1e-9, b = 1 + 1e-9;
    double upTo = -std::numeric_limits<double>::infinity(), from = std::numeric_limits<double>::infinity();
    bool covered = false;
    for (int i = 0; i < nf; ++i) {
      if (dl[i] > 0) upTo = std::max(upTo, (-mMiss - l1[i]) / dl[i]);
      else if (dl[i] < 0) from = std::min(from, (-mMiss - l1[i]) / dl[i]);
      else covered = covered || l1[i] <= -mMiss;
    }
    if (covered || upTo >= b || from <= a || upTo >= from) {
      *miss = true;
      return false;
    }
  }
  if (crossings < 0) crossings = lineCrossings(l1, dl, nf, m, te, tx, ie, ix) ? 1 : 0;
  int crossed[2];
  // The crossings' clearance with mc >= m (a parallel face's too: see crossingsClear).
  if (!(mc < std::numeric_limits<double>::infinity()) || !crossings ||
      !crossingsClear(l1, dl, nf, mc, te, tx, ie, ix, nearDiagonal, crossed) || !firstCrossingInSegment(te, tx, t))
    return false;
  const int hitFace = t == te ? crossed[0] : crossed[1];
  if (warped && topo->faceSize[hitFace] == 4) {
    // The crossing of the plane is up to W off VTK's: t where the line crosses the plane of the
    // triangle of VTK's split that holds the hit.
    const int* v = topo->face[hitFace];
    const Vec3 q[4] = {p[v[0]], p[v[1]], p[v[2]], p[v[3]]};
    if (!quadSplitCrossing(f, q, f.p1 + f.d * t, t)) return false;
  }
  if (face) {
    // |dl| = |cos| |d| / L; f.invLen = 1 / |d|.
    const double steep = kSteepCrossing * invL;
    const bool clear = std::fabs(dl[crossed[0]]) * f.invLen >= steep && std::fabs(dl[crossed[1]]) * f.invLen >= steep;
    *face = clear ? hitFace : -1;
  }
  return true;
}

/// tetraFirstHitIfCertain or convexFirstHitIfCertain, by the cell's type.
/// face, miss: as convexFirstHitIfCertain's (-1 and false for tetrahedra).
inline bool firstHitIfCertain(const SegmentFrame& f, const CellSet& cells, size_t c, double& t, int* face = nullptr,
                              bool* miss = nullptr) {
  const uint8_t type = cells.type(c);
  if (face) *face = -1;
  if (miss) *miss = false;
  if (type == kTetra) return tetraFirstHitIfCertain(f, cells, c, t);
  return convexFirstHitIfCertain(f, cells, c, t, face, miss);
}

/// What the ray queries ask of a candidate: segmentMayHitCell (kMiss: VTK cannot hit it at
/// t <= tMax) and then, with wantCertain, firstHitIfCertain (kCertain, with t; kMiss where it
/// proves that VTK reports no hit at all), the points of a tetrahedron read once for both.
/// kAskVtk otherwise. shapeMemo (optional): one ConvexShapeMemo byte per cell of `cells`, zero
/// at first, shared by every query on these cells (the same verdicts, fewer checks).
enum class CellVerdict { kMiss, kAskVtk, kCertain };
inline CellVerdict decideCell(const SegmentFrame& f, const CellSet& cells, size_t c, double tMax, bool wantCertain,
                              double& t, int* face = nullptr, uint8_t* shapeMemo = nullptr) {
  if (face) *face = -1;
  if (f.valid && cells.type(c) == kTetra && cells.numCellPoints(c) == 4) {
    const Vec3 v[4] = {cells.cellPoint(c, 0), cells.cellPoint(c, 1), cells.cellPoint(c, 2), cells.cellPoint(c, 3)};
    const int verdict = tetraMayHit(f, v, tMax);
    if (verdict == 0) return CellVerdict::kMiss;
    if (verdict > 0) return wantCertain && tetraCertainHit(f, v, t) ? CellVerdict::kCertain : CellVerdict::kAskVtk;
  }
  if (wantCertain && f.valid && f.tol == 0) {
    // Hexahedra, wedges and pyramids: segmentMayHitCell's ray-frame test and
    // convexFirstHitIfCertain on one read of the points (the same arithmetic, the same verdicts).
    const uint8_t type = cells.type(c);
    const CellTopology* topo =
        type == kHexahedron || type == kWedge || type == kPyramid ? cellTopology(type) : nullptr;
    if (topo && cells.numCellPoints(c) == topo->numPoints) {
      const int n = topo->numPoints;
      Vec3 p[CellSet::kMaxLocalPoints];
      RayFrameExtent rf;
      for (int k = 0; k < n; ++k) {
        double a, b;
        rf.add(f, p[k] = cells.cellPoint(c, k), a, b);
      }
      const double r = rf.radius(f);
      if (std::isfinite(r) && rf.outside(f, r, tMax)) return CellVerdict::kMiss;
      bool miss = false;
      if (convexCertainFromPoints(f, topo, p, rf.lo, rf.hi, rf.vmag, t, face, &miss, shapeMemo ? shapeMemo + c : nullptr))
        return CellVerdict::kCertain;
      return miss ? CellVerdict::kMiss : CellVerdict::kAskVtk;
    }
  }
  if (!segmentMayHitCell(f, cells, c, tMax)) return CellVerdict::kMiss;
  if (!wantCertain) return CellVerdict::kAskVtk;
  bool miss = false;
  if (firstHitIfCertain(f, cells, c, t, face, &miss)) return CellVerdict::kCertain;
  return miss ? CellVerdict::kMiss : CellVerdict::kAskVtk;
}

}  // namespace mtree
