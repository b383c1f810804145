// Timing for rtc-bench and its sweep: medians over repetitions, by wall clock or (--cpu-time)
// by the process's CPU time.
#pragma once

#include <algorithm>
#include <ctime>
#include <functional>
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

/// One contender of a round-robin timing: `fn` is timed, `untimed` runs before each call outside
/// the timing (as for time_stats_ms); `rounds` limits the rounds it takes part in (0: all).
struct Contender {
  std::function<void()> fn;
  std::function<void()> untimed = [] {};
  int rounds = 0;
};

/// Times the contenders in turn, one call each per round, for `rounds` rounds, so that a slow
/// spell of a shared machine (seconds long on the VMs this runs on) falls on all of them alike
/// instead of on whichever was timed during it. Returns each contender's times in ms by round.
inline std::vector<std::vector<double>> time_rounds_ms(int rounds, const std::vector<Contender>& contenders) {
  std::vector<std::vector<double>> ms(contenders.size());
  for (int r = 0; r < rounds; ++r) {
    for (std::size_t c = 0; c < contenders.size(); ++c) {
      if (contenders[c].rounds > 0 && r >= contenders[c].rounds) continue;
      contenders[c].untimed();
      Timer t;
      const double c0 = cpu_ms();
      contenders[c].fn();
      ms[c].push_back(g_cpu_time ? cpu_ms() - c0 : t.elapsed_ms());
    }
  }
  return ms;
}

/// The median of `v` (of an even count, the mean of the middle two, so that the median of
/// paired ratios does not lean to either side); 0 for none.
inline double median_of(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t m = v.size() / 2;
  return v.size() % 2 == 1 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

/// The median over the rounds both took part in of a[r] / b[r]: a ratio of two contenders
/// timed in the same round, which a slow spell changes far less than it changes either time.
inline double paired_ratio(const std::vector<double>& a, const std::vector<double>& b) {
  std::vector<double> r;
  for (std::size_t i = 0; i < a.size() && i < b.size(); ++i) {
    if (b[i] > 0.0) r.push_back(a[i] / b[i]);
  }
  return median_of(std::move(r));
}

}  // namespace rtc::bench
