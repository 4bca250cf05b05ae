/**
 * @class   vtkMatrixTreeStreamTracer
 * @brief   stream tracer whose velocity interpolation finds cells with a chosen cell locator
 *
 * vtkMatrixTreeStreamTracer is vtkPStreamTracer (serial, or across MPI ranks) with the cell
 * locator interpolator (INTERPOLATOR_WITH_CELL_LOCATOR) and a choice of locator: before the
 * integration, every vtkPointSet of the input (a data set, or each leaf of a composite data set)
 * is shallow-copied, a locator of the CellLocatorPrototype's class (NewInstance: the prototype's
 * settings are not copied) is built on the copy and set as its cell locator
 * (vtkPointSet::SetCellLocator), which vtkCellLocatorStrategy uses in preference to building
 * its own. The upstream data is not modified. Inputs that are not point sets (image data,
 * rectilinear grids) find cells by their own structure, as in vtkStreamTracer.
 *
 * The default prototype is a vtkMatrixTreeLocator. With a null prototype the filter is
 * vtkPStreamTracer with VTK's default cell locator.
 *
 * @sa
 * vtkStreamTracer vtkPStreamTracer vtkCellLocatorStrategy vtkMatrixTreeLocator
 */
#ifndef vtkMatrixTreeStreamTracer_h
#define vtkMatrixTreeStreamTracer_h

#include "MatrixTreeParaViewModule.h" // For export macro
#include "vtkPStreamTracer.h"

class vtkAbstractCellLocator;
class vtkDataObject;

class MATRIXTREEPARAVIEW_EXPORT vtkMatrixTreeStreamTracer : public vtkPStreamTracer
{
public:
  static vtkMatrixTreeStreamTracer* New();
  vtkTypeMacro(vtkMatrixTreeStreamTracer, vtkPStreamTracer);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  ///@{
  /** The class of the locator built on every point set of the input (default a vtkMatrixTreeLocator). */
  virtual void SetCellLocatorPrototype(vtkAbstractCellLocator*);
  vtkGetObjectMacro(CellLocatorPrototype, vtkAbstractCellLocator);
  ///@}

  /** Number of locators built by the last execution (one per point set of this rank's input). */
  vtkGetMacro(NumberOfLocatorsBuilt, int);

  /** Includes the prototype's modification time. */
  vtkMTimeType GetMTime() override;

protected:
  vtkMatrixTreeStreamTracer();
  ~vtkMatrixTreeStreamTracer() override;

  int RequestData(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;

private:
  vtkMatrixTreeStreamTracer(const vtkMatrixTreeStreamTracer&) = delete;
  void operator=(const vtkMatrixTreeStreamTracer&) = delete;

  vtkDataObject* WithLocators(vtkDataObject* input);
  vtkDataObject* PointSetWithLocator(vtkDataObject* block);

  vtkAbstractCellLocator* CellLocatorPrototype = nullptr;
  int NumberOfLocatorsBuilt = 0;
};

#endif
