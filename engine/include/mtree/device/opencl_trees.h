// The implicit split-plane trees (implicit_tree.h: general kd-trees and BSP trees) on an OpenCL
// device: the stackless derived-parent traversal (ImplicitSplitTree's Backtrack) as a kernel
// (opencl/trees.cl), one work-item per ray.
//
//   mtree::ocl::SplitTreeTracer tr(ctx); tr.upload(tree, mesh);
//   tr.intersectFirst(orig, dirs, n, 0, inf, t, prim);   // ImplicitSplitTree::intersectFirst's hits
//
// The kernel walks the tree as the CPU's Backtrack traversal does, in doubles with the same
// operation order and no contraction, and tests triangles with Moller-Trumbore: its hits (triangle
// and t, bit for bit), node visits and triangle tests equal the CPU's on PoCL
// (tests/cpp/test_opencl_trees.cpp). Same interface as ocl::Tracer, so renderOpenCL()
// (opencl_render.h) renders through either. Without an OpenCL SDK at build time every entry point
// throws ocl::Error.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "mtree/device/opencl.h"
#include "mtree/trees/implicit_tree.h"

namespace mtree {
namespace ocl {

class SplitTreeTracer {
 public:
  explicit SplitTreeTracer(std::shared_ptr<Context> ctx = nullptr);  // nullptr: Context::shared()
  ~SplitTreeTracer();
  SplitTreeTracer(const SplitTreeTracer&) = delete;
  SplitTreeTracer& operator=(const SplitTreeTracer&) = delete;

  /// Copies the tree (level descriptors, pointer matrices, node words, leaf table, triangle
  /// lists, planes, root box) and the mesh to the device. Throws std::length_error for a tree
  /// past 32-bit offsets.
  void upload(const ImplicitSplitTree& tree, const TriangleMesh& mesh);
  bool uploaded() const;
  /// Bytes held on the device by the tree (the mesh not counted).
  size_t deviceTreeBytes() const;

  /// n rays (3 doubles per origin and direction): t (inf on a miss), prim (MT_NULL on a miss);
  /// visits/tests, when given, the summed node visits and triangle tests.
  void intersectFirst(const double* orig, const double* dirs, size_t n, double tmin, double tmax, double* t,
                      uint32_t* prim, uint64_t* visits = nullptr, uint64_t* tests = nullptr,
                      std::vector<KernelTiming>* kernels = nullptr);
  /// Shadow rays: hit[i] = 1 when anything lies on ray i within [tmin, tmax].
  void intersectAny(const double* orig, const double* dirs, size_t n, double tmin, double tmax, uint8_t* hit,
                    uint64_t* visits = nullptr, uint64_t* tests = nullptr,
                    std::vector<KernelTiming>* kernels = nullptr);

  Context& context() const;

 private:
  // One batch through the first-hit kernel (hit == nullptr) or the any-hit kernel.
  void trace(const double* orig, const double* dirs, size_t n, double tmin, double tmax, double* t, uint32_t* prim,
             uint8_t* hit, uint64_t* visits, uint64_t* tests, std::vector<KernelTiming>* kernels);
  struct State;
  std::shared_ptr<Context> ctx_;
  std::unique_ptr<State> st_;
};

}  // namespace ocl
}  // namespace mtree
