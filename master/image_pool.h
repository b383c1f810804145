// Frames' pixel memory used again: a master's frames are all the same size, and a fresh one
// costs its whole size in page faults (a 2048x2048 float frame, 64 MiB: about 200 ms on a VM).
#pragma once

#include <cstddef>
#include <mutex>
#include <vector>

#include "common/image/image.h"

namespace rtc {

/// Holds finished frames' images for the next frames. Thread-safe: the frame writer gives
/// images back from its thread while the network thread takes them.
class ImagePool {
 public:
  /// Keeps at most `most_kept` images; more given back are freed.
  explicit ImagePool(std::size_t most_kept) : most_kept_(most_kept) {}
  ImagePool(const ImagePool&) = delete;
  ImagePool& operator=(const ImagePool&) = delete;

  /// An image of that size and those channels for a caller that writes every pixel (a frame
  /// is written only once all its tiles are in): a kept image of the same shape comes back as
  /// it is, with an earlier frame's pixels (filling 64 MiB cost about 20 ms a frame on a VM);
  /// any other is made so by Image::reset, in a kept image's memory when one is kept.
  [[nodiscard]] Image take_for_overwrite(int w, int h, bool with_depth, bool with_normal);
  /// Keeps `image`'s memory for a later take_for_overwrite() (or frees it when the pool is full).
  void give(Image&& image);
  [[nodiscard]] std::size_t kept() const;

 private:
  std::size_t most_kept_;
  mutable std::mutex mutex_;
  std::vector<Image> kept_;
};

}  // namespace rtc
