// The OpenCL back end's entry points when the engine is built without an OpenCL SDK: each one
// throws mtree::ocl::Error saying so (never a crash, never a silent CPU fallback).
#ifndef MATRIXTREE_HAVE_OPENCL

#include "mtree/device/opencl.h"

namespace mtree {
namespace ocl {
namespace {
[[noreturn]] void unavailable() {
  throw Error("OpenCL: this MatrixTree was built without OpenCL (no OpenCL SDK found by CMake, or "
              "-DMATRIXTREE_OPENCL=OFF); install ocl-icd-opencl-dev and opencl-headers and rebuild");
}
}  // namespace

struct Context::Impl {};
struct Builder::State {};
struct Tracer::State {};
struct VolumeRenderer::State {};
struct CellLocator::State {};

bool compiledWithOpenCL() { return false; }
std::vector<DeviceInfo> listDevices(std::string* why) {
  if (why) *why = "built without OpenCL";
  return {};
}
Context::Context(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Context::~Context() = default;
std::shared_ptr<Context> Context::create(const std::string&) { unavailable(); }
std::shared_ptr<Context> Context::shared(const std::string&) { unavailable(); }
const DeviceInfo& Context::device() const { unavailable(); }
std::string Context::deviceLabel() const { unavailable(); }

Builder::Builder(std::shared_ptr<Context>) { unavailable(); }
Builder::~Builder() = default;
void Builder::build(const TriangleMesh&, const BuildOptions&, MatrixTree&, BuildStats*, std::vector<KernelTiming>*) {
  unavailable();
}
void Builder::keepDevicePointers(bool) { unavailable(); }
const std::vector<std::vector<uint32_t>>& Builder::devicePointers() const { unavailable(); }
Context& Builder::context() const { unavailable(); }

Tracer::Tracer(std::shared_ptr<Context>) { unavailable(); }
Tracer::~Tracer() = default;
void Tracer::upload(const MatrixTree&, const TriangleMesh&) { unavailable(); }
bool Tracer::uploaded() const { return false; }
void Tracer::intersectFirst(const double*, const double*, size_t, double, double, double*, uint32_t*, uint64_t*,
                            uint64_t*, std::vector<KernelTiming>*) {
  unavailable();
}
void Tracer::intersectAny(const double*, const double*, size_t, double, double, uint8_t*, uint64_t*, uint64_t*,
                          std::vector<KernelTiming>*) {
  unavailable();
}
void Tracer::findLeaves(const double*, size_t, int32_t*, std::vector<KernelTiming>*) { unavailable(); }
Context& Tracer::context() const { unavailable(); }

CellLocator::CellLocator(std::shared_ptr<Context>) { unavailable(); }
CellLocator::~CellLocator() = default;
void CellLocator::upload(const MatrixTree&, const CellSet&, const LargeVector<uint8_t>&) { unavailable(); }
bool CellLocator::uploaded() const { return false; }
size_t CellLocator::deviceBytes() const { return 0; }
void CellLocator::locate(const double*, size_t, double, uint32_t*, std::vector<KernelTiming>*) { unavailable(); }
Context& CellLocator::context() const { unavailable(); }

VolumeRenderer::VolumeRenderer(std::shared_ptr<Context>) { unavailable(); }
VolumeRenderer::~VolumeRenderer() = default;
void VolumeRenderer::upload(const BlockSparseVolume&) { unavailable(); }
bool VolumeRenderer::uploaded() const { return false; }
VolumeImage VolumeRenderer::render(const VolumeGeometry&, const TransferTable&, const VolumeCamera&,
                                   const VolumeRenderOptions&, std::vector<KernelTiming>*) {
  unavailable();
}
Context& VolumeRenderer::context() const { unavailable(); }

}  // namespace ocl
}  // namespace mtree

#endif  // !MATRIXTREE_HAVE_OPENCL
