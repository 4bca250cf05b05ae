#include "vtkMatrixTreeRepresentation.h"

#include "vtkDataSet.h"
#include "vtkInformation.h"
#include "vtkInformationVector.h"
#include "vtkMatrixTree.h"
#include "vtkMatrixTreeInternals.h"
#include "vtkMatrixTreeLocator.h"
#include "vtkObjectFactory.h"
#include "vtkPolyData.h"
#include "vtkUnstructuredGrid.h"

#include <algorithm>

vtkStandardNewMacro(vtkMatrixTreeRepresentation);
vtkCxxSetObjectMacro(vtkMatrixTreeRepresentation, Locator, vtkMatrixTreeLocator);

vtkMatrixTreeRepresentation::vtkMatrixTreeRepresentation()
  : InternalLocator(vtkMatrixTreeLocator::New())
  , InternalTree(vtkMatrixTree::New())
{
}

vtkMatrixTreeRepresentation::~vtkMatrixTreeRepresentation()
{
  this->SetLocator(nullptr);
  this->InternalLocator->Delete();
  this->InternalTree->Delete();
}

vtkMTimeType vtkMatrixTreeRepresentation::GetMTime()
{
  vtkMTimeType t = this->Superclass::GetMTime();
  if (this->Locator)
  {
    t = std::max(t, this->Locator->GetMTime());
  }
  return t;
}

int vtkMatrixTreeRepresentation::FillInputPortInformation(int, vtkInformation* info)
{
  info->Set(vtkAlgorithm::INPUT_REQUIRED_DATA_TYPE(), "vtkDataSet");
  return 1;
}

int vtkMatrixTreeRepresentation::RequestData(
  vtkInformation*, vtkInformationVector** inputVector, vtkInformationVector* outputVector)
{
  vtkDataSet* input = vtkDataSet::GetData(inputVector[0], 0);
  vtkUnstructuredGrid* output = vtkUnstructuredGrid::GetData(outputVector, 0);
  if (!input || !output)
  {
    vtkErrorMacro("Input must be a vtkDataSet.");
    return 0;
  }
  output->Initialize();
  if (input->GetNumberOfCells() == 0)
  {
    return 1; // no cells, no tree: an empty output
  }
  const int b = this->BlockSize;
  if (!this->Locator && (b < 1 || b > 32 || (b & (b - 1))))
  {
    vtkErrorMacro("BlockSize must be a power of two in [1, 32], got " << b << ".");
    return 0;
  }
  if (!this->Locator && this->TreeType >= vtkMatrixTree::IMPLICIT_KDTREE)
  {
    vtkPolyData* surface = vtkPolyData::SafeDownCast(input);
    vtkMatrixTree* tree = this->InternalTree;
    tree->SetTreeType(this->TreeType);
    if (!surface)
    {
      vtkErrorMacro("TreeType " << tree->GetTreeTypeAsString() << " indexes triangles: the input must be a "
                                << "vtkPolyData (e.g. vtkGeometryFilter's output), got a " << input->GetClassName()
                                << ".");
      return 0;
    }
    tree->SetHeight(this->Height);
    tree->SetBlockSize(this->BlockSize);
    tree->SetExactOverlap(this->ExactOverlap);
    if (tree->GetDataSet() != surface)
    {
      tree->SetDataSet(surface);
    }
    if (!tree->BuildIfNeeded())
    {
      vtkErrorMacro("The " << tree->GetTreeTypeAsString() << " tree could not be built on this input.");
      return 0;
    }
    vtkMatrixTreeSplitTrees::Nodes(*tree->GetInternals(), this->MinLevel, this->MaxLevel, output);
    return 1;
  }
  vtkMatrixTreeLocator* loc = this->Locator ? this->Locator : this->InternalLocator;
  if (!this->Locator)
  {
    loc->SetTreeType(this->TreeType);
    loc->SetHeight(this->Height);
    loc->SetBlockSize(this->BlockSize);
    loc->SetExactOverlap(this->ExactOverlap);
  }
  if (loc->GetDataSet() != input)
  {
    loc->SetDataSet(input);
  }
  loc->BuildLocator(); // rebuilds only if the input or a setting changed
  if (loc->GetTreeHeight() == 0 && loc->GetNumberOfLeaves() == 0)
  {
    vtkErrorMacro("The locator could not be built on this input.");
    return 0;
  }
  loc->GenerateNodes(this->MinLevel, this->MaxLevel, output);
  return 1;
}

void vtkMatrixTreeRepresentation::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  os << indent << "MinLevel: " << this->MinLevel << "\n";
  os << indent << "MaxLevel: " << this->MaxLevel << (this->MaxLevel < 0 ? " (leaves)" : "") << "\n";
  static const char* const types[] = { "OCTREE", "KDTREE", "IMPLICIT_KDTREE", "BSP_TREE", "HYBRID" };
  os << indent << "TreeType: " << types[this->TreeType] << "\n";
  os << indent << "Height: " << this->Height << (this->Height == 0 ? " (automatic)" : "") << "\n";
  os << indent << "BlockSize: " << this->BlockSize << "\n";
  os << indent << "ExactOverlap: " << (this->ExactOverlap ? "On" : "Off") << "\n";
  os << indent << "Locator: " << this->Locator << "\n";
}
