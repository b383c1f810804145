// Wall-clock stopwatch for logs and benchmarks.
#pragma once

#include <chrono>

namespace rtc {

/// Measures elapsed wall time since construction or the last reset(). Not thread-safe.
class Timer {
 public:
  Timer() : start_(Clock::now()) {}
  void reset() { start_ = Clock::now(); }
  [[nodiscard]] double elapsed_ms() const {
    return std::chrono::duration<double, std::milli>(Clock::now() - start_).count();
  }

 private:
  using Clock = std::chrono::steady_clock;
  Clock::time_point start_;
};

}  // namespace rtc
