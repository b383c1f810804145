// Wall-clock stopwatch for logs and benchmarks.
#pragma once

#include <chrono>
#include <ctime>

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

/// CPU time of the whole process (all threads) in ms: on a busy machine a steadier measure of
/// work done than wall time.
[[nodiscard]] inline double process_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

}  // namespace rtc
