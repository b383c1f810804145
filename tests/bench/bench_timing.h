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

/// The time one call of `fn` takes, in ms: by the wall clock, or with --cpu-time by the
/// process's CPU time.
template <typename Fn>
double time_once_ms(Fn&& fn) {
  Timer t;
  const double c0 = cpu_ms();
  fn();
  return g_cpu_time ? cpu_ms() - c0 : t.elapsed_ms();
}

/// Median time of `reps` calls of `fn`, in ms (of an even count, the upper of the middle two).
template <typename Fn>
double time_median_ms(int reps, Fn&& fn) {
  std::vector<double> ms;
  for (int r = 0; r < reps; ++r) ms.push_back(time_once_ms(fn));
  std::sort(ms.begin(), ms.end());
  return ms[ms.size() / 2];
}

/// One contender of a round-robin timing: `fn` is timed, `untimed` runs before each call outside
/// the timing (builders release their previous result there, so that freeing it is not counted
/// as part of the next build; rtc-bench's ray streams run `fn` there once more, so that each is
/// timed with its own data in the caches); `rounds` limits the rounds it takes part in (0: all).
struct Contender {
  std::function<void()> fn;
  std::function<void()> untimed = [] {};
  int rounds = 0;
};

/// Times the contenders in turn, one call each per round, for `rounds` rounds, so that a slow
/// spell of a shared machine (seconds long on the VMs this runs on) falls on all of them alike
/// instead of on whichever was timed during it. Returns each contender's times in ms by round.
/// `min_first_ms` (> 0): after `rounds`, rounds go on until the first contender's times add up
/// to at least that, up to `max_rounds` in all: a build of a few milliseconds timed 5 times
/// gives a median of 5 samples, each taken right after the other contenders' work has evicted
/// its caches, where one of a second is timed as long as 5 rounds take anyway.
inline std::vector<std::vector<double>> time_rounds_ms(int rounds, const std::vector<Contender>& contenders,
                                                       double min_first_ms = 0.0, int max_rounds = 0) {
  std::vector<std::vector<double>> ms(contenders.size());
  double first_total = 0.0;
  for (int r = 0; r < rounds || (first_total < min_first_ms && r < max_rounds); ++r) {
    for (std::size_t c = 0; c < contenders.size(); ++c) {
      if (contenders[c].rounds > 0 && r >= contenders[c].rounds) continue;
      contenders[c].untimed();
      ms[c].push_back(time_once_ms(contenders[c].fn));
      if (c == 0) first_total += ms[c].back();
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
