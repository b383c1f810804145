// Temporal coherence on one machine (rtc-render): frames rendered one after another, only the
// tiles TemporalTracker finds dirty traced again, the others kept from the frame before.
#pragma once

#include <cstdint>
#include <vector>

#include "common/image/image.h"
#include "common/render/renderer.h"
#include "common/render/temporal.h"

namespace rtc {

class ProgressBar;

class TemporalFrames {
 public:
  /// `renderer` must outlive this. Tiles are tile_size squares in row-major order.
  /// Frames [first_frame, last_frame] are rendered (the mark grid covers what moves in them).
  TemporalFrames(const Renderer& renderer, int tile_size, int cells = kDefaultMarkCells, int first_frame = INT_MIN,
                 int last_frame = INT_MAX);

  struct Report {
    TemporalPlan plan;  ///< `dirty` left empty
    std::uint32_t tiles = 0;
    TileRayCounts counts;
  };

  /// Renders the prepared frame `state` (dirty tiles in parallel, TBB) and returns the whole
  /// image, valid until the next call. `progress` advances by the pixels of each traced tile.
  const Image& render(const FrameState& state, Report* report = nullptr, ProgressBar* progress = nullptr);

  [[nodiscard]] const MarkGrid& grid() const { return tracker_.grid(); }

 private:
  const Renderer* renderer_;
  int tile_size_;
  int tiles_x_, tiles_y_;
  TemporalTracker tracker_;
  Image canvas_;
};

}  // namespace rtc
