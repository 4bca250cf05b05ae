// VTK 9.1's EvaluatePosition and IntersectWithLine of the quadratic volume cells (see
// cell_mirror.h): vtkQuadraticTetra (10 points), vtkQuadraticHexahedron (20),
// vtkQuadraticWedge (15), vtkQuadraticPyramid (13) and vtkTriQuadraticHexahedron (27).
//
// EvaluatePosition: VTK's damped Newton inversion (isoparametricEvaluatePosition, steps halved),
// each type's interpolation functions and derivatives as VTK writes them; the triquadratic
// hexahedron starts from its corners' linear hexahedron's answer, the pyramid checks its apex
// first. IntersectWithLine: each face as VTK's face cell tests it — a vtkQuadraticTriangle as
// its four linear triangles, a vtkQuadraticQuad as four linear quads around its interpolated
// centre, a vtkBiQuadraticQuad as four linear quads around its centre node — and the face's
// pcoords mapped as the cell maps them (VTK 9.1's mappings, copied from the hexahedron's for the
// wedge and pyramid; the pyramid's triangle faces all test the pyramid's first six points, as
// 9.1's shallow copy of the cell's points into its triangle face makes it do).
#include <algorithm>
#include <cmath>

#include "cell_mirror_detail.h"
#include "mtree/cells/cells.h"
#include "mtree/vtk91/cell_mirror.h"

namespace mtree {
namespace vtk91 {
namespace mirror {

namespace {

// ---- interpolation functions and derivatives --------------------------------------------------

struct QuadraticTetra : StartAt<QuadraticTetra> {
  static constexpr int N = 10;
  static void functions(const double pcoords[3], double weights[10]) {
    const double r = pcoords[0], s = pcoords[1], t = pcoords[2];
    const double u = 1.0 - r - s - t;
    weights[0] = u * (2.0 * u - 1.0);
    weights[1] = r * (2.0 * r - 1.0);
    weights[2] = s * (2.0 * s - 1.0);
    weights[3] = t * (2.0 * t - 1.0);
    weights[4] = 4.0 * u * r;
    weights[5] = 4.0 * r * s;
    weights[6] = 4.0 * s * u;
    weights[7] = 4.0 * u * t;
    weights[8] = 4.0 * r * t;
    weights[9] = 4.0 * s * t;
  }
  static void derivs(const double pcoords[3], double d[30]) {
    const double r = pcoords[0], s = pcoords[1], t = pcoords[2];
    d[0] = 4.0 * (r + s + t) - 3.0;
    d[1] = 4.0 * r - 1.0;
    d[2] = 0.0;
    d[3] = 0.0;
    d[4] = 4.0 - 8.0 * r - 4.0 * s - 4.0 * t;
    d[5] = 4.0 * s;
    d[6] = -4.0 * s;
    d[7] = -4.0 * t;
    d[8] = 4.0 * t;
    d[9] = 0.0;
    d[10] = 4.0 * (r + s + t) - 3.0;
    d[11] = 0.0;
    d[12] = 4.0 * s - 1.0;
    d[13] = 0.0;
    d[14] = -4.0 * r;
    d[15] = 4.0 * r;
    d[16] = 4.0 - 4.0 * r - 8.0 * s - 4.0 * t;
    d[17] = -4.0 * t;
    d[18] = 0.0;
    d[19] = 4.0 * t;
    d[20] = 4.0 * (r + s + t) - 3.0;
    d[21] = 0.0;
    d[22] = 0.0;
    d[23] = 4.0 * t - 1.0;
    d[24] = -4.0 * r;
    d[25] = 0.0;
    d[26] = -4.0 * s;
    d[27] = 4.0 - 4.0 * r - 4.0 * s - 8.0 * t;
    d[28] = 4.0 * r;
    d[29] = 4.0 * s;
  }
  static constexpr int kMaxIteration = 20;
  static constexpr double kConverged = 1.e-05, kDamping = 0.5;
  static void start(double p[3]) { p[0] = p[1] = p[2] = .25; }
  static double detTolerance(const double* pts) {
    static constexpr int kEdges[6][2] = {{0, 1}, {1, 2}, {2, 0}, {0, 3}, {1, 3}, {2, 3}};
    return longestPairTolerance(pts, kEdges);
  }
  static bool inside(const double pc[3]) {
    return pc[0] >= -0.001 && pc[0] <= 1.001 && pc[1] >= -0.001 && pc[1] <= 1.001 && pc[2] >= -0.001 &&
           pc[2] <= 1.001 && pc[0] + pc[1] + pc[2] <= 1.001;
  }
  static void clamp(const double pcoords[3], double pc[3]) { clampUnit(pcoords, pc); }
};

/// The serendipity hexahedron's functions are written on [-1, 1]^3.
struct QuadraticHexahedron : StartAt<QuadraticHexahedron> {
  static constexpr int N = 20;
  static void functions(const double pcoords[3], double w[20]) {
    const double r = 2.0 * (pcoords[0] - 0.5), s = 2.0 * (pcoords[1] - 0.5), t = 2.0 * (pcoords[2] - 0.5);
    const double rm = 1.0 - r, rp = 1.0 + r, sm = 1.0 - s, sp = 1.0 + s, tm = 1.0 - t, tp = 1.0 + t;
    const double r2 = 1.0 - r * r, s2 = 1.0 - s * s, t2 = 1.0 - t * t;
    w[0] = 0.125 * rm * sm * tm * (-r - s - t - 2.0);
    w[1] = 0.125 * rp * sm * tm * (r - s - t - 2.0);
    w[2] = 0.125 * rp * sp * tm * (r + s - t - 2.0);
    w[3] = 0.125 * rm * sp * tm * (-r + s - t - 2.0);
    w[4] = 0.125 * rm * sm * tp * (-r - s + t - 2.0);
    w[5] = 0.125 * rp * sm * tp * (r - s + t - 2.0);
    w[6] = 0.125 * rp * sp * tp * (r + s + t - 2.0);
    w[7] = 0.125 * rm * sp * tp * (-r + s + t - 2.0);
    w[8] = 0.25 * r2 * sm * tm;
    w[9] = 0.25 * s2 * rp * tm;
    w[10] = 0.25 * r2 * sp * tm;
    w[11] = 0.25 * s2 * rm * tm;
    w[12] = 0.25 * r2 * sm * tp;
    w[13] = 0.25 * s2 * rp * tp;
    w[14] = 0.25 * r2 * sp * tp;
    w[15] = 0.25 * s2 * rm * tp;
    w[16] = 0.25 * t2 * rm * sm;
    w[17] = 0.25 * t2 * rp * sm;
    w[18] = 0.25 * t2 * rp * sp;
    w[19] = 0.25 * t2 * rm * sp;
  }
  static void derivs(const double pcoords[3], double d[60]) {
    const double r = 2.0 * (pcoords[0] - 0.5), s = 2.0 * (pcoords[1] - 0.5), t = 2.0 * (pcoords[2] - 0.5);
    const double rm = 1.0 - r, rp = 1.0 + r, sm = 1.0 - s, sp = 1.0 + s, tm = 1.0 - t, tp = 1.0 + t;
    d[0] = -0.125 * (sm * tm - 2.0 * r * sm * tm - s * sm * tm - t * sm * tm - 2.0 * sm * tm);
    d[1] = 0.125 * (sm * tm + 2.0 * r * sm * tm - s * sm * tm - t * sm * tm - 2.0 * sm * tm);
    d[2] = 0.125 * (sp * tm + 2.0 * r * sp * tm + s * sp * tm - t * sp * tm - 2.0 * sp * tm);
    d[3] = -0.125 * (sp * tm - 2.0 * r * sp * tm + s * sp * tm - t * sp * tm - 2.0 * sp * tm);
    d[4] = -0.125 * (sm * tp - 2.0 * r * sm * tp - s * sm * tp + t * sm * tp - 2.0 * sm * tp);
    d[5] = 0.125 * (sm * tp + 2.0 * r * sm * tp - s * sm * tp + t * sm * tp - 2.0 * sm * tp);
    d[6] = 0.125 * (sp * tp + 2.0 * r * sp * tp + s * sp * tp + t * sp * tp - 2.0 * sp * tp);
    d[7] = -0.125 * (sp * tp - 2.0 * r * sp * tp + s * sp * tp + t * sp * tp - 2.0 * sp * tp);
    d[8] = -0.5 * r * sm * tm;
    d[9] = 0.25 * (tm - s * s * tm);
    d[10] = -0.5 * r * sp * tm;
    d[11] = -0.25 * (tm - s * s * tm);
    d[12] = -0.5 * r * sm * tp;
    d[13] = 0.25 * (tp - s * s * tp);
    d[14] = -0.5 * r * sp * tp;
    d[15] = -0.25 * (tp - s * s * tp);
    d[16] = -0.25 * (sm - t * t * sm);
    d[17] = 0.25 * (sm - t * t * sm);
    d[18] = 0.25 * (sp - t * t * sp);
    d[19] = -0.25 * (sp - t * t * sp);
    d[20] = -0.125 * (rm * tm - 2.0 * s * rm * tm - r * rm * tm - t * rm * tm - 2.0 * rm * tm);
    d[21] = -0.125 * (rp * tm - 2.0 * s * rp * tm + r * rp * tm - t * rp * tm - 2.0 * rp * tm);
    d[22] = 0.125 * (rp * tm + 2.0 * s * rp * tm + r * rp * tm - t * rp * tm - 2.0 * rp * tm);
    d[23] = 0.125 * (rm * tm + 2.0 * s * rm * tm - r * rm * tm - t * rm * tm - 2.0 * rm * tm);
    d[24] = -0.125 * (rm * tp - 2.0 * s * rm * tp - r * rm * tp + t * rm * tp - 2.0 * rm * tp);
    d[25] = -0.125 * (rp * tp - 2.0 * s * rp * tp + r * rp * tp + t * rp * tp - 2.0 * rp * tp);
    d[26] = 0.125 * (rp * tp + 2.0 * s * rp * tp + r * rp * tp + t * rp * tp - 2.0 * rp * tp);
    d[27] = 0.125 * (rm * tp + 2.0 * s * rm * tp - r * rm * tp + t * rm * tp - 2.0 * rm * tp);
    d[28] = -0.25 * (tm - r * r * tm);
    d[29] = -0.5 * s * rp * tm;
    d[30] = 0.25 * (tm - r * r * tm);
    d[31] = -0.5 * s * rm * tm;
    d[32] = -0.25 * (tp - r * r * tp);
    d[33] = -0.5 * s * rp * tp;
    d[34] = 0.25 * (tp - r * r * tp);
    d[35] = -0.5 * s * rm * tp;
    d[36] = -0.25 * (rm - t * t * rm);
    d[37] = -0.25 * (rp - t * t * rp);
    d[38] = 0.25 * (rp - t * t * rp);
    d[39] = 0.25 * (rm - t * t * rm);
    d[40] = -0.125 * (rm * sm - 2.0 * t * rm * sm - r * rm * sm - s * rm * sm - 2.0 * rm * sm);
    d[41] = -0.125 * (rp * sm - 2.0 * t * rp * sm + r * rp * sm - s * rp * sm - 2.0 * rp * sm);
    d[42] = -0.125 * (rp * sp - 2.0 * t * rp * sp + r * rp * sp + s * rp * sp - 2.0 * rp * sp);
    d[43] = -0.125 * (rm * sp - 2.0 * t * rm * sp - r * rm * sp + s * rm * sp - 2.0 * rm * sp);
    d[44] = 0.125 * (rm * sm + 2.0 * t * rm * sm - r * rm * sm - s * rm * sm - 2.0 * rm * sm);
    d[45] = 0.125 * (rp * sm + 2.0 * t * rp * sm + r * rp * sm - s * rp * sm - 2.0 * rp * sm);
    d[46] = 0.125 * (rp * sp + 2.0 * t * rp * sp + r * rp * sp + s * rp * sp - 2.0 * rp * sp);
    d[47] = 0.125 * (rm * sp + 2.0 * t * rm * sp - r * rm * sp + s * rm * sp - 2.0 * rm * sp);
    d[48] = -0.25 * (sm - r * r * sm);
    d[49] = -0.25 * (rp - s * s * rp);
    d[50] = -0.25 * (sp - r * r * sp);
    d[51] = -0.25 * (rm - s * s * rm);
    d[52] = 0.25 * (sm - r * r * sm);
    d[53] = 0.25 * (rp - s * s * rp);
    d[54] = 0.25 * (sp - r * r * sp);
    d[55] = 0.25 * (rm - s * s * rm);
    d[56] = -0.5 * t * rm * sm;
    d[57] = -0.5 * t * rp * sm;
    d[58] = -0.5 * t * rp * sp;
    d[59] = -0.5 * t * rm * sp;
    for (int i = 0; i < 60; i++) d[i] *= 2;
  }
  static constexpr int kMaxIteration = 20;
  static constexpr double kConverged = 1.e-04, kDamping = 0.5;
  static void start(double p[3]) { p[0] = p[1] = p[2] = 0.5; }
  static double detTolerance(const double* pts) {
    static constexpr int kDiagonals[4][2] = {{0, 6}, {1, 7}, {2, 4}, {3, 5}};
    return longestPairTolerance(pts, kDiagonals);
  }
  static bool inside(const double pc[3]) {
    return pc[0] >= -0.001 && pc[0] <= 1.001 && pc[1] >= -0.001 && pc[1] <= 1.001 && pc[2] >= -0.001 &&
           pc[2] <= 1.001;
  }
  static void clamp(const double pcoords[3], double pc[3]) { clampUnit(pcoords, pc); }
};

struct QuadraticWedge : StartAt<QuadraticWedge> {
  static constexpr int N = 15;
  static void functions(const double pcoords[3], double w[15]) {
    const double r = pcoords[0], s = pcoords[1], t = pcoords[2];
    w[0] = 2 * (1 - r - s) * (1 - t) * (.5 - r - s - t);
    w[1] = 2 * r * (1 - t) * (r - t - 0.5);
    w[2] = 2 * s * (1 - t) * (s - t - 0.5);
    w[3] = 2 * (1 - r - s) * t * (t - r - s - 0.5);
    w[4] = 2 * r * t * (r + t - 1.5);
    w[5] = 2 * s * t * (s + t - 1.5);
    w[6] = 4 * r * (1 - r - s) * (1 - t);
    w[7] = 4 * r * s * (1 - t);
    w[8] = 4 * (1 - r - s) * s * (1 - t);
    w[9] = 4 * r * (1 - r - s) * t;
    w[10] = 4 * r * s * t;
    w[11] = 4 * (1 - r - s) * s * t;
    w[12] = 4 * t * (1 - r - s) * (1 - t);
    w[13] = 4 * t * r * (1 - t);
    w[14] = 4 * t * s * (1 - t);
  }
  static void derivs(const double pcoords[3], double d[45]) {
    const double r = pcoords[0], s = pcoords[1], t = pcoords[2];
    d[0] = 2 * (1 - t) * (-1.5 + 2 * r + 2 * s + t);
    d[1] = 2 * (1 - t) * (-0.5 + 2 * r - t);
    d[2] = 0;
    d[3] = 2 * t * (-0.5 + 2 * r + 2 * s - t);
    d[4] = 2 * t * (-1.5 + 2 * r + t);
    d[5] = 0;
    d[6] = 4 * (1 - t) * (1 - 2 * r - s);
    d[7] = 4 * (1 - t) * s;
    d[8] = -d[7];
    d[9] = 4 * t * (1 - 2 * r - s);
    d[10] = 4 * s * t;
    d[11] = -d[10];
    d[12] = -4 * t * (1 - t);
    d[13] = -d[12];
    d[14] = 0;
    d[15] = d[0];
    d[16] = 0;
    d[17] = 2 * (1 - t) * (-0.5 + 2 * s - t);
    d[18] = d[3];
    d[19] = 0;
    d[20] = 2 * t * (-1.5 + 2 * s + t);
    d[21] = -4 * (1 - t) * r;
    d[22] = -d[21];
    d[23] = 4 * (1 - t) * (1 - r - 2 * s);
    d[24] = -4 * r * t;
    d[25] = -d[24];
    d[26] = 4 * t * (1 - r - 2 * s);
    d[27] = d[12];
    d[28] = 0;
    d[29] = -d[27];
    d[30] = 2 * (1 - r - s) * (-1.5 + r + s + 2 * t);
    d[31] = 2 * r * (-0.5 - r + 2 * t);
    d[32] = 2 * s * (-0.5 - s + 2 * t);
    d[33] = 2 * (1 - r - s) * (-0.5 - r - s + 2 * t);
    d[34] = 2 * r * (-1.5 + r + 2 * t);
    d[35] = 2 * s * (-1.5 + s + 2 * t);
    d[36] = -4 * r * (1 - r - s);
    d[37] = -4 * r * s;
    d[38] = -4 * s * (1 - r - s);
    d[39] = -d[36];
    d[40] = -d[37];
    d[41] = -d[38];
    d[42] = 4 * (1 - 2 * t) * (1 - r - s);
    d[43] = 4 * (1 - 2 * t) * r;
    d[44] = 4 * (1 - 2 * t) * s;
  }
  static constexpr int kMaxIteration = 10;
  static constexpr double kConverged = 1.e-03, kDamping = 0.5;
  static void start(double p[3]) { p[0] = p[1] = p[2] = 0.5; }
  static double detTolerance(const double* pts) {
    static constexpr int kEdges[9][2] = {{0, 1}, {1, 2}, {2, 0}, {3, 4}, {4, 5}, {5, 3}, {0, 3}, {1, 4}, {2, 5}};
    return longestPairTolerance(pts, kEdges);
  }
  static bool inside(const double pc[3]) {
    return pc[0] >= -0.001 && pc[0] <= 1.001 && pc[1] >= -0.001 && pc[1] <= 1.001 && pc[2] >= -0.001 &&
           pc[2] <= 1.001 && pc[0] + pc[1] <= 1.001;
  }
  static void clamp(const double pcoords[3], double pc[3]) { clampUnit(pcoords, pc); }
};

struct QuadraticPyramid : StartAt<QuadraticPyramid> {
  static constexpr int N = 13;
  static void functions(const double pcoords[3], double w[13]) {
    const double r = 2.0 * (pcoords[0] - 0.5), s = 2.0 * (pcoords[1] - 0.5), t = 2.0 * (pcoords[2] - 0.5);
    const double r2 = r * r, s2 = s * s, t2 = t * t;
    w[0] = -(1 - r) * (1 - s) * (1 - t) * (4 + 3 * r + 3 * s + 2 * r * s + 2 * t + r * t + s * t + 2 * r * s * t) /
           16.0;
    w[1] = -(1 + r) * (1 - s) * (1 - t) * (4 - 3 * r + 3 * s - 2 * r * s + 2 * t - r * t + s * t - 2 * r * s * t) /
           16.0;
    w[2] = -(1 + r) * (1 + s) * (1 - t) * (4 - 3 * r - 3 * s + 2 * r * s + 2 * t - r * t - s * t + 2 * r * s * t) /
           16.0;
    w[3] = -(1 - r) * (1 + s) * (1 - t) * (4 + 3 * r - 3 * s - 2 * r * s + 2 * t + r * t - s * t - 2 * r * s * t) /
           16.0;
    w[4] = t * (1 + t) / 2.0;
    w[5] = (1 - r2) * (1 - s) * (1 - t) * (2 + s + s * t) / 8.0;
    w[6] = (1 + r) * (1 - s2) * (1 - t) * (2 - r - r * t) / 8.0;
    w[7] = (1 - r2) * (1 + s) * (1 - t) * (2 - s - s * t) / 8.0;
    w[8] = (1 - r) * (1 - s2) * (1 - t) * (2 + r + r * t) / 8.0;
    w[9] = (1 - r) * (1 - s) * (1 - t2) / 4.0;
    w[10] = (1 + r) * (1 - s) * (1 - t2) / 4.0;
    w[11] = (1 + r) * (1 + s) * (1 - t2) / 4.0;
    w[12] = (1 - r) * (1 + s) * (1 - t2) / 4.0;
  }
  static void derivs(const double pcoords[3], double d[39]) {
    const double r = 2 * pcoords[0] - 1, s = 2 * pcoords[1] - 1, t = 2 * pcoords[2] - 1;
    const double rm = 1.0 - r, rp = 1.0 + r, sm = 1.0 - s, sp = 1.0 + s, tm = 1.0 - t;
    const double r2 = 1.0 - r * r, t2 = 1.0 - t * t;
    d[0] = -0.125 * (sm * tm - 2.0 * r * sm * tm - s * sm * tm - t * sm * tm - 2.0 * sm * tm);
    d[1] = 0.125 * (sm * tm + 2.0 * r * sm * tm - s * sm * tm - t * sm * tm - 2.0 * sm * tm);
    d[2] = 0.125 * (sp * tm + 2.0 * r * sp * tm + s * sp * tm - t * sp * tm - 2.0 * sp * tm);
    d[3] = -0.125 * (sp * tm - 2.0 * r * sp * tm + s * sp * tm - t * sp * tm - 2.0 * sp * tm);
    d[4] = 0.0;
    d[5] = -0.5 * r * sm * tm;
    d[6] = 0.25 * (tm - s * s * tm);
    d[7] = -0.5 * r * sp * tm;
    d[8] = -0.25 * (tm - s * s * tm);
    d[9] = -0.25 * (1 - s) * (1 - t * t);
    d[10] = 0.25 * (1 - s) * (1 - t * t);
    d[11] = 0.25 * (1 + s) * (1 - t * t);
    d[12] = -0.25 * (1 + s) * (1 - t * t);
    d[13] = -0.125 * (rm * tm - 2.0 * s * rm * tm - r * rm * tm - t * rm * tm - 2.0 * rm * tm);
    d[14] = -0.125 * (rp * tm - 2.0 * s * rp * tm + r * rp * tm - t * rp * tm - 2.0 * rp * tm);
    d[15] = 0.125 * (rp * tm + 2.0 * s * rp * tm + r * rp * tm - t * rp * tm - 2.0 * rp * tm);
    d[16] = 0.125 * (rm * tm + 2.0 * s * rm * tm - r * rm * tm - t * rm * tm - 2.0 * rm * tm);
    d[17] = 0.0;
    d[18] = -0.25 * tm * r2;
    d[19] = -0.5 * tm * s * rp;
    d[20] = 0.25 * tm * r2;
    d[21] = -0.5 * tm * s * rm;
    d[22] = -0.25 * rm * t2;
    d[23] = -0.25 * rp * t2;
    d[24] = 0.25 * rp * t2;
    d[25] = 0.25 * rm * t2;
    d[26] = -0.125 * (rm * sm - 2.0 * t * rm * sm - r * rm * sm - s * rm * sm - 2.0 * rm * sm);
    d[27] = -0.125 * (rp * sm - 2.0 * t * rp * sm + r * rp * sm - s * rp * sm - 2.0 * rp * sm);
    d[28] = -0.125 * (rp * sp - 2.0 * t * rp * sp + r * rp * sp + s * rp * sp - 2.0 * rp * sp);
    d[29] = -0.125 * (rm * sp - 2.0 * t * rm * sp - r * rm * sp + s * rm * sp - 2.0 * rm * sp);
    d[30] = 0.5 + t;
    d[31] = -0.25 * (sm - r * r * sm);
    d[32] = -0.25 * (rp - s * s * rp);
    d[33] = -0.25 * (sp - r * r * sp);
    d[34] = -0.25 * (rm - s * s * rm);
    d[35] = -0.5 * (1 - r) * (1 - s) * t;
    d[36] = -0.5 * (1 + r) * (1 - s) * t;
    d[37] = -0.5 * (1 + r) * (1 + s) * t;
    d[38] = -0.5 * (1 - r) * (1 + s) * t;
    for (int i = 0; i < 39; i++) d[i] *= 2;
  }
  static constexpr int kMaxIteration = 20;
  static constexpr double kConverged = 1.e-03, kDamping = 0.5;
  static void start(double p[3]) { p[0] = p[1] = p[2] = 0.5; }
  static double detTolerance(const double* pts) {
    static constexpr int kEdges[8][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {0, 4}, {1, 4}, {2, 4}, {3, 4}};
    return longestPairTolerance(pts, kEdges);
  }
  static bool inside(const double pc[3]) {
    return pc[0] >= -0.001 && pc[0] <= 1.001 && pc[1] >= -0.001 && pc[1] <= 1.001 && pc[2] >= -0.001 &&
           pc[2] <= 1.001;
  }
  static void clamp(const double pcoords[3], double pc[3]) { clampUnit(pcoords, pc); }
};

struct TriQuadraticHexahedron {
  static constexpr int N = 27;
  struct G {
    double g1r, g1s, g1t, g2r, g2s, g2t, g3r, g3s, g3t;
    explicit G(const double pcoords[3]) {
      const double r = 2.0 * (pcoords[0] - 0.5), s = 2.0 * (pcoords[1] - 0.5), t = 2.0 * (pcoords[2] - 0.5);
      g1r = -0.5 * r * (1 - r);
      g1s = -0.5 * s * (1 - s);
      g1t = -0.5 * t * (1 - t);
      g2r = (1 + r) * (1 - r);
      g2s = (1 + s) * (1 - s);
      g2t = (1 + t) * (1 - t);
      g3r = 0.5 * r * (1 + r);
      g3s = 0.5 * s * (1 + s);
      g3t = 0.5 * t * (1 + t);
    }
  };
  /// The 27 products a[i] b[j] c[k] in VTK's node order, a, b, c the 1-D functions (or their
  /// derivatives) of r, s, t: index 0, 1, 2 = VTK's g1, g2, g3.
  static void products(const double a[3], const double b[3], const double c[3], double* w) {
    // Node (i, j, k) of VTK's list: corners, edges, faces (20..25 in VTK's order), centre.
    static constexpr int kNode[27][3] = {{0, 0, 0}, {2, 0, 0}, {2, 2, 0}, {0, 2, 0}, {0, 0, 2}, {2, 0, 2}, {2, 2, 2},
                                         {0, 2, 2}, {1, 0, 0}, {2, 1, 0}, {1, 2, 0}, {0, 1, 0}, {1, 0, 2}, {2, 1, 2},
                                         {1, 2, 2}, {0, 1, 2}, {0, 0, 1}, {2, 0, 1}, {2, 2, 1}, {0, 2, 1}, {0, 1, 1},
                                         {2, 1, 1}, {1, 0, 1}, {1, 2, 1}, {1, 1, 0}, {1, 1, 2}, {1, 1, 1}};
    for (int n = 0; n < 27; ++n) w[n] = a[kNode[n][0]] * b[kNode[n][1]] * c[kNode[n][2]];
  }
  static void functions(const double pcoords[3], double w[27]) {
    const G g(pcoords);
    const double a[3] = {g.g1r, g.g2r, g.g3r}, b[3] = {g.g1s, g.g2s, g.g3s}, c[3] = {g.g1t, g.g2t, g.g3t};
    products(a, b, c, w);
  }
  static void derivs(const double pcoords[3], double d[81]) {
    const G g(pcoords);
    const double r = 2.0 * (pcoords[0] - 0.5), s = 2.0 * (pcoords[1] - 0.5), t = 2.0 * (pcoords[2] - 0.5);
    const double ar[3] = {r - 0.5, -2 * r, r + 0.5}, as[3] = {s - 0.5, -2 * s, s + 0.5}, at[3] = {t - 0.5, -2 * t, t + 0.5};
    const double a[3] = {g.g1r, g.g2r, g.g3r}, b[3] = {g.g1s, g.g2s, g.g3s}, c[3] = {g.g1t, g.g2t, g.g3t};
    products(ar, b, c, d);
    products(a, as, c, d + 27);
    products(a, b, at, d + 54);
    for (int i = 0; i < 81; i++) d[i] *= 2;
  }
  static constexpr int kMaxIteration = 10;
  static constexpr double kConverged = 1.e-03, kDamping = 0.5;
  static double detTolerance(const double*) { return 1.e-20; }
  /// The start: the pcoords its corners' linear hexahedron leaves (whatever it returns; with the
  /// closest point and dist2 it writes, which stay if this cell's own iteration fails).
  static void initialize(const double* pts, const double x[3], double* closestPoint, int& subId, double pcoords[3],
                         double& dist2, double params[3]) {
    pcoords[0] = pcoords[1] = pcoords[2] = params[0] = params[1] = params[2] = 0.5;
    double hexWeights[8];
    isoparametricEvaluatePosition<HexahedronNewton>(pts, x, closestPoint, subId, pcoords, dist2, hexWeights);
    params[0] = pcoords[0];
    params[1] = pcoords[1];
    params[2] = pcoords[2];
  }
  static bool inside(const double pc[3]) {
    return pc[0] >= -0.001 && pc[0] <= 1.001 && pc[1] >= -0.001 && pc[1] <= 1.001 && pc[2] >= -0.001 &&
           pc[2] <= 1.001;
  }
  static void clamp(const double pcoords[3], double pc[3]) { clampUnit(pcoords, pc); }
};


/// vtkQuadraticPyramid::EvaluatePosition: the apex first (as vtkPyramid), then Newton.
int quadraticPyramidEvaluatePosition(const double* pts, const double x[3], double* closestPoint, int& subId,
                                     double pcoords[3], double& dist2, double* weights) {
  subId = 0;
  if (pyramidAtApex<QuadraticPyramid>(pts, x, closestPoint, pcoords, dist2, weights)) return 1;
  return isoparametricEvaluatePosition<QuadraticPyramid>(pts, x, closestPoint, subId, pcoords, dist2, weights);
}

// ---- faces ------------------------------------------------------------------------------------

/// vtkQuadraticTriangle::IntersectWithLine: its four linear triangles in VTK's order, the first
/// hit (the triangle's own pcoords). q: the 6 points.
int quadraticTriangleIntersect(const double* const q[6], const double p1[3], const double p2[3], double tol,
                               double& t, double x[3], double pcoords[3], int& subId) {
  static constexpr int kTris[4][3] = {{0, 3, 5}, {3, 1, 4}, {5, 4, 2}, {4, 5, 3}};
  subId = 0;
  int subTest;
  for (const auto& tri : kTris)
    if (triangleIntersectWithLine(q[tri[0]], q[tri[1]], q[tri[2]], p1, p2, tol, t, x, pcoords, subTest)) return 1;
  return 0;
}

/// The four linear quads of a vtkQuadraticQuad (around its centre interpolated at (0.5, 0.5))
/// or a vtkBiQuadraticQuad (around its node 8), the first hit. q: 8 or 9 points.
int quadraticQuadIntersect(const double* const q[9], bool biquadratic, const double p1[3], const double p2[3],
                           double tol, double& t, double x[3], double pcoords[3], int& subId) {
  static constexpr int kQuads[4][4] = {{0, 4, 8, 7}, {4, 1, 5, 8}, {8, 5, 2, 6}, {7, 8, 6, 3}};
  subId = 0;
  double centre[3];
  const double* p[9];
  for (int i = 0; i < 8; ++i) p[i] = q[i];
  if (biquadratic) {
    p[8] = q[8];
  } else {
    // vtkQuadraticQuad::Subdivide: its functions at (0.5, 0.5), summed point by point.
    const double r = 0.5, s = 0.5;
    double w[8];
    w[4] = 4 * r * (1.0 - r) * (1.0 - s);
    w[5] = 4 * r * (1.0 - s) * s;
    w[6] = 4 * r * (1.0 - r) * s;
    w[7] = 4 * (1.0 - r) * (1.0 - s) * s;
    w[0] = (1.0 - r) * (1.0 - s) - 0.5 * (w[4] + w[7]);
    w[1] = r * (1.0 - s) - 0.5 * (w[4] + w[5]);
    w[2] = r * s - 0.5 * (w[5] + w[6]);
    w[3] = (1.0 - r) * s - 0.5 * (w[6] + w[7]);
    centre[0] = centre[1] = centre[2] = 0.0;
    for (int i = 0; i < 8; i++)
      for (int j = 0; j < 3; j++) centre[j] += q[i][j] * w[i];
    p[8] = centre;
  }
  int subTest;
  for (const auto& quad : kQuads) {
    double pts[12];
    for (int k = 0; k < 4; ++k)
      for (int a = 0; a < 3; ++a) pts[3 * k + a] = p[quad[k]][a];
    if (quadIntersectWithLine(pts, nullptr, p1, p2, tol, t, x, pcoords, subTest)) return 1;
  }
  return 0;
}

/// The pcoords mapping VTK 9.1's quadratic hexahedron writes for a hit on face f (the wedge,
/// the pyramid and the triquadratic hexahedron repeat it).
void hexFaceMapping(int f, const double pc[3], double pcoords[3]) {
  switch (f) {
    case 0: pcoords[0] = 0.0, pcoords[1] = pc[1], pcoords[2] = pc[0]; break;
    case 1: pcoords[0] = 1.0, pcoords[1] = pc[0], pcoords[2] = pc[1]; break;
    case 2: pcoords[0] = pc[0], pcoords[1] = 0.0, pcoords[2] = pc[1]; break;
    case 3: pcoords[0] = pc[1], pcoords[1] = 1.0, pcoords[2] = pc[0]; break;
    case 4: pcoords[0] = pc[1], pcoords[1] = pc[0], pcoords[2] = 0.0; break;
    default: pcoords[0] = pc[0], pcoords[1] = pc[1], pcoords[2] = 1.0; break;
  }
}

/// vtkQuadraticTetra's mapping of a face hit (its linear tetrahedron's).
void tetraFaceMapping(int f, const double pc[3], double pcoords[3]) {
  switch (f) {
    case 0: pcoords[0] = pc[0], pcoords[1] = pc[1], pcoords[2] = 0.0; break;
    case 1: pcoords[0] = 0.0, pcoords[1] = pc[1], pcoords[2] = 0.0; break;
    case 2: pcoords[0] = pc[0], pcoords[1] = 0.0, pcoords[2] = 0.0; break;
    default: pcoords[0] = pc[0], pcoords[1] = pc[1], pcoords[2] = pc[2]; break;
  }
}

/// The faces of each type as VTK lists them (point indices; triangles 6, quads 8 or 9).
struct QuadraticFaces {
  int num;
  int size[6];
  int node[6][9];
};
const QuadraticFaces* quadraticFaces(uint8_t type) {
  static const QuadraticFaces tetra = {
      4, {6, 6, 6, 6, 0, 0}, {{0, 1, 3, 4, 8, 7}, {1, 2, 3, 5, 9, 8}, {2, 0, 3, 6, 7, 9}, {0, 2, 1, 6, 5, 4}}};
  static const QuadraticFaces hex = {6,
                                     {8, 8, 8, 8, 8, 8},
                                     {{0, 4, 7, 3, 16, 15, 19, 11},
                                      {1, 2, 6, 5, 9, 18, 13, 17},
                                      {0, 1, 5, 4, 8, 17, 12, 16},
                                      {3, 7, 6, 2, 19, 14, 18, 10},
                                      {0, 3, 2, 1, 11, 10, 9, 8},
                                      {4, 5, 6, 7, 12, 13, 14, 15}}};
  static const QuadraticFaces wedge = {5,
                                       {6, 6, 8, 8, 8, 0},
                                       {{0, 1, 2, 6, 7, 8},
                                        {3, 5, 4, 11, 10, 9},
                                        {0, 3, 4, 1, 12, 9, 13, 6},
                                        {1, 4, 5, 2, 13, 10, 14, 7},
                                        {2, 5, 3, 0, 14, 11, 12, 8}}};
  // The triangle faces test points 0..5 (see the file comment).
  static const QuadraticFaces pyramid = {
      5,
      {8, 6, 6, 6, 6, 0},
      {{0, 3, 2, 1, 8, 7, 6, 5}, {0, 1, 2, 3, 4, 5}, {0, 1, 2, 3, 4, 5}, {0, 1, 2, 3, 4, 5}, {0, 1, 2, 3, 4, 5}}};
  static const QuadraticFaces triHex = {6,
                                        {9, 9, 9, 9, 9, 9},
                                        {{0, 4, 7, 3, 16, 15, 19, 11, 20},
                                         {1, 2, 6, 5, 9, 18, 13, 17, 21},
                                         {0, 1, 5, 4, 8, 17, 12, 16, 22},
                                         {3, 7, 6, 2, 19, 14, 18, 10, 23},
                                         {0, 3, 2, 1, 11, 10, 9, 8, 24},
                                         {4, 5, 6, 7, 12, 13, 14, 15, 25}}};
  switch (type) {
    case 24: return &tetra;
    case 25: return &hex;
    case 26: return &wedge;
    case 27: return &pyramid;
    case 29: return &triHex;
    default: return nullptr;
  }
}

}  // namespace

bool quadraticCovers(uint8_t type, int64_t n) {
  switch (type) {
    case 24: return n == 10;  // VTK_QUADRATIC_TETRA
    case 25: return n == 20;  // VTK_QUADRATIC_HEXAHEDRON
    case 26: return n == 15;  // VTK_QUADRATIC_WEDGE
    case 27: return n == 13;  // VTK_QUADRATIC_PYRAMID
    case 29: return n == 27;  // VTK_TRIQUADRATIC_HEXAHEDRON
    default: return false;
  }
}

int quadraticEvaluatePosition(uint8_t type, const double* pts, const double x[3], double* closestPoint, int& subId,
                              double pcoords[3], double& dist2, double* weights) {
  switch (type) {
    case 24:
      return isoparametricEvaluatePosition<QuadraticTetra>(pts, x, closestPoint, subId, pcoords, dist2, weights);
    case 25:
      return isoparametricEvaluatePosition<QuadraticHexahedron>(pts, x, closestPoint, subId, pcoords, dist2, weights);
    case 26:
      return isoparametricEvaluatePosition<QuadraticWedge>(pts, x, closestPoint, subId, pcoords, dist2, weights);
    case 27: return quadraticPyramidEvaluatePosition(pts, x, closestPoint, subId, pcoords, dist2, weights);
    case 29:
      return isoparametricEvaluatePosition<TriQuadraticHexahedron>(pts, x, closestPoint, subId, pcoords, dist2,
                                                                   weights);
    default: return -1;
  }
}

int quadraticIntersectWithLine(uint8_t type, const double* pts, const double p1[3], const double p2[3], double tol,
                               double& t, double x[3], double pcoords[3], int& subId) {
  const QuadraticFaces* faces = quadraticFaces(type);
  if (!faces) return 0;
  int intersection = 0;
  double tTemp, pc[3], xTemp[3];
  t = kDoubleMax;
  for (int f = 0; f < faces->num; ++f) {
    const double* q[9];
    for (int k = 0; k < faces->size[f]; ++k) q[k] = pts + 3 * faces->node[f][k];
    const int inter = faces->size[f] == 6
                          ? quadraticTriangleIntersect(q, p1, p2, tol, tTemp, xTemp, pc, subId)
                          : quadraticQuadIntersect(q, faces->size[f] == 9, p1, p2, tol, tTemp, xTemp, pc, subId);
    if (!inter) continue;
    intersection = 1;
    if (tTemp < t) {
      t = tTemp;
      x[0] = xTemp[0];
      x[1] = xTemp[1];
      x[2] = xTemp[2];
      if (type == 24) tetraFaceMapping(f, pc, pcoords);
      else hexFaceMapping(f, pc, pcoords);
    }
  }
  return intersection;
}

}  // namespace mirror
}  // namespace vtk91
}  // namespace mtree
