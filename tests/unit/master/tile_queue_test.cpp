// TileQueue: Hilbert order, frames in flight, tail re-issue (first result wins), lost workers.
#include "master/tile_queue.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <map>
#include <set>

#include "master/frame_stats.h"

namespace rtc {
namespace {

using Clock = TileQueue::Clock;

TEST(TileOrder, CoversTheFrameOnceWithEdgeTiles) {
  const auto tiles = tiles_in_hilbert_order(100, 70, 32);
  ASSERT_EQ(tiles.size(), 4u * 3u);
  std::vector<int> covered(100 * 70, 0);
  std::set<std::uint32_t> indices;
  for (const TileRect& t : tiles) {
    indices.insert(t.index);
    for (std::uint32_t y = t.y; y < t.y + t.height; ++y)
      for (std::uint32_t x = t.x; x < t.x + t.width; ++x) ++covered[y * 100 + x];
  }
  EXPECT_EQ(indices.size(), tiles.size());
  for (int c : covered) ASSERT_EQ(c, 1);
}

TEST(TileOrder, ConsecutiveTilesAreNeighboursOnPowerOfTwoGrids) {
  const auto tiles = tiles_in_hilbert_order(256, 256, 32);  // 8 x 8 tiles
  ASSERT_EQ(tiles.size(), 64u);
  for (std::size_t i = 1; i < tiles.size(); ++i) {
    const int dx = std::abs(static_cast<int>(tiles[i].x) - static_cast<int>(tiles[i - 1].x));
    const int dy = std::abs(static_cast<int>(tiles[i].y) - static_cast<int>(tiles[i - 1].y));
    EXPECT_EQ(dx + dy, 32) << "tiles " << i - 1 << " and " << i << " are not adjacent";
  }
}

TEST(TileQueue, HandsOutOldestFrameFirstAndCompletesFrames) {
  TileQueue q(64, 64, 32);  // 4 tiles
  q.open_frame(0);
  q.open_frame(1);
  const auto now = Clock::now();
  std::vector<TileAssignment> got;
  while (auto a = q.next_for(1, now)) got.push_back(*a);
  ASSERT_EQ(got.size(), 8u);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(got[i].frame, 0);
  for (int i = 4; i < 8; ++i) EXPECT_EQ(got[i].frame, 1);
  EXPECT_EQ(q.outstanding(1), 8u);
  for (const auto& a : got) {
    if (a.frame == 1) {
      EXPECT_EQ(q.complete(1, a.frame, a.rect.index), TileOutcome::Accepted);
    }
  }
  EXPECT_FALSE(q.pop_done_frame().has_value()) << "frame 0 is not done: frames finish in order";
  for (const auto& a : got) {
    if (a.frame == 0) {
      EXPECT_EQ(q.complete(1, a.frame, a.rect.index), TileOutcome::Accepted);
    }
  }
  EXPECT_EQ(q.pop_done_frame(), 0);
  EXPECT_EQ(q.pop_done_frame(), 1);
  EXPECT_EQ(q.frames_open(), 0u);
  EXPECT_EQ(q.outstanding(1), 0u);
}

TEST(TileQueue, ResultForATileNotGivenIsRejected) {
  TileQueue q(64, 64, 32);
  q.open_frame(0);
  const auto a = q.next_for(1, Clock::now());
  ASSERT_TRUE(a);
  EXPECT_EQ(q.complete(2, 0, a->rect.index), TileOutcome::NotAssigned);
  EXPECT_EQ(q.complete(1, 7, a->rect.index), TileOutcome::NotAssigned);
  EXPECT_EQ(q.complete(1, 0, a->rect.index), TileOutcome::Accepted);
  EXPECT_EQ(q.complete(1, 0, a->rect.index), TileOutcome::NotAssigned) << "a second result for the same tile";
}

TEST(TileQueue, LostWorkerTilesGoBackInOrder) {
  TileQueue q(128, 32, 32);  // 4 tiles in a row
  q.open_frame(0);
  const auto now = Clock::now();
  const auto a = q.next_for(1, now);
  const auto b = q.next_for(1, now);
  const auto c = q.next_for(2, now);
  ASSERT_TRUE(a && b && c);
  EXPECT_EQ(q.complete(1, 0, a->rect.index), TileOutcome::Accepted);
  EXPECT_EQ(q.worker_lost(1), 1u) << "only the unfinished tile goes back";
  EXPECT_EQ(q.outstanding(1), 0u);
  const auto again = q.next_for(2, now);
  ASSERT_TRUE(again);
  EXPECT_EQ(again->rect.index, b->rect.index) << "requeued tiles go to the front";
}

TEST(TileQueue, TailIsReissuedAndFirstResultWins) {
  TileQueue q(64, 32, 32);  // 2 tiles
  q.open_frame(0);
  const auto t0 = Clock::now();
  const auto a = q.next_for(1, t0);
  const auto b = q.next_for(1, t0);
  ASSERT_TRUE(a && b);
  EXPECT_FALSE(q.next_for(2, t0));
  EXPECT_FALSE(q.reissue_for(2, t0)) << "not held long enough yet";
  const auto copy = q.reissue_for(2, t0 + std::chrono::milliseconds(1));
  ASSERT_TRUE(copy);
  EXPECT_TRUE(copy->reissue);
  EXPECT_EQ(copy->rect.index, a->rect.index) << "the oldest-assigned tile";
  EXPECT_EQ(q.complete(2, 0, copy->rect.index), TileOutcome::Accepted);
  EXPECT_EQ(q.complete(1, 0, a->rect.index), TileOutcome::Duplicate);
  // A tile two workers hold is not copied a third time.
  const auto second = q.reissue_for(2, t0 + std::chrono::milliseconds(1));
  ASSERT_TRUE(second);
  EXPECT_EQ(second->rect.index, b->rect.index);
  EXPECT_FALSE(q.reissue_for(3, t0 + std::chrono::milliseconds(1)));
  EXPECT_EQ(q.worker_lost(1), 0u) << "worker 2 still holds the copy";
  EXPECT_EQ(q.complete(2, 0, b->rect.index), TileOutcome::Accepted);
  EXPECT_EQ(q.pop_done_frame(), 0);
}

TEST(TileQueue, LateDuplicateAfterTheFrameWasPoppedIsADuplicate) {
  TileQueue q(32, 32, 32);
  q.open_frame(5);
  const auto t0 = Clock::now();
  const auto a = q.next_for(1, t0);
  const auto copy = q.reissue_for(2, t0 + std::chrono::milliseconds(1));
  ASSERT_TRUE(a && copy);
  EXPECT_EQ(q.complete(2, 5, 0), TileOutcome::Accepted);
  EXPECT_EQ(q.pop_done_frame(), 5);
  EXPECT_EQ(q.outstanding(1), 1u);
  EXPECT_EQ(q.complete(1, 5, 0), TileOutcome::Duplicate);
  EXPECT_EQ(q.outstanding(1), 0u);
}

TEST(TileQueue, DroppedFrameReleasesItsTiles) {
  TileQueue q(64, 64, 32);
  q.open_frame(0);
  ASSERT_TRUE(q.next_for(1, Clock::now()));
  q.drop_frame(0);
  EXPECT_EQ(q.outstanding(1), 0u);
  EXPECT_EQ(q.frames_open(), 0u);
}

TEST(FrameStats, BoundIsLinkCapacityOverBytesPerFrame) {
  FrameStats s;
  s.wire_bytes = 1'048'576 + 1024 * 16;
  s.interval_ms = 100;
  s.link_bytes_per_s = 100e6 / 8;
  EXPECT_NEAR(s.bound_fps(), 12.5e6 / 1'064'960.0, 1e-9);
  EXPECT_NEAR(s.fps(), 10.0, 1e-12);
  s.pixel_bytes = 500;
  s.raw_bytes = 1000;
  EXPECT_DOUBLE_EQ(s.compression_ratio(), 2.0);
  const RunSummary r = summarize({s, s, s}, 0.3);
  EXPECT_NEAR(r.median_fps, 10.0, 1e-9);
  EXPECT_NEAR(r.mean_fps, 10.0, 1e-9);
  EXPECT_NE(summary_json(r).find("\"median_bound_fps\""), std::string::npos);
}

// The summary's "achieved" compares the frames that sent pixels with their own bound: a frame
// that sent none (temporal coherence, nothing moved) has no bound and used to count in the fps
// median but not in the bound's.
TEST(FrameStats, AchievedIsOverTheFramesThatSentPixels) {
  FrameStats sent;
  sent.wire_bytes = 1'000'000;
  sent.interval_ms = 100;  // 10 fps
  sent.link_bytes_per_s = 20e6;  // bound 20 fps
  sent.link_source = "measured";
  FrameStats none = sent;
  none.wire_bytes = 0;
  none.interval_ms = 1;  // 1000 fps, no bound
  const RunSummary r = summarize({sent, none, none, none, sent}, 0.5);
  EXPECT_NEAR(r.median_fps, 1000.0, 1e-9);
  EXPECT_NEAR(r.median_bound_fps, 20.0, 1e-9);
  EXPECT_NEAR(r.achieved_vs_bound, 0.5, 1e-9);
  EXPECT_EQ(r.bounded_frames, 2u);
  const std::string text = format_summary(r);
  EXPECT_NE(text.find("achieved 50.0% of it (over the 2 frames that sent pixels; 3 sent none)"), std::string::npos) << text;
  EXPECT_EQ(text.find("above the bound"), std::string::npos) << text;
  EXPECT_NE(summary_json(r).find("\"achieved_vs_bound\":0.5"), std::string::npos) << summary_json(r);
  // Faster than the bound: the probe measured the link too slow, and the summary says so.
  sent.link_bytes_per_s = 5e6;  // bound 5 fps
  const std::string above = format_summary(summarize({sent, sent}, 0.2));
  EXPECT_NE(above.find("achieved 200.0% of it (above the bound: the link measured slower than it is"), std::string::npos)
      << above;
}

TEST(FrameStats, SummarySaysARunWasStopped) {
  FrameStats f;
  f.wire_bytes = 1000;
  f.interval_ms = 10;
  RunSummary r = summarize({f, f, f}, 0.03);
  r.frames_planned = 24;
  r.stopped = "stopped by SIGINT";
  EXPECT_EQ(format_summary(r).rfind("summary: 3 of 24 frames (stopped by SIGINT: 21 not rendered) in 0.03 s", 0), 0u)
      << format_summary(r);
  EXPECT_NE(summary_json(r).find("\"stopped\":\"stopped by SIGINT\""), std::string::npos) << summary_json(r);
  EXPECT_NE(summary_json(r).find("\"frames_planned\":24"), std::string::npos) << summary_json(r);
  EXPECT_NE(summary_json(r).find("\"cut_short\":false"), std::string::npos) << summary_json(r);  // the master sets it
  r.cut_short = true;
  EXPECT_NE(summary_json(r).find("\"cut_short\":true"), std::string::npos) << summary_json(r);
  r.stopped.clear();
  r.frames_planned = 3;
  EXPECT_EQ(format_summary(r).rfind("summary: 3 frames in 0.03 s", 0), 0u) << format_summary(r);
  EXPECT_NE(summary_json(r).find("\"stopped\":null"), std::string::npos) << summary_json(r);
  RunSummary none = summarize({}, 0.0);
  none.frames_planned = 24;
  none.stopped = "stopped by SIGTERM";
  EXPECT_EQ(format_summary(none), "summary: no frame finished of the 24 asked for (stopped by SIGTERM)");
}

// The frame writer's part of the summary: frames on disk, the time each took, and how long new
// frames waited for the writer (only when they did; only when frames were to be written).
TEST(FrameStats, SummarySaysWhatTheWriterDid) {
  FrameStats f;
  f.wire_bytes = 1000;
  f.interval_ms = 10;
  RunSummary r = summarize({f, f, f, f}, 0.04);
  EXPECT_EQ(format_summary(r).find("written"), std::string::npos) << format_summary(r);
  EXPECT_EQ(summary_json(r).find("frames_written"), std::string::npos) << summary_json(r);
  r.writing = true;
  r.frames_written = 4;
  r.write_s = 0.5;
  EXPECT_NE(format_summary(r).find("; 4 frames written (125 ms each to encode and write)"), std::string::npos)
      << format_summary(r);
  EXPECT_EQ(format_summary(r).find("waited"), std::string::npos) << format_summary(r);
  r.writer_held_s = 1.25;
  EXPECT_NE(format_summary(r).find("(125 ms each to encode and write), new frames waited 1.25 s for the writer"),
            std::string::npos)
      << format_summary(r);
  EXPECT_NE(summary_json(r).find("\"frames_written\":4"), std::string::npos) << summary_json(r);
  EXPECT_NE(summary_json(r).find("\"writer_held_s\":1.25"), std::string::npos) << summary_json(r);
  r.frames_written = 0;  // every write failed
  EXPECT_NE(format_summary(r).find("; 0 frames written, new frames waited"), std::string::npos) << format_summary(r);
}

TEST(FrameStats, GivenLineRateCarriesTcpPayloadOnly) {
  // 1448 payload bytes per 1538-byte Ethernet frame: Fast Ethernet carries 94.1 Mbit/s of TCP.
  EXPECT_NEAR(link_payload_bytes_per_s(100) * 8 / 1e6, 94.148, 1e-3);
  FrameStats s;
  s.wire_bytes = 8'410'000;
  s.link_bytes_per_s = link_payload_bytes_per_s(100);
  s.link_line_mbit_per_s = 100;
  s.link_source = "given";
  EXPECT_NEAR(s.bound_fps(), 12.5e6 * 1448 / 1538 / 8'410'000, 1e-9);
  EXPECT_NE(format_frame_line(s).find("94.1 Mbit/s of messages on 100.0 Mbit/s given"), std::string::npos)
      << format_frame_line(s);
  EXPECT_NE(frame_json(s).find("\"link_line_mbit_per_s\":100.0"), std::string::npos) << frame_json(s);
}

}  // namespace
}  // namespace rtc
