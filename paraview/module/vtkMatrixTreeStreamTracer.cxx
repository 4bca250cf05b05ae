#include "vtkMatrixTreeStreamTracer.h"

#include "vtkAbstractCellLocator.h"
#include "vtkCompositeDataIterator.h"
#include "vtkCompositeDataSet.h"
#include "vtkInformation.h"
#include "vtkInformationVector.h"
#include "vtkMatrixTreeLocator.h"
#include "vtkNew.h"
#include "vtkObjectFactory.h"
#include "vtkPointSet.h"
#include "vtkSmartPointer.h"

#include <algorithm>

vtkStandardNewMacro(vtkMatrixTreeStreamTracer);
vtkCxxSetObjectMacro(vtkMatrixTreeStreamTracer, CellLocatorPrototype, vtkAbstractCellLocator);

//------------------------------------------------------------------------------
vtkMatrixTreeStreamTracer::vtkMatrixTreeStreamTracer()
{
  this->SetInterpolatorTypeToCellLocator();
  vtkNew<vtkMatrixTreeLocator> prototype;
  this->SetCellLocatorPrototype(prototype);
}

//------------------------------------------------------------------------------
vtkMatrixTreeStreamTracer::~vtkMatrixTreeStreamTracer()
{
  this->SetCellLocatorPrototype(nullptr);
}

//------------------------------------------------------------------------------
vtkMTimeType vtkMatrixTreeStreamTracer::GetMTime()
{
  const vtkMTimeType t = this->Superclass::GetMTime();
  return this->CellLocatorPrototype ? std::max(t, this->CellLocatorPrototype->GetMTime()) : t;
}

//------------------------------------------------------------------------------
// A shallow copy of a point set with a locator of the prototype's class built on it and set as
// its cell locator; anything else is returned as is (it finds cells by its own structure).
// The caller owns the returned reference.
vtkDataObject* vtkMatrixTreeStreamTracer::PointSetWithLocator(vtkDataObject* block)
{
  vtkPointSet* ps = vtkPointSet::SafeDownCast(block);
  if (!ps || ps->GetNumberOfCells() == 0)
  {
    if (block)
    {
      block->Register(this);
    }
    return block;
  }
  vtkPointSet* copy = ps->NewInstance();
  copy->ShallowCopy(ps);
  auto locator = vtk::TakeSmartPointer(this->CellLocatorPrototype->NewInstance());
  locator->SetDataSet(copy);
  locator->BuildLocator();
  copy->SetCellLocator(locator);
  ++this->NumberOfLocatorsBuilt;
  return copy;
}

//------------------------------------------------------------------------------
// The input with every point set replaced by PointSetWithLocator's copy (the composite
// structure is kept). The caller owns the returned reference.
vtkDataObject* vtkMatrixTreeStreamTracer::WithLocators(vtkDataObject* input)
{
  vtkCompositeDataSet* composite = vtkCompositeDataSet::SafeDownCast(input);
  if (!composite)
  {
    return this->PointSetWithLocator(input);
  }
  vtkCompositeDataSet* out = composite->NewInstance();
  out->CopyStructure(composite);
  auto it = vtk::TakeSmartPointer(composite->NewIterator());
  for (it->InitTraversal(); !it->IsDoneWithTraversal(); it->GoToNextItem())
  {
    auto block = vtk::TakeSmartPointer(this->PointSetWithLocator(it->GetCurrentDataObject()));
    out->SetDataSet(it, block);
  }
  return out;
}

//------------------------------------------------------------------------------
int vtkMatrixTreeStreamTracer::RequestData(
  vtkInformation* request, vtkInformationVector** inputVector, vtkInformationVector* outputVector)
{
  this->NumberOfLocatorsBuilt = 0;
  if (!this->CellLocatorPrototype)
  {
    return this->Superclass::RequestData(request, inputVector, outputVector);
  }
  // The same input information, each data object replaced by its copy with locators; the seed
  // port (1) is passed as it is.
  vtkNew<vtkInformationVector> located;
  const int n = inputVector[0]->GetNumberOfInformationObjects();
  located->SetNumberOfInformationObjects(n);
  for (int i = 0; i < n; ++i)
  {
    vtkInformation* original = inputVector[0]->GetInformationObject(i);
    vtkNew<vtkInformation> info;
    info->Copy(original, 0);
    auto data = vtk::TakeSmartPointer(this->WithLocators(original->Get(vtkDataObject::DATA_OBJECT())));
    info->Set(vtkDataObject::DATA_OBJECT(), data);
    located->SetInformationObject(i, info);
  }
  vtkInformationVector* inputs[2] = { located, inputVector[1] };
  return this->Superclass::RequestData(request, inputs, outputVector);
}

//------------------------------------------------------------------------------
void vtkMatrixTreeStreamTracer::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  os << indent << "CellLocatorPrototype: ";
  if (this->CellLocatorPrototype)
  {
    os << this->CellLocatorPrototype->GetClassName() << "\n";
  }
  else
  {
    os << "(none)\n";
  }
  os << indent << "NumberOfLocatorsBuilt: " << this->NumberOfLocatorsBuilt << "\n";
}
