// OpenCL back end of the engine: the §5.1 build and the tree queries as kernels (opencl/*.cl,
// embedded into the library at build time), for PoCL on a CPU and for any GPU driver.
//
//   auto ctx = mtree::ocl::Context::shared();           // device from $MATRIXTREE_OPENCL_DEVICE or the first one
//   mtree::ocl::Builder(ctx).build(mesh, opt, tree);    // the same tree as MatrixTreeBuilder's, array for array
//   mtree::ocl::Tracer tr(ctx); tr.upload(tree, mesh);  // any MatrixTree, built on either back end
//   tr.intersectFirst(orig, dirs, n, 0, inf, t, prim);  // the same hits as intersectFirst()
//   mtree::ocl::VolumeRenderer vr(ctx); vr.upload(vol); // a BlockSparseVolume (volume.h)
//   VolumeImage img = vr.render(geo, tf, cam, opt);     // the same image as renderVolume()
//   mtree::ocl::CellLocator cl(ctx); cl.upload(tree, cells, leafBoxes);  // a CellSet's tree
//   cl.locate(pts, n, 1e-3, out);                       // per point: no cell, found, or host resumes
//
// Every OpenCL call is checked: a failure throws mtree::ocl::Error naming the call, the error
// code and the device (with the build log when a kernel fails to compile). Without an OpenCL SDK
// at build time (MATRIXTREE_HAVE_OPENCL undefined) every entry point throws Error saying so.
// OpenCL types stay out of this header, so it can be included anywhere.
#pragma once

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "mtree/cells/cells.h"
#include "mtree/core/matrix_tree.h"
#include "mtree/core/primitives.h"
#include "mtree/volume/volume.h"

namespace mtree {
namespace ocl {

/// Every OpenCL failure: no platform or device, a failed call, a failed kernel compile.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// True if the engine was built with the OpenCL back end.
bool compiledWithOpenCL();

struct DeviceInfo {
  int platformIndex = -1, deviceIndex = -1;  // indices in clGetPlatformIDs / clGetDeviceIDs order
  std::string platform, name, vendor, version, driver;
  bool gpu = false;
  bool fp64 = false;  // cl_khr_fp64 (the kernels need it)
  uint64_t globalMemBytes = 0, maxAllocBytes = 0;
  unsigned computeUnits = 0;
  size_t maxWorkGroup = 0;
};

/// All devices of all platforms. Never throws: an empty list (with the reason in *why) when
/// there is no OpenCL at all, no ICD, no platform or no device.
std::vector<DeviceInfo> listDevices(std::string* why = nullptr);

/// Device time of one kernel summed over its launches (OpenCL profiling events).
struct KernelTiming {
  std::string kernel;
  double ms = 0;
  int launches = 0;
};

/// A device, its context and in-order queue, and the compiled programs (cached per build
/// options). Thread-safe: operations on one context are serialised by a mutex.
class Context {
 public:
  /// selector: "" = $MATRIXTREE_OPENCL_DEVICE if set, else the first GPU, else the first device;
  /// "P:D" = device D of platform P; "N" = the N-th device over all platforms; any other text =
  /// the first device whose "platform / device" name contains it (case-insensitive).
  /// Throws Error when no device matches (listing the devices there are).
  static std::shared_ptr<Context> create(const std::string& selector = "");
  /// One context per selector for the whole process, so kernels are compiled once.
  static std::shared_ptr<Context> shared(const std::string& selector = "");
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  const DeviceInfo& device() const;
  /// "name (platform)": what benchmarks print as the device.
  std::string deviceLabel() const;

  struct Impl;
  Impl& impl() const { return *impl_; }

 private:
  explicit Context(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// The §5.1 build on the device, one kernel per step (opencl/build.cl, scan.cl, sort.cl). Gives
/// the same tree as MatrixTreeBuilder<TriangleMesh>::build: same height and level shapes, same
/// pointer matrices, blocks, leaf ranges and triangle order. Phases in BuildStats have the CPU
/// builder's names plus "upload" and "download" (host wall time, the queue drained at each).
/// Device buffers are kept and reused between builds (per-frame rebuilds).
class Builder {
 public:
  explicit Builder(std::shared_ptr<Context> ctx = nullptr);  // nullptr: Context::shared()
  ~Builder();
  Builder(const Builder&) = delete;
  Builder& operator=(const Builder&) = delete;

  /// Same contract as MatrixTreeBuilder::build (invalid options throw std::invalid_argument, an
  /// empty mesh gives an empty tree); device failures throw Error and leave `tree` empty.
  /// opt.threads only affects the host-side copy into `tree`. kernels: per-kernel device time.
  void build(const TriangleMesh& mesh, const BuildOptions& opt, MatrixTree& tree, BuildStats* stats = nullptr,
             std::vector<KernelTiming>* kernels = nullptr);

  /// The pointer matrices the device computed in the last build, level 0..H (tests compare them
  /// with the host tree's; recorded only after keepDevicePointers(true)).
  void keepDevicePointers(bool on);
  const std::vector<std::vector<uint32_t>>& devicePointers() const;

  Context& context() const;

 private:
  struct State;
  std::shared_ptr<Context> ctx_;
  std::unique_ptr<State> st_;
};

/// Queries on the device (opencl/query.cl) over a MatrixTree uploaded once. Answers equal the
/// CPU engine's: leafFind(), intersectFirst() (Moller-Trumbore, ties to the smaller triangle id),
/// intersectAny().
class Tracer {
 public:
  explicit Tracer(std::shared_ptr<Context> ctx = nullptr);
  ~Tracer();
  Tracer(const Tracer&) = delete;
  Tracer& operator=(const Tracer&) = delete;

  /// Copies the tree and the mesh it was built over to the device.
  void upload(const MatrixTree& tree, const TriangleMesh& mesh);
  bool uploaded() const;

  /// n rays (3 doubles per origin and direction): t (inf on a miss), prim (MT_NULL on a miss).
  /// visits/tests, when given, get the summed node visits and triangle tests.
  void intersectFirst(const double* orig, const double* dirs, size_t n, double tmin, double tmax, double* t,
                      uint32_t* prim, uint64_t* visits = nullptr, uint64_t* tests = nullptr,
                      std::vector<KernelTiming>* kernels = nullptr);
  /// Shadow rays: hit[i] = 1 when anything lies on ray i within [tmin, tmax].
  void intersectAny(const double* orig, const double* dirs, size_t n, double tmin, double tmax, uint8_t* hit,
                    uint64_t* visits = nullptr, uint64_t* tests = nullptr,
                    std::vector<KernelTiming>* kernels = nullptr);
  /// n points: 5 ints each (level, i, j, k, exists) as MatrixTree::leafFind; level -1 outside.
  void findLeaves(const double* pts, size_t n, int32_t* out, std::vector<KernelTiming>* kernels = nullptr);

  Context& context() const;

 private:
  struct State;
  std::shared_ptr<Context> ctx_;
  std::unique_ptr<State> st_;
};

/// Batched point location in the cells of a CellSet (opencl/query_cells.cl), over the matrix
/// tree built on it, uploaded once. The device does what the CPU point-location loop does before
/// it asks VTK: per point, leafFind, then the leaf's candidates in tree order, each first tested
/// against its quantized leaf-local box (the same double arithmetic as the host, contraction
/// off, hence the same rejections). Tetrahedra are then decided on the device: barycentric
/// coordinates computed with an error bound, a cell rejected or accepted only when every
/// coordinate is outside / inside [-tol, 1 + tol] by more than that bound. Anything else (other
/// cell types, a tetrahedron too close to the tolerance to call, a degenerate one) stops the scan
/// and hands the candidate's position to the host, which continues the CPU loop from there. So
/// the host, finishing each point, returns exactly the cell the CPU loop returns.
class CellLocator {
 public:
  /// Per point, locate() writes two uint32: the outcome and a position in the tree's primitive
  /// index array (tree.primitiveIndices()).
  enum Outcome : uint32_t {
    kNoCell = 0,  // outside the tree, in an empty node, or every candidate rejected: no cell
    kFound = 1,   // the tetrahedron at the position contains the point (within tol)
    kResume = 2,  // the host continues the candidate scan at the position (leaf of leafFind)
  };

  explicit CellLocator(std::shared_ptr<Context> ctx = nullptr);  // nullptr: Context::shared()
  ~CellLocator();
  CellLocator(const CellLocator&) = delete;
  CellLocator& operator=(const CellLocator&) = delete;

  /// Copies the tree (levels, leaf ranges, primitive indices), the cells (points, offsets,
  /// connectivity, types) and leafBoxes to the device. leafBoxes: 6 bytes per primitive index
  /// (same order): the cell's box in its leaf's frame, lo/hi per axis in 1/255 of the leaf
  /// (xlo xhi ylo yhi zlo zhi); a point p of leaf box lb is tested as
  /// q[a] = min(255, max(0, (p[a] - lb.lo[a]) * (255 / (lb.hi[a] - lb.lo[a])))). Throws
  /// std::invalid_argument when the sizes disagree. Call again after every rebuild.
  void upload(const MatrixTree& tree, const CellSet& cells, const LargeVector<uint8_t>& leafBoxes);
  bool uploaded() const;
  /// Bytes held on the device by the upload (not counting the per-call point buffers).
  size_t deviceBytes() const;

  /// n points (3 doubles each); tol: the tetrahedron's acceptance tolerance on barycentric
  /// coordinates (VTK's vtkTetra::EvaluatePosition: 1e-3). out: 2 uint32 per point (Outcome,
  /// position). kernels: device time per kernel, plus "(upload)" (the points) and "(download)"
  /// (the answers).
  void locate(const double* pts, size_t n, double tol, uint32_t* out, std::vector<KernelTiming>* kernels = nullptr);

  Context& context() const;

 private:
  struct State;
  std::shared_ptr<Context> ctx_;
  std::unique_ptr<State> st_;
};

/// Volume ray casting on the device (opencl/volume.cl) over a BlockSparseVolume uploaded once,
/// in every voxel storage the CPU renders, as the CPU holds it (no conversion, no extra copy):
/// Float32: the pointer matrix and the allocated DIM^3 float blocks; UInt8/UInt16: the brick
/// pointers, the visible (DIM+1)^3 apron bricks in 8 or 16 bits and their cell masks; plus the
/// matrix-tree occupancy levels. Device memory is therefore the engine's own stats().bytes, less
/// the per-brick ranges. render() takes renderVolume()'s arguments and gives its image: same
/// rays, samples at the same t, trilinear interpolation, the same step-corrected table,
/// compositing, early termination and empty-space skipping (same samples and skips counted). For
/// each storage the kernel follows the CPU marcher of that storage step for step (Float32: the
/// double-position march; UInt8/UInt16 in float: marchApron's float positions, z-y-x
/// interpolation and transmittance compositing; in double: the brick-by-brick march), so unshaded
/// images match the CPU's bit for bit on PoCL (x86-64 host, whose CPU marcher for 8/16 bits is
/// the SSE2 one); with opt.shade the device's float division, sqrt and pow (a few ulp in OpenCL)
/// leave differences of ~1e-7. opt.threads only affects the host upsampling when
/// imageSampleDistance > 1. img.ms: host wall time of the whole call.
class VolumeRenderer {
 public:
  explicit VolumeRenderer(std::shared_ptr<Context> ctx = nullptr);
  ~VolumeRenderer();
  VolumeRenderer(const VolumeRenderer&) = delete;
  VolumeRenderer& operator=(const VolumeRenderer&) = delete;

  /// Copies `vol` (built: levelCount() > 0) to the device; throws std::invalid_argument if not.
  /// Call again only when the volume was rebuilt (reclassified): renders reuse the upload.
  void upload(const BlockSparseVolume& vol);
  bool uploaded() const;
  /// Same contract as renderVolume (invalid arguments throw std::invalid_argument); `tf` must
  /// be the table the uploaded volume was classified with, as on the CPU.
  VolumeImage render(const VolumeGeometry& geo, const TransferTable& tf, const VolumeCamera& cam,
                     const VolumeRenderOptions& opt, std::vector<KernelTiming>* kernels = nullptr);

  Context& context() const;

 private:
  struct State;
  std::shared_ptr<Context> ctx_;
  std::unique_ptr<State> st_;
};

}  // namespace ocl
}  // namespace mtree
