// walk_order.h's logging walks, compiled once per ISA: traverse_coherent with a triangle test
// that logs each triangle it is asked to test, then does Wald's test.
#include <cstdint>

#include "common/accel/kd_traverse.h"
#include "tests/unit/accel/walk_order.h"

RTC_ISA_BEGIN
namespace rtc::RTC_ISA_NS {
namespace {

template <int N>
struct LoggingTest {
  static constexpr bool kConservative = false;
  LoggingTest(const RayPacket<N>& /*ray*/, vbool<N> /*active*/) {}
  template <bool kOcclusion>
  void intersect(const TriRecord& rec, const RayPacket<N>& ray, vbool<N> active, HitPacket<N>& hit,
                 vbool<N>& occluded) const {
    WalkLog& l = *current();
    if (l.count < WalkLog::kMax) l.ids[l.count] = rec.wald.id;
    ++l.count;
    intersect_triangle<N, kOcclusion>(rec.wald, static_cast<std::int32_t>(rec.wald.id), ray, active, hit, occluded);
  }
  static WalkLog*& current() {
    static thread_local WalkLog* log_now = nullptr;
    return log_now;
  }
};

template <int N, ShadowWalk kWalk>
unsigned walk_packet(const KdTree& tree, const RayQuery* rays, int count, const RayQuery* filler) {
  RayLanes<N> lanes;
  for (int i = 0; i < N; ++i) lanes.set(i, i < count ? rays[i] : filler != nullptr ? *filler : rays[count - 1]);
  const RayPacket<N> p = lanes.packet();
  HitPacket<N> unused;
  vbool<N> occ(false);
  traverse_coherent<N, true, LoggingTest, kWalk>(tree, p, vbool<N>::from_bits((1u << count) - 1u), unused, occ);
  return bits(occ);
}

template <ShadowWalk kWalk>
unsigned walk(const KdTree& tree, const RayQuery* rays, int count, const RayQuery* filler, bool packet) {
  if (packet) return walk_packet<RTC_ISA_WIDTH, kWalk>(tree, rays, count, filler);
  unsigned out = 0;
  for (int i = 0; i < count; ++i) out |= walk_packet<1, kWalk>(tree, rays + i, 1, nullptr) << i;
  return out;
}

}  // namespace

void walk_log(const KdTree& tree, const RayQuery* rays, int count, const RayQuery* filler, bool packet,
              ShadowWalk walk_order, WalkLog& log) {
  log.occluded = 0;
  if (count < 1 || count > RTC_ISA_WIDTH) {
    log.count = -1;
    return;
  }
  log.count = 0;
  LoggingTest<1>::current() = &log;
  LoggingTest<RTC_ISA_WIDTH>::current() = &log;
  switch (walk_order) {
    case ShadowWalk::Near:
      log.occluded = walk<ShadowWalk::Near>(tree, rays, count, filler, packet);
      break;
    case ShadowWalk::Far:
      log.occluded = walk<ShadowWalk::Far>(tree, rays, count, filler, packet);
      break;
    case ShadowWalk::Dense:
      log.occluded = walk<ShadowWalk::Dense>(tree, rays, count, filler, packet);
      break;
  }
  LoggingTest<1>::current() = nullptr;
  LoggingTest<RTC_ISA_WIDTH>::current() = nullptr;
}

}  // namespace rtc::RTC_ISA_NS
RTC_ISA_END
