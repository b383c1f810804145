// How an rtc process asks glibc's malloc to keep the memory it frees, so that the next frame's
// build (or the next rep of a benchmark) does not fault its pages in again.
#pragma once

#include <string>

namespace rtc {

/// What keep_freed_memory did.
struct FreedMemoryPolicy {
  bool applied = false;  ///< the thresholds below were set
  std::string reason;    ///< why not, when not applied (for the debug log)
};

/// Asks glibc's malloc to keep freed memory for reuse instead of giving it back to the kernel:
/// blocks up to 32 MiB come from the heap (mallopt M_MMAP_THRESHOLD, glibc's largest; a fixed
/// value also stops glibc from moving the threshold as blocks are freed), and the heap's free
/// top is not trimmed below 2 GiB (M_TRIM_THRESHOLD). Without it every kd-tree build gives its scratch
/// arrays back and the next one faults them in again page by page: on a VM where a 4 KiB fault
/// costs ~15 us that was a fifth of a 2-thread build of spd-tree (build_experiments.md,
/// session 47). The price: a process keeps its peak heap (a worker's largest build) until it
/// ends, and reuses it for every later frame.
///
/// Call once, first thing in main, before other threads start. Does nothing where the user set
/// either threshold (MALLOC_TRIM_THRESHOLD_, MALLOC_MMAP_THRESHOLD_, or a glibc.malloc tunable
/// for them in GLIBC_TUNABLES), or RTC_MALLOC_KEEP=0, or on a C library other than glibc.
FreedMemoryPolicy keep_freed_memory();

/// Says at debug level what keep_freed_memory did (call after init_logging).
void log_freed_memory_policy(const FreedMemoryPolicy& policy);

/// keep_freed_memory's decision from the environment alone: the reason not to set the
/// thresholds, or an empty string to set them. `env` looks a variable up (getenv's contract).
std::string freed_memory_veto(const char* (*env)(const char* name));

}  // namespace rtc
