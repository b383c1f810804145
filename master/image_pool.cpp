// Frames' pixel memory used again (see image_pool.h).
#include "master/image_pool.h"

#include <utility>

namespace rtc {

Image ImagePool::take_for_overwrite(int w, int h, bool with_depth, bool with_normal) {
  Image image;
  {
    std::lock_guard lock(mutex_);
    if (!kept_.empty()) {
      image = std::move(kept_.back());
      kept_.pop_back();
    }
  }
  if (!image.has_shape(w, h, with_depth, with_normal)) image.reset(w, h, with_depth, with_normal);
  return image;
}

void ImagePool::give(Image&& image) {
  Image dropped;  // freed outside the lock
  std::lock_guard lock(mutex_);
  if (kept_.size() < most_kept_) {
    kept_.push_back(std::move(image));
  } else {
    dropped = std::move(image);
  }
}

std::size_t ImagePool::kept() const {
  std::lock_guard lock(mutex_);
  return kept_.size();
}

}  // namespace rtc
