// keep_freed_memory: glibc malloc thresholds that keep freed memory in the process.
#include "common/base/process_memory.h"

#include <sys/resource.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

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

namespace {

/// The first number in `path` (nullopt where it is missing or holds no number, e.g. "max").
std::optional<std::uint64_t> read_number(const std::string& path) {
  std::ifstream in(path);
  std::uint64_t value = 0;
  if (in >> value) return value;
  return std::nullopt;
}

/// The number after `key` on its line of a "key value [unit]" file (memory.stat,
/// /proc/meminfo), or nullopt.
std::optional<std::uint64_t> read_stat(const std::string& path, const std::string& key) {
  std::ifstream in(path);
  std::string line, name;
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    std::uint64_t value = 0;
    if (fields >> name >> value && name == key) return value;
  }
  return std::nullopt;
}

/// What the memory cgroups this process is in still allow it (limit minus usage, the smallest
/// over the cgroup and its ancestors), or nullopt where no limit is set or none can be read. A
/// container's limit is not in /proc/meminfo, which shows the whole machine.
std::optional<std::uint64_t> cgroup_memory_left() {
  std::optional<std::uint64_t> left;
  // Usage counts the page cache too; its inactive part is given back under pressure, so it is
  // left out, as the kubelet's working set does.
  const auto take = [&left](std::optional<std::uint64_t> limit, std::optional<std::uint64_t> usage,
                            std::optional<std::uint64_t> inactive_file) {
    if (!limit || !usage || *limit >= (std::uint64_t{1} << 60)) return;  // v1 reports "no limit" as ~2^63
    const std::uint64_t used = *usage - std::min(*usage, inactive_file.value_or(0));
    const std::uint64_t here = *limit > used ? *limit - used : 0;
    left = left ? std::min(*left, here) : here;
  };
  std::ifstream cgroups("/proc/self/cgroup");
  std::string line;
  while (std::getline(cgroups, line)) {
    // "0::/path" (v2), "N:memory:/path" or "N:cpu,memory:/path" (v1).
    const std::size_t first = line.find(':');
    const std::size_t second = first == std::string::npos ? first : line.find(':', first + 1);
    if (second == std::string::npos) continue;
    const std::string controllers = line.substr(first + 1, second - first - 1);
    std::string path = line.substr(second + 1);
    const bool v2 = controllers.empty();
    if (!v2 && ("," + controllers + ",").find(",memory,") == std::string::npos) continue;
    const std::string root = v2 ? "/sys/fs/cgroup" : "/sys/fs/cgroup/memory";
    const char* limit_file = v2 ? "/memory.max" : "/memory.limit_in_bytes";
    const char* usage_file = v2 ? "/memory.current" : "/memory.usage_in_bytes";
    // Up from the process's cgroup to the root; in a container with its own cgroup namespace
    // the path reads "/" and the files are at the root.
    for (;;) {
      const std::string dir = root + (path == "/" ? "" : path);
      take(read_number(dir + limit_file), read_number(dir + usage_file),
           read_stat(dir + "/memory.stat", v2 ? "inactive_file" : "total_inactive_file"));
      if (path.empty() || path == "/") break;
      const std::size_t slash = path.rfind('/');
      path = slash == 0 || slash == std::string::npos ? "/" : path.substr(0, slash);
    }
  }
  return left;
}

}  // namespace

std::optional<std::uint64_t> available_memory_bytes() {
  std::optional<std::uint64_t> available = read_stat("/proc/meminfo", "MemAvailable:");
  if (available) *available *= 1024;  // the kernel reports kB
  if (const std::optional<std::uint64_t> cgroup = cgroup_memory_left()) {
    available = available ? std::min(*available, *cgroup) : *cgroup;
  }
  // An address-space limit (ulimit -v) leaves this process what it has not mapped yet.
  rlimit limit{};
  if (::getrlimit(RLIMIT_AS, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY) {
    const std::optional<std::uint64_t> mapped_kb = read_stat("/proc/self/status", "VmSize:");
    const std::uint64_t mapped = mapped_kb ? *mapped_kb * 1024 : 0;
    const std::uint64_t cap = static_cast<std::uint64_t>(limit.rlim_cur);
    const std::uint64_t left = cap > mapped ? cap - mapped : 0;
    available = available ? std::min(*available, left) : left;
  }
  return available;
}

void check_memory(const std::string& what, std::uint64_t need, const std::string& hint) {
  const std::optional<std::uint64_t> available = available_memory_bytes();
  if (!available || need <= *available) return;
  throw Error(fmt::format("{} needs at least {:.1f} GB of memory and {:.1f} GB are available to this process: {}", what,
                          need / 1e9, *available / 1e9, hint));
}

}  // namespace rtc
