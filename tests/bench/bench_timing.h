// Timing for rtc-bench and its sweep: medians over repetitions, by wall clock or (--cpu-time)
// by the process's CPU time.
#pragma once

#include <algorithm>
#include <ctime>
#include <utility>
#include <vector>

#include "common/base/timer.h"

namespace rtc::bench {

/// --cpu-time: time sections by the process's CPU time instead of the wall clock, for A/B
/// comparisons on a machine that is busy with other work (descheduled time is not counted).
inline bool g_cpu_time = false;

inline double cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

/// The median and the fastest of a set of timings, in ms.
struct TimeStats {
  double median_ms = 0.0;
  double min_ms = 0.0;
};

/// Times `reps` calls of `fn`; `untimed` runs before each call, outside the timing (builders
/// pass the release of the previous result there, so that freeing it is not counted as part
/// of the next build).
template <typename Fn, typename Untimed>
TimeStats time_stats_ms(int reps, Fn&& fn, Untimed&& untimed) {
  std::vector<double> ms;
  for (int r = 0; r < reps; ++r) {
    untimed();
    Timer t;
    const double c0 = cpu_ms();
    fn();
    ms.push_back(g_cpu_time ? cpu_ms() - c0 : t.elapsed_ms());
  }
  std::sort(ms.begin(), ms.end());
  return TimeStats{ms[ms.size() / 2], ms.front()};
}

/// Median time of `reps` calls of `fn`, in ms; `untimed` as for time_stats_ms.
template <typename Fn, typename Untimed>
double time_median_ms(int reps, Fn&& fn, Untimed&& untimed) {
  return time_stats_ms(reps, std::forward<Fn>(fn), std::forward<Untimed>(untimed)).median_ms;
}

/// Median time of `reps` calls of `fn`, in ms.
template <typename Fn>
double time_median_ms(int reps, Fn&& fn) {
  return time_median_ms(reps, std::forward<Fn>(fn), [] {});
}

}  // namespace rtc::bench
