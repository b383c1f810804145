// The master's tile work queue (see tile_queue.h).
#include "master/tile_queue.h"

#include <algorithm>
#include <utility>

#include "common/base/error.h"

namespace rtc {

namespace {

// Position of (x, y) along the Hilbert curve filling an n x n grid (n a power of two).
std::uint64_t hilbert_index(std::uint32_t n, std::uint32_t x, std::uint32_t y) {
  std::uint64_t d = 0;
  for (std::uint32_t s = n / 2; s > 0; s /= 2) {
    const std::uint32_t rx = (x & s) ? 1u : 0u;
    const std::uint32_t ry = (y & s) ? 1u : 0u;
    d += static_cast<std::uint64_t>(s) * s * ((3u * rx) ^ ry);
    if (ry == 0) {  // rotate the quadrant
      if (rx == 1) {
        x = s - 1 - x;
        y = s - 1 - y;
      }
      std::swap(x, y);
    }
  }
  return d;
}

}  // namespace

std::vector<TileRect> tiles_in_hilbert_order(int width, int height, int tile_size) {
  RTC_CHECK(width > 0 && height > 0 && tile_size > 0, "tiles_in_hilbert_order: empty frame or tile");
  const auto tiles_x = static_cast<std::uint32_t>((width + tile_size - 1) / tile_size);
  const auto tiles_y = static_cast<std::uint32_t>((height + tile_size - 1) / tile_size);
  std::uint32_t n = 1;
  while (n < std::max(tiles_x, tiles_y)) n *= 2;
  std::vector<std::pair<std::uint64_t, TileRect>> keyed;
  keyed.reserve(static_cast<std::size_t>(tiles_x) * tiles_y);
  for (std::uint32_t ty = 0; ty < tiles_y; ++ty) {
    for (std::uint32_t tx = 0; tx < tiles_x; ++tx) {
      TileRect r;
      r.index = ty * tiles_x + tx;
      r.x = tx * static_cast<std::uint32_t>(tile_size);
      r.y = ty * static_cast<std::uint32_t>(tile_size);
      r.width = std::min<std::uint32_t>(static_cast<std::uint32_t>(tile_size), static_cast<std::uint32_t>(width) - r.x);
      r.height = std::min<std::uint32_t>(static_cast<std::uint32_t>(tile_size), static_cast<std::uint32_t>(height) - r.y);
      keyed.emplace_back(hilbert_index(n, tx, ty), r);
    }
  }
  std::sort(keyed.begin(), keyed.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<TileRect> out;
  out.reserve(keyed.size());
  for (const auto& [key, rect] : keyed) out.push_back(rect);
  return out;
}

TileQueue::TileQueue(int width, int height, int tile_size)
    : order_(tiles_in_hilbert_order(width, height, tile_size)), position_(order_.size()) {
  for (std::uint32_t i = 0; i < order_.size(); ++i) position_[order_[i].index] = i;
}

void TileQueue::open_frame(int frame, const std::vector<std::uint8_t>* needed) {
  RTC_CHECK(frames_.count(frame) == 0, "TileQueue::open_frame: frame opened twice");
  RTC_CHECK(needed == nullptr || needed->size() == order_.size(), "TileQueue::open_frame: one entry per tile");
  FrameState& f = frames_[frame];
  f.tiles.resize(order_.size());
  for (const TileRect& r : order_) {
    const std::uint8_t need = needed != nullptr ? (*needed)[r.index] : 1;
    if (need == 0) {
      f.tiles[r.index].done = true;
      ++f.done;
    } else if (need == 1) {
      f.waiting.push_back(r.index);
    } else {
      f.tiles[r.index].held = true;
    }
  }
  open_order_.push_back(frame);
}

void TileQueue::release(int frame, std::uint32_t tile) {
  const auto it = frames_.find(frame);
  if (it == frames_.end() || tile >= it->second.tiles.size() || !it->second.tiles[tile].held) return;
  it->second.tiles[tile].held = false;
  it->second.waiting.push_back(tile);
}

void TileQueue::keep(int frame, std::uint32_t tile) {
  const auto it = frames_.find(frame);
  if (it == frames_.end() || tile >= it->second.tiles.size() || !it->second.tiles[tile].held) return;
  it->second.tiles[tile].held = false;
  it->second.tiles[tile].done = true;
  ++it->second.done;
}

std::optional<TileAssignment> TileQueue::next_for(WorkerId worker, Clock::time_point now) {
  for (const int frame : open_order_) {
    FrameState& f = frames_.at(frame);
    if (f.waiting.empty()) continue;
    const std::uint32_t index = f.waiting.front();
    f.waiting.pop_front();
    TileState& t = f.tiles[index];
    t.holders.insert(worker);
    t.assigned_at = now;
    held_[worker].insert({frame, index});
    return TileAssignment{frame, rect(index), false};
  }
  return std::nullopt;
}

std::optional<TileAssignment> TileQueue::reissue_for(WorkerId worker, Clock::time_point assigned_before) {
  for (const int frame : open_order_) {
    FrameState& f = frames_.at(frame);
    std::optional<std::uint32_t> best;
    for (std::uint32_t i = 0; i < f.tiles.size(); ++i) {
      const TileState& t = f.tiles[i];
      if (t.done || t.holders.size() != 1 || t.holders.count(worker) != 0 || t.assigned_at >= assigned_before) continue;
      if (!best || t.assigned_at < f.tiles[*best].assigned_at) best = i;
    }
    if (!best) continue;
    f.tiles[*best].holders.insert(worker);
    held_[worker].insert({frame, *best});
    return TileAssignment{frame, rect(*best), true};
  }
  return std::nullopt;
}

bool TileQueue::holds(WorkerId worker, int frame, std::uint32_t tile) const {
  const auto held = held_.find(worker);
  return held != held_.end() && held->second.count({frame, tile}) != 0;
}

TileOutcome TileQueue::complete(WorkerId worker, int frame, std::uint32_t tile) {
  const auto held = held_.find(worker);
  if (held == held_.end() || held->second.erase({frame, tile}) == 0) return TileOutcome::NotAssigned;
  const auto it = frames_.find(frame);
  if (it == frames_.end()) return TileOutcome::Duplicate;  // frame already finished and popped
  TileState& t = it->second.tiles.at(tile);
  t.holders.erase(worker);
  if (t.done) return TileOutcome::Duplicate;
  t.done = true;
  ++it->second.done;
  return TileOutcome::Accepted;
}

std::size_t TileQueue::worker_lost(WorkerId worker) {
  const auto held = held_.find(worker);
  if (held == held_.end()) return 0;
  // Per frame, the tiles nobody else holds, pushed to the front in reverse Hilbert order so the
  // queue hands them out again in Hilbert order (held_ is sorted by row-major index).
  std::map<int, std::vector<std::uint32_t>> back;
  for (const auto& [frame, tile] : held->second) {
    const auto f = frames_.find(frame);
    if (f == frames_.end()) continue;
    TileState& t = f->second.tiles.at(tile);
    t.holders.erase(worker);
    if (!t.done && t.holders.empty()) back[frame].push_back(tile);
  }
  held_.erase(held);
  std::size_t requeued = 0;
  for (auto& [frame, tiles] : back) {
    std::sort(tiles.begin(), tiles.end(), [this](std::uint32_t a, std::uint32_t b) { return position_[a] > position_[b]; });
    for (const std::uint32_t tile : tiles) frames_.at(frame).waiting.push_front(tile);
    requeued += tiles.size();
  }
  return requeued;
}

std::size_t TileQueue::outstanding(WorkerId worker) const {
  const auto held = held_.find(worker);
  return held == held_.end() ? 0 : held->second.size();
}

std::size_t TileQueue::waiting() const {
  std::size_t n = 0;
  for (const auto& [frame, f] : frames_) n += f.waiting.size();
  return n;
}

std::uint32_t TileQueue::tiles_done(int frame) const {
  const auto it = frames_.find(frame);
  return it == frames_.end() ? 0 : it->second.done;
}

bool TileQueue::frame_done(int frame) const {
  const auto it = frames_.find(frame);
  return it != frames_.end() && it->second.done == order_.size();
}

bool TileQueue::tile_done(int frame, std::uint32_t tile) const {
  const auto it = frames_.find(frame);
  return it == frames_.end() || tile >= it->second.tiles.size() || it->second.tiles[tile].done;
}

std::optional<int> TileQueue::pop_done_frame() {
  if (open_order_.empty()) return std::nullopt;
  const int frame = open_order_.front();
  if (!frame_done(frame)) return std::nullopt;
  frames_.erase(frame);
  open_order_.erase(open_order_.begin());
  return frame;
}

std::vector<int> TileQueue::open_frames() const { return open_order_; }

void TileQueue::drop_frame(int frame) {
  frames_.erase(frame);
  open_order_.erase(std::remove(open_order_.begin(), open_order_.end(), frame), open_order_.end());
  for (auto& [worker, held] : held_) {
    for (auto it = held.begin(); it != held.end();) {
      it = it->first == frame ? held.erase(it) : std::next(it);
    }
  }
}

}  // namespace rtc
