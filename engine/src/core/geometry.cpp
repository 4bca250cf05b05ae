#include "mtree/core/geometry.h"

namespace mtree {

namespace {

// Projects the triangle (relative to the box centre) and the box on `axis`; true if separated.
inline bool separatedOn(Vec3 axis, Vec3 v0, Vec3 v1, Vec3 v2, Vec3 half) {
  const double p0 = dot(v0, axis), p1 = dot(v1, axis), p2 = dot(v2, axis);
  const double r = half.x * std::fabs(axis.x) + half.y * std::fabs(axis.y) + half.z * std::fabs(axis.z);
  const double mn = std::min(p0, std::min(p1, p2));
  const double mx = std::max(p0, std::max(p1, p2));
  return mn > r || mx < -r;
}

}  // namespace

bool triangleOverlapsBox(Vec3 a, Vec3 b, Vec3 c, const Box& box) {
  const Vec3 ctr = box.center();
  const Vec3 half = box.extent() * 0.5;
  const Vec3 v0 = a - ctr, v1 = b - ctr, v2 = c - ctr;
  // Box normals: the triangle's bounding box against the box.
  for (int k = 0; k < 3; ++k) {
    const double mn = std::min(v0[k], std::min(v1[k], v2[k]));
    const double mx = std::max(v0[k], std::max(v1[k], v2[k]));
    if (mn > half[k] || mx < -half[k]) return false;
  }
  const Vec3 e0 = v1 - v0, e1 = v2 - v1, e2 = v0 - v2;
  // Triangle normal (skipped when degenerate: the edge axes below then decide).
  const Vec3 n = cross(e0, e1);
  if (dot(n, n) > 0.0 && separatedOn(n, v0, v1, v2, half)) return false;
  // Edge x box-axis cross products.
  const Vec3 edges[3] = {e0, e1, e2};
  for (const Vec3& e : edges) {
    const Vec3 axes[3] = {Vec3(0, -e.z, e.y), Vec3(e.z, 0, -e.x), Vec3(-e.y, e.x, 0)};
    for (const Vec3& ax : axes) {
      if (ax.x == 0 && ax.y == 0 && ax.z == 0) continue;
      if (separatedOn(ax, v0, v1, v2, half)) return false;
    }
  }
  return true;
}

bool convexOverlapsBox(const Vec3* pts, int n, const Vec3* faceNormals, int nf, const Vec3* edges,
                       int ne, const Box& box) {
  const Vec3 ctr = box.center();
  const Vec3 half = box.extent() * 0.5;
  auto separated = [&](Vec3 axis) {
    double mn = std::numeric_limits<double>::infinity(), mx = -mn;
    for (int i = 0; i < n; ++i) {
      const double p = dot(pts[i] - ctr, axis);
      mn = std::min(mn, p);
      mx = std::max(mx, p);
    }
    const double r = half.x * std::fabs(axis.x) + half.y * std::fabs(axis.y) + half.z * std::fabs(axis.z);
    return mn > r || mx < -r;
  };
  for (int k = 0; k < 3; ++k) {
    Vec3 ax(0, 0, 0);
    ax[k] = 1;
    if (separated(ax)) return false;
  }
  for (int f = 0; f < nf; ++f)
    if (dot(faceNormals[f], faceNormals[f]) > 0 && separated(faceNormals[f])) return false;
  for (int e = 0; e < ne; ++e) {
    const Vec3 d = edges[e];
    const Vec3 axes[3] = {Vec3(0, -d.z, d.y), Vec3(d.z, 0, -d.x), Vec3(-d.y, d.x, 0)};
    for (const Vec3& ax : axes) {
      if (ax.x == 0 && ax.y == 0 && ax.z == 0) continue;
      if (separated(ax)) return false;
    }
  }
  return true;
}

}  // namespace mtree
