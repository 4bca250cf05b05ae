// Shared by the test suites that drive the VTK filters: an observer that records the errors a
// VTK object reports (vtkErrorMacro fires ErrorEvent), so a test can assert that bad input gave
// an error with a useful message rather than a crash or silence.
#pragma once

#include <string>

#include "vtkCommand.h"

namespace mtest {

/// Counts ErrorEvents and keeps the last message. Attach with
/// obj->AddObserver(vtkCommand::ErrorEvent, catcher).
class ErrorCatcher : public vtkCommand {
 public:
  static ErrorCatcher* New() { return new ErrorCatcher; }
  void Execute(vtkObject*, unsigned long, void* data) override {
    ++count;
    message = data ? static_cast<const char*>(data) : "";
  }
  int count = 0;
  std::string message;
};

}  // namespace mtest
