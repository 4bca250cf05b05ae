#include "vtkMatrixTreeBackend.h"

#include "mtree/device/opencl.h"

//------------------------------------------------------------------------------
const char* vtkMatrixTreeBackend::Name(int backend)
{
  return backend == OPENCL ? "opencl" : "cpu";
}

//------------------------------------------------------------------------------
void vtkMatrixTreeBackend::Print(
  ostream& os, vtkIndent indent, int backend, const char* selector, const char* deviceName)
{
  os << indent << "Backend: " << Name(backend) << "\n";
  os << indent << "OpenCLDevice: " << (selector ? selector : "(default)") << "\n";
  os << indent << "OpenCLDeviceName: " << (deviceName ? deviceName : "") << "\n";
}

//------------------------------------------------------------------------------
bool vtkMatrixTreeDevice::Acquire(const char* selector)
{
  const std::string wanted = selector ? selector : "";
  if (this->Context && wanted == this->Selector)
  {
    return false;
  }
  this->Release();
  this->Context = mtree::ocl::Context::shared(wanted); // throws: no context held
  this->Selector = wanted;
  this->DeviceName = this->Context->device().name;
  return true;
}

//------------------------------------------------------------------------------
void vtkMatrixTreeDevice::Release()
{
  this->Context.reset();
  this->Selector.clear();
  this->DeviceName.clear();
}
