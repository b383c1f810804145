// Which end of a shadow ray the kd-tree walk starts from, and the per-light choice between the
// two ends. Not compiled per ISA: plain integer and float arithmetic, the same on every ISA.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <string_view>

#include <x86intrin.h>

#include "common/base/error.h"

namespace rtc {

/// The order in which an occlusion (shadow) query visits the leaves along each ray: from the
/// ray's origin (Near) or from the far end of its segment (Far). The answer is the same either
/// way: a lane is occluded when any triangle in the leaves its segment touches hits it within
/// (t_min, t_max), each child's segment is computed from its parent's whatever the order, and
/// the walk stops early only once every lane has a hit. Only the cost differs. Shadow rays
/// start on a surface, where the surface's own leaves rarely block them; on scenes whose
/// blockers lie far from the lit points (a mountain's ridges, the rings, the gears) the far end
/// finds them sooner, where clustered detail shadows itself (a sphereflake, a tree's leaves)
/// the near end does. Auto picks per run of packets (ShadowOrderChooser).
enum class ShadowOrder : std::uint8_t { Auto, Near, Far };

[[nodiscard]] inline const char* shadow_order_name(ShadowOrder order) {
  switch (order) {
    case ShadowOrder::Near:
      return "near";
    case ShadowOrder::Far:
      return "far";
    case ShadowOrder::Auto:
      break;
  }
  return "auto";
}

/// "auto", "near" or "far"; anything else is an rtc::Error naming the text.
[[nodiscard]] inline ShadowOrder parse_shadow_order(std::string_view text) {
  if (text == "auto") return ShadowOrder::Auto;
  if (text == "near") return ShadowOrder::Near;
  if (text == "far") return ShadowOrder::Far;
  throw Error("shadow order '" + std::string(text) + "': expected auto, near or far");
}

/// Time and rays of shadow packets walked in each order, summed over many runs of packets and
/// shared by threads (a renderer keeps one per light for all its tiles and frames): a packet's
/// time varies far more than the two orders' means differ (standard deviations 2-15 times the
/// mean on the shared scenes), so one tile's packets alone cannot tell the orders apart.
struct ShadowOrderTally {
  std::atomic<std::uint64_t> ticks[2] = {0, 0};  // [far_first]
  std::atomic<std::uint64_t> rays[2] = {0, 0};
  std::atomic<std::uint32_t> runs = 0;  // runs started
  std::atomic<bool> far_preferred = false;  // the order runs take (but exploring ones)
};

/// Picks the walk order of a run of shadow packets (one light's rays over a tile, say): one
/// order for the whole run, from the mean time per ray each order took in the shared tally's
/// runs, decided when the run's first packet asks (a chooser no packet asks costs nothing and
/// is not counted). Until both orders have kMinRays rays there, a run takes the one with
/// fewer; then the preferred one, except every kExplore-th run, which takes the other so that
/// both means stay current (every kExploreRare-th run where the other's mean is kApart times the
/// preferred one's or more: there an exploring run costs most and tells least; spd-mount-s10's
/// near-first shadow packets take 1.5 times as long as its far-first ones, and its 16-wide
/// shadow rays ran 1.055x as fast exploring every 64th run as every 16th). The tally's
/// preferred order changes only when the other's mean is kMargin below its own: switching
/// costs a warm-up, so two orders within noise of each other
/// (spd-tree) should not take turns. A run times its packets after its first kWarmUp (every
/// one in exploring runs and before kMinRays, every kTimeEvery-th otherwise) and flush() adds
/// them to the tally. With a fixed order (Near, Far), or without a tally, it always answers
/// one order (Near for Auto without a tally) and times nothing.
///
/// Use: `far_first = next()` before a packet's walk, `done(rays)` after it.
///
/// Why runs and warm-up: a packet walked in the order the packets before it did not take ran
/// 1.5 times slower than in a run of its own order (spd-mount-s10: far-first 752 ticks per ray
/// among near-first packets, 500 among far-first ones; near-first 1,004 against 684), so single
/// packets of the other order would always look slower. And time, not a count of the walk's
/// steps: the orders visit about as many nodes and test about as many triangles per ray there
/// (46.0 and 46.8), yet far-first takes 0.7 of the time, since the nodes in empty space are in
/// cache and a dense surface's leaves are not. The choice thus depends on the machine's timing;
/// the answer never does.
class ShadowOrderChooser {
 public:
  static constexpr std::uint32_t kExplore = 16;
  static constexpr std::uint32_t kExploreRare = 64;  ///< a multiple of kExplore
  static constexpr double kApart = 1.25;
  static_assert(kExploreRare % kExplore == 0, "a run exploring at the rare interval explores at the usual one too");
  static constexpr std::uint32_t kWarmUp = 4;
  static constexpr std::uint32_t kTimeEvery = 8;  ///< of the runs taking the preferred order
  static constexpr std::uint64_t kMinRays = 2048;
  static constexpr double kMargin = 0.05;

  explicit ShadowOrderChooser(ShadowOrder mode = ShadowOrder::Auto, ShadowOrderTally* shared = nullptr)
      : far_first_(mode == ShadowOrder::Far), shared_(mode == ShadowOrder::Auto ? shared : nullptr) {}

  /// The next packet's walk order (the run's): true for far-first. Starts the packet's clock
  /// when it is one to time (timing()).
  [[nodiscard]] bool next() {
    if (shared_ == nullptr) return far_first_;
    if (packets_ == 0) start_run();
    const std::uint32_t n = packets_++;
    timing_ = n >= kWarmUp && (n - kWarmUp) % time_every_ == 0;
    if (timing_) clock_ = __rdtsc();
    return far_first_;
  }

  /// Whether the packet next() last answered for is timed.
  [[nodiscard]] bool timing() const { return timing_; }

  /// After the walk of the packet next() last answered for, of `rays` rays: its time, when timed.
  void done(unsigned rays) {
    if (timing_) record(__rdtsc() - clock_, rays);
  }

  /// Adds `ticks` (time stamp counter ticks) for `rays` rays to the run's figures; done() calls it.
  void record(std::uint64_t ticks, unsigned rays) {
    ticks_ += ticks;
    rays_ += rays;
  }

  /// Adds the run's figures to the shared tally (once; later calls add nothing).
  void flush() {
    if (shared_ == nullptr) return;
    if (rays_ > 0) {
      const int k = far_first_ ? 1 : 0;
      shared_->ticks[k].fetch_add(ticks_, std::memory_order_relaxed);
      shared_->rays[k].fetch_add(rays_, std::memory_order_relaxed);
    }
    shared_ = nullptr;
    timing_ = false;
  }

  /// The run's order (decided by the first next()).
  [[nodiscard]] bool far_first() const { return far_first_; }

 private:
  void start_run() {
    const std::uint32_t n = shared_->runs.fetch_add(1, std::memory_order_relaxed);
    std::uint64_t ticks[2], rays[2];
    for (int k = 0; k < 2; ++k) {
      ticks[k] = shared_->ticks[k].load(std::memory_order_relaxed);
      rays[k] = shared_->rays[k].load(std::memory_order_relaxed);
    }
    if (rays[0] < kMinRays || rays[1] < kMinRays) {
      far_first_ = rays[1] < rays[0] || (rays[1] == rays[0] && (n & 1u) != 0);
      time_every_ = 1;
      return;
    }
    // Whether order a's mean ticks per ray is below f times order b's, compared without
    // division.
    const auto mean_below = [&](int a, int b, double f) {
      return static_cast<double>(ticks[a]) * static_cast<double>(rays[b]) <
             f * static_cast<double>(ticks[b]) * static_cast<double>(rays[a]);
    };
    const bool far = shared_->far_preferred.load(std::memory_order_relaxed);
    const int p = far ? 1 : 0;
    const bool other_faster = mean_below(1 - p, p, 1.0 - kMargin);
    const bool preferred = other_faster ? !far : far;
    if (other_faster) shared_->far_preferred.store(preferred, std::memory_order_relaxed);
    // The other order's mean at least kApart times the preferred one's (the preferred order
    // as it stands now, after any switch above).
    const int q = preferred ? 1 : 0;
    const bool apart = !mean_below(1 - q, q, kApart);
    const std::uint32_t every = apart ? kExploreRare : kExplore;
    const bool explore = n % every == every - 1;
    far_first_ = explore ? !preferred : preferred;
    time_every_ = explore ? 1 : kTimeEvery;
  }

  bool far_first_;
  ShadowOrderTally* shared_;
  bool timing_ = false;
  std::uint32_t time_every_ = 1;
  std::uint32_t packets_ = 0;
  std::uint64_t clock_ = 0;             // the timed packet's start
  std::uint64_t ticks_ = 0, rays_ = 0;  // this run's timed packets
};

}  // namespace rtc
