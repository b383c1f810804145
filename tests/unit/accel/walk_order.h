// The order an occlusion walk tests a tree's triangles in, per ISA (walk_order_kernels.cpp,
// compiled once per ISA): what the answer never shows, since occlusion is the same in every
// order (ShadowOrder), for the tests of the walk orders themselves.
#pragma once

#include <cstdint>

#include "common/accel/kd_tree.h"
#include "common/accel/shadow_order.h"
#include "common/accel/trace.h"

namespace rtc {

/// The triangle ids one occlusion walk tested, in order (the first kMax), and its answer.
struct WalkLog {
  static constexpr int kMax = 4096;
  std::uint32_t ids[kMax];
  int count = 0;         ///< tests made (may exceed kMax; ids holds the first kMax)
  unsigned occluded = 0;  ///< bit i: ray i blocked
};

/// Walks `count` rays (1 to the ISA's packet width; all pointing into one octant) as one packet
/// (`packet`) or ray by ray, in the order `walk`, logging the triangle tests into `log`. A
/// packet's lanes past `count` are inactive copies of `filler`, or of the last ray where it is
/// null. A `count` out of range logs nothing (log.count -1).
using WalkLogFn = void (*)(const KdTree& tree, const RayQuery* rays, int count, const RayQuery* filler, bool packet,
                           ShadowWalk walk, WalkLog& log);

#ifdef RTC_HAVE_ISA_SSE42
namespace isa_sse42 {
void walk_log(const KdTree& tree, const RayQuery* rays, int count, const RayQuery* filler, bool packet,
              ShadowWalk walk, WalkLog& log);
}
#endif
#ifdef RTC_HAVE_ISA_AVX2
namespace isa_avx2 {
void walk_log(const KdTree& tree, const RayQuery* rays, int count, const RayQuery* filler, bool packet,
              ShadowWalk walk, WalkLog& log);
}
#endif
#ifdef RTC_HAVE_ISA_AVX512
namespace isa_avx512 {
void walk_log(const KdTree& tree, const RayQuery* rays, int count, const RayQuery* filler, bool packet,
              ShadowWalk walk, WalkLog& log);
}
#endif

}  // namespace rtc
