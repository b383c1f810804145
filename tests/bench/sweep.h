// rtc-bench --sweep: run time against error. Renders a scene with every setting that trades
// time for accuracy and measures each against the double-precision reference render
// (tests/support/reference_render.h); writes sweep.csv (with the Pareto front marked) and the
// reference image; tests/bench/plot_sweep.py draws the plot.
#pragma once

#include <filesystem>

#include "common/scene/scene.h"

namespace rtc::bench {

struct SweepOptions {
  std::filesystem::path out_dir;  ///< created if missing
  int reps = 3;                   ///< render timings are medians over this many frames
  bool quick = false;             ///< fewer variants (the ctest run)
  bool embree_check = true;       ///< cross-check the reference's visibility with Embree
};

/// Runs the sweep and prints a table. Returns the number of variants whose output held a NaN
/// or an infinity (0 when all is well). Throws rtc::Error for unusable options or files.
int run_sweep(const Scene& scene, const SweepOptions& options);

}  // namespace rtc::bench
