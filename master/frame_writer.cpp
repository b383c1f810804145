// Background frame writer (see frame_writer.h).
#include "master/frame_writer.h"

#include <utility>

#include "common/base/error.h"

namespace rtc {

FrameWriter::FrameWriter(ImageWriteOptions options, std::function<void(const std::string&)> on_error,
                         ImagePool* pool)
    : options_(std::move(options)), on_error_(std::move(on_error)), pool_(pool), thread_([this] { loop(); }) {}

FrameWriter::~FrameWriter() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void FrameWriter::submit(std::string path, Image image) {
  {
    std::lock_guard lock(mutex_);
    queue_.emplace_back(std::move(path), std::move(image));
  }
  wake_.notify_all();
}

std::size_t FrameWriter::pending() const { return totals().pending; }

bool FrameWriter::flush_for(std::chrono::milliseconds limit) {
  std::unique_lock lock(mutex_);
  return idle_.wait_for(lock, limit, [this] { return queue_.empty() && !busy_; });
}

std::string FrameWriter::first_error() const {
  std::lock_guard lock(mutex_);
  return first_error_;
}

FrameWriter::Totals FrameWriter::totals() const {
  std::lock_guard lock(mutex_);
  Totals t = totals_;
  t.pending = queue_.size() + (busy_ ? 1 : 0);
  return t;
}

void FrameWriter::loop() {
  std::unique_lock lock(mutex_);
  for (;;) {
    wake_.wait(lock, [this] { return stop_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stop_ and nothing left
    auto [path, image] = std::move(queue_.front());
    queue_.pop_front();
    busy_ = true;
    lock.unlock();
    std::string error;
    const auto started = std::chrono::steady_clock::now();
    try {
      write_image(path, image, options_);
    } catch (const std::exception& e) {
      error = e.what();
    }
    const double took_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    if (pool_ != nullptr) pool_->give(std::move(image));
    if (!error.empty() && on_error_) on_error_(error);
    lock.lock();
    if (!error.empty() && first_error_.empty()) first_error_ = error;
    if (error.empty()) {
      ++totals_.written;
      totals_.write_s += took_s;
    } else {
      ++totals_.failed;
    }
    busy_ = false;
    if (queue_.empty()) idle_.notify_all();
  }
}

}  // namespace rtc
