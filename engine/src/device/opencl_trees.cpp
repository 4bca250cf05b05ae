// OpenCL host code for the implicit split-plane trees (opencl/trees.cl). See opencl_trees.h.
#include "mtree/device/opencl_trees.h"

#include <algorithm>
#include <limits>
#include <stdexcept>

#ifdef MATRIXTREE_HAVE_OPENCL
#include "opencl_internal.h"
#endif

namespace mtree {
namespace ocl {

#ifdef MATRIXTREE_HAVE_OPENCL

struct SplitTreeTracer::State {
  Buffer levels, ptrs, words, leafStart, prims, planes, box, pts, tris;
  Buffer orig, dirs, tOut, primOut, hitOut, counters;
  int dirCount = 0, tagBits = 0;
  size_t treeBytes = 0;
  bool empty = true, uploaded = false;
};

SplitTreeTracer::SplitTreeTracer(std::shared_ptr<Context> ctx)
    : ctx_(ctx ? std::move(ctx) : Context::shared()), st_(new State) {}
SplitTreeTracer::~SplitTreeTracer() = default;
Context& SplitTreeTracer::context() const { return *ctx_; }
bool SplitTreeTracer::uploaded() const { return st_->uploaded; }
size_t SplitTreeTracer::deviceTreeBytes() const { return st_->treeBytes; }

void SplitTreeTracer::upload(const ImplicitSplitTree& tree, const TriangleMesh& mesh) {
  Context::Impl& impl = ctx_->impl();
  std::lock_guard<std::recursive_mutex> lock(impl.mutex);
  State& S = *st_;
  S.uploaded = false;
  S.empty = tree.empty();
  S.treeBytes = 0;
  if (S.empty) {
    S.uploaded = true;
    return;
  }
  // Every level's pointer matrix in one array, its entries in another; offsets in the descriptors.
  std::vector<MtSparseDesc> levels(tree.numLevels());
  std::vector<uint32_t> ptrs, words;
  for (int l = 0; l < tree.numLevels(); ++l) {
    const BlockSparseMatrix<uint32_t>& m = tree.level(l);
    if (ptrs.size() + m.pointers().size() >= MT_NULL || words.size() + m.data().size() >= MT_NULL)
      throw std::length_error("SplitTreeTracer: tree too large for 32-bit offsets");
    levels[l] = m.desc();
    levels[l].ptrOffset = static_cast<uint32_t>(ptrs.size());
    levels[l].dataOffset = static_cast<uint32_t>(words.size());
    ptrs.insert(ptrs.end(), m.pointers().begin(), m.pointers().end());
    words.insert(words.end(), m.data().begin(), m.data().end());
  }
  const SplitFrame& f = tree.frame();
  std::vector<double> planes(5 * f.count), box(6);
  for (int k = 0; k < f.count; ++k) {
    planes[5 * k] = f.normal[k].x;
    planes[5 * k + 1] = f.normal[k].y;
    planes[5 * k + 2] = f.normal[k].z;
    planes[5 * k + 3] = f.anchor[k];
    planes[5 * k + 4] = f.scale[k];
  }
  for (int a = 0; a < 3; ++a) {
    box[a] = tree.rootBox().lo[a];
    box[3 + a] = tree.rootBox().hi[a];
  }
  S.dirCount = f.count;
  S.tagBits = f.tagBits;
  Launcher run(impl, nullptr);
  auto put = [&](Buffer& b, const void* src, size_t bytes, const char* what, bool isTree) {
    b.ensure(impl, bytes, what);
    run.write(b, src, bytes, what);
    if (isTree) S.treeBytes += bytes;
  };
  put(S.levels, levels.data(), levels.size() * sizeof(MtSparseDesc), "level descriptors", true);
  put(S.ptrs, ptrs.data(), ptrs.size() * sizeof(uint32_t), "pointer matrices", true);
  put(S.words, words.data(), words.size() * sizeof(uint32_t), "node words", true);
  put(S.leafStart, tree.leafStart().data(), tree.leafStart().size() * sizeof(uint32_t), "leaf table", true);
  put(S.prims, tree.primitiveIndices().data(), tree.primitiveIndices().size() * sizeof(uint32_t), "triangle lists",
      true);
  put(S.planes, planes.data(), planes.size() * sizeof(double), "planes", true);
  put(S.box, box.data(), box.size() * sizeof(double), "root box", true);
  put(S.pts, mesh.points().data(), mesh.points().size() * sizeof(double), "vertices", false);
  put(S.tris, mesh.triangles().data(), mesh.triangles().size() * sizeof(uint32_t), "triangles", false);
  run.finish();
  S.uploaded = true;
}

namespace {
void requireUploaded(bool up) {
  if (!up) throw Error("OpenCL SplitTreeTracer: no tree uploaded; call upload(tree, mesh) first");
}
void sumCounters(Launcher& run, Buffer& counters, size_t n, uint64_t* visits, uint64_t* tests) {
  std::vector<uint32_t> c(2 * n);
  run.read(counters, c.data(), c.size() * sizeof(uint32_t), "ray counters");
  for (size_t i = 0; i < n; ++i) {
    if (visits) *visits += c[2 * i];
    if (tests) *tests += c[2 * i + 1];
  }
}
}  // namespace

void SplitTreeTracer::intersectFirst(const double* orig, const double* dirs, size_t n, double tmin, double tmax,
                                     double* t, uint32_t* prim, uint64_t* visits, uint64_t* tests,
                                     std::vector<KernelTiming>* kernels) {
  trace(orig, dirs, n, tmin, tmax, t, prim, nullptr, visits, tests, kernels);
}

void SplitTreeTracer::intersectAny(const double* orig, const double* dirs, size_t n, double tmin, double tmax,
                                   uint8_t* hit, uint64_t* visits, uint64_t* tests,
                                   std::vector<KernelTiming>* kernels) {
  trace(orig, dirs, n, tmin, tmax, nullptr, nullptr, hit, visits, tests, kernels);
}

void SplitTreeTracer::trace(const double* orig, const double* dirs, size_t n, double tmin, double tmax, double* t,
                            uint32_t* prim, uint8_t* hit, uint64_t* visits, uint64_t* tests,
                            std::vector<KernelTiming>* kernels) {
  State& S = *st_;
  requireUploaded(S.uploaded);
  if (visits) *visits = 0;
  if (tests) *tests = 0;
  if (n == 0) return;
  if (n >= MT_NULL) throw std::length_error("OpenCL SplitTreeTracer: more than 2^32 rays in one batch");
  if (S.empty) {
    for (size_t i = 0; i < n; ++i) {
      if (hit) {
        hit[i] = 0;
      } else {
        t[i] = std::numeric_limits<double>::infinity();
        prim[i] = MT_NULL;
      }
    }
    return;
  }
  Context::Impl& impl = ctx_->impl();
  std::lock_guard<std::recursive_mutex> lock(impl.mutex);
  Launcher run(impl, kernels);
  S.orig.ensure(impl, 3 * n * sizeof(double), "ray origins");
  S.dirs.ensure(impl, 3 * n * sizeof(double), "ray directions");
  if (hit) {
    S.hitOut.ensure(impl, n, "shadow hits");
  } else {
    S.tOut.ensure(impl, n * sizeof(double), "hit distances");
    S.primOut.ensure(impl, n * sizeof(uint32_t), "hit triangles");
  }
  const bool count = visits || tests;
  if (count) S.counters.ensure(impl, 2 * n * sizeof(uint32_t), "ray counters");
  run.write(S.orig, orig, 3 * n * sizeof(double), "ray origins");
  run.write(S.dirs, dirs, 3 * n * sizeof(double), "ray directions");
  const uint32_t nn = static_cast<uint32_t>(n);
  const cl_int D = S.dirCount, tb = S.tagBits;
  // The counters argument is a buffer or a null pointer: two spellings of the same launch.
  auto launch = [&](const auto& counters) {
    if (hit)
      run.run("mt_split_any_hit", n, 0, S.levels, S.ptrs, S.words, S.leafStart, S.prims, S.planes, S.box, D, tb, S.pts,
              S.tris, S.orig, S.dirs, nn, tmin, tmax, S.hitOut, counters);
    else
      run.run("mt_split_first_hit", n, 0, S.levels, S.ptrs, S.words, S.leafStart, S.prims, S.planes, S.box, D, tb,
              S.pts, S.tris, S.orig, S.dirs, nn, tmin, tmax, S.tOut, S.primOut, counters);
  };
  if (count)
    launch(S.counters);
  else
    launch(nullptr);
  if (hit) {
    run.read(S.hitOut, hit, n, "shadow hits");
  } else {
    run.read(S.tOut, t, n * sizeof(double), "hit distances");
    run.read(S.primOut, prim, n * sizeof(uint32_t), "hit triangles");
  }
  if (count) sumCounters(run, S.counters, n, visits, tests);
  run.finish();
}

#else  // built without OpenCL: every entry point says so

namespace {
[[noreturn]] void unavailable() {
  throw Error("OpenCL: this MatrixTree was built without OpenCL (no OpenCL SDK found by CMake, or "
              "-DMATRIXTREE_OPENCL=OFF); install ocl-icd-opencl-dev and opencl-headers and rebuild");
}
}  // namespace

struct SplitTreeTracer::State {};
SplitTreeTracer::SplitTreeTracer(std::shared_ptr<Context>) { unavailable(); }
SplitTreeTracer::~SplitTreeTracer() = default;
Context& SplitTreeTracer::context() const { unavailable(); }
bool SplitTreeTracer::uploaded() const { return false; }
size_t SplitTreeTracer::deviceTreeBytes() const { return 0; }
void SplitTreeTracer::upload(const ImplicitSplitTree&, const TriangleMesh&) { unavailable(); }
void SplitTreeTracer::intersectFirst(const double*, const double*, size_t, double, double, double*, uint32_t*,
                                     uint64_t*, uint64_t*, std::vector<KernelTiming>*) {
  unavailable();
}
void SplitTreeTracer::intersectAny(const double*, const double*, size_t, double, double, uint8_t*, uint64_t*,
                                   uint64_t*, std::vector<KernelTiming>*) {
  unavailable();
}
void SplitTreeTracer::trace(const double*, const double*, size_t, double, double, double*, uint32_t*, uint8_t*,
                            uint64_t*, uint64_t*, std::vector<KernelTiming>*) {
  unavailable();
}

#endif

}  // namespace ocl
}  // namespace mtree
