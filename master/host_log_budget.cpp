// Per-host bound on the master's connection warnings (see host_log_budget.h).
#include "master/host_log_budget.h"

#include <iterator>

namespace rtc {

bool HostLogBudget::allow(const std::string& host, Clock::time_point now, std::string& note) {
  note.clear();
  auto it = hosts_.find(host);
  if (it == hosts_.end()) {
    if (hosts_.size() >= kMostHosts) forget_quiet(now);
    it = hosts_.emplace(host, Entry{now, 0, 0}).first;
  }
  Entry& e = it->second;
  std::uint64_t left_out_before = 0;
  if (now - e.window_start >= kWindow) {
    left_out_before = e.left_out;
    e = Entry{now, 0, 0};
  }
  if (e.logged >= kLinesPerWindow) {
    ++e.left_out;
    return false;
  }
  ++e.logged;
  if (left_out_before > 0) {
    note += "; " + std::to_string(left_out_before) + " more such line" + (left_out_before == 1 ? " was" : "s were") +
            " left out before this one";
  }
  if (e.logged == kLinesPerWindow) {
    note += "; more such lines about " + host + " are left out for " + std::to_string(kWindow.count()) + " s";
  }
  return true;
}

void HostLogBudget::forget_quiet(Clock::time_point now) {
  // A host whose window has ended with nothing left out has nothing to say later.
  for (auto it = hosts_.begin(); it != hosts_.end();) {
    it = now - it->second.window_start >= kWindow && it->second.left_out == 0 ? hosts_.erase(it) : std::next(it);
  }
}

}  // namespace rtc
