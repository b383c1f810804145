// keep_freed_memory: glibc malloc thresholds that keep freed memory in the process.
#include "common/base/process_memory.h"

#include <cstdlib>
#include <cstring>
#include <fstream>

#include <spdlog/spdlog.h>

#include "common/base/error.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

// A sanitizer replaces malloc: its mallopt does nothing (ASan's returns 0).
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define RTC_SANITIZER_MALLOC 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || __has_feature(memory_sanitizer)
#define RTC_SANITIZER_MALLOC 1
#endif
#endif

namespace rtc {

std::string freed_memory_veto(const char* (*env)(const char* name)) {
  const char* keep = env("RTC_MALLOC_KEEP");
  if (keep != nullptr && std::strcmp(keep, "0") == 0) return "RTC_MALLOC_KEEP=0";
  for (const char* name : {"MALLOC_TRIM_THRESHOLD_", "MALLOC_MMAP_THRESHOLD_"}) {
    if (env(name) != nullptr) return std::string(name) + " is set";
  }
  const char* tunables = env("GLIBC_TUNABLES");
  if (tunables != nullptr) {
    for (const char* name : {"glibc.malloc.trim_threshold", "glibc.malloc.mmap_threshold"}) {
      if (std::strstr(tunables, name) != nullptr) return std::string("GLIBC_TUNABLES sets ") + name;
    }
  }
  return {};
}

FreedMemoryPolicy keep_freed_memory() {
  FreedMemoryPolicy policy;
#if defined(RTC_SANITIZER_MALLOC)
  policy.reason = "a sanitizer's allocator";
#elif !defined(__GLIBC__)
  policy.reason = "not glibc";
#else
  policy.reason = freed_memory_veto([](const char* name) -> const char* { return std::getenv(name); });
  if (!policy.reason.empty()) return policy;
  // 32 MiB: glibc's DEFAULT_MMAP_THRESHOLD_MAX on 64-bit, the largest it accepts.
  constexpr int kMmapThreshold = 32 << 20;
  policy.mmap_threshold_set = mallopt(M_MMAP_THRESHOLD, kMmapThreshold) == 1;
  policy.trim_threshold_set = mallopt(M_TRIM_THRESHOLD, 0x7FFFFFFF) == 1;  // int's largest, 2 GiB
  if (!policy.mmap_threshold_set) policy.reason += "mallopt refused M_MMAP_THRESHOLD 32 MiB; ";
  if (!policy.trim_threshold_set) policy.reason += "mallopt refused M_TRIM_THRESHOLD 2 GiB; ";
#endif
  return policy;
}

void log_freed_memory_policy(const FreedMemoryPolicy& policy) {
  if (policy.applied()) {
    spdlog::debug("malloc keeps freed memory for reuse (M_MMAP_THRESHOLD 32 MiB, M_TRIM_THRESHOLD 2 GiB)");
  } else if (policy.mmap_threshold_set || policy.trim_threshold_set) {
    spdlog::debug("malloc keeps freed memory in part: {}", policy.reason);
  } else {
    spdlog::debug("malloc's thresholds left as they are: {}", policy.reason);
  }
}

std::optional<std::uint64_t> available_memory_bytes() {
  std::ifstream meminfo("/proc/meminfo");
  std::string key;
  std::uint64_t value = 0;
  std::string unit;
  while (meminfo >> key >> value) {
    std::getline(meminfo, unit);
    if (key == "MemAvailable:") return value * 1024;  // the kernel reports kB
  }
  return std::nullopt;
}

void check_memory(const std::string& what, std::uint64_t need, const std::string& hint) {
  const std::optional<std::uint64_t> available = available_memory_bytes();
  if (!available || need <= *available) return;
  throw Error(fmt::format("{} needs at least {:.1f} GB of memory and this machine has {:.1f} GB available: {}", what,
                          need / 1e9, *available / 1e9, hint));
}

}  // namespace rtc
