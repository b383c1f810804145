// rtc-bench's round-robin timing (bench_timing.h): who runs when, and the medians and paired
// ratios the comparison tables are made of.
#include <gtest/gtest.h>

#include <numeric>
#include <string>
#include <vector>

#include "tests/bench/bench_timing.h"

namespace {

using rtc::bench::Contender;
using rtc::bench::median_of;
using rtc::bench::paired_ratio;
using rtc::bench::time_rounds_ms;

TEST(BenchTiming, ContendersTakeOneTurnEachPerRound) {
  std::string log;
  const std::vector<Contender> contenders = {
      {[&] { log += 'a'; }, [&] { log += '-'; }},
      {[&] { log += 'b'; }},
      {[&] { log += 'c'; }, [&] { log += '.'; }, 2},  // the first 2 rounds only
  };
  const std::vector<std::vector<double>> ms = time_rounds_ms(3, contenders);
  // Each untimed step right before its contender, the contenders in turn, round after round.
  EXPECT_EQ(log, "-ab.c-ab.c-ab");
  ASSERT_EQ(ms.size(), 3u);
  EXPECT_EQ(ms[0].size(), 3u);
  EXPECT_EQ(ms[1].size(), 3u);
  EXPECT_EQ(ms[2].size(), 2u);
  for (const std::vector<double>& times : ms) {
    for (const double t : times) EXPECT_GE(t, 0.0);
  }
}

TEST(BenchTiming, ShortFirstContenderGetsMoreRoundsUpToTheCap) {
  // Each call of the first contender takes at least 1 ms: after the 2 rounds asked for, rounds
  // go on until its times add up to 5 ms, but never past the cap; a contender limited to its
  // first rounds stays limited.
  const auto sleep_1ms = [] {
    const rtc::Timer t;
    while (t.elapsed_ms() < 1.0) {
    }
  };
  int b_calls = 0;
  const std::vector<Contender> contenders = {{sleep_1ms}, {[&] { ++b_calls; }}, {[] {}, [] {}, 1}};
  const std::vector<std::vector<double>> ms = time_rounds_ms(2, contenders, 5.0, 100);
  ASSERT_EQ(ms.size(), 3u);
  // 1 ms or more a call: at most 5 calls reach 5 ms (fewer where the machine stalls one), and
  // the rounds stop as soon as they do.
  ASSERT_GE(ms[0].size(), 2u);  // the rounds asked for, whatever they took
  EXPECT_LE(ms[0].size(), 5u);
  const double total = std::accumulate(ms[0].begin(), ms[0].end(), 0.0);
  EXPECT_GE(total, 5.0);
  if (ms[0].size() > 2) {
    EXPECT_LT(total - ms[0].back(), 5.0);
  }
  EXPECT_EQ(ms[1].size(), ms[0].size());
  EXPECT_EQ(b_calls, static_cast<int>(ms[0].size()));
  EXPECT_EQ(ms[2].size(), 1u);
  // The cap wins over the minimum time.
  EXPECT_EQ(time_rounds_ms(2, contenders, 1e9, 4)[0].size(), 4u);
  // A minimum the rounds asked for already reach adds none.
  EXPECT_EQ(time_rounds_ms(3, contenders, 1.0, 100)[0].size(), 3u);
}

TEST(BenchTiming, MedianOfOddAndEvenCounts) {
  EXPECT_EQ(median_of({}), 0.0);
  EXPECT_EQ(median_of({7.0}), 7.0);
  EXPECT_EQ(median_of({9.0, 1.0, 4.0}), 4.0);
  EXPECT_EQ(median_of({9.0, 1.0, 4.0, 2.0}), 3.0);  // the mean of the middle two
}

TEST(BenchTiming, PairedRatioIsTheMedianOfEachRoundsRatio) {
  // A slow spell in round 2 doubles both times: the paired ratio does not see it, the ratio of
  // the medians does (4 / 2 = 2).
  const std::vector<double> embree = {2.0, 4.0, 2.2};
  const std::vector<double> rtc = {1.0, 2.0, 2.0};
  EXPECT_DOUBLE_EQ(paired_ratio(embree, rtc), 2.0);
  EXPECT_DOUBLE_EQ(median_of(embree) / median_of(rtc), 1.1);
  // Only the rounds both took part in count (Embree's high-quality build runs in the first 3).
  EXPECT_DOUBLE_EQ(paired_ratio({1.0, 2.0, 3.0, 40.0, 50.0}, {1.0, 1.0, 1.0}), 2.0);
  EXPECT_EQ(paired_ratio({}, {1.0}), 0.0);
}

}  // namespace
