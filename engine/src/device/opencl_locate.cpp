// OpenCL host code, part 5: batched point location in a CellSet (opencl/query_cells.cl).
#ifdef MATRIXTREE_HAVE_OPENCL

#include <algorithm>
#include <cmath>
#include <string>

#include "opencl_internal.h"

namespace mtree {
namespace ocl {

struct CellLocator::State {
  TreeBuffers tree;
  Buffer boxes, pts, offsets, conn, types;
  Buffer query, out;
  int H = 0;
  bool empty = true, uploaded = false;
  size_t bytes = 0;
};

CellLocator::CellLocator(std::shared_ptr<Context> ctx) : ctx_(ctx ? std::move(ctx) : Context::shared()), st_(new State) {}
CellLocator::~CellLocator() = default;
Context& CellLocator::context() const { return *ctx_; }
bool CellLocator::uploaded() const { return st_->uploaded; }
size_t CellLocator::deviceBytes() const { return st_->uploaded ? st_->bytes : 0; }

void CellLocator::upload(const MatrixTree& tree, const CellSet& cells, const LargeVector<uint8_t>& leafBoxes) {
  if (leafBoxes.size() != 6 * tree.primitiveIndices().size())
    throw std::invalid_argument("OpenCL CellLocator: leafBoxes must hold 6 bytes per primitive index (" +
                                std::to_string(6 * tree.primitiveIndices().size()) + "), got " +
                                std::to_string(leafBoxes.size()));
  Context::Impl& impl = ctx_->impl();
  std::lock_guard<std::recursive_mutex> lock(impl.mutex);
  State& S = *st_;
  S.uploaded = false;
  S.bytes = 0;
  S.empty = tree.empty() || cells.size() == 0;
  S.H = tree.height();
  if (S.empty) {
    S.uploaded = true;
    return;
  }
  // The cells as flat arrays (the CellSet keeps them private; rebuilt from its accessors).
  const size_t nc = cells.size();
  std::vector<uint32_t> offsets(nc + 1, 0), conn;
  std::vector<uint8_t> types(nc);
  for (size_t c = 0; c < nc; ++c) offsets[c + 1] = offsets[c] + static_cast<uint32_t>(cells.numCellPoints(c));
  conn.resize(offsets[nc]);
  for (size_t c = 0; c < nc; ++c) {
    const CellSet::PointIds ids = cells.cellPointIds(c);
    for (int64_t k = 0; k < cells.numCellPoints(c); ++k) conn[offsets[c] + k] = ids[k];
    types[c] = cells.type(c);
  }
  Launcher run(impl, nullptr);
  auto put = [&](Buffer& b, const void* src, size_t bytes, const char* what) {
    b.ensure(impl, bytes, what);
    run.write(b, src, bytes, what);
    S.bytes += bytes;
  };
  S.bytes += uploadTree(impl, run, tree, "OpenCL CellLocator", S.tree);
  put(S.boxes, leafBoxes.data(), leafBoxes.size(), "quantized leaf boxes");
  std::vector<double> pts(3 * cells.numPoints());  // the device reads doubles
  for (size_t i = 0; i < cells.numPoints(); ++i) {
    const Vec3 p = cells.point(i);
    pts[3 * i] = p.x;
    pts[3 * i + 1] = p.y;
    pts[3 * i + 2] = p.z;
  }
  put(S.pts, pts.data(), pts.size() * sizeof(double), "cell points");
  put(S.offsets, offsets.data(), offsets.size() * sizeof(uint32_t), "cell offsets");
  put(S.conn, conn.data(), conn.size() * sizeof(uint32_t), "cell connectivity");
  put(S.types, types.data(), types.size(), "cell types");
  run.finish();
  S.uploaded = true;
}

void CellLocator::locate(const double* pts, size_t n, double tol, uint32_t* out, std::vector<KernelTiming>* kernels) {
  State& S = *st_;
  if (!S.uploaded) throw Error("OpenCL CellLocator: nothing uploaded; call upload(tree, cells, leafBoxes) first");
  if (n == 0) return;
  if (n >= MT_NULL / 2) throw std::length_error("OpenCL CellLocator: more than 2^31 points in one batch");
  if (S.empty) {
    std::fill(out, out + 2 * n, uint32_t{kNoCell});
    return;
  }
  Context::Impl& impl = ctx_->impl();
  std::lock_guard<std::recursive_mutex> lock(impl.mutex);
  Launcher run(impl, kernels);
  S.query.ensure(impl, 3 * n * sizeof(double), "query points");
  S.out.ensure(impl, 2 * n * sizeof(uint32_t), "location answers");
  run.write(S.query, pts, 3 * n * sizeof(double), "query points");
  const cl_int H = S.H;
  const TreeBuffers& T = S.tree;
  run.run("mt_locate_cells", n, 0, T.levels, T.ptrs, T.inner, T.leaves, T.geom, H, T.prims, S.boxes, S.pts, S.offsets,
          S.conn, S.types, S.query, static_cast<uint32_t>(n), tol, S.out);
  run.read(S.out, out, 2 * n * sizeof(uint32_t), "location answers");
  run.finish();
}

}  // namespace ocl
}  // namespace mtree

#endif  // MATRIXTREE_HAVE_OPENCL
