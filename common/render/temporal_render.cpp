// Temporal coherence on one machine: the tracker's plan, dirty tiles traced in parallel.
#include "common/render/temporal_render.h"

#include <algorithm>
#include <mutex>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "common/base/error.h"
#include "common/base/progress.h"

namespace rtc {
namespace {

int tiles_along(int pixels, int tile_size) {
  if (tile_size <= 0) throw Error("tile size must be positive, got " + std::to_string(tile_size));
  return (pixels + tile_size - 1) / tile_size;
}

}  // namespace

TemporalFrames::TemporalFrames(const Renderer& renderer, int tile_size, int cells, int first_frame, int last_frame)
    : renderer_(&renderer),
      tile_size_(tile_size),
      tiles_x_(tiles_along(renderer.scene().width, tile_size)),
      tiles_y_(tiles_along(renderer.scene().height, tile_size)),
      tracker_(renderer.scene(), mark_grid_for(renderer.scene(), cells, first_frame, last_frame),
               static_cast<std::uint32_t>(tiles_x_) * static_cast<std::uint32_t>(tiles_y_)) {}

const Image& TemporalFrames::render(const FrameState& state, Report* report, ProgressBar* progress) {
  TemporalPlan plan = tracker_.plan(state.frame);
  if (canvas_.width != state.width || canvas_.height != state.height) {
    const bool aovs = renderer_->options().aovs;
    canvas_ = Image(state.width, state.height, aovs, aovs);
  }
  std::vector<std::uint32_t> dirty;
  for (std::uint32_t t = 0; t < plan.dirty.size(); ++t) {
    if (plan.dirty[t] == TemporalPlan::kTrace) dirty.push_back(t);
  }
  std::vector<TileMarks> marks(dirty.size());
  struct ThreadScratch {
    explicit ThreadScratch(const MarkGrid& grid) : recorder(grid) {}
    MarkRecorder recorder;
    Image tile;
    TileRayCounts counts;
  };
  tbb::enumerable_thread_specific<ThreadScratch> scratch([&] { return ThreadScratch(tracker_.grid()); });
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, dirty.size(), 1), [&](const auto& r) {
    ThreadScratch& s = scratch.local();
    for (std::size_t i = r.begin(); i != r.end(); ++i) {
      const int tx = static_cast<int>(dirty[i] % static_cast<std::uint32_t>(tiles_x_));
      const int ty = static_cast<int>(dirty[i] / static_cast<std::uint32_t>(tiles_x_));
      const int x0 = tx * tile_size_, y0 = ty * tile_size_;
      const int w = std::min(tile_size_, state.width - x0), h = std::min(tile_size_, state.height - y0);
      renderer_->render_tile(state, x0, y0, w, h, s.tile, &s.counts, &s.recorder);
      s.recorder.take(marks[i]);
      canvas_.blit(s.tile, x0, y0);
      if (progress != nullptr) progress->add(static_cast<std::uint64_t>(w) * static_cast<std::uint64_t>(h));
    }
  });
  // One frame at a time: no later plan waits on these tiles, so done() decides nothing more.
  for (std::size_t i = 0; i < dirty.size(); ++i) (void)tracker_.done(dirty[i], plan.id, &marks[i]);
  if (report != nullptr) {
    report->tiles = tracker_.tiles();
    report->counts = TileRayCounts{};
    for (const ThreadScratch& s : scratch) report->counts += s.counts;
    plan.dirty.clear();
    report->plan = std::move(plan);
  }
  return canvas_;
}

}  // namespace rtc
