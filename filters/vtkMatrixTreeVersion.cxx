#include "vtkMatrixTreeVersion.h"

#include "vtkObjectFactory.h"

// Set from PROJECT_VERSION by filters/CMakeLists.txt.
#ifndef MATRIXTREE_VERSION_STRING
#error "MATRIXTREE_VERSION_STRING must be defined by the build"
#endif

vtkStandardNewMacro(vtkMatrixTreeVersion);

//------------------------------------------------------------------------------
const char* vtkMatrixTreeVersion::GetVersion()
{
  return MATRIXTREE_VERSION_STRING;
}

//------------------------------------------------------------------------------
void vtkMatrixTreeVersion::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  os << indent << "Version: " << vtkMatrixTreeVersion::GetVersion() << "\n";
}
