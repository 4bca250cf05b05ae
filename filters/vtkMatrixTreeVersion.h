/**
 * @class   vtkMatrixTreeVersion
 * @brief   version of the MatrixTree library
 *
 * vtkMatrixTreeVersion reports the version of MatrixTree that this
 * MatrixTree::Filters module was built from, as "major.minor.patch". It is a
 * static query: no instance is needed (`vtkMatrixTreeVersion::GetVersion()`,
 * or `vtkMatrixTreeVersion.GetVersion()` from Python).
 *
 * Thread safety: GetVersion() returns a pointer to a string literal and may be
 * called from any thread.
 *
 * @sa
 * vtkVersion
 */
#ifndef vtkMatrixTreeVersion_h
#define vtkMatrixTreeVersion_h

#include "MatrixTreeFiltersModule.h" // For export macro
#include "vtkObject.h"

class MATRIXTREEFILTERS_EXPORT vtkMatrixTreeVersion : public vtkObject
{
public:
  static vtkMatrixTreeVersion* New();
  vtkTypeMacro(vtkMatrixTreeVersion, vtkObject);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  /**
   * The MatrixTree version, e.g. "0.1.0".
   */
  static const char* GetVersion();

protected:
  vtkMatrixTreeVersion() = default;
  ~vtkMatrixTreeVersion() override = default;

private:
  vtkMatrixTreeVersion(const vtkMatrixTreeVersion&) = delete;
  void operator=(const vtkMatrixTreeVersion&) = delete;
};

#endif
