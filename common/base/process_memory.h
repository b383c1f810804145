// How an rtc process asks glibc's malloc to keep the memory it frees, so that the next frame's
// kd-tree build (or a benchmark's next rep) does not fault its pages in again.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace rtc {

/// What keep_freed_memory did.
struct FreedMemoryPolicy {
  bool mmap_threshold_set = false;  ///< M_MMAP_THRESHOLD is 32 MiB
  bool trim_threshold_set = false;  ///< M_TRIM_THRESHOLD is 2 GiB
  std::string reason;               ///< why neither was set, or why one was refused
  [[nodiscard]] bool applied() const { return mmap_threshold_set && trim_threshold_set; }
};

/// Asks glibc's malloc to keep freed memory for reuse instead of giving it back to the kernel:
/// blocks up to 32 MiB come from the heap (mallopt M_MMAP_THRESHOLD, glibc's largest; a fixed
/// value also stops glibc from raising the threshold as blocks are freed, which sent the next
/// block of that size to fresh heap pages), and a heap's free top goes back to the kernel only
/// once it passes 2 GiB (M_TRIM_THRESHOLD). Without it a kd-tree build gave much of its scratch
/// back and the next build faulted it in again page by page: on a VM where a 4 KiB page's
/// first touch costs ~15 us, 0.76-0.90x the time for repeated builds at 2 threads
/// (build_experiments.md, session 47; on the Xeon VM of session 38, where faults were cheap, 0.97-1.02x).
///
/// Not kept: blocks over 32 MiB (mmapped and unmapped as before; the kd-tree build keeps its own
/// of 2 MiB and more, alloc_pages), and a thread arena's extra 64 MiB heaps once wholly free.
/// The price: a process holds on to about its largest heap (a worker's largest build) per
/// malloc arena until it ends, and reuses it for later frames.
///
/// Call once, first thing (before any thread starts). Sets nothing where the user set either
/// threshold (MALLOC_TRIM_THRESHOLD_, MALLOC_MMAP_THRESHOLD_, or glibc.malloc.trim_threshold /
/// mmap_threshold in GLIBC_TUNABLES), with RTC_MALLOC_KEEP=0, under a sanitizer's allocator, or
/// on a C library other than glibc.
FreedMemoryPolicy keep_freed_memory();

/// Says at debug level what keep_freed_memory did (call after init_logging).
void log_freed_memory_policy(const FreedMemoryPolicy& policy);

/// keep_freed_memory's decision from the environment: the reason not to set the thresholds,
/// or an empty string to set them. `env` looks a variable up (getenv's contract).
std::string freed_memory_veto(const char* (*env)(const char* name));

/// The memory a new allocation can get without swapping: MemAvailable in /proc/meminfo, or less
/// where a memory cgroup (a container's limit) or an address-space limit (ulimit -v, less what
/// the process has mapped) leaves less; nullopt where none can be read.
std::optional<std::uint64_t> available_memory_bytes();

/// Throws rtc::Error ("<what> needs at least X GB of memory and Y GB are available to this
/// process: <hint>") when `need` bytes exceed available_memory_bytes(), so that a frame far too big for
/// the machine is refused up front instead of the process being killed for memory halfway;
/// does nothing where the available memory is unknown.
void check_memory(const std::string& what, std::uint64_t need, const std::string& hint);

}  // namespace rtc
