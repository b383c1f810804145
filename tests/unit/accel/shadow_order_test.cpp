// ShadowOrderChooser: which walk order each run of shadow packets takes, from a shared tally.
#include <gtest/gtest.h>

#include <cstdint>

#include "common/accel/shadow_order.h"
#include "common/base/error.h"

namespace rtc {
namespace {

// A run of `packets` packets of 8 rays, each timed packet taking `ticks_per_ray` per ray;
// returns the run's order.
bool run(ShadowOrderTally& tally, int packets, std::uint64_t near_ticks, std::uint64_t far_ticks,
         ShadowOrder mode = ShadowOrder::Auto) {
  ShadowOrderChooser c(mode, &tally);
  for (int i = 0; i < packets; ++i) {
    const bool far_first = c.next();
    EXPECT_EQ(far_first, c.far_first());  // one order for the whole run
    if (c.timing()) c.record(8 * (far_first ? far_ticks : near_ticks), 8);
  }
  c.flush();
  c.flush();  // adds nothing more
  return c.far_first();
}

// A tally past the alternating start: kMinRays rays in each order at the given ticks per ray,
// `far_preferred`, and `runs` runs started.
void settled(ShadowOrderTally& tally, std::uint64_t near_ticks, std::uint64_t far_ticks, bool far_preferred = false,
             std::uint32_t runs = 0) {
  tally.ticks[0] = near_ticks * ShadowOrderChooser::kMinRays;
  tally.rays[0] = ShadowOrderChooser::kMinRays;
  tally.ticks[1] = far_ticks * ShadowOrderChooser::kMinRays;
  tally.rays[1] = ShadowOrderChooser::kMinRays;
  tally.far_preferred = far_preferred;
  tally.runs = runs;
}

TEST(ShadowOrder, NamesParseAndBadTextIsAnError) {
  for (const ShadowOrder o : {ShadowOrder::Auto, ShadowOrder::Near, ShadowOrder::Far}) {
    EXPECT_EQ(parse_shadow_order(shadow_order_name(o)), o);
  }
  EXPECT_THROW((void)parse_shadow_order("nearest"), Error);
  EXPECT_THROW((void)parse_shadow_order(""), Error);
}

TEST(ShadowOrder, FixedOrdersAndAutoWithoutTallyTimeNothing) {
  ShadowOrderTally tally;
  EXPECT_FALSE(run(tally, 64, 100, 10, ShadowOrder::Near));
  EXPECT_TRUE(run(tally, 64, 10, 100, ShadowOrder::Far));
  {
    ShadowOrderChooser unused(ShadowOrder::Auto, &tally);  // no packet asks: no run
    unused.flush();
  }
  EXPECT_EQ(tally.rays[0].load() + tally.rays[1].load(), 0u);
  EXPECT_EQ(tally.runs.load(), 0u);
  ShadowOrderChooser alone;  // Auto without a tally: near-first, untimed
  for (int i = 0; i < 32; ++i) {
    EXPECT_FALSE(alone.next());
    EXPECT_FALSE(alone.timing());
    alone.done(8);
  }
}

// Runs alternate until both orders have kMinRays timed rays, then the faster order is taken by
// all runs but every kExplore-th, or every kExploreRare-th where the slower order's mean is
// kApart times the faster one's or more; the warm-up packets of a run are never timed.
TEST(ShadowOrder, AutoTriesBothThenTakesTheFasterAndKeepsExploring) {
  struct Case {
    std::uint64_t fast, slow;  // ticks per ray
    std::uint32_t every;       // exploring runs
  };
  for (const Case c : {Case{100, 300, ShadowOrderChooser::kExploreRare}, Case{100, 110, ShadowOrderChooser::kExplore},
                       Case{100, 125, ShadowOrderChooser::kExploreRare}, Case{100, 124, ShadowOrderChooser::kExplore}}) {
    for (const bool far_faster : {false, true}) {
      SCOPED_TRACE(::testing::Message() << (far_faster ? "far faster" : "near faster") << ", " << c.fast << " against "
                                        << c.slow << " ticks per ray");
      const std::uint64_t near_ticks = far_faster ? c.slow : c.fast, far_ticks = far_faster ? c.fast : c.slow;
      ShadowOrderTally tally;
      // 64 packets of 8 rays, 60 timed: 480 rays per run.
      int runs = 0;
      int far_runs = 0;
      while (tally.rays[0].load() < ShadowOrderChooser::kMinRays ||
             tally.rays[1].load() < ShadowOrderChooser::kMinRays) {
        const bool far = run(tally, 64, near_ticks, far_ticks);
        EXPECT_EQ(far, runs % 2 == 1) << "run " << runs;  // near, far, near, ...
        far_runs += far ? 1 : 0;
        ++runs;
        ASSERT_LT(runs, 100);
      }
      EXPECT_EQ(tally.rays[0].load(), static_cast<std::uint64_t>(runs - far_runs) * 60 * 8);
      EXPECT_EQ(tally.ticks[0].load(), tally.rays[0].load() * near_ticks);
      EXPECT_EQ(tally.ticks[1].load(), tally.rays[1].load() * far_ticks);
      int explored = 0;
      for (int k = 0; k < 4 * static_cast<int>(c.every); ++k) {
        const std::uint32_t n = tally.runs.load();
        const bool far = run(tally, 64, near_ticks, far_ticks);
        const bool explore = n % c.every == c.every - 1;
        EXPECT_EQ(far, explore ? !far_faster : far_faster) << "run " << n;
        explored += explore ? 1 : 0;
      }
      EXPECT_EQ(explored, 4);
    }
  }
}

// The interval follows the order a run takes after any switch: with the preferred order (far)
// twice as slow as the other, run 15 switches to near, against which far is kApart apart, so it
// does not explore (measured against the stale preference, near would be 0.5x, not apart, and
// run 15 would explore, taking far).
TEST(ShadowOrder, ExploringIntervalFollowsTheOrderAfterASwitch) {
  ShadowOrderTally tally;
  settled(tally, 100, 200, true, ShadowOrderChooser::kExplore - 1);
  ShadowOrderChooser c(ShadowOrder::Auto, &tally);
  EXPECT_FALSE(c.next());
  EXPECT_FALSE(tally.far_preferred.load());
  c.flush();
  // Orders closer than kApart: the same run number explores.
  ShadowOrderTally close;
  settled(close, 100, 120, true, ShadowOrderChooser::kExplore - 1);
  ShadowOrderChooser d(ShadowOrder::Auto, &close);
  EXPECT_TRUE(d.next());  // switched to near, then exploring: far
  EXPECT_FALSE(close.far_preferred.load());
}

// An order within kMargin of the preferred one does not take over (switching costs a warm-up);
// one clearly faster does.
TEST(ShadowOrder, KeepsThePreferredOrderUnlessTheOtherIsClearlyFaster) {
  ShadowOrderTally tally;
  const auto settle = [&](std::uint64_t near_ticks, std::uint64_t far_ticks) {
    int far_runs = 0;
    for (int k = 0; k < 64; ++k) {
      const std::uint32_t n = tally.runs.load();
      const bool far = run(tally, 64, near_ticks, far_ticks);
      if (n % ShadowOrderChooser::kExplore != ShadowOrderChooser::kExplore - 1) far_runs += far ? 1 : 0;
    }
    return far_runs;
  };
  EXPECT_LT(settle(100, 98), 8);  // far 2% faster: the runs stay near-first once settled
  EXPECT_FALSE(tally.far_preferred.load());
  EXPECT_GT(settle(100, 50), 8);  // far twice as fast: taken over
  EXPECT_TRUE(tally.far_preferred.load());
}

// A run in the faster order times every kTimeEvery-th packet after the warm-up; an exploring
// run, and every run before both orders have kMinRays, times every packet after it.
TEST(ShadowOrder, WhichPacketsAreTimed) {
  ShadowOrderTally tally;
  settled(tally, 100, 200);
  ShadowOrderChooser faster(ShadowOrder::Auto, &tally);  // run 0: near, the faster
  int timed = 0;
  for (std::uint32_t i = 0; i < 40; ++i) {
    EXPECT_FALSE(faster.next());
    const bool t = faster.timing();
    EXPECT_EQ(t, i >= ShadowOrderChooser::kWarmUp && (i - ShadowOrderChooser::kWarmUp) % ShadowOrderChooser::kTimeEvery == 0)
        << i;
    timed += t ? 1 : 0;
  }
  EXPECT_EQ(timed, static_cast<int>((40 - ShadowOrderChooser::kWarmUp + ShadowOrderChooser::kTimeEvery - 1) /
                                    ShadowOrderChooser::kTimeEvery));
  // The slower order takes twice as long: only every kExploreRare-th run explores.
  tally.runs = ShadowOrderChooser::kExplore - 1;
  ShadowOrderChooser not_exploring(ShadowOrder::Auto, &tally);
  EXPECT_FALSE(not_exploring.next());
  tally.runs = ShadowOrderChooser::kExploreRare - 1;
  ShadowOrderChooser explorer(ShadowOrder::Auto, &tally);
  for (std::uint32_t i = 0; i < 40; ++i) {
    EXPECT_TRUE(explorer.next());
    EXPECT_EQ(explorer.timing(), i >= ShadowOrderChooser::kWarmUp) << i;
  }
}

}  // namespace
}  // namespace rtc
