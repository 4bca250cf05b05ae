// A seeded random-input driver for the fuzz harnesses, for builds without libFuzzer (GCC, the
// normal build): the same command line as libFuzzer's for what the scripts use.
//
//   fuzz_x FILE_OR_DIR...        replay every file given (directories: every file in them), in
//                                name order: the regression inputs; exits 0 if none fails
//   fuzz_x [-seed=N] [-max_total_time=S] [-runs=N] [-max_len=N] [-timeout=T]
//                                random inputs (lengths 0..max_len, default 4096) from a
//                                std::mt19937_64 seeded with N (default 1) until S seconds or N
//                                runs (default 10 s); a case running T seconds (default 60) fails
//
// A failing case (abort from a broken invariant, a sanitizer report, a crash, a time-out) has its
// input written to crash-<harness>-<seed>-<run> in the working directory first, to be replayed
// and kept under tests/fuzz/regressions/<harness>/.
#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include <fcntl.h>
#include <unistd.h>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

namespace {
std::vector<uint8_t> gInput;  // the case running now, for the crash handler
char gCrashPath[512] = "";

void onCrash(int sig) {
  // Async-signal-safe: open/write/close only, then the default action.
  const int fd = open(gCrashPath, O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd >= 0) {
    if (!gInput.empty() && write(fd, gInput.data(), gInput.size()) < 0) {
    }
    close(fd);
  }
  const char msg[] = "standalone fuzz driver: the failing input is in ";
  if (write(2, msg, sizeof msg - 1) < 0 || write(2, gCrashPath, std::strlen(gCrashPath)) < 0 || write(2, "\n", 1) < 0) {
  }
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

bool flag(const char* arg, const char* name, long long& value) {
  const size_t n = std::strlen(name);
  if (std::strncmp(arg, name, n) != 0) return false;
  value = std::atoll(arg + n);
  return true;
}
}  // namespace

int main(int argc, char** argv) {
  long long seed = 1, seconds = -1, runs = -1, maxLen = 4096, timeout = 60;
  std::vector<std::filesystem::path> files;
  bool replay = false;  // a file or directory was named (an empty regression directory included)
  for (int i = 1; i < argc; ++i) {
    if (flag(argv[i], "-seed=", seed) || flag(argv[i], "-max_total_time=", seconds) || flag(argv[i], "-runs=", runs) ||
        flag(argv[i], "-max_len=", maxLen) || flag(argv[i], "-timeout=", timeout))
      continue;
    if (argv[i][0] == '-') continue;  // other libFuzzer flags: ignored
    const std::filesystem::path p(argv[i]);
    replay = true;
    if (std::filesystem::is_directory(p)) {
      std::vector<std::filesystem::path> in;
      for (const auto& e : std::filesystem::directory_iterator(p))
        if (e.is_regular_file()) in.push_back(e.path());
      std::sort(in.begin(), in.end());
      files.insert(files.end(), in.begin(), in.end());
    } else {
      files.push_back(p);
    }
  }
  const std::string harness = std::filesystem::path(argv[0]).filename().string();
  for (int sig : {SIGABRT, SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGALRM}) std::signal(sig, onCrash);

  if (replay) {
    for (const auto& f : files) {
      std::ifstream is(f, std::ios::binary);
      gInput.assign(std::istreambuf_iterator<char>(is), std::istreambuf_iterator<char>());
      std::snprintf(gCrashPath, sizeof gCrashPath, "crash-%s-replay", harness.c_str());
      alarm(static_cast<unsigned>(timeout));
      LLVMFuzzerTestOneInput(gInput.data(), gInput.size());
      alarm(0);
    }
    std::printf("%s: replayed %zu input(s), all passed\n", harness.c_str(), files.size());
    return 0;
  }
  if (seconds < 0 && runs < 0) seconds = 10;
  std::mt19937_64 rng(static_cast<uint64_t>(seed));
  const auto t0 = std::chrono::steady_clock::now();
  long long run = 0;
  for (; runs < 0 || run < runs; ++run) {
    if (seconds >= 0 &&
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() >= static_cast<double>(seconds))
      break;
    gInput.resize(static_cast<size_t>(rng() % static_cast<uint64_t>(maxLen + 1)));
    for (uint8_t& b : gInput) b = static_cast<uint8_t>(rng());
    std::snprintf(gCrashPath, sizeof gCrashPath, "crash-%s-%lld-%lld", harness.c_str(), seed, run);
    alarm(static_cast<unsigned>(timeout));
    LLVMFuzzerTestOneInput(gInput.data(), gInput.size());
    alarm(0);
  }
  std::printf("%s: %lld random input(s) from seed %lld in %.1f s, all passed\n", harness.c_str(), run, seed,
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  return 0;
}
