// common/base/process_memory: freed memory kept in the process (glibc's malloc thresholds), and
// when the environment overrides it (part of base_test).
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <cstddef>
#include <cstdlib>
#include <map>
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
