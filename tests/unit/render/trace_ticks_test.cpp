// The trace-call tally (trace_ticks.h): its rows and names, and what the renderer adds to it:
// nothing in a default build, every ray it traces in an RTC_TRACE_TICKS build (the ticks preset).
#include <gtest/gtest.h>

#include <cstdint>

#include <tbb/global_control.h>

#include "common/accel/trace.h"
#include "common/image/image.h"
#include "common/render/renderer.h"
#include "common/render/trace_ticks.h"
#include "common/scene/load.h"

namespace rtc {
namespace {

TEST(TraceTicks, LaneFillSplitsAtHalfTheWidth) {
  EXPECT_EQ(lane_fill(16, 16), LaneFill::Full);
  EXPECT_EQ(lane_fill(15, 16), LaneFill::MoreThanHalf);
  EXPECT_EQ(lane_fill(9, 16), LaneFill::MoreThanHalf);
  EXPECT_EQ(lane_fill(8, 16), LaneFill::AtMostHalf);
  EXPECT_EQ(lane_fill(1, 16), LaneFill::AtMostHalf);
  EXPECT_EQ(lane_fill(4, 4), LaneFill::Full);
  EXPECT_EQ(lane_fill(3, 4), LaneFill::MoreThanHalf);
  EXPECT_EQ(lane_fill(2, 4), LaneFill::AtMostHalf);
  EXPECT_EQ(lane_fill(1, 1), LaneFill::Full);
}

TEST(TraceTicks, RowsSumTheirCallsInAFixedOrder) {
  reset_trace_ticks();
  add_trace_ticks(true, TraceCall::Shadow, 1, LaneFill::AtMostHalf, 500, 3);
  add_trace_ticks(false, TraceCall::Shadow, 1, LaneFill::AtMostHalf, 700, 2);
  add_trace_ticks(false, TraceCall::Primary, -1, LaneFill::Full, 100, 16);
  add_trace_ticks(false, TraceCall::Primary, -1, LaneFill::Full, 300, 16);
  add_trace_ticks(false, TraceCall::Shadow, 12, LaneFill::Full, 40, 16);  // past the last light row
  add_trace_ticks(false, TraceCall::Mirror, -1, LaneFill::MoreThanHalf, 60, 10);
  const std::vector<TraceTickRow> rows = trace_ticks();
  ASSERT_EQ(rows.size(), 5u);
  // rtc's rows first: primary, mirror, shadow by light; then the external tracer's.
  EXPECT_FALSE(rows[0].external);
  EXPECT_EQ(rows[0].call, TraceCall::Primary);
  EXPECT_EQ(rows[0].light, -1);
  EXPECT_EQ(rows[0].ticks, 400u);
  EXPECT_EQ(rows[0].calls, 2u);
  EXPECT_EQ(rows[0].rays, 32u);
  EXPECT_EQ(rows[1].call, TraceCall::Mirror);
  EXPECT_EQ(rows[1].fill, LaneFill::MoreThanHalf);
  EXPECT_EQ(rows[2].call, TraceCall::Shadow);
  EXPECT_EQ(rows[2].light, 1);
  EXPECT_EQ(rows[2].ticks, 700u);
  EXPECT_EQ(rows[3].light, kTraceTickLights - 1);
  EXPECT_EQ(rows[3].rays, 16u);
  EXPECT_TRUE(rows[4].external);
  EXPECT_EQ(rows[4].light, 1);
  EXPECT_EQ(rows[4].ticks, 500u);
  EXPECT_EQ(trace_tick_row_name(rows[0], 16), "primary, 16 of 16 lanes");
  EXPECT_EQ(trace_tick_row_name(rows[1], 16), "mirror, 9-15 of 16 lanes");
  EXPECT_EQ(trace_tick_row_name(rows[2], 16), "shadow, light 1, 1-8 of 16 lanes");
  EXPECT_EQ(trace_tick_row_name(rows[3], 16), "shadow, light 7+, 16 of 16 lanes");
  // Narrower packets: AVX2's 8 lanes, SSE4.2's 4, single rays.
  EXPECT_EQ(trace_tick_row_name(rows[1], 8), "mirror, 5-7 of 8 lanes");
  EXPECT_EQ(trace_tick_row_name(rows[2], 8), "shadow, light 1, 1-4 of 8 lanes");
  EXPECT_EQ(trace_tick_row_name(rows[1], 4), "mirror, 3 of 4 lanes");
  EXPECT_EQ(trace_tick_row_name(rows[2], 4), "shadow, light 1, 1-2 of 4 lanes");
  EXPECT_EQ(trace_tick_row_name(rows[0], 1), "primary, 1 of 1 lanes");
  reset_trace_ticks();
  EXPECT_TRUE(trace_ticks().empty());
}

TEST(TraceTicks, TheRendererTimesEveryTraceCallOnlyWhenBuiltToDoSo) {
  Scene scene = default_scene();
  scene.width = 96;
  scene.height = 72;
  scene.settings.spp = 2;
  scene.settings.max_depth = 6;  // mirror bounces, some regrouped across packets
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
  Renderer r(scene, RenderOptions{});
  const auto fs = r.prepare(0);
  reset_trace_ticks();
  TileRayCounts counts;
  const Image image = r.render_frame(*fs, 32, nullptr, &counts);
  ASSERT_EQ(image.width, scene.width);
  const std::vector<TraceTickRow> rows = trace_ticks();
  reset_trace_ticks();
  if (!kTraceTicks) {
    // A default build's renderer times nothing: its kernels carry no clock reads.
    EXPECT_TRUE(rows.empty());
    return;
  }
  ASSERT_GT(counts.shadow, 0u);
  ASSERT_GT(counts.reflection, 0u);
  std::uint64_t rays[3] = {0, 0, 0};
  for (const TraceTickRow& row : rows) {
    EXPECT_FALSE(row.external);  // no external tracer here
    EXPECT_GT(row.calls, 0u);
    EXPECT_GT(row.ticks, 0u);
    const std::uint64_t width = static_cast<std::uint64_t>(trace_kernels(r.isa()).packet_width);
    if (row.fill == LaneFill::Full) {
      EXPECT_EQ(row.rays, row.calls * width);
    } else if (row.fill == LaneFill::AtMostHalf) {
      EXPECT_LE(row.rays, row.calls * (width / 2));
    } else {
      EXPECT_GT(row.rays, row.calls * (width / 2));
      EXPECT_LT(row.rays, row.calls * width);
    }
    if (row.call == TraceCall::Shadow) {
      EXPECT_GE(row.light, 0);
      EXPECT_LT(row.light, static_cast<int>(scene.lights.size()));
    } else {
      EXPECT_EQ(row.light, -1);
    }
    rays[static_cast<int>(row.call)] += row.rays;
  }
  // Every ray the frame traced, and no other: primary rays but those skipped as empty space.
  EXPECT_EQ(rays[0], counts.primary - counts.primary_skipped);
  EXPECT_EQ(rays[1], counts.reflection);
  EXPECT_EQ(rays[2], counts.shadow);
}

}  // namespace
}  // namespace rtc
