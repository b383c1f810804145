// keep_freed_memory: glibc malloc thresholds that keep freed memory in the process.
#include "common/base/process_memory.h"

#include <cstdlib>
#include <cstring>

#include <spdlog/spdlog.h>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace rtc {

namespace {

const char* std_getenv(const char* name) { return std::getenv(name); }

}  // namespace

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
  policy.reason = freed_memory_veto(&std_getenv);
  if (!policy.reason.empty()) return policy;
#if defined(__GLIBC__)
  // 32 MiB: glibc's DEFAULT_MMAP_THRESHOLD_MAX on 64-bit, the largest it accepts. Larger blocks
  // (a big tree's arrays) are mmapped as before; the kd-tree build keeps those itself
  // (alloc_pages' page cache).
  constexpr int kMmapThreshold = 32 << 20;
  const bool mmap_ok = mallopt(M_MMAP_THRESHOLD, kMmapThreshold) == 1;
  const bool trim_ok = mallopt(M_TRIM_THRESHOLD, 0x7FFFFFFF) == 1;  // int's largest, 2 GiB
  policy.applied = mmap_ok && trim_ok;
  if (!policy.applied) policy.reason = "mallopt refused the thresholds";
#else
  policy.reason = "not glibc";
#endif
  return policy;
}

void log_freed_memory_policy(const FreedMemoryPolicy& policy) {
  if (policy.applied) {
    spdlog::debug("malloc keeps freed memory for reuse (M_MMAP_THRESHOLD 32 MiB, M_TRIM_THRESHOLD 2 GiB)");
  } else {
    spdlog::debug("malloc's thresholds left as they are: {}", policy.reason);
  }
}

}  // namespace rtc
