// OpenCL host code, part 3: queries through an uploaded matrix tree (opencl/query.cl).
#ifdef MATRIXTREE_HAVE_OPENCL

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "opencl_internal.h"

namespace mtree {
namespace ocl {

/// A ray kernel's output buffer and where its n results go on the host.
struct RayOutput {
  Buffer& buffer;
  void* host;
  size_t bytesPerRay;
  const char* what;
};

struct Tracer::State {
  TreeBuffers tree;
  Buffer pts, tris;
  Buffer orig, dirs, tOut, primOut, hitOut, counters, points, leafOut;
  int H = 0;
  bool empty = true, uploaded = false;

  /// A ray kernel's launch (mt_first_hit, mt_any_hit): checks the batch, uploads the n rays,
  /// runs `kernel` on the tree, the triangles, the rays, then `out`'s buffers and the per-ray
  /// counters (a null buffer unless visits or tests are wanted), reads the outputs back and sums
  /// the counters (node visits, triangle tests). False, with nothing run, for an empty batch or
  /// tree: the caller writes the misses.
  template <size_t N>
  bool trace(Context::Impl& impl, const char* kernel, const double* o, const double* d, size_t n, double tmin,
             double tmax, uint64_t* visits, uint64_t* tests, std::vector<KernelTiming>* kernels,
             const RayOutput (&out)[N]) {
    requireUploaded();
    if (visits) *visits = 0;
    if (tests) *tests = 0;
    if (n == 0) return false;
    if (n >= MT_NULL) throw std::length_error("OpenCL Tracer: more than 2^32 rays in one batch");
    if (empty) return false;
    std::lock_guard<std::recursive_mutex> lock(impl.mutex);
    Launcher run(impl, kernels);
    orig.ensure(impl, 3 * n * sizeof(double), "ray origins");
    dirs.ensure(impl, 3 * n * sizeof(double), "ray directions");
    for (const RayOutput& r : out) r.buffer.ensure(impl, n * r.bytesPerRay, r.what);
    const bool count = visits || tests;
    if (count) counters.ensure(impl, 2 * n * sizeof(uint32_t), "ray counters");
    run.write(orig, o, 3 * n * sizeof(double), "ray origins");
    run.write(dirs, d, 3 * n * sizeof(double), "ray directions");
    launch(run, kernel, n, tmin, tmax, out, count ? &counters : nullptr, std::make_index_sequence<N>());
    for (const RayOutput& r : out) run.read(r.buffer, r.host, n * r.bytesPerRay, r.what);
    if (count) {
      std::vector<uint32_t> c(2 * n);
      run.read(counters, c.data(), c.size() * sizeof(uint32_t), "ray counters");
      for (size_t i = 0; i < n; ++i) {
        if (visits) *visits += c[2 * i];
        if (tests) *tests += c[2 * i + 1];
      }
    }
    run.finish();
    return true;
  }
  template <size_t N, size_t... I>
  void launch(Launcher& run, const char* kernel, size_t n, double tmin, double tmax, const RayOutput (&out)[N],
              const Buffer* count, std::index_sequence<I...>) {
    run.run(kernel, n, 0, tree.levels, tree.ptrs, tree.inner, tree.leaves, tree.geom, cl_int(H), tree.prims, pts, tris,
            orig, dirs, static_cast<uint32_t>(n), tmin, tmax, out[I].buffer..., count);
  }
  void requireUploaded() const {
    if (!uploaded) throw Error("OpenCL Tracer: no tree uploaded; call upload(tree, mesh) first");
  }
};

Tracer::Tracer(std::shared_ptr<Context> ctx) : ctx_(ctx ? std::move(ctx) : Context::shared()), st_(new State) {}
Tracer::~Tracer() = default;
Context& Tracer::context() const { return *ctx_; }
bool Tracer::uploaded() const { return st_->uploaded; }

void Tracer::upload(const MatrixTree& tree, const TriangleMesh& mesh) {
  Context::Impl& impl = ctx_->impl();
  std::lock_guard<std::recursive_mutex> lock(impl.mutex);
  State& S = *st_;
  S.uploaded = false;
  S.empty = tree.empty();
  S.H = tree.height();
  if (S.empty) {
    S.uploaded = true;
    return;
  }
  Launcher run(impl, nullptr);
  uploadTree(impl, run, tree, "MatrixTree (OpenCL)", S.tree);
  S.pts.ensure(impl, mesh.points().size() * sizeof(double), "vertices");
  run.write(S.pts, mesh.points().data(), mesh.points().size() * sizeof(double), "vertices");
  S.tris.ensure(impl, mesh.triangles().size() * sizeof(uint32_t), "triangles");
  run.write(S.tris, mesh.triangles().data(), mesh.triangles().size() * sizeof(uint32_t), "triangles");
  run.finish();
  S.uploaded = true;
}

FlatTree flattenTree(const MatrixTree& tree, const char* who) {
  const int H = tree.height();
  if (H + 1 > MT_MAX_LEVELS) throw std::length_error(std::string(who) + ": more levels than MT_MAX_LEVELS");
  FlatTree f;
  f.levels.resize(H + 1);
  for (int l = 0; l <= H; ++l) {
    MtLevelDesc& d = f.levels[l];
    d = MtLevelDesc{};
    d.matrix = l == H ? tree.leafLevel().desc() : tree.innerLevel(l).desc();
    const std::vector<uint32_t>& p = l == H ? tree.leafLevel().pointers() : tree.innerLevel(l).pointers();
    if (f.ptrs.size() + p.size() >= MT_NULL || f.inner.size() >= MT_NULL)
      throw std::length_error(std::string(who) + ": tree too large for 32-bit offsets");
    d.matrix.ptrOffset = static_cast<uint32_t>(f.ptrs.size());
    f.ptrs.insert(f.ptrs.end(), p.begin(), p.end());
    if (l < H) {
      d.matrix.dataOffset = static_cast<uint32_t>(f.inner.size());
      f.inner.insert(f.inner.end(), tree.innerLevel(l).data().begin(), tree.innerLevel(l).data().end());
    } else {
      d.matrix.dataOffset = 0;
    }
    for (int a = 0; a < 3; ++a) d.logDims[a] = tree.logDim(l, a);
  }
  f.geom = MtTreeGeom{};
  const Box& root = tree.rootBox();
  for (int a = 0; a < 3; ++a) {
    f.geom.lo[a] = root.lo[a];
    f.geom.hi[a] = root.hi[a];
    // 1 / leaf size exactly as the builder computes it (builder.h: invLeaf_).
    f.geom.invLeaf[a] = std::ldexp(1.0, tree.logDim(H, a)) / root.extent()[a];
  }
  for (int l = 0; l <= H; ++l)
    for (int a = 0; a < 3; ++a) f.geom.cellSize[l][a] = tree.cellSize(l)[a];
  return f;
}

size_t uploadTree(Context::Impl& impl, Launcher& run, const MatrixTree& tree, const char* who, TreeBuffers& b) {
  const FlatTree flat = flattenTree(tree, who);
  size_t bytes = 0;
  auto put = [&](Buffer& buf, const void* src, size_t n, const char* what) {
    buf.ensure(impl, n, what);
    run.write(buf, src, n, what);
    bytes += n;
  };
  const LargeVector<MtLeafRange>& leaves = tree.leafLevel().data();
  const LargeVector<uint32_t>& prims = tree.primitiveIndices();
  put(b.levels, flat.levels.data(), flat.levels.size() * sizeof(MtLevelDesc), "level descriptors");
  put(b.ptrs, flat.ptrs.data(), flat.ptrs.size() * sizeof(uint32_t), "pointer matrices");
  put(b.inner, flat.inner.data(), flat.inner.size(), "inner levels");
  put(b.leaves, leaves.data(), leaves.size() * sizeof(MtLeafRange), "leaf ranges");
  put(b.prims, prims.data(), prims.size() * sizeof(uint32_t), "primitive indices");
  put(b.geom, &flat.geom, sizeof(MtTreeGeom), "tree geometry");
  return bytes;
}

void Tracer::intersectFirst(const double* orig, const double* dirs, size_t n, double tmin, double tmax, double* t,
                            uint32_t* prim, uint64_t* visits, uint64_t* tests, std::vector<KernelTiming>* kernels) {
  State& S = *st_;
  const RayOutput out[] = {{S.tOut, t, sizeof(double), "hit distances"}, {S.primOut, prim, sizeof(uint32_t), "hit triangles"}};
  if (!S.trace(ctx_->impl(), "mt_first_hit", orig, dirs, n, tmin, tmax, visits, tests, kernels, out))
    for (size_t i = 0; i < n; ++i) {
      t[i] = std::numeric_limits<double>::infinity();
      prim[i] = MT_NULL;
    }
}

void Tracer::intersectAny(const double* orig, const double* dirs, size_t n, double tmin, double tmax, uint8_t* hit,
                          uint64_t* visits, uint64_t* tests, std::vector<KernelTiming>* kernels) {
  State& S = *st_;
  const RayOutput out[] = {{S.hitOut, hit, 1, "shadow hits"}};
  if (!S.trace(ctx_->impl(), "mt_any_hit", orig, dirs, n, tmin, tmax, visits, tests, kernels, out))
    std::fill(hit, hit + n, uint8_t{0});
}

void Tracer::findLeaves(const double* pts, size_t n, int32_t* out, std::vector<KernelTiming>* kernels) {
  State& S = *st_;
  S.requireUploaded();
  if (n == 0) return;
  if (n >= MT_NULL / 5) throw std::length_error("OpenCL Tracer: too many points in one batch");
  if (S.empty) {
    for (size_t i = 0; i < n; ++i) {
      out[5 * i] = -1;
      out[5 * i + 1] = out[5 * i + 2] = out[5 * i + 3] = out[5 * i + 4] = 0;
    }
    return;
  }
  Context::Impl& impl = ctx_->impl();
  std::lock_guard<std::recursive_mutex> lock(impl.mutex);
  Launcher run(impl, kernels);
  S.points.ensure(impl, 3 * n * sizeof(double), "points");
  S.leafOut.ensure(impl, 5 * n * sizeof(int32_t), "located leaves");
  run.write(S.points, pts, 3 * n * sizeof(double), "points");
  const TreeBuffers& T = S.tree;
  run.run("mt_find_leaves", n, 0, T.levels, T.ptrs, T.inner, T.leaves, T.geom, cl_int(S.H), S.points,
          static_cast<uint32_t>(n), S.leafOut);
  run.read(S.leafOut, out, 5 * n * sizeof(int32_t), "located leaves");
  run.finish();
}

}  // namespace ocl
}  // namespace mtree

#endif  // MATRIXTREE_HAVE_OPENCL
