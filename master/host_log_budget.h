// Log lines about connections that never became workers (refused at the limits, a failed TLS
// handshake, closed before authenticating), bounded per host: a scanner or a misconfigured
// client connecting in a loop would otherwise write one warning per attempt, without end.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>

namespace rtc {

class HostLogBudget {
 public:
  using Clock = std::chrono::steady_clock;
  /// Lines about one host logged per window at most.
  static constexpr int kLinesPerWindow = 20;
  static constexpr std::chrono::seconds kWindow{60};
  /// Hosts remembered before the quiet ones (nothing left out) are forgotten.
  static constexpr std::size_t kMostHosts = 1024;

  /// Whether a line about `host` may be logged at `now`; when it may not, the line is counted.
  /// `note` is set to what the line should end with: the count of lines left out in the window
  /// before (when any were), and, on the window's last allowed line, that the rest are left out.
  [[nodiscard]] bool allow(const std::string& host, Clock::time_point now, std::string& note);

  [[nodiscard]] std::size_t hosts() const { return hosts_.size(); }

 private:
  struct Entry {
    Clock::time_point window_start;
    int logged = 0;
    std::uint64_t left_out = 0;
  };
  void forget_quiet(Clock::time_point now);

  std::map<std::string, Entry> hosts_;
};

}  // namespace rtc
