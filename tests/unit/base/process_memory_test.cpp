// common/base/process_memory: freed memory kept in the process (glibc's malloc thresholds), and
// when the environment overrides it (part of base_test).
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <exception>
#include <fstream>
#include <map>
#include <optional>
#include <string>

#include "common/base/process_memory.h"

namespace rtc {
namespace {

long minor_faults() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_minflt;
}

// Writes one byte per 4 KiB page of a fresh block of `bytes`; returns the block.
char* touch_new_block(std::size_t bytes) {
  auto* p = static_cast<char*>(std::malloc(bytes));
  if (p == nullptr) return nullptr;
  for (std::size_t i = 0; i < bytes; i += 4096) p[i] = static_cast<char>(i);
  // Keep the stores: the compiler may not drop writes to memory it cannot see freed unread.
  asm volatile("" : : "r"(p) : "memory");
  return p;
}

std::map<std::string, std::string>* fake_env = nullptr;
const char* lookup(const char* name) {
  const auto it = fake_env->find(name);
  return it == fake_env->end() ? nullptr : it->second.c_str();
}
std::string veto_with(std::map<std::string, std::string> env) {
  fake_env = &env;
  std::string veto = freed_memory_veto(&lookup);
  fake_env = nullptr;
  return veto;
}

TEST(ProcessMemory, UserSettingsVetoTheThresholds) {
  EXPECT_EQ(veto_with({}), "");
  EXPECT_EQ(veto_with({{"RTC_MALLOC_KEEP", "1"}}), "");
  EXPECT_EQ(veto_with({{"GLIBC_TUNABLES", "glibc.malloc.hugetlb=1"}}), "");  // not a threshold
  EXPECT_EQ(veto_with({{"RTC_MALLOC_KEEP", "0"}}), "RTC_MALLOC_KEEP=0");
  EXPECT_EQ(veto_with({{"MALLOC_TRIM_THRESHOLD_", "1000"}}), "MALLOC_TRIM_THRESHOLD_ is set");
  EXPECT_EQ(veto_with({{"MALLOC_MMAP_THRESHOLD_", "1000"}}), "MALLOC_MMAP_THRESHOLD_ is set");
  EXPECT_EQ(veto_with({{"GLIBC_TUNABLES", "glibc.malloc.hugetlb=1:glibc.malloc.trim_threshold=9"}}),
            "GLIBC_TUNABLES sets glibc.malloc.trim_threshold");
  EXPECT_EQ(veto_with({{"GLIBC_TUNABLES", "glibc.malloc.mmap_threshold=9"}}),
            "GLIBC_TUNABLES sets glibc.malloc.mmap_threshold");
}

// A block freed and asked for again is reused without faulting its pages in anew. With glibc's
// defaults a 16 MiB block is mmapped, given back on free, and the next one (the threshold has
// moved past it) comes from fresh heap pages: ~4096 faults (tried, with the mallopt calls out).
// (Where transparent huge pages are "always", fresh heap pages may come 2 MiB at a time and the
// test would pass without the thresholds too; Debian's default is "madvise".)
TEST(ProcessMemory, FreedBlockIsReusedWithoutFaults) {
  const FreedMemoryPolicy policy = keep_freed_memory();
  if (!policy.mmap_threshold_set && !policy.trim_threshold_set && policy.reason.find("mallopt") == std::string::npos) {
    GTEST_SKIP() << "thresholds not set here: " << policy.reason;  // a sanitizer, the user's settings
  }
  ASSERT_TRUE(policy.applied()) << policy.reason;
  constexpr std::size_t kBytes = std::size_t{16} << 20;
  char* first = touch_new_block(kBytes);
  ASSERT_NE(first, nullptr);
  std::free(first);
  const long before = minor_faults();
  char* second = touch_new_block(kBytes);
  const long faults = minor_faults() - before;
  ASSERT_NE(second, nullptr);
  std::free(second);
  EXPECT_LT(faults, 64) << "faults touching a block of " << kBytes / 4096 << " pages freed just before";
}

}  // namespace
}  // namespace rtc

// An address-space limit (ulimit -v) counts: what the process has not mapped yet of it is all a
// new frame can get, whatever the machine has free. check_memory then refuses with the figures.
TEST(ProcessMemory, AddressSpaceLimitBoundsTheAvailableMemory) {
  rlimit saved{};
  ASSERT_EQ(::getrlimit(RLIMIT_AS, &saved), 0);
  const std::optional<std::uint64_t> before = rtc::available_memory_bytes();
  ASSERT_TRUE(before.has_value());
  std::uint64_t mapped_kb = 0;
  {
    std::ifstream status("/proc/self/status");
    std::string key;
    while (status >> key) {
      if (key == "VmSize:") {
        status >> mapped_kb;
        break;
      }
    }
  }
  ASSERT_GT(mapped_kb, 0u);
  const std::uint64_t headroom = 256ull << 20;  // 256 MiB beyond what is mapped now
  rlimit limit = saved;
  limit.rlim_cur = mapped_kb * 1024 + headroom;
  if (saved.rlim_cur != RLIM_INFINITY && saved.rlim_cur < limit.rlim_cur) GTEST_SKIP() << "a tighter limit is set already";
  ASSERT_EQ(::setrlimit(RLIMIT_AS, &limit), 0);
  const std::optional<std::uint64_t> limited = rtc::available_memory_bytes();
  std::string error;
  try {
    rtc::check_memory("a test frame", 1ull << 30, "use a smaller one");
  } catch (const std::exception& e) {
    error = e.what();
  }
  ::setrlimit(RLIMIT_AS, &saved);
  ASSERT_TRUE(limited.has_value());
  EXPECT_LE(*limited, headroom);
  EXPECT_GE(*limited, headroom / 2);  // the reads above mapped a little, not half of it
  // 0.1-0.3 GB: the 256 MiB less what the process mapped meanwhile.
  EXPECT_TRUE(error.starts_with("a test frame needs at least 1.1 GB of memory and 0.")) << error;
  EXPECT_TRUE(error.ends_with(" GB are available to this process: use a smaller one")) << error;
}
