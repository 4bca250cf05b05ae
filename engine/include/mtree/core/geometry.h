// Small geometry kernel of the engine: vectors, boxes, triangle/box overlap, ray/triangle
// intersection. Doubles throughout: CFD grids with coordinates of 1e6 and cells of 1e-3 need them,
// and the ray tracer's cost is in memory traffic, not in the width of the arithmetic.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

// Forced inlining for the few small functions of the ray loops (GCC otherwise keeps the
// triangle tests out of line in the traversal lambdas: a call per triangle).
#if defined(__GNUC__) || defined(__clang__)
#define MT_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define MT_ALWAYS_INLINE inline
#endif

namespace mtree {

struct Vec3 {
  double x = 0, y = 0, z = 0;
  Vec3() = default;
  constexpr Vec3(double a, double b, double c) : x(a), y(b), z(c) {}
  explicit Vec3(const double* p) : x(p[0]), y(p[1]), z(p[2]) {}
  double operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  double& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
};
inline Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec3 operator*(Vec3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
inline Vec3 operator*(double s, Vec3 a) { return a * s; }
inline double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 cross(Vec3 a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double norm(Vec3 a) { return std::sqrt(dot(a, a)); }
inline Vec3 normalized(Vec3 a) {
  const double n = norm(a);
  return n > 0 ? a * (1.0 / n) : a;
}
inline Vec3 vmin(Vec3 a, Vec3 b) { return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)}; }
inline Vec3 vmax(Vec3 a, Vec3 b) { return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)}; }
inline bool isFinite(Vec3 a) { return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z); }

struct Box {
  Vec3 lo{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
          std::numeric_limits<double>::infinity()};
  Vec3 hi{-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
          -std::numeric_limits<double>::infinity()};
  void extend(Vec3 p) { lo = vmin(lo, p); hi = vmax(hi, p); }
  void extend(const Box& b) { lo = vmin(lo, b.lo); hi = vmax(hi, b.hi); }
  bool empty() const { return !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z); }
  Vec3 extent() const { return hi - lo; }
  Vec3 center() const { return (lo + hi) * 0.5; }
  bool contains(Vec3 p) const {
    return p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y && p.z >= lo.z && p.z <= hi.z;
  }
  bool overlaps(const Box& b) const {
    return lo.x <= b.hi.x && b.lo.x <= hi.x && lo.y <= b.hi.y && b.lo.y <= hi.y && lo.z <= b.hi.z &&
           b.lo.z <= hi.z;
  }
};

/// Separating-axis test of a triangle against a closed axis-aligned box (Akenine-Möller 2001:
/// the 3 box normals, the triangle normal, and the 9 edge x box-axis cross products).
/// Conservative by construction of the caller: pass a box already padded for round-off.
bool triangleOverlapsBox(Vec3 a, Vec3 b, Vec3 c, const Box& box);

/// The separating-axis test of one triangle against many boxes of one size (the candidate leaves
/// of the build): the 10 non-trivial axes (normal, 9 edge x box-axis products), the triangle's
/// projection interval and the box radius on each are computed once; a box then costs one dot
/// product per axis. The 3 box-normal axes are not tested: callers only pass boxes that their
/// bounding-box range already overlaps, so those axes never separate (skipping them can only
/// say "overlap", i.e. stays conservative).
class TriangleBoxTester {
 public:
  TriangleBoxTester(Vec3 a, Vec3 b, Vec3 c, Vec3 half) {
    const Vec3 e[3] = {b - a, c - b, a - c};
    auto add = [&](Vec3 ax) {
      if (ax.x == 0 && ax.y == 0 && ax.z == 0) return;
      const double p0 = dot(a, ax), p1 = dot(b, ax), p2 = dot(c, ax);
      axis_[n_] = ax;
      lo_[n_] = std::min(p0, std::min(p1, p2));
      hi_[n_] = std::max(p0, std::max(p1, p2));
      r_[n_] = half.x * std::fabs(ax.x) + half.y * std::fabs(ax.y) + half.z * std::fabs(ax.z);
      ++n_;
    };
    add(cross(e[0], e[1]));
    for (const Vec3& d : e) {
      add(Vec3(0, -d.z, d.y));
      add(Vec3(d.z, 0, -d.x));
      add(Vec3(-d.y, d.x, 0));
    }
  }
  /// Does the triangle overlap the box of the construction's half size centred at `c`?
  bool overlaps(Vec3 c) const {
    for (int k = 0; k < n_; ++k) {
      const double pc = dot(c, axis_[k]);
      if (lo_[k] - pc > r_[k] || hi_[k] - pc < -r_[k]) return false;
    }
    return true;
  }

 private:
  Vec3 axis_[10];
  double lo_[10], hi_[10], r_[10];
  int n_ = 0;
};

/// Separating-axis test of a convex polytope (the convex hull of `n` points, given with its
/// `nf` face normals and `ne` edge directions) against a box. Used for linear cells.
bool convexOverlapsBox(const Vec3* pts, int n, const Vec3* faceNormals, int nf, const Vec3* edges,
                       int ne, const Box& box);

/// Möller–Trumbore ray/triangle test (1997). Returns true and t, u, v if the ray hits the
/// triangle with t in [tmin, tmax]. Edges are shared by neighbours up to round-off only: use
/// the watertight test where a hole in a closed mesh matters.
MT_ALWAYS_INLINE bool rayTriangleMT(Vec3 o, Vec3 d, Vec3 a, Vec3 b, Vec3 c, double tmin, double tmax,
                          double& t, double& u, double& v) {
  const Vec3 e1 = b - a, e2 = c - a;
  const Vec3 p = cross(d, e2);
  const double det = dot(e1, p);
  if (det == 0.0 || !std::isfinite(det)) return false;
  // The division waits until the edge tests pass (most candidates fail one): they compare the
  // unscaled numerators with det's sign folded in, which is the same decision as comparing the
  // quotients except within an ulp of an edge, where either answer is a correct hit or miss.
  const double sg = det > 0 ? 1.0 : -1.0, adet = det * sg;
  const Vec3 s = o - a;
  const double un = dot(s, p) * sg;
  // Written as !(inside) so that NaN (e.g. from an infinite origin) is rejected too.
  if (!(un >= 0.0 && un <= adet)) return false;
  const Vec3 q = cross(s, e1);
  const double vn = dot(d, q) * sg;
  if (!(vn >= 0.0 && un + vn <= adet)) return false;
  const double inv = 1.0 / det;
  const double uu = un * sg * inv, vv = vn * sg * inv;
  const double tt = dot(e2, q) * inv;
  if (!(tt >= tmin && tt <= tmax)) return false;
  t = tt;
  u = uu;
  v = vv;
  return true;
}

/// Slab test of a ray against a box; returns the clipped [t0, t1] or false if it misses.
/// Axes with d == 0 are handled explicitly (no 0 * inf).
inline bool rayBox(Vec3 o, Vec3 d, const Box& box, double& t0, double& t1) {
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0) {
      if (o[a] < box.lo[a] || o[a] > box.hi[a]) return false;
      continue;
    }
    const double inv = 1.0 / d[a];
    double tn = (box.lo[a] - o[a]) * inv, tf = (box.hi[a] - o[a]) * inv;
    if (tn > tf) std::swap(tn, tf);
    t0 = std::max(t0, tn);
    t1 = std::min(t1, tf);
    if (t0 > t1) return false;
  }
  return true;
}

}  // namespace mtree
