// ShadowOrderChooser: which walk order each run of shadow packets takes, from a shared tally.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>

#include "common/accel/shadow_order.h"
#include "common/base/error.h"

namespace rtc {
namespace {

using Ticks = std::array<std::uint64_t, kShadowWalks>;  // ticks per ray, by ShadowWalk

constexpr ShadowWalk kNear = ShadowWalk::Near, kFar = ShadowWalk::Far, kDense = ShadowWalk::Dense;

int index(ShadowWalk w) { return static_cast<int>(w); }

// A run of `packets` packets of 8 rays, each timed packet taking `ticks[walk]` per ray; returns
// the run's walk.
ShadowWalk run(ShadowOrderTally& tally, int packets, const Ticks& ticks, ShadowOrder mode = ShadowOrder::Auto) {
  ShadowOrderChooser c(mode, &tally);
  for (int i = 0; i < packets; ++i) {
    const ShadowWalk walk = c.next();
    EXPECT_EQ(walk, c.walk());  // one order for the whole run
    if (c.timing()) c.record(8 * ticks[index(walk)], 8);
  }
  c.flush();
  c.flush();  // adds nothing more
  return c.walk();
}

// A tally past the start: kMinRays rays in each walk at the given ticks per ray, `preferred`
// (an index into ShadowOrderChooser::kAutoWalks, 0: dense), and `runs` runs started.
void settled(ShadowOrderTally& tally, const Ticks& ticks, std::uint8_t preferred = 0, std::uint32_t runs = 0) {
  for (int k = 0; k < kShadowWalks; ++k) {
    tally.ticks[k] = ticks[k] * ShadowOrderChooser::kMinRays;
    tally.rays[k] = ShadowOrderChooser::kMinRays;
  }
  tally.preferred = preferred;
  tally.runs = runs;
}

TEST(ShadowOrder, NamesParseAndBadTextIsAnError) {
  for (const ShadowOrder o : {ShadowOrder::Auto, ShadowOrder::Near, ShadowOrder::Far, ShadowOrder::Dense}) {
    EXPECT_EQ(parse_shadow_order(shadow_order_name(o)), o);
  }
  EXPECT_EQ(shadow_walk_of(ShadowOrder::Near), kNear);
  EXPECT_EQ(shadow_walk_of(ShadowOrder::Far), kFar);
  EXPECT_EQ(shadow_walk_of(ShadowOrder::Dense), kDense);
  EXPECT_EQ(shadow_walk_of(ShadowOrder::Auto), kNear);
  for (const ShadowWalk w : {kNear, kFar, kDense}) EXPECT_EQ(shadow_walk_of(shadow_order_of(w)), w);
  EXPECT_THROW((void)parse_shadow_order("nearest"), Error);
  EXPECT_THROW((void)parse_shadow_order(""), Error);
}

TEST(ShadowOrder, FixedOrdersAndAutoWithoutTallyTimeNothing) {
  ShadowOrderTally tally;
  EXPECT_EQ(run(tally, 64, {100, 10, 10}, ShadowOrder::Near), kNear);
  EXPECT_EQ(run(tally, 64, {10, 100, 10}, ShadowOrder::Far), kFar);
  EXPECT_EQ(run(tally, 64, {10, 10, 100}, ShadowOrder::Dense), kDense);
  {
    ShadowOrderChooser unused(ShadowOrder::Auto, &tally);  // no packet asks: no run
    unused.flush();
  }
  for (int k = 0; k < kShadowWalks; ++k) EXPECT_EQ(tally.rays[k].load(), 0u);
  EXPECT_EQ(tally.runs.load(), 0u);
  ShadowOrderChooser alone;  // Auto without a tally: near-first, untimed
  for (int i = 0; i < 32; ++i) {
    EXPECT_EQ(alone.next(), kNear);
    EXPECT_FALSE(alone.timing());
    alone.done(8);
  }
}

// Auto's candidates: dense first, then far; near is never taken.
TEST(ShadowOrder, AutoPicksBetweenDenseAndFar) {
  ASSERT_EQ(ShadowOrderChooser::kAutoWalks.size(), 2u);
  EXPECT_EQ(ShadowOrderChooser::kAutoWalks[0], kDense);
  EXPECT_EQ(ShadowOrderChooser::kAutoWalks[1], kFar);
}

// Runs alternate until both candidates have kMinRays timed rays, then the faster is taken by
// all runs but every kExplore-th, or every kExploreRare-th where the slower one's mean is kApart
// times the faster one's or more; the warm-up packets of a run are never timed. Near, however
// fast, is never taken.
TEST(ShadowOrder, AutoTriesBothThenTakesTheFasterAndKeepsExploring) {
  struct Case {
    std::uint64_t fast, slow;  // ticks per ray
    std::uint32_t every;       // exploring runs
  };
  for (const Case c : {Case{100, 300, ShadowOrderChooser::kExploreRare}, Case{100, 110, ShadowOrderChooser::kExplore},
                       Case{100, 125, ShadowOrderChooser::kExploreRare}, Case{100, 124, ShadowOrderChooser::kExplore}}) {
    for (const bool far_faster : {false, true}) {
      SCOPED_TRACE(::testing::Message() << (far_faster ? "far faster" : "dense faster") << ", " << c.fast
                                        << " against " << c.slow << " ticks per ray");
      const Ticks ticks = {1, far_faster ? c.fast : c.slow, far_faster ? c.slow : c.fast};
      const ShadowWalk faster = far_faster ? kFar : kDense, slower = far_faster ? kDense : kFar;
      ShadowOrderTally tally;
      // 64 packets of 8 rays, 60 timed: 480 rays per run.
      int runs = 0;
      int far_runs = 0;
      while (tally.rays[index(kDense)].load() < ShadowOrderChooser::kMinRays ||
             tally.rays[index(kFar)].load() < ShadowOrderChooser::kMinRays) {
        const ShadowWalk w = run(tally, 64, ticks);
        EXPECT_EQ(w, runs % 2 == 1 ? kFar : kDense) << "run " << runs;  // dense, far, dense, ...
        far_runs += w == kFar ? 1 : 0;
        ++runs;
        ASSERT_LT(runs, 100);
      }
      EXPECT_EQ(tally.rays[index(kNear)].load(), 0u);
      EXPECT_EQ(tally.rays[index(kDense)].load(), static_cast<std::uint64_t>(runs - far_runs) * 60 * 8);
      EXPECT_EQ(tally.ticks[index(kDense)].load(), tally.rays[index(kDense)].load() * ticks[index(kDense)]);
      EXPECT_EQ(tally.ticks[index(kFar)].load(), tally.rays[index(kFar)].load() * ticks[index(kFar)]);
      int explored = 0;
      for (int k = 0; k < 4 * static_cast<int>(c.every); ++k) {
        const std::uint32_t n = tally.runs.load();
        const ShadowWalk w = run(tally, 64, ticks);
        const bool explore = n % c.every == c.every - 1;
        EXPECT_EQ(w, explore ? slower : faster) << "run " << n;
        explored += explore ? 1 : 0;
      }
      EXPECT_EQ(explored, 4);
      EXPECT_EQ(tally.rays[index(kNear)].load(), 0u);
    }
  }
}

// The interval follows the walk a run takes after any switch: with the preferred walk (far)
// twice as slow as dense, run kExplore - 1 switches to dense, against which far is kApart
// apart, so it does not explore (measured against the stale preference, dense would be 0.5x,
// not apart, and the run would explore, taking far).
TEST(ShadowOrder, ExploringIntervalFollowsTheOrderAfterASwitch) {
  ShadowOrderTally tally;
  settled(tally, {1, 200, 100}, 1, ShadowOrderChooser::kExplore - 1);  // preferred: candidate 1, far
  ShadowOrderChooser c(ShadowOrder::Auto, &tally);
  EXPECT_EQ(c.next(), kDense);
  EXPECT_EQ(tally.preferred.load(), 0u);
  c.flush();
  // Walks closer than kApart: the same run number explores.
  ShadowOrderTally close;
  settled(close, {1, 120, 100}, 1, ShadowOrderChooser::kExplore - 1);
  ShadowOrderChooser d(ShadowOrder::Auto, &close);
  EXPECT_EQ(d.next(), kFar);  // switched to dense, then exploring: far
  EXPECT_EQ(close.preferred.load(), 0u);
}

// The first preference is the faster of the settling runs' means, however close; after that
// a walk within kMargin of the preferred one does not take over (switching costs a warm-up),
// one clearly faster does.
TEST(ShadowOrder, FirstPicksTheFasterThenKeepsItUnlessTheOtherIsClearlyFaster) {
  ShadowOrderTally tally;
  EXPECT_EQ(tally.preferred.load(), ShadowOrderTally::kNoPreference);
  const auto settle = [&](const Ticks& ticks) {
    int far_runs = 0;
    for (int k = 0; k < 64; ++k) {
      const std::uint32_t n = tally.runs.load();
      const ShadowWalk got = run(tally, 64, ticks);
      if (n % ShadowOrderChooser::kExplore != ShadowOrderChooser::kExplore - 1) far_runs += got == kFar ? 1 : 0;
    }
    return far_runs;
  };
  settle({1, 102, 100});  // dense 2% faster: preferred from the first settled run
  EXPECT_EQ(tally.preferred.load(), 0u);
  EXPECT_LT(settle({1, 98, 100}), 8);  // now far 2% faster: the runs stay dense
  EXPECT_EQ(tally.preferred.load(), 0u);
  EXPECT_GT(settle({1, 50, 100}), 8);  // far twice as fast: taken over
  EXPECT_EQ(tally.preferred.load(), 1u);
  // A fresh tally where far is 2% faster prefers far.
  ShadowOrderTally fresh;
  while (fresh.preferred.load() == ShadowOrderTally::kNoPreference) {
    run(fresh, 64, {1, 98, 100});
    ASSERT_LT(fresh.runs.load(), 100u);
  }
  EXPECT_EQ(fresh.preferred.load(), 1u);
}

// A run in the faster order times every kTimeEvery-th packet after the warm-up; an exploring
// run, and every run before both candidates have kMinRays, times every packet after it.
TEST(ShadowOrder, WhichPacketsAreTimed) {
  ShadowOrderTally tally;
  settled(tally, {1, 200, 100});
  ShadowOrderChooser faster(ShadowOrder::Auto, &tally);  // run 0: dense, the faster
  int timed = 0;
  for (std::uint32_t i = 0; i < 40; ++i) {
    EXPECT_EQ(faster.next(), kDense);
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
  EXPECT_EQ(not_exploring.next(), kDense);
  tally.runs = ShadowOrderChooser::kExploreRare - 1;
  ShadowOrderChooser explorer(ShadowOrder::Auto, &tally);
  for (std::uint32_t i = 0; i < 40; ++i) {
    EXPECT_EQ(explorer.next(), kFar);
    EXPECT_EQ(explorer.timing(), i >= ShadowOrderChooser::kWarmUp) << i;
  }
}

}  // namespace
}  // namespace rtc
