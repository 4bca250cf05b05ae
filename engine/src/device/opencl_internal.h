// Private to the engine's OpenCL host code (opencl_*.cpp): checked calls, buffers, launches.
#pragma once
#ifdef MATRIXTREE_HAVE_OPENCL

#include <CL/cl.h>

#include <map>
#include <mutex>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "mtree/device/opencl.h"

namespace mtree {
namespace ocl {
namespace detail {

const char* errorName(cl_int code);
/// Throws Error("<call> failed: <NAME> (<code>) at <file>:<line> on <device>") unless code == CL_SUCCESS.
void check(cl_int code, const char* call, const char* file, int line, const std::string& device = "");

}  // namespace detail

#define MT_CL_CHECK(call) ::mtree::ocl::detail::check((call), #call, __FILE__, __LINE__, impl.info.name)

struct Context::Impl {
  cl_platform_id platform = nullptr;
  cl_device_id dev = nullptr;
  cl_context ctx = nullptr;
  cl_command_queue queue = nullptr;
  DeviceInfo info;
  int wg = 128;  // work-group size of the scan / sort / reduction kernels (MT_WG)
  std::recursive_mutex mutex;
  std::map<std::string, cl_program> programs;                    // by build options
  std::map<std::pair<cl_program, std::string>, cl_kernel> kernels;

  ~Impl();
  /// The program of all kernels built with `options` (compiled once, then cached).
  cl_program program(const std::string& options);
  /// A kernel of the default program (MT_WG = wg).
  cl_kernel kernel(const char* name);
  std::string defaultOptions() const;
};

/// A device buffer (owning). Allocation checks the device's limits first, so a request that
/// cannot fit reports sizes instead of a bare CL_MEM_OBJECT_ALLOCATION_FAILURE.
struct Buffer {
  cl_mem mem = nullptr;
  size_t bytes = 0;
  Buffer() = default;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;
  Buffer(Buffer&& o) noexcept : mem(o.mem), bytes(o.bytes) { o.mem = nullptr; o.bytes = 0; }
  Buffer& operator=(Buffer&& o) noexcept {
    std::swap(mem, o.mem);
    std::swap(bytes, o.bytes);
    return *this;
  }
  ~Buffer() { if (mem) clReleaseMemObject(mem); }
  /// (Re)allocates when smaller than `need` bytes (at least 16). what: named in errors.
  void ensure(Context::Impl& impl, size_t need, const char* what);
};

/// Kernel launches on one context's queue, with optional per-kernel profiling.
class Launcher {
 public:
  Launcher(Context::Impl& impl, std::vector<KernelTiming>* timings) : impl_(impl), timings_(timings) {}
  ~Launcher();
  template <class... Args>
  void run(const char* name, size_t global, size_t local, const Args&... args) {
    cl_kernel k = impl_.kernel(name);
    cl_uint i = 0;
    (setArg(k, name, i++, args), ...);
    enqueue(k, name, global, local);
  }
  /// Waits for the queue and adds the profiled times into the timings list.
  void finish();
  void write(const Buffer& b, const void* src, size_t bytes, const char* what);
  void read(const Buffer& b, void* dst, size_t bytes, const char* what);
  void fill(const Buffer& b, const void* pattern, size_t patternBytes, size_t bytes, const char* what);

 private:
  void setArg(cl_kernel k, const char* name, cl_uint i, const Buffer& b) { setRaw(k, name, i, sizeof(cl_mem), &b.mem); }
  void setArg(cl_kernel k, const char* name, cl_uint i, std::nullptr_t) {
    setRaw(k, name, i, sizeof(cl_mem), nullptr);
  }
  /// A buffer or none (a null buffer argument).
  void setArg(cl_kernel k, const char* name, cl_uint i, const Buffer* b) {
    setRaw(k, name, i, sizeof(cl_mem), b ? &b->mem : nullptr);
  }
  template <class T>
  void setArg(cl_kernel k, const char* name, cl_uint i, const T& v) {
    static_assert(!std::is_pointer<T>::value, "kernel arguments: values, Buffers, const Buffer* or nullptr");
    setRaw(k, name, i, sizeof(T), &v);
  }
  void setRaw(cl_kernel k, const char* name, cl_uint i, size_t size, const void* v);
  void enqueue(cl_kernel k, const char* name, size_t global, size_t local);
  void record(const char* name, cl_event e);

  Context::Impl& impl_;
  std::vector<KernelTiming>* timings_;
  std::vector<std::pair<std::string, cl_event>> events_;
};

/// A matrix tree in the layout query.cl reads: level descriptors, every pointer matrix in one
/// array, every inner level's bytes in another, and the geometry (MtTreeGeom). Shared by the
/// Tracer and the CellLocator uploads. `who` names the caller in the error for trees past 32-bit
/// offsets.
struct FlatTree {
  std::vector<MtLevelDesc> levels;
  std::vector<uint32_t> ptrs;
  std::vector<uint8_t> inner;
  MtTreeGeom geom;
};
FlatTree flattenTree(const MatrixTree& tree, const char* who);

/// The device buffers of a flattened tree and its primitive indices (MT_TREE_PARAMS of query.cl,
/// then prims), as the Tracer and the CellLocator hold them.
struct TreeBuffers {
  Buffer levels, ptrs, inner, leaves, prims, geom;
};
/// Uploads `tree` (flattened by flattenTree) into `b` through `run`; returns the bytes written.
size_t uploadTree(Context::Impl& impl, Launcher& run, const MatrixTree& tree, const char* who, TreeBuffers& b);

}  // namespace ocl
}  // namespace mtree

#endif
