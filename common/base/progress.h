// One-line terminal progress bar (percentage, rate, ETA) for long command-line runs.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <mutex>
#include <string>

namespace rtc {

/// Counts work units (tiles, rays, frames) out of a known total and, only when stderr is a
/// terminal (isatty, and TERM is not "dumb"), redraws one line on stderr at most about ten
/// times a second:  "label [#########.........]  45.2%  1234 tiles/s  ETA 0:12".
/// Otherwise it writes nothing at all, so logs and pipes stay clean; the caller prints its
/// own summary line. add() and finish() are thread-safe; add() costs one atomic increment
/// when not drawing.
class ProgressBar {
 public:
  /// `unit` names the work in the rate ("tiles" gives "1234 tiles/s"); empty gives "1234/s".
  explicit ProgressBar(std::uint64_t total, std::string label = {}, std::string unit = {});
  /// Draws to `out` when `draw` is true, whatever it is: for tests and other streams.
  ProgressBar(std::uint64_t total, std::string label, std::string unit, std::FILE* out,
              bool draw);
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;
  /// Calls finish().
  ~ProgressBar();

  /// Adds `n` finished units (the count may pass the total; the bar stops at 100%).
  void add(std::uint64_t n = 1);
  /// Clears the bar's line; later add() calls count but draw nothing. Idempotent.
  void finish();

  [[nodiscard]] std::uint64_t done() const { return done_.load(std::memory_order_relaxed); }
  [[nodiscard]] std::uint64_t total() const { return total_; }
  /// Whether anything is drawn at all.
  [[nodiscard]] bool drawing() const { return draw_; }
  /// Seconds since construction.
  [[nodiscard]] double elapsed_s() const;

 private:
  using Clock = std::chrono::steady_clock;
  // About ten redraws a second: smooth to the eye, negligible next to the work counted.
  static constexpr std::int64_t kRedrawIntervalNs = 100'000'000;
  void draw_line(std::uint64_t done_units);

  const std::uint64_t total_;
  const std::string label_;
  const std::string unit_;
  std::FILE* const out_;
  const bool draw_;
  const Clock::time_point start_;
  std::atomic<std::uint64_t> done_{0};
  // Since start_; the throttle. The first draw waits one interval, so runs shorter than
  // that draw nothing and the first rate shown is not a noisy guess.
  std::atomic<std::int64_t> next_draw_ns_{kRedrawIntervalNs};
  std::mutex draw_mutex_;                      // guards the writes and finished_
  bool finished_ = false;
  bool drawn_ = false;
};

}  // namespace rtc
