// A surface given as VTK's polydata gives it (polygons and triangle strips, as offsets into a
// connectivity array) as the TriangleMesh the ray tracer indexes, with the polydata cell each
// triangle came from.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "mtree/core/primitives.h"

namespace mtree {

struct TriangulatedSurface {
  TriangleMesh mesh;
  std::vector<int64_t> cellOfTriangle;  // polydata cell id of each triangle
};

/// Polygons are fanned from their first point (triangles (0, k, k + 1)); strips give triangles
/// (k, k + 1, k + 2) with every second one turned, (k + 1, k, k + 2), so that all face one way
/// (vtkTriangleStrip's order). Cell ids number the polygons from firstCell and the strips after
/// them (polydata numbers verts, lines, polys, strips). Polygons of fewer than 3 points give no
/// triangle. Throws std::invalid_argument on offsets that do not rise from 0 to the connectivity
/// size, a point index out of range, or a non-finite coordinate.
inline TriangulatedSurface triangulateSurface(std::vector<double> points, const int64_t* polyOffsets, size_t numPolys,
                                              const int64_t* polyConn, size_t polyConnSize,
                                              const int64_t* stripOffsets, size_t numStrips,
                                              const int64_t* stripConn, size_t stripConnSize, int64_t firstCell) {
  const int64_t np = static_cast<int64_t>(points.size() / 3);
  std::vector<uint32_t> tris;
  TriangulatedSurface s;
  auto checkCells = [&](const int64_t* off, size_t n, const int64_t* conn, size_t connSize, const char* what) {
    if (n == 0) return;
    if (off[0] != 0 || off[n] != static_cast<int64_t>(connSize))
      throw std::invalid_argument(std::string(what) + " offsets must run from 0 to the connectivity size");
    for (size_t c = 0; c < n; ++c)
      if (off[c + 1] < off[c]) throw std::invalid_argument(std::string(what) + " offsets must not decrease");
    for (size_t k = 0; k < connSize; ++k)
      if (conn[k] < 0 || conn[k] >= np)
        throw std::invalid_argument(std::string(what) + " connectivity entry " + std::to_string(k) + " is point " +
                                    std::to_string(conn[k]) + " but there are " + std::to_string(np) + " points");
  };
  checkCells(polyOffsets, numPolys, polyConn, polyConnSize, "polygon");
  checkCells(stripOffsets, numStrips, stripConn, stripConnSize, "strip");
  auto add = [&](int64_t a, int64_t b, int64_t c, int64_t cell) {
    tris.push_back(static_cast<uint32_t>(a));
    tris.push_back(static_cast<uint32_t>(b));
    tris.push_back(static_cast<uint32_t>(c));
    s.cellOfTriangle.push_back(cell);
  };
  for (size_t c = 0; c < numPolys; ++c) {
    const int64_t* ids = polyConn + polyOffsets[c];
    const int64_t n = polyOffsets[c + 1] - polyOffsets[c];
    for (int64_t k = 1; k + 1 < n; ++k) add(ids[0], ids[k], ids[k + 1], firstCell + static_cast<int64_t>(c));
  }
  for (size_t c = 0; c < numStrips; ++c) {
    const int64_t* ids = stripConn + stripOffsets[c];
    const int64_t n = stripOffsets[c + 1] - stripOffsets[c];
    const int64_t cell = firstCell + static_cast<int64_t>(numPolys + c);
    for (int64_t k = 0; k + 2 < n; ++k) {
      if (k % 2 == 0) add(ids[k], ids[k + 1], ids[k + 2], cell);
      else add(ids[k + 1], ids[k], ids[k + 2], cell);
    }
  }
  s.mesh = TriangleMesh(std::move(points), std::move(tris));
  return s;
}

}  // namespace mtree
