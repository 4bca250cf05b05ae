// OpenCL host code, part 1: error names and checked calls, device listing and selection,
// programs compiled from the embedded kernel sources and cached per build options, buffers and
// kernel launches with profiling.
#ifdef MATRIXTREE_HAVE_OPENCL

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <sstream>

#include "mtree_opencl_sources.h"  // generated from opencl/*.cl by opencl/embed.cmake
#include "opencl_internal.h"

namespace mtree {
namespace ocl {

bool compiledWithOpenCL() { return true; }

namespace detail {

const char* errorName(cl_int code) {
  switch (code) {
#define MT_CASE(x) \
  case x:          \
    return #x;
    MT_CASE(CL_SUCCESS) MT_CASE(CL_DEVICE_NOT_FOUND) MT_CASE(CL_DEVICE_NOT_AVAILABLE)
    MT_CASE(CL_COMPILER_NOT_AVAILABLE) MT_CASE(CL_MEM_OBJECT_ALLOCATION_FAILURE) MT_CASE(CL_OUT_OF_RESOURCES)
    MT_CASE(CL_OUT_OF_HOST_MEMORY) MT_CASE(CL_PROFILING_INFO_NOT_AVAILABLE) MT_CASE(CL_MEM_COPY_OVERLAP)
    MT_CASE(CL_IMAGE_FORMAT_MISMATCH) MT_CASE(CL_IMAGE_FORMAT_NOT_SUPPORTED) MT_CASE(CL_BUILD_PROGRAM_FAILURE)
    MT_CASE(CL_MAP_FAILURE) MT_CASE(CL_MISALIGNED_SUB_BUFFER_OFFSET)
    MT_CASE(CL_EXEC_STATUS_ERROR_FOR_EVENTS_IN_WAIT_LIST) MT_CASE(CL_COMPILE_PROGRAM_FAILURE)
    MT_CASE(CL_LINKER_NOT_AVAILABLE) MT_CASE(CL_LINK_PROGRAM_FAILURE) MT_CASE(CL_DEVICE_PARTITION_FAILED)
    MT_CASE(CL_KERNEL_ARG_INFO_NOT_AVAILABLE) MT_CASE(CL_INVALID_VALUE) MT_CASE(CL_INVALID_DEVICE_TYPE)
    MT_CASE(CL_INVALID_PLATFORM) MT_CASE(CL_INVALID_DEVICE) MT_CASE(CL_INVALID_CONTEXT)
    MT_CASE(CL_INVALID_QUEUE_PROPERTIES) MT_CASE(CL_INVALID_COMMAND_QUEUE) MT_CASE(CL_INVALID_HOST_PTR)
    MT_CASE(CL_INVALID_MEM_OBJECT) MT_CASE(CL_INVALID_IMAGE_FORMAT_DESCRIPTOR) MT_CASE(CL_INVALID_IMAGE_SIZE)
    MT_CASE(CL_INVALID_SAMPLER) MT_CASE(CL_INVALID_BINARY) MT_CASE(CL_INVALID_BUILD_OPTIONS)
    MT_CASE(CL_INVALID_PROGRAM) MT_CASE(CL_INVALID_PROGRAM_EXECUTABLE) MT_CASE(CL_INVALID_KERNEL_NAME)
    MT_CASE(CL_INVALID_KERNEL_DEFINITION) MT_CASE(CL_INVALID_KERNEL) MT_CASE(CL_INVALID_ARG_INDEX)
    MT_CASE(CL_INVALID_ARG_VALUE) MT_CASE(CL_INVALID_ARG_SIZE) MT_CASE(CL_INVALID_KERNEL_ARGS)
    MT_CASE(CL_INVALID_WORK_DIMENSION) MT_CASE(CL_INVALID_WORK_GROUP_SIZE) MT_CASE(CL_INVALID_WORK_ITEM_SIZE)
    MT_CASE(CL_INVALID_GLOBAL_OFFSET) MT_CASE(CL_INVALID_EVENT_WAIT_LIST) MT_CASE(CL_INVALID_EVENT)
    MT_CASE(CL_INVALID_OPERATION) MT_CASE(CL_INVALID_GL_OBJECT) MT_CASE(CL_INVALID_BUFFER_SIZE)
    MT_CASE(CL_INVALID_MIP_LEVEL) MT_CASE(CL_INVALID_GLOBAL_WORK_SIZE) MT_CASE(CL_INVALID_PROPERTY)
    MT_CASE(CL_INVALID_IMAGE_DESCRIPTOR) MT_CASE(CL_INVALID_COMPILER_OPTIONS) MT_CASE(CL_INVALID_LINKER_OPTIONS)
    MT_CASE(CL_INVALID_DEVICE_PARTITION_COUNT)
#undef MT_CASE
    case -1001:
      return "CL_PLATFORM_NOT_FOUND_KHR";
    default:
      return "unknown OpenCL error";
  }
}

void check(cl_int code, const char* call, const char* file, int line, const std::string& device) {
  if (code == CL_SUCCESS) return;
  std::ostringstream s;
  s << "OpenCL: " << call << " failed: " << errorName(code) << " (" << code << ") at "
    << std::strrchr(file, '/') + 1 << ":" << line;
  if (!device.empty()) s << " on device '" << device << "'";
  if (code == CL_MEM_OBJECT_ALLOCATION_FAILURE || code == CL_OUT_OF_RESOURCES)
    s << " (device out of memory or resources: try a smaller mesh, height or batch)";
  throw Error(s.str());
}

namespace {
std::string deviceString(cl_device_id d, cl_device_info what) {
  size_t n = 0;
  if (clGetDeviceInfo(d, what, 0, nullptr, &n) != CL_SUCCESS || n == 0) return "";
  std::string s(n, '\0');
  if (clGetDeviceInfo(d, what, n, &s[0], nullptr) != CL_SUCCESS) return "";
  while (!s.empty() && (s.back() == '\0' || s.back() == ' ')) s.pop_back();
  return s;
}
template <class T>
T deviceValue(cl_device_id d, cl_device_info what) {
  T v{};
  clGetDeviceInfo(d, what, sizeof(T), &v, nullptr);
  return v;
}
std::string platformString(cl_platform_id p, cl_platform_info what) {
  size_t n = 0;
  if (clGetPlatformInfo(p, what, 0, nullptr, &n) != CL_SUCCESS || n == 0) return "";
  std::string s(n, '\0');
  if (clGetPlatformInfo(p, what, n, &s[0], nullptr) != CL_SUCCESS) return "";
  while (!s.empty() && s.back() == '\0') s.pop_back();
  return s;
}
std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

struct Found {
  DeviceInfo info;
  cl_platform_id platform;
  cl_device_id dev;
};

std::vector<Found> enumerate(std::string* why) {
  std::vector<Found> out;
  cl_uint np = 0;
  const cl_int e = clGetPlatformIDs(0, nullptr, &np);
  if (e != CL_SUCCESS || np == 0) {
    if (why)
      *why = std::string("no OpenCL platform (clGetPlatformIDs: ") + (e == CL_SUCCESS ? "0 platforms" : errorName(e)) +
             "); install an OpenCL driver, e.g. Debian's pocl-opencl-icd for the CPU";
    return out;
  }
  std::vector<cl_platform_id> plats(np);
  clGetPlatformIDs(np, plats.data(), nullptr);
  for (cl_uint p = 0; p < np; ++p) {
    cl_uint nd = 0;
    if (clGetDeviceIDs(plats[p], CL_DEVICE_TYPE_ALL, 0, nullptr, &nd) != CL_SUCCESS || nd == 0) continue;
    std::vector<cl_device_id> devs(nd);
    clGetDeviceIDs(plats[p], CL_DEVICE_TYPE_ALL, nd, devs.data(), nullptr);
    for (cl_uint d = 0; d < nd; ++d) {
      Found f;
      f.platform = plats[p];
      f.dev = devs[d];
      DeviceInfo& i = f.info;
      i.platformIndex = static_cast<int>(p);
      i.deviceIndex = static_cast<int>(d);
      i.platform = platformString(plats[p], CL_PLATFORM_NAME);
      i.name = deviceString(devs[d], CL_DEVICE_NAME);
      i.vendor = deviceString(devs[d], CL_DEVICE_VENDOR);
      i.version = deviceString(devs[d], CL_DEVICE_VERSION);
      i.driver = deviceString(devs[d], CL_DRIVER_VERSION);
      i.gpu = (deviceValue<cl_device_type>(devs[d], CL_DEVICE_TYPE) & CL_DEVICE_TYPE_GPU) != 0;
      const std::string ext = deviceString(devs[d], CL_DEVICE_EXTENSIONS);
      i.fp64 = ext.find("cl_khr_fp64") != std::string::npos ||
               deviceValue<cl_device_fp_config>(devs[d], CL_DEVICE_DOUBLE_FP_CONFIG) != 0;
      i.globalMemBytes = deviceValue<cl_ulong>(devs[d], CL_DEVICE_GLOBAL_MEM_SIZE);
      i.maxAllocBytes = deviceValue<cl_ulong>(devs[d], CL_DEVICE_MAX_MEM_ALLOC_SIZE);
      i.computeUnits = deviceValue<cl_uint>(devs[d], CL_DEVICE_MAX_COMPUTE_UNITS);
      i.maxWorkGroup = deviceValue<size_t>(devs[d], CL_DEVICE_MAX_WORK_GROUP_SIZE);
      out.push_back(f);
    }
  }
  if (out.empty() && why) *why = "OpenCL platforms exist but none has a device";
  return out;
}

std::string describe(const std::vector<Found>& all) {
  std::ostringstream s;
  for (const Found& f : all)
    s << "\n  " << f.info.platformIndex << ":" << f.info.deviceIndex << "  " << f.info.name << " (" << f.info.platform
      << ")";
  return s.str();
}
}  // namespace
}  // namespace detail

std::vector<DeviceInfo> listDevices(std::string* why) {
  std::vector<DeviceInfo> out;
  for (const auto& f : detail::enumerate(why)) out.push_back(f.info);
  return out;
}

// ---------------------------------------------------------------------------------------------
Context::Context(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Context::~Context() = default;
const DeviceInfo& Context::device() const { return impl_->info; }
std::string Context::deviceLabel() const { return impl_->info.name + " (" + impl_->info.platform + ")"; }

std::shared_ptr<Context> Context::create(const std::string& selectorArg) {
  std::string why;
  const auto all = detail::enumerate(&why);
  if (all.empty()) throw Error("OpenCL: no device: " + why);
  std::string sel = selectorArg;
  std::string source = "selector";
  if (sel.empty()) {
    const char* env = std::getenv("MATRIXTREE_OPENCL_DEVICE");
    if (env && *env) {
      sel = env;
      source = "MATRIXTREE_OPENCL_DEVICE";
    }
  }
  const detail::Found* pick = nullptr;
  if (sel.empty()) {
    for (const auto& f : all)
      if (f.info.gpu && f.info.fp64) { pick = &f; break; }
    if (!pick) pick = &all.front();
  } else {
    int p = -1, d = -1;
    char tail = 0;
    if (std::sscanf(sel.c_str(), "%d:%d%c", &p, &d, &tail) == 2) {
      for (const auto& f : all)
        if (f.info.platformIndex == p && f.info.deviceIndex == d) pick = &f;
    } else if (std::sscanf(sel.c_str(), "%d%c", &d, &tail) == 1) {
      if (d >= 0 && d < static_cast<int>(all.size())) pick = &all[d];
    } else {
      const std::string want = detail::lower(sel);
      for (const auto& f : all)
        if (detail::lower(f.info.platform + " / " + f.info.name).find(want) != std::string::npos) { pick = &f; break; }
    }
    if (!pick)
      throw Error("OpenCL: no device matches " + source + " '" + sel +
                  "' (use \"P:D\", a device number, or part of a name); devices here:" + detail::describe(all));
  }
  auto impl = std::make_unique<Impl>();
  Impl& i = *impl;
  i.platform = pick->platform;
  i.dev = pick->dev;
  i.info = pick->info;
  if (!i.info.fp64)
    throw Error("OpenCL: device '" + i.info.name +
                "' lacks cl_khr_fp64 (double precision), which the kernels need to match the CPU engine");
  // Work-group size of the scan and sort kernels: 128, or the device's largest power of two below.
  i.wg = 128;
  while (i.wg > 16 && static_cast<size_t>(i.wg) > i.info.maxWorkGroup) i.wg /= 2;
  if (static_cast<size_t>(i.wg) > i.info.maxWorkGroup)
    throw Error("OpenCL: device '" + i.info.name + "' allows work-groups of only " +
                std::to_string(i.info.maxWorkGroup) + " items (16 needed)");
  cl_int err = CL_SUCCESS;
  const cl_context_properties props[] = {CL_CONTEXT_PLATFORM, reinterpret_cast<cl_context_properties>(i.platform), 0};
  i.ctx = clCreateContext(props, 1, &i.dev, nullptr, nullptr, &err);
  detail::check(err, "clCreateContext", __FILE__, __LINE__, i.info.name);
  i.queue = clCreateCommandQueue(i.ctx, i.dev, CL_QUEUE_PROFILING_ENABLE, &err);
  detail::check(err, "clCreateCommandQueue", __FILE__, __LINE__, i.info.name);
  return std::shared_ptr<Context>(new Context(std::move(impl)));
}

std::shared_ptr<Context> Context::shared(const std::string& selector) {
  static std::mutex m;
  static std::map<std::string, std::shared_ptr<Context>> cache;
  std::lock_guard<std::mutex> lock(m);
  const char* env = std::getenv("MATRIXTREE_OPENCL_DEVICE");
  const std::string key = selector + "|" + (env ? env : "");
  auto it = cache.find(key);
  if (it != cache.end()) return it->second;
  auto ctx = create(selector);
  cache[key] = ctx;
  return ctx;
}

Context::Impl::~Impl() {
  for (auto& k : kernels) clReleaseKernel(k.second);
  for (auto& p : programs) clReleaseProgram(p.second);
  if (queue) clReleaseCommandQueue(queue);
  if (ctx) clReleaseContext(ctx);
}

std::string Context::Impl::defaultOptions() const {
  return "-DMT_WG=" + std::to_string(wg) + " -DMT_ITEMS=8";
}

cl_program Context::Impl::program(const std::string& options) {
  std::lock_guard<std::recursive_mutex> lock(mutex);
  auto it = programs.find(options);
  if (it != programs.end()) return it->second;
  // The source: the shared layout header, the common helpers, then every kernel file.
  std::vector<const char*> parts = {embedded::kLayout, embedded::kCommon};
  for (const auto& s : embedded::kKernels) parts.push_back(s.text);
  cl_int err = CL_SUCCESS;
  cl_program prog = clCreateProgramWithSource(ctx, static_cast<cl_uint>(parts.size()), parts.data(), nullptr, &err);
  detail::check(err, "clCreateProgramWithSource", __FILE__, __LINE__, info.name);
  err = clBuildProgram(prog, 1, &dev, options.c_str(), nullptr, nullptr);
  if (err != CL_SUCCESS) {
    size_t n = 0;
    clGetProgramBuildInfo(prog, dev, CL_PROGRAM_BUILD_LOG, 0, nullptr, &n);
    std::string log(n, '\0');
    if (n) clGetProgramBuildInfo(prog, dev, CL_PROGRAM_BUILD_LOG, n, &log[0], nullptr);
    clReleaseProgram(prog);
    throw Error(std::string("OpenCL: clBuildProgram(options \"") + options + "\") failed: " +
                detail::errorName(err) + " on device '" + info.name + "'; build log:\n" + log);
  }
  programs[options] = prog;
  return prog;
}

cl_kernel Context::Impl::kernel(const char* name) {
  std::lock_guard<std::recursive_mutex> lock(mutex);
  cl_program prog = program(defaultOptions());
  const auto key = std::make_pair(prog, std::string(name));
  auto it = kernels.find(key);
  if (it != kernels.end()) return it->second;
  cl_int err = CL_SUCCESS;
  cl_kernel k = clCreateKernel(prog, name, &err);
  detail::check(err, (std::string("clCreateKernel(") + name + ")").c_str(), __FILE__, __LINE__, info.name);
  kernels[key] = k;
  return k;
}

// ---------------------------------------------------------------------------------------------
void Buffer::ensure(Context::Impl& impl, size_t need, const char* what) {
  need = std::max<size_t>(need, 16);
  if (mem && bytes >= need) return;
  if (mem) {
    clReleaseMemObject(mem);
    mem = nullptr;
    bytes = 0;
  }
  if (need > impl.info.maxAllocBytes)
    throw Error("OpenCL: buffer '" + std::string(what) + "' needs " + std::to_string(need) + " bytes, more than the " +
                std::to_string(impl.info.maxAllocBytes) + " bytes device '" + impl.info.name +
                "' allows in one allocation (CL_DEVICE_MAX_MEM_ALLOC_SIZE); try a smaller mesh or height");
  cl_int err = CL_SUCCESS;
  mem = clCreateBuffer(impl.ctx, CL_MEM_READ_WRITE, need, nullptr, &err);
  detail::check(err, (std::string("clCreateBuffer(") + what + ", " + std::to_string(need) + " bytes)").c_str(),
                __FILE__, __LINE__, impl.info.name);
  bytes = need;
}

Launcher::~Launcher() {
  for (auto& e : events_) clReleaseEvent(e.second);
}

void Launcher::setRaw(cl_kernel k, const char* name, cl_uint i, size_t size, const void* v) {
  auto& impl = impl_;
  const cl_int err = clSetKernelArg(k, i, size, v);
  if (err != CL_SUCCESS)
    detail::check(err, (std::string("clSetKernelArg(") + name + ", arg " + std::to_string(i) + ")").c_str(), __FILE__,
                  __LINE__, impl.info.name);
}

void Launcher::enqueue(cl_kernel k, const char* name, size_t global, size_t local) {
  if (global == 0) return;
  if (local) global = (global + local - 1) / local * local;
  cl_event e = nullptr;
  const cl_int err = clEnqueueNDRangeKernel(impl_.queue, k, 1, nullptr, &global, local ? &local : nullptr, 0, nullptr,
                                            timings_ ? &e : nullptr);
  detail::check(err, (std::string("clEnqueueNDRangeKernel(") + name + ")").c_str(), __FILE__, __LINE__,
                impl_.info.name);
  if (e) record(name, e);
}

void Launcher::record(const char* name, cl_event e) { events_.emplace_back(name, e); }

void Launcher::finish() {
  auto& impl = impl_;
  MT_CL_CHECK(clFinish(impl.queue));
  if (!timings_) return;
  for (auto& ev : events_) {
    cl_ulong a = 0, b = 0;
    MT_CL_CHECK(clGetEventProfilingInfo(ev.second, CL_PROFILING_COMMAND_START, sizeof a, &a, nullptr));
    MT_CL_CHECK(clGetEventProfilingInfo(ev.second, CL_PROFILING_COMMAND_END, sizeof b, &b, nullptr));
    auto it = std::find_if(timings_->begin(), timings_->end(), [&](const KernelTiming& t) { return t.kernel == ev.first; });
    if (it == timings_->end()) {
      timings_->push_back(KernelTiming{ev.first, 0, 0});
      it = timings_->end() - 1;
    }
    it->ms += static_cast<double>(b - a) * 1e-6;
    ++it->launches;
    clReleaseEvent(ev.second);
  }
  events_.clear();
}

void Launcher::write(const Buffer& b, const void* src, size_t bytes, const char* what) {
  if (!bytes) return;
  cl_event e = nullptr;
  const cl_int err =
      clEnqueueWriteBuffer(impl_.queue, b.mem, CL_TRUE, 0, bytes, src, 0, nullptr, timings_ ? &e : nullptr);
  detail::check(err, (std::string("clEnqueueWriteBuffer(") + what + ")").c_str(), __FILE__, __LINE__, impl_.info.name);
  if (e) record("(upload)", e);
}

void Launcher::read(const Buffer& b, void* dst, size_t bytes, const char* what) {
  if (!bytes) return;
  cl_event e = nullptr;
  const cl_int err =
      clEnqueueReadBuffer(impl_.queue, b.mem, CL_TRUE, 0, bytes, dst, 0, nullptr, timings_ ? &e : nullptr);
  detail::check(err, (std::string("clEnqueueReadBuffer(") + what + ")").c_str(), __FILE__, __LINE__, impl_.info.name);
  if (e) record("(download)", e);
}

void Launcher::fill(const Buffer& b, const void* pattern, size_t patternBytes, size_t bytes, const char* what) {
  if (!bytes) return;
  cl_event e = nullptr;
  const cl_int err = clEnqueueFillBuffer(impl_.queue, b.mem, pattern, patternBytes, 0, bytes, 0, nullptr,
                                         timings_ ? &e : nullptr);
  detail::check(err, (std::string("clEnqueueFillBuffer(") + what + ")").c_str(), __FILE__, __LINE__, impl_.info.name);
  if (e) record("(fill)", e);
}

}  // namespace ocl
}  // namespace mtree

#endif  // MATRIXTREE_HAVE_OPENCL
