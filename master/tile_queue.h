// The master's work queue: frames split into tiles in a coherent (Hilbert) order, handed to
// workers with several frames in flight, the tail re-issued to idle workers (first result
// wins), and a lost worker's tiles put back. Pure bookkeeping: no sockets, no pixels.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <set>
#include <vector>

namespace rtc {

struct TileRect {
  std::uint32_t index = 0;  ///< position in the frame's row-major tile grid
  std::uint32_t x = 0, y = 0, width = 0, height = 0;
};

/// Tiles of a width x height frame, tile_size square (smaller at the right and bottom edges),
/// ordered along a Hilbert curve over the tile grid so consecutive tiles are neighbours (rays
/// of neighbouring tiles walk the same kd-tree nodes: the worker's caches stay warm).
[[nodiscard]] std::vector<TileRect> tiles_in_hilbert_order(int width, int height, int tile_size);

struct TileAssignment {
  int frame = 0;
  TileRect rect;
  bool reissue = false;  ///< a copy of a tile another worker holds (tail of a frame)
};

enum class TileOutcome {
  Accepted,     ///< first result for this tile: use its pixels
  Duplicate,    ///< the tile was already done (a re-issued copy): drop the pixels
  NotAssigned,  ///< the worker was never given this tile (or the frame is unknown): a protocol violation
};

/// Not thread-safe (the master's network thread owns it).
class TileQueue {
 public:
  using WorkerId = std::uint32_t;

  TileQueue(int width, int height, int tile_size);

  [[nodiscard]] std::uint32_t tiles_per_frame() const { return static_cast<std::uint32_t>(order_.size()); }
  [[nodiscard]] const std::vector<TileRect>& tiles() const { return order_; }

  /// Adds a frame's tiles at the back of the queue. Frames must be opened once each. With
  /// `needed` (one entry per tile index, temporal coherence: TemporalPlan::dirty), tiles with
  /// 1 wait to be handed out, tiles with 0 are done from the start (their pixels come from
  /// elsewhere), tiles with 2 are held: neither handed out nor done until release() or keep().
  void open_frame(int frame, const std::vector<std::uint8_t>* needed = nullptr);
  /// A held tile of an open frame joins the back of the queue.
  void release(int frame, std::uint32_t tile);
  /// A held tile of an open frame is done without being traced.
  void keep(int frame, std::uint32_t tile);
  /// Whether the oldest open frame has all its tiles done (pop_done_frame would return it).
  [[nodiscard]] bool oldest_done() const { return !open_order_.empty() && frame_done(open_order_.front()); }
  [[nodiscard]] std::size_t frames_open() const { return frames_.size(); }
  [[nodiscard]] bool is_open(int frame) const { return frames_.count(frame) != 0; }

  using Clock = std::chrono::steady_clock;

  /// The next tile for `worker`: the first waiting tile of the oldest open frame; nullopt when
  /// none waits.
  std::optional<TileAssignment> next_for(WorkerId worker, Clock::time_point now);
  /// The tail of a frame: a copy of the oldest-assigned unfinished tile of the oldest frame that
  /// exactly one other worker holds and has held since before `assigned_before`; nullopt when
  /// there is none. The first result returned wins (see complete()).
  std::optional<TileAssignment> reissue_for(WorkerId worker, Clock::time_point assigned_before);
  /// Whether `worker` holds (frame, tile) now.
  [[nodiscard]] bool holds(WorkerId worker, int frame, std::uint32_t tile) const;
  /// The rectangle of tile `index`.
  [[nodiscard]] const TileRect& rect(std::uint32_t index) const { return order_[position_[index]]; }

  /// A worker returned (frame, tile).
  TileOutcome complete(WorkerId worker, int frame, std::uint32_t tile);

  /// The worker is gone: every tile it held that is neither done nor held by another worker
  /// goes back to the front of the queue (in order). Returns how many went back.
  std::size_t worker_lost(WorkerId worker);

  /// Tiles the worker holds (given and not yet returned, including finished-elsewhere copies).
  [[nodiscard]] std::size_t outstanding(WorkerId worker) const;
  [[nodiscard]] std::size_t waiting() const;  ///< tiles nobody holds yet, over all open frames

  [[nodiscard]] bool frame_done(int frame) const;
  /// Tiles of an open frame done (traced or kept); 0 for a frame not open.
  [[nodiscard]] std::uint32_t tiles_done(int frame) const;
  /// Whether tile `tile` of open frame `frame` is done (true for a frame no longer open).
  [[nodiscard]] bool tile_done(int frame, std::uint32_t tile) const;
  /// Removes the oldest open frame when all its tiles are done and returns its number.
  std::optional<int> pop_done_frame();
  /// The open frames, oldest first.
  [[nodiscard]] std::vector<int> open_frames() const;
  /// Forgets a frame (abandoned at shutdown); its assignments stop counting as outstanding.
  void drop_frame(int frame);

 private:
  struct TileState {
    std::set<WorkerId> holders;
    bool done = false;
    bool held = false;  ///< opened neither waiting nor done (release() or keep() decides)
    Clock::time_point assigned_at{};  ///< when the first current holder got it
  };
  struct FrameState {
    std::vector<TileState> tiles;  ///< by TileRect::index
    std::deque<std::uint32_t> waiting;  ///< tile indices in Hilbert order
    std::uint32_t done = 0;
  };

  std::vector<TileRect> order_;
  std::map<int, FrameState> frames_;  ///< open frames, by number; oldest = first opened
  std::vector<int> open_order_;       ///< frame numbers in the order opened
  std::map<WorkerId, std::set<std::pair<int, std::uint32_t>>> held_;  ///< worker -> (frame, tile)
  std::vector<std::uint32_t> position_;  ///< tile index -> position in order_
};

}  // namespace rtc
