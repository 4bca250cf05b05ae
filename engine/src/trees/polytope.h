// Private to engine/src/trees: convex polytopes as face lists, clipped by planes. The BSP
// builder's cells (their SAH areas) and the split-plane pictures (a node's plane within its cell).
#pragma once

#include <algorithm>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "mtree/core/geometry.h"

namespace mtree {
namespace detail {

constexpr int kMaxPolyVerts = 96;  // a face of a cell cut by at most 46 planes has far fewer

/// A convex polytope as its faces, each a convex polygon counter-clockwise about its outward
/// normal. Only the SAH's areas and the cells' projection ranges come from it: its round-off
/// changes the costs a little, never which triangles a child holds.
struct Poly {
  std::vector<Vec3> v;          // the faces' vertices, face after face
  std::vector<uint32_t> start;  // face f is v[start[f], start[f + 1])
  size_t faces() const { return start.empty() ? 0 : start.size() - 1; }
};

inline Poly boxPoly(const Box& b) {
  const double x0 = b.lo.x, x1 = b.hi.x, y0 = b.lo.y, y1 = b.hi.y, z0 = b.lo.z, z1 = b.hi.z;
  const Vec3 faces[6][4] = {{{x0, y0, z0}, {x0, y0, z1}, {x0, y1, z1}, {x0, y1, z0}},
                            {{x1, y0, z0}, {x1, y1, z0}, {x1, y1, z1}, {x1, y0, z1}},
                            {{x0, y0, z0}, {x1, y0, z0}, {x1, y0, z1}, {x0, y0, z1}},
                            {{x0, y1, z0}, {x0, y1, z1}, {x1, y1, z1}, {x1, y1, z0}},
                            {{x0, y0, z0}, {x0, y1, z0}, {x1, y1, z0}, {x1, y0, z0}},
                            {{x0, y0, z1}, {x1, y0, z1}, {x1, y1, z1}, {x0, y1, z1}}};
  Poly p;
  p.start.push_back(0);
  for (const auto& f : faces) {
    p.v.insert(p.v.end(), f, f + 4);
    p.start.push_back(static_cast<uint32_t>(p.v.size()));
  }
  return p;
}

/// Twice the vector area of polygon v[0..n) (its normal times twice its area).
inline Vec3 vectorArea2(const Vec3* v, int n) {
  Vec3 s(0, 0, 0);
  for (int i = 1; i + 1 < n; ++i) s = s + cross(v[i] - v[0], v[i + 1] - v[0]);
  return s;
}

inline double surfaceArea(const Poly& p) {
  double a = 0;
  for (size_t f = 0; f < p.faces(); ++f)
    a += 0.5 * norm(vectorArea2(&p.v[p.start[f]], static_cast<int>(p.start[f + 1] - p.start[f])));
  return a;
}

/// Sutherland–Hodgman: polygon in[0..n) clipped to sign (dot(nrm, x) - w) <= 0. Returns the
/// vertex count written to out; `leave` / `enter` get the points where the boundary leaves and
/// re-enters the half-space (when `crossed`).
inline int clipPolygon(const Vec3* in, int n, Vec3 nrm, double w, double sign, Vec3* out, Vec3& leave, Vec3& enter,
                bool& crossed) {
  int m = 0;
  crossed = false;
  bool haveLeave = false, haveEnter = false;
  for (int i = 0; i < n; ++i) {
    const Vec3& P = in[i];
    const Vec3& Q = in[i + 1 == n ? 0 : i + 1];
    const double dp = sign * (dot(nrm, P) - w), dq = sign * (dot(nrm, Q) - w);
    const bool pin = dp <= 0, qin = dq <= 0;
    if (pin && m < kMaxPolyVerts) out[m++] = P;
    if (pin != qin) {
      const double f = std::min(1.0, std::max(0.0, dp / (dp - dq)));
      const Vec3 X = P + (Q - P) * f;
      if (m < kMaxPolyVerts) out[m++] = X;
      if (pin) {
        leave = X;
        haveLeave = true;
      } else {
        enter = X;
        haveEnter = true;
      }
    }
  }
  crossed = haveLeave && haveEnter;
  return m;
}

/// The cut of p by the plane dot(nrm, x) = w: the polygon where the plane meets p (empty when it
/// misses), counter-clockwise about sign * nrm. `edges` are the faces' cut segments, enter ->
/// leave, as clipPolygon reports them for that sign; each starts (to round-off) where another ends.
inline std::vector<Vec3> chainCap(const std::vector<std::pair<Vec3, Vec3>>& edges) {
  std::vector<Vec3> cap;
  if (edges.size() < 3) return cap;
  cap = {edges[0].first, edges[0].second};
  std::vector<bool> used(edges.size(), false);
  used[0] = true;
  for (size_t k = 1; k < edges.size(); ++k) {
    size_t best = 0;
    double bestD = std::numeric_limits<double>::infinity();
    for (size_t j = 0; j < edges.size(); ++j) {
      if (used[j]) continue;
      const Vec3 d = edges[j].first - cap.back();
      const double dd = dot(d, d);
      if (dd < bestD) {
        bestD = dd;
        best = j;
      }
    }
    used[best] = true;
    cap.push_back(edges[best].second);
  }
  cap.pop_back();  // the chain closes on its first point
  if (cap.size() < 3) cap.clear();
  return cap;
}

/// The part of p on the side sign (dot(nrm, x) - w) <= 0, closed by its cap.
inline Poly clipPoly(const Poly& p, Vec3 nrm, double w, double sign) {
  Poly out;
  out.start.push_back(0);
  Vec3 buf[kMaxPolyVerts];
  std::vector<std::pair<Vec3, Vec3>> edges;  // the cap's edges, enter -> leave
  for (size_t f = 0; f < p.faces(); ++f) {
    Vec3 leave, enter;
    bool crossed;
    const int m = clipPolygon(&p.v[p.start[f]], static_cast<int>(p.start[f + 1] - p.start[f]), nrm, w, sign, buf,
                              leave, enter, crossed);
    if (m >= 3) {
      out.v.insert(out.v.end(), buf, buf + m);
      out.start.push_back(static_cast<uint32_t>(out.v.size()));
    }
    if (crossed) edges.push_back({enter, leave});
  }
  const std::vector<Vec3> cap = chainCap(edges);
  if (!cap.empty()) {
    out.v.insert(out.v.end(), cap.begin(), cap.end());
    out.start.push_back(static_cast<uint32_t>(out.v.size()));
  }
  return out;
}

/// The polygon where the plane dot(nrm, x) = w cuts p (empty when it misses p).
inline std::vector<Vec3> cutPolygon(const Poly& p, Vec3 nrm, double w) {
  Vec3 buf[kMaxPolyVerts];
  std::vector<std::pair<Vec3, Vec3>> edges;
  for (size_t f = 0; f < p.faces(); ++f) {
    Vec3 leave, enter;
    bool crossed;
    clipPolygon(&p.v[p.start[f]], static_cast<int>(p.start[f + 1] - p.start[f]), nrm, w, 1.0, buf, leave, enter,
                crossed);
    if (crossed) edges.push_back({enter, leave});
  }
  return chainCap(edges);
}

}  // namespace detail
}  // namespace mtree

