// HostLogBudget: at most kLinesPerWindow lines a host per window, the last saying so, and the
// count left out said with the first line of a later window.
#include "master/host_log_budget.h"

#include <string>

#include <gtest/gtest.h>

namespace rtc {
namespace {

TEST(HostLogBudget, BoundsEachHostAndSaysWhatWasLeftOut) {
  HostLogBudget budget;
  const HostLogBudget::Clock::time_point t0{};
  std::string note;
  for (int i = 0; i < HostLogBudget::kLinesPerWindow - 1; ++i) {
    ASSERT_TRUE(budget.allow("10.0.0.1", t0, note));
    EXPECT_EQ(note, "");
  }
  ASSERT_TRUE(budget.allow("10.0.0.1", t0, note));
  EXPECT_EQ(note, "; more such lines about 10.0.0.1 are left out for 60 s");
  for (int i = 0; i < 5; ++i) EXPECT_FALSE(budget.allow("10.0.0.1", t0 + std::chrono::seconds(59), note));
  // Another host has its own budget.
  EXPECT_TRUE(budget.allow("10.0.0.2", t0 + std::chrono::seconds(59), note));
  EXPECT_EQ(note, "");
  // The next window: the count left out comes with its first line.
  ASSERT_TRUE(budget.allow("10.0.0.1", t0 + std::chrono::seconds(60), note));
  EXPECT_EQ(note, "; 5 more such lines were left out before this one");
  ASSERT_TRUE(budget.allow("10.0.0.1", t0 + std::chrono::seconds(61), note));
  EXPECT_EQ(note, "");
  // One left out reads in the singular.
  HostLogBudget one;
  for (int i = 0; i < HostLogBudget::kLinesPerWindow; ++i) ASSERT_TRUE(one.allow("h", t0, note));
  EXPECT_FALSE(one.allow("h", t0, note));
  ASSERT_TRUE(one.allow("h", t0 + std::chrono::minutes(5), note));
  EXPECT_EQ(note, "; 1 more such line was left out before this one");
}

TEST(HostLogBudget, ForgetsQuietHostsOnlyWhenFull) {
  HostLogBudget budget;
  const HostLogBudget::Clock::time_point t0{};
  std::string note;
  for (std::size_t i = 0; i < HostLogBudget::kMostHosts; ++i) {
    ASSERT_TRUE(budget.allow("host" + std::to_string(i), t0, note));
  }
  EXPECT_EQ(budget.hosts(), HostLogBudget::kMostHosts);
  // One of them had lines left out: it is kept to say so; the quiet ones whose window has ended go.
  for (int i = 1; i < HostLogBudget::kLinesPerWindow; ++i) ASSERT_TRUE(budget.allow("host0", t0, note));
  EXPECT_FALSE(budget.allow("host0", t0, note));
  EXPECT_TRUE(budget.allow("new", t0 + std::chrono::seconds(61), note));
  EXPECT_EQ(budget.hosts(), 2u);
  EXPECT_TRUE(budget.allow("host0", t0 + std::chrono::seconds(62), note));
  EXPECT_EQ(note, "; 1 more such line was left out before this one");
}

}  // namespace
}  // namespace rtc
