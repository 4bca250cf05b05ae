// Private to the MatrixTree::Filters module (not wrapped, not installed): the backend setting
// that vtkMatrixTree, vtkMatrixTreeRayCaster, vtkMatrixTreeVolumeRayCaster and
// vtkMatrixTreeLocator share. Each class keeps its public Backend (CPU = 0, OPENCL = 1) and
// OpenCLDevice properties; what they mean is here:
//   - vtkMatrixTreeBackend::Name/Print: the backend's name, and the PrintSelf lines of the
//     settings (Backend, OpenCLDevice, OpenCLDeviceName);
//   - vtkMatrixTreeDevice: the OpenCL device an OPENCL class runs on, resolved from its
//     OpenCLDevice selector (mtree::ocl::Context::shared: "" or null = $MATRIXTREE_OPENCL_DEVICE,
//     else the first GPU, else the first device; "P:D"; "N"; or part of a name) and kept while
//     the selector stays the same.
#ifndef vtkMatrixTreeBackend_h
#define vtkMatrixTreeBackend_h

#include "vtkIndent.h"
#include "vtkIOStream.h"

#include <memory>
#include <string>

namespace mtree
{
namespace ocl
{
class Context;
}
}

namespace vtkMatrixTreeBackend
{
/// The classes' Backend values (their enums Backends have the same).
constexpr int CPU = 0;
constexpr int OPENCL = 1;
/// "opencl" for OPENCL, "cpu" for anything else (GetBackendAsString).
const char* Name(int backend);
/// The PrintSelf lines "Backend", "OpenCLDevice" ("(default)" when null) and "OpenCLDeviceName".
void Print(ostream& os, vtkIndent indent, int backend, const char* selector, const char* deviceName);
}

/// The OpenCL device of a class whose Backend is OPENCL: the context for its OpenCLDevice
/// selector and the device's name. The class makes its device objects (builder, tracer,
/// renderer, locator) on the context Acquire returns, anew whenever Acquire says the context
/// changed.
class vtkMatrixTreeDevice
{
public:
  /// Resolves `selector` (null: ""). True when the context is not the one held before (the first
  /// call, a changed selector, or after a failure or Release): the caller's device objects are
  /// stale. Throws mtree::ocl::Error when no device matches or the build has no OpenCL, and then
  /// holds no context (the next call resolves again).
  bool Acquire(const char* selector);
  /// The context of the last successful Acquire (null before it, after a failure or Release).
  const std::shared_ptr<mtree::ocl::Context>& GetContext() const { return this->Context; }
  /// The device's name ("" when no context is held): GetOpenCLDeviceName.
  const char* GetDeviceName() const { return this->DeviceName.c_str(); }
  /// Drops the context.
  void Release();

private:
  std::shared_ptr<mtree::ocl::Context> Context;
  std::string Selector;
  std::string DeviceName;
};

#endif
