// OpenCL host code, part 3: queries through an uploaded matrix tree (opencl/query.cl).
#ifdef MATRIXTREE_HAVE_OPENCL

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "opencl_internal.h"

namespace mtree {
namespace ocl {

struct Tracer::State {
  Buffer levels, ptrs, inner, leaves, prims, geom, pts, tris;
  Buffer orig, dirs, tOut, primOut, hitOut, counters, points, leafOut;
  int H = 0;
  bool empty = true, uploaded = false;
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
  const FlatTree flat = flattenTree(tree, "MatrixTree (OpenCL)");
  Launcher run(impl, nullptr);
  auto put = [&](Buffer& b, const void* src, size_t bytes, const char* what) {
    b.ensure(impl, bytes, what);
    run.write(b, src, bytes, what);
  };
  put(S.levels, flat.levels.data(), flat.levels.size() * sizeof(MtLevelDesc), "level descriptors");
  put(S.ptrs, flat.ptrs.data(), flat.ptrs.size() * sizeof(uint32_t), "pointer matrices");
  put(S.inner, flat.inner.data(), flat.inner.size(), "inner levels");
  put(S.leaves, tree.leafLevel().data().data(), tree.leafLevel().data().size() * sizeof(MtLeafRange), "leaf ranges");
  put(S.prims, tree.primitiveIndices().data(), tree.primitiveIndices().size() * sizeof(uint32_t), "triangle indices");
  put(S.geom, flat.geom.data(), flat.geom.size() * sizeof(double), "tree geometry");
  put(S.pts, mesh.points().data(), mesh.points().size() * sizeof(double), "vertices");
  put(S.tris, mesh.triangles().data(), mesh.triangles().size() * sizeof(uint32_t), "triangles");
  run.finish();
  S.uploaded = true;
}

FlatTree flattenTree(const MatrixTree& tree, const char* who) {
  const int H = tree.height();
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
  f.geom.assign(9 + 3 * (H + 1), 0.0);
  const Box& root = tree.rootBox();
  for (int a = 0; a < 3; ++a) {
    f.geom[a] = root.lo[a];
    f.geom[3 + a] = root.hi[a];
    // 1 / leaf size exactly as the builder computes it (builder.h: invLeaf_).
    f.geom[6 + a] = std::ldexp(1.0, tree.logDim(H, a)) / root.extent()[a];
  }
  for (int l = 0; l <= H; ++l)
    for (int a = 0; a < 3; ++a) f.geom[9 + 3 * l + a] = tree.cellSize(l)[a];
  return f;
}

namespace {
/// Sums the per-ray (node visits, triangle tests) pairs the ray kernels wrote into `counters`.
void addRayCounters(Launcher& run, Buffer& counters, size_t n, uint64_t* visits, uint64_t* tests) {
  std::vector<uint32_t> c(2 * n);
  run.read(counters, c.data(), c.size() * sizeof(uint32_t), "ray counters");
  for (size_t i = 0; i < n; ++i) {
    if (visits) *visits += c[2 * i];
    if (tests) *tests += c[2 * i + 1];
  }
}

void requireUploaded(bool up) {
  if (!up) throw Error("OpenCL Tracer: no tree uploaded; call upload(tree, mesh) first");
}
}  // namespace

void Tracer::intersectFirst(const double* orig, const double* dirs, size_t n, double tmin, double tmax, double* t,
                            uint32_t* prim, uint64_t* visits, uint64_t* tests, std::vector<KernelTiming>* kernels) {
  State& S = *st_;
  requireUploaded(S.uploaded);
  if (visits) *visits = 0;
  if (tests) *tests = 0;
  if (n == 0) return;
  if (n >= MT_NULL) throw std::length_error("OpenCL Tracer: more than 2^32 rays in one batch");
  if (S.empty) {
    for (size_t i = 0; i < n; ++i) {
      t[i] = std::numeric_limits<double>::infinity();
      prim[i] = MT_NULL;
    }
    return;
  }
  Context::Impl& impl = ctx_->impl();
  std::lock_guard<std::recursive_mutex> lock(impl.mutex);
  Launcher run(impl, kernels);
  S.orig.ensure(impl, 3 * n * sizeof(double), "ray origins");
  S.dirs.ensure(impl, 3 * n * sizeof(double), "ray directions");
  S.tOut.ensure(impl, n * sizeof(double), "hit distances");
  S.primOut.ensure(impl, n * sizeof(uint32_t), "hit triangles");
  const bool count = visits || tests;
  if (count) S.counters.ensure(impl, 2 * n * sizeof(uint32_t), "ray counters");
  run.write(S.orig, orig, 3 * n * sizeof(double), "ray origins");
  run.write(S.dirs, dirs, 3 * n * sizeof(double), "ray directions");
  const uint32_t nn = static_cast<uint32_t>(n);
  const cl_int H = S.H;
  if (count)
    run.run("mt_first_hit", n, 0, S.levels, S.ptrs, S.inner, S.leaves, S.geom, H, S.prims, S.pts, S.tris, S.orig,
            S.dirs, nn, tmin, tmax, S.tOut, S.primOut, S.counters);
  else
    run.run("mt_first_hit", n, 0, S.levels, S.ptrs, S.inner, S.leaves, S.geom, H, S.prims, S.pts, S.tris, S.orig,
            S.dirs, nn, tmin, tmax, S.tOut, S.primOut, nullptr);
  run.read(S.tOut, t, n * sizeof(double), "hit distances");
  run.read(S.primOut, prim, n * sizeof(uint32_t), "hit triangles");
  if (count) addRayCounters(run, S.counters, n, visits, tests);
  run.finish();
}

void Tracer::intersectAny(const double* orig, const double* dirs, size_t n, double tmin, double tmax, uint8_t* hit,
                          uint64_t* visits, uint64_t* tests, std::vector<KernelTiming>* kernels) {
  State& S = *st_;
  requireUploaded(S.uploaded);
  if (visits) *visits = 0;
  if (tests) *tests = 0;
  if (n == 0) return;
  if (n >= MT_NULL) throw std::length_error("OpenCL Tracer: more than 2^32 rays in one batch");
  if (S.empty) {
    std::fill(hit, hit + n, uint8_t{0});
    return;
  }
  Context::Impl& impl = ctx_->impl();
  std::lock_guard<std::recursive_mutex> lock(impl.mutex);
  Launcher run(impl, kernels);
  S.orig.ensure(impl, 3 * n * sizeof(double), "ray origins");
  S.dirs.ensure(impl, 3 * n * sizeof(double), "ray directions");
  S.hitOut.ensure(impl, n, "shadow hits");
  const bool count = visits || tests;
  if (count) S.counters.ensure(impl, 2 * n * sizeof(uint32_t), "ray counters");
  run.write(S.orig, orig, 3 * n * sizeof(double), "ray origins");
  run.write(S.dirs, dirs, 3 * n * sizeof(double), "ray directions");
  const uint32_t nn = static_cast<uint32_t>(n);
  const cl_int H = S.H;
  if (count)
    run.run("mt_any_hit", n, 0, S.levels, S.ptrs, S.inner, S.leaves, S.geom, H, S.prims, S.pts, S.tris, S.orig,
            S.dirs, nn, tmin, tmax, S.hitOut, S.counters);
  else
    run.run("mt_any_hit", n, 0, S.levels, S.ptrs, S.inner, S.leaves, S.geom, H, S.prims, S.pts, S.tris, S.orig,
            S.dirs, nn, tmin, tmax, S.hitOut, nullptr);
  run.read(S.hitOut, hit, n, "shadow hits");
  if (count) addRayCounters(run, S.counters, n, visits, tests);
  run.finish();
}

void Tracer::findLeaves(const double* pts, size_t n, int32_t* out, std::vector<KernelTiming>* kernels) {
  State& S = *st_;
  requireUploaded(S.uploaded);
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
  const cl_int H = S.H;
  run.run("mt_find_leaves", n, 0, S.levels, S.ptrs, S.inner, S.leaves, S.geom, H, S.points, static_cast<uint32_t>(n),
          S.leafOut);
  run.read(S.leafOut, out, 5 * n * sizeof(int32_t), "located leaves");
  run.finish();
}

}  // namespace ocl
}  // namespace mtree

#endif  // MATRIXTREE_HAVE_OPENCL
