#pragma once
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <x86intrin.h>
namespace rtc {
struct TraceTicks {
  std::atomic<std::uint64_t> t[64] = {};
  std::atomic<std::uint64_t> n[64] = {};
  ~TraceTicks() { std::fprintf(stderr, "TICKS rtc closest %.1f M occl %.1f M | embree closest %.1f M occl %.1f M | calls %llu %llu %llu %llu\n", t[0]/1e6, t[1]/1e6, t[2]/1e6, t[3]/1e6, (unsigned long long)n[0].load(), (unsigned long long)n[1].load(), (unsigned long long)n[2].load(), (unsigned long long)n[3].load());
    for (int b = 0; b < 3; ++b) std::fprintf(stderr, "TICKS bucket %d: rtc %.1f M (%llu packets) embree %.1f M (%llu)\n", b, t[4+b]/1e6, (unsigned long long)n[4+b].load(), t[8+b]/1e6, (unsigned long long)n[8+b].load());
    for (int l = 0; l < 8; ++l) std::fprintf(stderr, "TICKS light %d: rtc sparse %.1f M (%llu) full %.1f M (%llu) | embree sparse %.1f M full %.1f M\n", l, t[16+l]/1e6, (unsigned long long)n[16+l].load(), t[32+l]/1e6, (unsigned long long)n[32+l].load(), t[24+l]/1e6, t[40+l]/1e6); }
};
inline TraceTicks g_ticks;
inline thread_local int g_light = 0;
struct TickScope {
  int k; std::uint64_t s;
  explicit TickScope(int kk) : k(kk), s(__rdtsc()) {}
  ~TickScope() { g_ticks.t[k].fetch_add(__rdtsc() - s, std::memory_order_relaxed); g_ticks.n[k].fetch_add(1, std::memory_order_relaxed); }
};
}
