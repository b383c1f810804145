// Writes finished frames on a thread of its own so the master's network thread never waits on
// image encoding or the disk. Bounded: the master stops opening frames while it is full.
#pragma once

#include <chrono>
#include <cstddef>
#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

#include "common/image/image.h"
#include "master/image_pool.h"

namespace rtc {

class FrameWriter {
 public:
  /// `on_error` is called (on the writer thread) with "path: reason" when a write fails;
  /// later frames are still attempted. Each frame's image goes back to `pool` once written
  /// (or failed) when one is given; the pool must outlive the writer.
  FrameWriter(ImageWriteOptions options, std::function<void(const std::string&)> on_error,
              ImagePool* pool = nullptr);
  ~FrameWriter();  ///< writes what is queued, then joins
  FrameWriter(const FrameWriter&) = delete;
  FrameWriter& operator=(const FrameWriter&) = delete;

  /// The master opens no new frame while this many frames wait to be written or are being
  /// written, so that at most kMaxPending - 1 + frames in flight are ever held here.
  static constexpr std::size_t kMaxPending = 4;

  void submit(std::string path, Image image);
  [[nodiscard]] std::size_t pending() const;
  /// Waits at most `limit` for every submitted frame to be written (or to fail): true when they
  /// all are.
  [[nodiscard]] bool flush_for(std::chrono::milliseconds limit);
  /// The first failure ("path: reason"), empty when every write succeeded.
  [[nodiscard]] std::string first_error() const;

  struct Totals {
    std::size_t written = 0;  ///< frames on disk
    std::size_t failed = 0;
    std::size_t pending = 0;  ///< frames waiting or being written (as pending())
    double write_s = 0;  ///< wall time spent encoding and writing the frames on disk (the writer's thread)
  };
  [[nodiscard]] Totals totals() const;  ///< read under one lock: the counts agree

 private:
  void loop();

  ImageWriteOptions options_;
  std::function<void(const std::string&)> on_error_;
  ImagePool* pool_;
  mutable std::mutex mutex_;
  std::condition_variable wake_, idle_;
  std::deque<std::pair<std::string, Image>> queue_;
  bool busy_ = false;
  std::string first_error_;
  Totals totals_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace rtc
