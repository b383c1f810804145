// Progress bar: throttled redraws of one stderr line, only on a terminal.
#include "common/base/progress.h"

#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <string_view>
#include <utility>

#include <fmt/format.h>

namespace rtc {
namespace {

constexpr int kDefaultColumns = 80;
constexpr int kMinBarWidth = 10;
constexpr int kMaxBarWidth = 40;

bool stderr_is_terminal() {
  if (::isatty(::fileno(stderr)) == 0) return false;
  const char* term = std::getenv("TERM");
  return term == nullptr || std::string_view(term) != "dumb";
}

int terminal_columns(std::FILE* out) {
  winsize size{};
  if (::ioctl(::fileno(out), TIOCGWINSZ, &size) == 0 && size.ws_col > 0) return size.ws_col;
  return kDefaultColumns;
}

// "950", "12.3k", "4.56M": short enough for the line whatever the unit.
std::string short_number(double value) {
  if (value >= 1e9) return fmt::format("{:.2f}G", value / 1e9);
  if (value >= 1e6) return fmt::format("{:.2f}M", value / 1e6);
  if (value >= 1e4) return fmt::format("{:.1f}k", value / 1e3);
  if (value >= 100) return fmt::format("{:.0f}", value);
  return fmt::format("{:.1f}", value);
}

std::string clock_time(double seconds) {
  const auto total = static_cast<std::int64_t>(seconds + 0.5);
  const std::int64_t hours = total / 3600;
  const std::int64_t minutes = total / 60 % 60;
  const std::int64_t secs = total % 60;
  if (hours > 0) return fmt::format("{}:{:02}:{:02}", hours, minutes, secs);
  return fmt::format("{}:{:02}", minutes, secs);
}

}  // namespace

ProgressBar::ProgressBar(std::uint64_t total, std::string label, std::string unit)
    : ProgressBar(total, std::move(label), std::move(unit), stderr, stderr_is_terminal()) {}

ProgressBar::ProgressBar(std::uint64_t total, std::string label, std::string unit,
                         std::FILE* out, bool draw)
    : total_(total),
      label_(std::move(label)),
      unit_(std::move(unit)),
      out_(out),
      draw_(draw && out != nullptr),
      start_(Clock::now()) {}

ProgressBar::~ProgressBar() { finish(); }

double ProgressBar::elapsed_s() const {
  return std::chrono::duration<double>(Clock::now() - start_).count();
}

void ProgressBar::add(std::uint64_t n) {
  done_.fetch_add(n, std::memory_order_relaxed);
  if (!draw_) return;
  const std::int64_t now_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - start_).count();
  std::int64_t due_ns = next_draw_ns_.load(std::memory_order_relaxed);
  if (now_ns < due_ns) return;
  // One thread claims each redraw slot; the others go back to work without waiting.
  if (!next_draw_ns_.compare_exchange_strong(due_ns, now_ns + kRedrawIntervalNs,
                                             std::memory_order_relaxed)) {
    return;
  }
  const std::lock_guard lock(draw_mutex_);
  if (!finished_) draw_line(done());
}

void ProgressBar::finish() {
  const std::lock_guard lock(draw_mutex_);
  if (finished_) return;
  finished_ = true;
  if (drawn_) {
    std::fputs("\r\x1b[K", out_);
    std::fflush(out_);
  }
}

void ProgressBar::draw_line(std::uint64_t done_units) {
  const std::uint64_t shown = std::min(done_units, total_);
  const double fraction =
      total_ == 0 ? 1.0 : static_cast<double>(shown) / static_cast<double>(total_);
  const double seconds = elapsed_s();
  const double rate = seconds > 0.0 ? static_cast<double>(done_units) / seconds : 0.0;
  const std::string eta =
      shown >= total_ ? "0:00"
      : rate > 0.0    ? clock_time(static_cast<double>(total_ - shown) / rate)
                      : "--:--";
  const std::string prefix = label_.empty() ? std::string() : fmt::format("{} ", label_);
  const std::string suffix =
      fmt::format(" {:5.1f}%  {}{}{}/s  ETA {}", 100.0 * fraction, short_number(rate),
                  unit_.empty() ? "" : " ", unit_, eta);

  // Leave the last column free: writing into it makes some terminals wrap.
  const int room = terminal_columns(out_) - 1 - static_cast<int>(prefix.size() + suffix.size());
  std::string bar;
  if (room - 2 >= kMinBarWidth) {
    const int width = std::min(room - 2, kMaxBarWidth);
    const auto filled = static_cast<int>(fraction * width);
    bar = fmt::format("[{}{}]", std::string(static_cast<std::size_t>(filled), '#'),
                      std::string(static_cast<std::size_t>(width - filled), '.'));
  }
  const std::string line = fmt::format("\r{}{}{}\x1b[K", prefix, bar, suffix);
  std::fputs(line.c_str(), out_);
  std::fflush(out_);
  drawn_ = true;
}

}  // namespace rtc
