// Shared by the OpenCL test suites: the process-wide device context, or a skip with the reason
// (printed once) when there is no OpenCL device.
#pragma once

#include <gtest/gtest.h>

#include <cstdio>
#include <memory>
#include <string>

#include "mtree/device/opencl.h"

namespace mtest {

/// The shared context, or nullptr with the reason (printed once) when there is no device.
inline std::shared_ptr<mtree::ocl::Context> openclDevice(std::string* why) {
  static std::shared_ptr<mtree::ocl::Context> ctx;
  static std::string reason;
  static bool tried = false;
  if (!tried) {
    tried = true;
    try {
      ctx = mtree::ocl::Context::shared();
      std::printf("[ opencl   ] device: %s\n", ctx->deviceLabel().c_str());
    } catch (const mtree::ocl::Error& e) {
      reason = e.what();
      std::printf("[ opencl   ] no OpenCL device, skipping: %s\n", reason.c_str());
    }
  }
  *why = reason;
  return ctx;
}

}  // namespace mtest

/// Declares `ctx` (the shared context) or skips the test with the reason.
#define REQUIRE_DEVICE(ctx)                                \
  std::string why_;                                        \
  auto ctx = mtest::openclDevice(&why_);                   \
  if (!ctx) {                                              \
    GTEST_SKIP() << "no OpenCL device: " << why_;          \
  }                                                        \
  do {                                                     \
  } while (0)
