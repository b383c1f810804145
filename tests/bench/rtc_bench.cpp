// rtc-bench: kd-tree build time, primary and shadow ray throughput and full Whitted frame time
// of rtc's tracer on one scene, optionally beside Embree 3 tracing the same rays in the same
// run (--compare-embree), with per-pixel agreement. Speed is reported, never asserted.
#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>

#include "common/accel/trace.h"
#include "common/accel/walk_stats.h"
#include "common/base/cli_checks.h"
#include "common/base/error.h"
#include "common/base/isa.h"
#include "common/base/log.h"
#include "common/base/process_memory.h"
#include "common/scene/scene_cli.h"
#include "common/base/timer.h"
#include "common/image/image.h"
#include "common/render/render_kernels.h"
#include "common/render/renderer.h"
#include "common/render/shading.h"
#include "common/render/trace_ticks.h"
#include "common/simd/tsc.h"
#include "common/scene/load.h"
#include "tests/support/embree_oracle.h"
#include "tests/support/hit_compare.h"
#include "tests/bench/bench_timing.h"
#include "tests/bench/sweep.h"

namespace {

// The CPU's model name as /proc/cpuinfo gives it (the tables name the machine they were taken
// on: sessions ran on an AMD EPYC VM and on an Intel Xeon VM); "unknown" where it is not there.
std::string cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("model name", 0) == 0) {
      const std::size_t colon = line.find(':');
      if (colon != std::string::npos) {
        const std::size_t start = line.find_first_not_of(" \t", colon + 1);
        if (start != std::string::npos) return line.substr(start);
      }
    }
  }
  return "unknown";
}

using rtc::RayHit;
using rtc::RayQuery;
using rtc::test::EmbreeMode;
using rtc::test::EmbreeScene;

constexpr int kTile = 16;  // rays are handed to threads a 16x16 tile at a time

/// A ray stream in packet order: every `width` consecutive rays are one block of pixels;
/// `pixel` is -1 for padding lanes (copies of a real ray of the block, not counted).
struct RayStream {
  int width = 1;
  std::vector<RayQuery> rays;
  std::vector<std::int64_t> pixel;
  std::vector<std::size_t> chunk_begin;  // one chunk per tile, for threads
  std::uint64_t real = 0;
};

// --tiles FROM:TO: the share of the image's 16x16 tiles (in rows, top to bottom) that the primary
// and shadow modes trace, on every side alike: tiles [floor(FROM n), floor(TO n)) of n, each
// product nudged up by 1e-9 so that a share such as 0.57 of 1200 tiles (683.99999...) starts
// at tile 684.
struct TileShare {
  double from = 0.0, to = 1.0;
  [[nodiscard]] bool whole() const { return from == 0.0 && to == 1.0; }
  [[nodiscard]] std::pair<std::size_t, std::size_t> range(std::size_t n) const {
    const auto tile = [n](double f) {
      return std::min(n, static_cast<std::size_t>(std::floor(f * static_cast<double>(n) + 1e-9)));
    };
    return {tile(from), tile(to)};
  }
};

// "FROM:TO" with 0 <= FROM < TO <= 1 (fractions of the tiles); throws rtc::Error otherwise.
TileShare parse_tile_share(const std::string& text) {
  const std::size_t colon = text.find(':');
  TileShare t;
  std::size_t used_from = 0, used_to = 0;
  try {
    if (colon == std::string::npos) throw std::invalid_argument("no colon");
    t.from = std::stod(text.substr(0, colon), &used_from);
    t.to = std::stod(text.substr(colon + 1), &used_to);
  } catch (const std::exception&) {
    throw rtc::Error("--tiles '" + text + "': expected FROM:TO, two fractions of the image's tiles (e.g. 0.125:0.25)");
  }
  if (used_from != colon || used_to != text.size() - colon - 1 || !(t.from >= 0.0) || !(t.to <= 1.0) ||
      !(t.from < t.to)) {
    throw rtc::Error("--tiles '" + text + "': expected FROM:TO with 0 <= FROM < TO <= 1");
  }
  return t;
}

// The image's kTile x kTile tiles (those on the right and bottom edges may be partial).
std::size_t tile_count(const rtc::FrameState& fs) {
  return static_cast<std::size_t>((fs.width + kTile - 1) / kTile) *
         static_cast<std::size_t>((fs.height + kTile - 1) / kTile);
}

// The elements of `by_pixel` (one per pixel) at `pixels`, in that order.
template <typename T>
std::vector<T> at_pixels(const std::vector<T>& by_pixel, const std::vector<std::size_t>& pixels) {
  std::vector<T> out;
  out.reserve(pixels.size());
  for (const std::size_t px : pixels) out.push_back(by_pixel[px]);
  return out;
}

RayStream primary_stream(const rtc::FrameState& fs, int width, const TileShare& share) {
  RayStream s;
  s.width = width;
  const int bw = rtc::packet_block_width(width), bh = width / bw;
  const auto [first_tile, end_tile] = share.range(tile_count(fs));
  std::size_t tile = 0;
  for (int ty = 0; ty < fs.height; ty += kTile) {
    for (int tx = 0; tx < fs.width; tx += kTile, ++tile) {
      if (tile < first_tile || tile >= end_tile) continue;
      s.chunk_begin.push_back(s.rays.size());
      for (int by = ty; by < std::min(ty + kTile, fs.height); by += bh) {
        for (int bx = tx; bx < std::min(tx + kTile, fs.width); bx += bw) {
          const std::size_t first = s.rays.size();
          for (int i = 0; i < width; ++i) {
            const int x = bx + i % bw, y = by + i / bw;
            const bool real = x < std::min(tx + kTile, fs.width) && y < std::min(ty + kTile, fs.height);
            if (real) {
              const rtc::Ray r = fs.camera_rays.ray(x, y);
              s.rays.push_back(RayQuery{r.origin, 0.0f, r.dir, std::numeric_limits<float>::infinity()});
              s.pixel.push_back(static_cast<std::int64_t>(y) * fs.width + x);
              ++s.real;
            } else {
              s.rays.push_back(s.rays[first]);
              s.pixel.push_back(-1);
            }
          }
        }
      }
    }
  }
  s.chunk_begin.push_back(s.rays.size());
  return s;
}

// Shadow rays from our primary hits to every light, made by the renderer's own code
// (rtc::surface_at, rtc::shadow_ray), grouped per light in the primary packets' blocks.
RayStream shadow_stream(const rtc::FrameState& fs, const RayStream& primary, const std::vector<RayHit>& hits) {
  RayStream s;
  s.width = primary.width;
  const int w = primary.width;
  for (std::size_t c = 0; c + 1 < primary.chunk_begin.size(); ++c) {
    s.chunk_begin.push_back(s.rays.size());
    for (const rtc::PointLight& light : fs.lights) {
      for (std::size_t b = primary.chunk_begin[c]; b < primary.chunk_begin[c + 1]; b += static_cast<std::size_t>(w)) {
        RayQuery lane[16];
        bool want[16] = {};
        int first_real = -1;
        for (int i = 0; i < w; ++i) {
          const std::size_t k = b + static_cast<std::size_t>(i);
          if (primary.pixel[k] < 0 || hits[k].prim == rtc::kNoHit) continue;
          const rtc::SurfaceSample surface =
              rtc::surface_at(fs, primary.rays[k].dir, hits[k].prim, hits[k].beta, hits[k].gamma);
          const std::optional<rtc::ShadowRay> ray = rtc::shadow_ray(surface, light);
          if (!ray) continue;
          lane[i] = ray->ray;
          want[i] = true;
          if (first_real < 0) first_real = i;
        }
        if (first_real < 0) continue;
        for (int i = 0; i < w; ++i) {
          s.rays.push_back(want[i] ? lane[i] : lane[first_real]);
          s.pixel.push_back(want[i] ? 1 : -1);
          s.real += want[i] ? 1 : 0;
        }
      }
    }
  }
  s.chunk_begin.push_back(s.rays.size());
  return s;
}

// The renderer's rays through Embree: for each packet the renderer makes (up to its width, 16
// with AVX-512), the narrowest Embree packet call that holds its active rays.
EmbreeMode packet_mode(std::size_t count) {
  if (count <= 1) return EmbreeMode::Single;
  if (count <= 4) return EmbreeMode::Packet4;
  return count <= 8 ? EmbreeMode::Packet8 : EmbreeMode::Packet16;
}
void embree_intersect(void* context, const RayQuery* rays, RayHit* hits, std::size_t count) {
  static_cast<const EmbreeScene*>(context)->intersect(rays, hits, count, packet_mode(count));
}
void embree_occluded(void* context, const RayQuery* rays, std::uint8_t* out, std::size_t count) {
  static_cast<const EmbreeScene*>(context)->occluded(rays, out, count, packet_mode(count));
}

template <typename Fn>
void for_chunks(const RayStream& s, Fn&& fn) {
  tbb::parallel_for(std::size_t{0}, s.chunk_begin.size() - 1, [&](std::size_t c) {
    fn(s.chunk_begin[c], s.chunk_begin[c + 1] - s.chunk_begin[c]);
  });
}

// One pass of a stream through kernels `k`: occlusion into `occ`, or closest hits into `hits`.
// `refine`: closest hits also get their distances recomputed in double (refine_hit_distances),
// as rtc's stream API reports them. The throughput figures set against Embree leave that out,
// since Embree's hits get no such step: both sides then do the same work, tracing.
void trace_stream(const rtc::TraceKernels& k, const rtc::FrameState& fs, const RayStream& s, bool shadow,
                  bool packets, std::vector<RayHit>& hits, std::vector<std::uint8_t>& occ, bool refine = false,
                  rtc::ShadowOrder order = rtc::ShadowOrder::Auto, rtc::ShadowOrderTally* tally = nullptr) {
  hits.resize(s.rays.size());
  occ.resize(s.rays.size());
  for_chunks(s, [&](std::size_t first, std::size_t n) {
    if (shadow) {
      k.occluded_in_order(fs.geometry->single_tree(), s.rays.data() + first, occ.data() + first, n, packets, order,
                          tally);
    } else {
      k.intersect(fs.geometry->single_tree(), s.rays.data() + first, hits.data() + first, n, packets);
      if (refine) {
        rtc::refine_hit_distances(fs.geometry->positions, fs.geometry->triangles, s.rays.data() + first,
                                  hits.data() + first, n);
      }
    }
  });
}

// A walk tally (stats builds, RTC_WALK_STATS) as JSON: its totals, over all repetitions.
nlohmann::json walk_json(const rtc::WalkStats& w) {
  nlohmann::json out = nlohmann::json::object();
  for (const auto& [name, field] : rtc::kWalkStatsFields) out[name] = w.*field;
  return out;
}

// The trace-call tally (RTC_TRACE_TICKS builds) as JSON, a row per kind of call with each
// side's ticks, calls and rays per frame (`frames`: how many each side rendered, the same).
nlohmann::json trace_ticks_json(const std::vector<rtc::TraceTickRow>& rows, int width, double frames) {
  nlohmann::json out = nlohmann::json::array();
  for (const rtc::TraceTickRow& r : rows) {
    const char* side = r.external ? "embree" : "rtc";
    nlohmann::json* row = nullptr;
    for (nlohmann::json& o : out) {
      if (o["call"] == static_cast<int>(r.call) && o["light"] == r.light && o["fill"] == static_cast<int>(r.fill)) row = &o;
    }
    if (row == nullptr) {
      out.push_back({{"name", rtc::trace_tick_row_name(r, static_cast<unsigned>(width))},
                     {"call", static_cast<int>(r.call)},
                     {"light", r.light},
                     {"fill", static_cast<int>(r.fill)}});
      row = &out.back();
    }
    (*row)[side] = {{"ticks_per_frame", static_cast<double>(r.ticks) / frames},
                    {"calls_per_frame", static_cast<double>(r.calls) / frames},
                    {"rays_per_frame", static_cast<double>(r.rays) / frames}};
  }
  return out;
}

// The tally as a table: per frame, each side's M ticks and ticks per call, and the external
// tracer's ticks over rtc's (above 1: rtc spends less there).
void print_trace_ticks(const nlohmann::json& rows, bool compare) {
  std::printf("          trace calls (RTC_TRACE_TICKS build; per frame: M ticks, ticks per call, rays per call%s):\n",
              compare ? "; Embree renderer's ticks over rtc's" : "");
  double total[2] = {0.0, 0.0};
  for (const nlohmann::json& r : rows) {
    std::string line = fmt::format("            {:<34}", r["name"].get<std::string>());
    double t[2] = {0.0, 0.0};
    int k = 0;
    for (const char* side : {"rtc", "embree"}) {
      if (r.contains(side)) {
        const nlohmann::json& s = r[side];
        t[k] = s["ticks_per_frame"].get<double>();
        total[k] += t[k];
        const double calls = s["calls_per_frame"].get<double>();
        line += fmt::format(" {} {:8.2f} M ({:7.0f}/call, {:5.2f} rays)", side, t[k] / 1e6, t[k] / calls,
                            s["rays_per_frame"].get<double>() / calls);
      }
      ++k;
    }
    if (t[0] > 0.0 && t[1] > 0.0) line += fmt::format("  {:.3f}", t[1] / t[0]);
    std::printf("%s\n", line.c_str());
  }
  std::string line = fmt::format("            {:<34} rtc {:8.2f} M", "all trace calls", total[0] / 1e6);
  if (compare) line += fmt::format(", embree {:8.2f} M", total[1] / 1e6);
  if (total[0] > 0.0 && total[1] > 0.0) line += fmt::format("  {:.3f}", total[1] / total[0]);
  std::printf("%s\n", line.c_str());
}

std::vector<RayHit> by_pixel(const RayStream& s, const std::vector<RayHit>& hits, std::size_t pixels) {
  std::vector<RayHit> out(pixels);
  for (std::size_t i = 0; i < s.rays.size(); ++i) {
    if (s.pixel[i] >= 0) out[static_cast<std::size_t>(s.pixel[i])] = hits[i];
  }
  return out;
}

std::vector<RayQuery> rays_by_pixel(const RayStream& s, std::size_t pixels) {
  std::vector<RayQuery> out(pixels);
  for (std::size_t i = 0; i < s.rays.size(); ++i) {
    if (s.pixel[i] >= 0) out[static_cast<std::size_t>(s.pixel[i])] = s.rays[i];
  }
  return out;
}

void write_dump(const std::string& prefix, const rtc::FrameState& fs, const std::vector<RayHit>& hits) {
  std::vector<float> t(hits.size());
  std::vector<std::uint32_t> prim(hits.size());
  for (std::size_t i = 0; i < hits.size(); ++i) {
    const bool hit = hits[i].prim != rtc::kNoHit;
    t[i] = hit ? hits[i].t : std::numeric_limits<float>::infinity();
    prim[i] = hit ? fs.geometry->source_index[hits[i].prim] : 0xFFFFFFFFu;
  }
  auto write = [](const std::string& path, const void* data, std::size_t bytes) {
    std::ofstream f(path, std::ios::binary);
    f.write(static_cast<const char*>(data), static_cast<std::streamsize>(bytes));
    if (!f) throw rtc::Error(path + ": cannot write the dump: " + std::strerror(errno));
  };
  write(prefix + ".t.f32", t.data(), t.size() * sizeof(float));
  write(prefix + ".prim.u32", prim.data(), prim.size() * sizeof(std::uint32_t));
}

const EmbreeMode kEmbreeModes[] = {EmbreeMode::Single, EmbreeMode::Packet4, EmbreeMode::Packet8,
                                   EmbreeMode::Packet16};

int run(int argc, char** argv) {
  // Before any thread starts: a build's freed scratch stays for the next (process_memory.h).
  const rtc::FreedMemoryPolicy freed_memory = rtc::keep_freed_memory();
  CLI::App app{"rtc-bench: rtc tracer throughput on one scene, optionally beside Embree"};
  std::string scene_path;
  int threads = 0, reps = 5;
  std::vector<std::string> modes;
  std::string isa_text, dump_prefix, log_level = "warn";
  bool json = false, compare = false;
  app.add_option("scene", scene_path,
                 "a view.json / scene file / mesh, or a folder holding view.json; omitted: the built-in default scene");
  app.add_option("--threads", threads, "threads (default: all cores)")->check(CLI::Range(1, 1024));
  app.add_option("--reps", reps, "repetitions; figures are medians")->check(CLI::Range(1, 1000));
  std::string tiles_text;
  app.add_option("--tiles", tiles_text,
                 "primary and shadow modes: trace only this share of the image's 16x16 tiles, FROM:TO as fractions "
                 "of them in rows from the top (e.g. 0.125:0.25), on every side alike (default 0:1, all)");
  int build_reps = 0;
  app.add_option("--build-reps", build_reps,
                 "builds timed (default: --reps, and more, up to 100, until rtc's builds add up to half a second); "
                 "1 for profiling the tracing")
      ->check(CLI::Range(1, 1000));
  app.add_option("--mode", modes, "primary, shadow, full (repeatable; default: all three)")
      ->check(CLI::IsMember({"primary", "shadow", "full"}));
  app.add_option("--isa", isa_text,
                 "kernel ISA: sse4, avx2, avx512, or all (every one this CPU runs; the best is the headline figure); "
                 "default: the best available, or all with --compare-embree")
      ->check(rtc::kNotEmpty);
  app.add_flag("--json", json, "one JSON object per line per mode instead of the table");
  app.add_option("--dump", dump_prefix, "write PREFIX.t.f32 and PREFIX.prim.u32 of the primary hits")
      ->check(rtc::kNotEmpty);
  app.add_flag("--compare-embree", compare, "trace the same rays with Embree 3 in the same run");
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error, critical, off");
  app.add_flag("--cpu-time", rtc::bench::g_cpu_time,
               "time by process CPU time (summed over threads), not wall time: for A/B runs on a busy machine");
  bool no_warm_up = false;
  app.add_flag("--no-warm-up", no_warm_up,
               "primary and shadow modes: time each contender's pass right after the contender before it, with no "
               "untimed pass of its own first (the order up to 2026-11-29, which left Embree's 4- to 16-wide modes "
               "the caches of another Embree mode and rtc's packets those of Embree's)");
  rtc::KdBuildOptions kd_options;
  app.add_option("--kd-traversal-cost", kd_options.traversal_cost, "SAH K_T")->check(rtc::kNotNan)->check(CLI::PositiveNumber);
  app.add_option("--kd-footprint", kd_options.footprint_pixels,
                 "view-aware SAH: small nodes' lengths counted this many pixels longer (0: the plain SAH)")
      ->check(rtc::kNotNan)->check(CLI::Range(0.0f, 1024.0f))
      ->capture_default_str();
  app.add_option("--kd-footprint-max-refs", kd_options.footprint_max_refs,
                 "view-aware SAH: for nodes of at most this many references")
      ->check(CLI::Range(0, 1 << 30))
      ->capture_default_str();
  app.add_option("--kd-intersection-cost", kd_options.intersection_cost, "SAH K_I")->check(rtc::kNotNan)->check(CLI::PositiveNumber);
  app.add_option("--kd-empty-bonus", kd_options.empty_bonus, "SAH empty-space bonus")->check(rtc::kNotNan)->check(CLI::Range(0.0f, 0.99f));
  app.add_option("--kd-empty-cut", kd_options.empty_cut,
                 "event-sweep nodes whose triangles leave at least this fraction of the cell empty on one side are "
                 "cut there without the SAH sweep (above 1: off)")
      ->check(rtc::kNotNan)->check(CLI::Range(0.0f, 1e9f))
      ->capture_default_str();
  app.add_option("--kd-max-depth", kd_options.max_depth, "kd-tree depth limit (0: 8 + 1.3 log2 N)")
      ->check(CLI::Range(0, 60));
  std::string kd_clip_text = "auto";
  rtc::add_kd_clip_option(app, kd_clip_text);
  app.add_option("--kd-leaf-size", kd_options.leaf_size, "nodes this small become leaves")->check(CLI::Range(1, 1024));
  app.add_option("--kd-leaf-box-saving", kd_options.leaf_box_saving,
                 "leaves get a box of their contents, tested before them, where it saves at least this many "
                 "triangle tests per visit by the SAH's estimate (0: no boxes)")
      ->check(rtc::kNotNan)->check(CLI::Range(0.0f, 1e9f));
  // --ab-kd-OPTION: a second tree built with another value of --kd-OPTION, timed beside the first.
  const auto ab_help = [](const char* option) {
    return std::string("primary and shadow modes: also build a tree with this --kd-") + option +
           " (and the other --ab-kd-* where given) and time its packets and single rays rep by rep beside the first "
           "tree's (paired ratios; the answers must be the same)";
  };
  float ab_leaf_box_saving = -1.0f;
  app.add_option("--ab-kd-leaf-box-saving", ab_leaf_box_saving, ab_help("leaf-box-saving"))
      ->check(rtc::kNotNan)->check(CLI::Range(0.0f, 1e9f));
  float ab_empty_cut = -1.0f;
  app.add_option("--ab-kd-empty-cut", ab_empty_cut, ab_help("empty-cut"))
      ->check(rtc::kNotNan)->check(CLI::Range(0.0f, 1e9f));
  app.add_option("--kd-exact-below", kd_options.exact_below,
                 "nodes of more references than this are split with the binned SAH, smaller ones built as blocks "
                 "with the exact event sweep")
      ->check(CLI::Range(1, 1 << 30))
      ->capture_default_str();
  int ab_exact_below = -1;
  app.add_option("--ab-kd-exact-below", ab_exact_below, ab_help("exact-below"))
      ->check(CLI::Range(1, 1 << 30));
  app.add_option("--kd-binned-root-above", kd_options.binned_root_above,
                 "the root is split with the binned SAH above this many references, so that a scene of one block "
                 "(at most --kd-exact-below) builds as two side by side (at least --kd-exact-below: off)")
      ->check(CLI::Range(1, 1 << 30))
      ->capture_default_str();
  int ab_binned_root_above = -1;
  app.add_option("--ab-kd-binned-root-above", ab_binned_root_above, ab_help("binned-root-above"))
      ->check(CLI::Range(1, 1 << 30));
  float ab_footprint = -1.0f;
  app.add_option("--ab-kd-footprint", ab_footprint, ab_help("footprint"))
      ->check(rtc::kNotNan)->check(CLI::Range(0.0f, 1024.0f));
  app.add_option("--kd-mask-below", kd_options.mask_below,
                 "subtrees of at most this many references (up to 256) built with bit masks, not clipped below "
                 "their root (0: the event sweep to the leaves; -1: 64 with --kd-clip on, 256 with it off)")
      ->check(CLI::Range(-1, 256))
      ->capture_default_str();
  std::string kd_build_isa;
  app.add_option("--kd-build-isa", kd_build_isa,
                 "the widest vector code the kd-tree build takes (KdBuildOptions::simd_limit; sse4: the scalar "
                 "code), as far as the CPU goes; every choice builds the same tree (default: avx512)")
      ->check(CLI::IsMember({"sse4", "avx2", "avx512"}));
  int ab_mask_below = -2;  // -1 is a value (the default's rule)
  app.add_option("--ab-kd-mask-below", ab_mask_below, ab_help("mask-below"))->check(CLI::Range(-1, 256));
  int ab_max_depth = -1;
  app.add_option("--ab-kd-max-depth", ab_max_depth, ab_help("max-depth"))->check(CLI::Range(0, 60));
  float ab_traversal_cost = -1.0f;
  app.add_option("--ab-kd-traversal-cost", ab_traversal_cost, ab_help("traversal-cost"))
      ->check(rtc::kNotNan)->check(CLI::PositiveNumber);
  float ab_intersection_cost = -1.0f;
  app.add_option("--ab-kd-intersection-cost", ab_intersection_cost, ab_help("intersection-cost"))
      ->check(rtc::kNotNan)->check(CLI::PositiveNumber);
  float ab_empty_bonus = -1.0f;
  app.add_option("--ab-kd-empty-bonus", ab_empty_bonus, ab_help("empty-bonus"))->check(rtc::kNotNan)->check(CLI::Range(0.0f, 0.99f));
  std::string sweep_dir;
  bool sweep_quick = false, no_embree_check = false;
  int width = 0, height = 0;
  app.add_option("--sweep", sweep_dir,
                 "run time against error: render with every setting that trades time for accuracy, measure each "
                 "against a double-precision reference, write DIR/sweep.csv, DIR/reference.exr and DIR/reference.json "
                 "(plot with tests/bench/plot_sweep.py)")
      ->check(rtc::kNotEmpty);
  app.add_flag("--sweep-quick", sweep_quick, "with --sweep: a few settings per group only");
  app.add_flag("--no-embree-check", no_embree_check, "with --sweep: skip the Embree cross-check of the reference");
  app.add_option("--width", width, "image width (default: the scene's)")->check(CLI::Range(1, 32768));
  app.add_option("--height", height, "image height (default: the scene's)")->check(CLI::Range(1, 32768));
  std::string intersector;
  app.add_option("--intersector", intersector, "ray/triangle test: wald or watertight (default: the scene's, normally wald)")
      ->check(CLI::IsMember({"wald", "watertight"}));
  bool no_specialise = false, no_skip_empty = false, kernel_ab = false, no_lights = false, no_mirrors = false;
  bool no_aovs = false;
  int spp = 0;
  app.add_flag("--no-specialise", no_specialise,
               "full mode: the general tile kernel instead of the one specialised to the scene's features");
  app.add_flag("--no-skip-empty", no_skip_empty, "full mode: trace primary rays that miss the scene's bounds too");
  std::string shadow_order_text = "auto";
  app.add_option("--shadow-order", shadow_order_text,
                 "the order of shadow rays' kd-tree walks: auto (chosen from the time each order took), near "
                 "(from the ray's origin), far (from the light's end), dense (the denser child first where both are "
                 "entered); the same answers in every order")
      ->check(CLI::IsMember({"auto", "near", "far", "dense"}))
      ->capture_default_str();
  std::string ab_shadow_order_text;
  app.add_option("--ab-shadow-order", ab_shadow_order_text,
                 "shadow mode: also time the packets in this shadow order (with a tally of its own), rep by rep beside "
                 "the first's (paired ratio; the answers must be the same)")
      ->check(CLI::IsMember({"auto", "near", "far", "dense"}));
  app.add_flag("--kernel-ab", kernel_ab,
               "full mode: time the general and the specialised kernel, each with and without empty-space skipping, "
               "interleaved rep by rep, and check that all four give the same pixels");
  int ab_reps = 0;
  app.add_option("--ab-reps", ab_reps, "with --kernel-ab: repetitions of the four (default: --reps)")
      ->check(CLI::Range(1, 1000));
  app.add_flag("--no-lights", no_lights, "scene variant: remove the lights (no shadow rays)");
  app.add_flag("--no-mirrors", no_mirrors, "scene variant: no reflective materials (no mirror rays)");
  app.add_flag("--no-aovs", no_aovs, "full mode: render colour only, no depth and normal channels");
  app.add_option("--spp", spp, "samples per pixel (default: the scene's)")->check(CLI::Range(1, 4096));
  if (const std::optional<int> status = rtc::parse_command_line(app, argc, argv, "rtc-bench")) return *status;
  const rtc::ShadowOrder shadow_order = rtc::parse_shadow_order(shadow_order_text);
  const std::optional<rtc::ShadowOrder> ab_shadow_order =
      ab_shadow_order_text.empty() ? std::nullopt : std::optional(rtc::parse_shadow_order(ab_shadow_order_text));
  rtc::init_logging(log_level);
  rtc::log_freed_memory_policy(freed_memory);
  if (modes.empty()) modes = {"primary", "shadow", "full"};
  const TileShare tile_share = app.count("--tiles") == 0 ? TileShare{} : parse_tile_share(tiles_text);
  if (!tile_share.whole() && !sweep_dir.empty()) {
    throw rtc::Error("--tiles applies to the primary and shadow modes, not to --sweep");
  }
  if (!tile_share.whole() &&
      std::any_of(modes.begin(), modes.end(), [](const std::string& m) { return m != "primary" && m != "shadow"; })) {
    throw rtc::Error("--tiles applies to the primary and shadow modes (the full mode renders whole frames): give "
                     "--mode primary and/or --mode shadow");
  }
  if (!kd_build_isa.empty()) kd_options.simd_limit = rtc::parse_isa(kd_build_isa);
  if (!tile_share.whole() && !dump_prefix.empty()) throw rtc::Error("--dump writes whole images: leave out --tiles");
  if (!dump_prefix.empty()) {  // the dump's folder is made (or found wanting) before the scene loads
    const std::filesystem::path folder = std::filesystem::path(dump_prefix).parent_path();
    std::error_code ec;
    if (!folder.empty()) std::filesystem::create_directories(folder, ec);
    if (ec) throw rtc::Error("--dump: cannot make the folder " + folder.string() + ": " + ec.message());
  }
  if (ab_reps == 0) ab_reps = reps;
  // --ab-kd-*: a second tree, built once (untimed), whose rays are timed beside the first's.
  const bool ab_tree =
      ab_leaf_box_saving >= 0.0f || ab_empty_cut >= 0.0f || ab_exact_below >= 0 || ab_binned_root_above >= 0 ||
      ab_footprint >= 0.0f || ab_mask_below >= -1 || ab_max_depth >= 0 || ab_traversal_cost > 0.0f ||
      ab_intersection_cost > 0.0f || ab_empty_bonus >= 0.0f;
  if (ab_tree &&
      std::none_of(modes.begin(), modes.end(), [](const std::string& m) { return m == "primary" || m == "shadow"; })) {
    throw rtc::Error("--ab-kd-* options time primary and shadow rays: give --mode primary or --mode shadow");
  }

  std::filesystem::path path(scene_path);
  auto load = [&] {
    rtc::Scene sc = scene_path.empty() ? rtc::default_scene() : rtc::load_scene(path);
    if (width > 0 || height > 0) rtc::set_resolution(sc, width > 0 ? width : sc.width, height > 0 ? height : sc.height);
    if (!intersector.empty()) {
      sc.settings.intersector = intersector == "watertight" ? rtc::Intersector::Watertight : rtc::Intersector::Wald;
    }
    if (no_lights) {
      sc.lights.clear();
      sc.animation.lights.clear();
    }
    if (no_mirrors) {
      for (rtc::Material& m : sc.materials) m.reflective = false;
    }
    if (spp > 0) sc.settings.spp = spp;
    // The frame timed (the first), checked as rtc-render checks the frames it renders, so that a
    // degenerate camera is named with the file instead of failing inside the first trace.
    rtc::check_cameras(sc, sc.animation.frame_begin, sc.animation.frame_begin,
                       rtc::scene_label(path.string()));
    return sc;
  };
  const int thread_count = threads > 0 ? threads : static_cast<int>(tbb::info::default_concurrency());
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(thread_count));
  std::vector<rtc::Isa> isas;
  if (isa_text == "all" || (isa_text.empty() && compare)) {
    for (const rtc::Isa i : rtc::compiled_isas()) {
      if (rtc::cpu_supports(i)) isas.push_back(i);
    }
  } else {
    isas.push_back(isa_text.empty() ? rtc::best_isa() : rtc::parse_isa(isa_text));
  }
  const rtc::Isa isa = isas.back();
  const rtc::TraceKernels& kernels = rtc::trace_kernels(isa);

  if (!sweep_dir.empty()) {
    rtc::bench::SweepOptions so;
    so.out_dir = sweep_dir;
    so.reps = app.count("--reps") > 0 ? reps : 3;
    so.quick = sweep_quick;
    so.embree_check = !no_embree_check;
    const int bad = rtc::bench::run_sweep(load(), so);
    if (bad > 0) {
      std::fprintf(stderr, "rtc-bench: error: %d sweep outputs held NaN or Inf values (see the table)\n", bad);
      return 3;
    }
    return 0;
  }

  rtc::Timer load_timer;
  rtc::Scene scene = load();
  const double load_ms = load_timer.elapsed_ms();
  const std::string name = scene.name;

  kd_options.clip = rtc::kd_clip_for(scene, rtc::parse_kd_clip(kd_clip_text));
  // Build time: median over the reps (--build-reps when given), like every other figure; without
  // --build-reps, builds go on past the reps until rtc's add up to kMinBuildMs (at most
  // kMaxBuildRounds rounds): 5 builds of a small scene, each right after Embree's builds have
  // evicted its caches, read 1.2x this median on bunny (2 ms at 2 threads: 0.58 against 0.48
  // s/M) and 2-5x on BoxTextured (12 triangles). Builds of 100 ms and more take the reps only. The
  // previous rep's state is freed before the clock starts, on both sides. With --compare-embree
  // rtc's build and Embree's two take turns round by round (time_rounds_ms), so that a slow
  // spell of the machine falls on all three alike; Embree's high-quality build takes part in the
  // first 3 rounds only (seconds each on the largest scenes).
  constexpr double kMinBuildMs = 500.0;
  constexpr int kMaxBuildRounds = 100;
  std::shared_ptr<rtc::FrameState> fs;
  std::unique_ptr<EmbreeScene> embree, embree_hq;
  std::vector<rtc::bench::Contender> builders;
  builders.push_back({[&] {
                        fs = rtc::build_frame_state(scene, scene.animation.frame_begin, scene.settings, kd_options);
                      },
                      [&] {
                        embree.reset();
                        embree_hq.reset();
                        fs.reset();
                      }});
  if (compare) {
    builders.push_back(
        {[&] { embree = std::make_unique<EmbreeScene>(fs->geometry->positions, fs->geometry->triangles); },
         [&] { embree.reset(); }});
    builders.push_back(
        {[&] {
           embree_hq = std::make_unique<EmbreeScene>(fs->geometry->positions, fs->geometry->triangles, false, true);
         },
         [&] { embree_hq.reset(); }, 3});
  }
  const std::vector<std::vector<double>> build_rounds =
      build_reps > 0 ? rtc::bench::time_rounds_ms(build_reps, builders)
                     : rtc::bench::time_rounds_ms(reps, builders, kMinBuildMs, kMaxBuildRounds);
  embree_hq.reset();
  const double build_ms = rtc::bench::median_of(build_rounds[0]);
  const double build_min_ms = *std::min_element(build_rounds[0].begin(), build_rounds[0].end());
  const rtc::KdBuildStats& kd = fs->geometry->single_tree().stats();
  std::shared_ptr<rtc::FrameState> fs_ab;
  // The two trees gave different answers (a tree changes no answer: a hit on a plane goes on
  // into the next leaf, and ties are settled by triangle id): an error, after the figures.
  bool ab_differ = false;
  bool ab_order_differ = false;  // --ab-shadow-order's two orders gave different answers
  rtc::KdBuildOptions ab_options = kd_options;
  if (ab_leaf_box_saving >= 0.0f) ab_options.leaf_box_saving = ab_leaf_box_saving;
  if (ab_empty_cut >= 0.0f) ab_options.empty_cut = ab_empty_cut;
  if (ab_exact_below >= 0) ab_options.exact_below = ab_exact_below;
  if (ab_binned_root_above >= 0) ab_options.binned_root_above = ab_binned_root_above;
  if (ab_footprint >= 0.0f) ab_options.footprint_pixels = ab_footprint;
  if (ab_mask_below >= -1) ab_options.mask_below = ab_mask_below;
  if (ab_max_depth >= 0) ab_options.max_depth = ab_max_depth;
  if (ab_traversal_cost > 0.0f) ab_options.traversal_cost = ab_traversal_cost;
  if (ab_intersection_cost > 0.0f) ab_options.intersection_cost = ab_intersection_cost;
  if (ab_empty_bonus >= 0.0f) ab_options.empty_bonus = ab_empty_bonus;
  if (ab_tree) {
    fs_ab = rtc::build_frame_state(scene, scene.animation.frame_begin, scene.settings, ab_options);
  }
  const std::size_t pixels = static_cast<std::size_t>(fs->width) * static_cast<std::size_t>(fs->height);
  double embree_build_ms = 0.0, embree_build_hq_ms = 0.0, build_vs_embree_hq = 0.0;
  if (compare) {
    embree_build_ms = rtc::bench::median_of(build_rounds[1]);
    embree_build_hq_ms = rtc::bench::median_of(build_rounds[2]);
    build_vs_embree_hq = rtc::bench::paired_ratio(build_rounds[0], build_rounds[2]);
  }

  nlohmann::json base = {{"scene", name},
                         {"threads", thread_count},
                         {"cpu", cpu_model()},
                         {"isa", std::string(rtc::isa_name(isa))},
                         {"intersector", rtc::intersector_name(scene.settings.intersector)},
                         {"shadow_order", rtc::shadow_order_name(shadow_order)},
                         {"width", fs->width},
                         {"height", fs->height},
                         {"triangles", kd.triangles},
                         {"load_ms", load_ms},
                         {"build_ms", build_ms},
                         {"build_min_ms", build_min_ms},
                         {"build_rounds", build_rounds[0].size()},
                         {"kd_nodes", kd.nodes},
                         {"kd_leaves", kd.leaves},
                         {"kd_max_depth", kd.max_depth},
                         {"kd_max_depth_limit", kd_options.max_depth},
                         {"kd_tris_per_leaf", kd.mean_tris_per_leaf},
                         {"kd_sah_cost", kd.sah_cost},
                         {"kd_refs", kd.prim_refs},
                         {"kd_bytes", kd.bytes},
                         {"kd_clip", kd_options.clip},
                         {"kd_build_isa_limit", std::string(rtc::isa_name(kd_options.simd_limit))},
                         {"kd_traversal_cost", kd_options.traversal_cost},
                         {"kd_footprint", kd_options.footprint_pixels},
                         {"kd_footprint_max_refs", kd_options.footprint_max_refs},
                         {"kd_intersection_cost", kd_options.intersection_cost},
                         {"kd_mask_below", kd_options.effective_mask_below()},
                         {"kd_empty_cut", kd_options.empty_cut},
                         {"kd_empty_bonus", kd_options.empty_bonus},
                         {"kd_exact_below", kd_options.exact_below},
                         {"kd_binned_root_above", kd_options.binned_root_above},
                         {"kd_blocks", kd.blocks},
                         {"kd_leaf_box_saving", kd_options.leaf_box_saving},
                         {"kd_leaf_boxes", kd.leaf_boxes},
                         {"kd_forks", kd.forks},
                         {"reps", reps}};
  base["tiles"] = {tile_share.from, tile_share.to};
  if (compare) {
    base["embree_build_ms"] = embree_build_ms;
    base["embree_build_hq_ms"] = embree_build_hq_ms;
    // rtc's build time over Embree's high-quality one, paired within each round.
    base["build_vs_embree_hq_paired"] = build_vs_embree_hq;
  }
  if (!json) {
    std::printf("%s: %llu triangles, %dx%d, %d threads, isa %s, intersector %s; load %.0f ms\n", name.c_str(),
                static_cast<unsigned long long>(kd.triangles), fs->width, fs->height, thread_count,
                std::string(rtc::isa_name(isa)).c_str(), rtc::intersector_name(scene.settings.intersector), load_ms);
    std::printf("  build: rtc kd-tree %.1f ms (%s)\n", build_ms, kd.to_string().c_str());
    if (!tile_share.whole()) {
      std::printf("  tiles: %g to %g of the image's 16x16 tiles (in rows from the top), on every side\n",
                  tile_share.from, tile_share.to);
    }
    if (compare) {
      // The ratio is not rtc's median over Embree's: each round times the three builds back to
      // back, and the median of the rounds' own ratios moves far less with a slow spell.
      std::printf("  build: embree BVH %.1f ms (medium quality), %.1f ms (high quality); rtc's time over the high "
                  "quality one %.2fx (the median of the rounds' ratios, each round timing both back to back)\n",
                  embree_build_ms, embree_build_hq_ms, build_vs_embree_hq);
    }
  }

  // Primary rays are needed by the shadow mode too.
  const RayStream primary = primary_stream(*fs, kernels.packet_width, tile_share);
  std::vector<RayHit> hits;
  std::vector<std::uint8_t> unused_occ;
  trace_stream(kernels, *fs, primary, false, true, hits, unused_occ, true);
  const std::vector<RayHit> our_pixels = by_pixel(primary, hits, pixels);
  std::vector<std::size_t> traced;  // --tiles: the pixels of the tiles traced, in order
  if (!tile_share.whole()) {
    if (primary.real == 0) {
      throw rtc::Error(fmt::format("--tiles {}:{} holds none of the image's {} tiles of 16x16 pixels", tile_share.from,
                                   tile_share.to, tile_count(*fs)));
    }
    for (const std::int64_t px : primary.pixel) {
      if (px >= 0) traced.push_back(static_cast<std::size_t>(px));
    }
    std::sort(traced.begin(), traced.end());
  }
  if (!dump_prefix.empty()) write_dump(dump_prefix, *fs, our_pixels);

  for (const std::string& mode : modes) {
    nlohmann::json out = base;
    out["mode"] = mode;
    if (mode == "primary" || mode == "shadow") {
      const bool shadow = mode == "shadow";
      out["warm_up"] = !no_warm_up;  // frames (full) take no warm-up pass
      const RayStream shadows = shadow ? shadow_stream(*fs, primary, hits) : RayStream{};
      const RayStream& s = shadow ? shadows : primary;
      std::vector<std::uint8_t> occ, occ_single;
      std::vector<RayHit> scratch, scratch_single;
      // One tally of the shadow walk orders' times per kernel, kept over the repetitions as a
      // renderer keeps one over its frames.
      rtc::ShadowOrderTally tally_packets, tally_single;
      auto ours = [&](bool packets, bool refine) {
        trace_stream(kernels, *fs, s, shadow, packets, packets ? scratch : scratch_single, packets ? occ : occ_single,
                     refine, shadow_order, packets ? &tally_packets : &tally_single);
      };
      // The other ISAs, each with its own packet shape (the same rays, blocked 2x2 / 4x2 / 4x4).
      struct OtherIsa {
        rtc::Isa isa;
        const rtc::TraceKernels* kernels;
        RayStream stream;
        std::vector<RayHit> hits;
        std::vector<std::uint8_t> occ;
        rtc::ShadowOrderTally tally;
      };
      std::vector<std::unique_ptr<OtherIsa>> others;
      for (const rtc::Isa other : isas) {
        if (other == isa) continue;
        auto o = std::make_unique<OtherIsa>();
        o->isa = other;
        o->kernels = &rtc::trace_kernels(other);
        const RayStream p2 = primary_stream(*fs, o->kernels->packet_width, tile_share);
        trace_stream(*o->kernels, *fs, p2, false, true, o->hits, o->occ, true);
        o->stream = shadow ? shadow_stream(*fs, p2, o->hits) : p2;
        others.push_back(std::move(o));
      }
      // Embree's modes on the same rays: primary rays blocked for each packet width, shadow rays
      // as they are (packets are consecutive rays of one light).
      struct EmbreeRun {
        EmbreeMode mode;
        RayStream stream;
        std::vector<RayHit> hits;
        std::vector<std::uint8_t> occ;
      };
      std::vector<EmbreeRun> embree_runs;
      if (compare) {
        for (EmbreeMode em : kEmbreeModes) {
          if (!embree->supports(em)) continue;
          EmbreeRun e{em, shadow ? shadows : primary_stream(*fs, static_cast<int>(em), tile_share), {}, {}};
          e.stream.width = static_cast<int>(em);
          e.hits.resize(e.stream.rays.size());
          e.occ.resize(e.stream.rays.size());
          embree_runs.push_back(std::move(e));
        }
      }

      // Every contender takes one turn per round (time_rounds_ms): rtc's packets, its single
      // rays, its primary hits with refined distances, its other ISAs, Embree's modes.
      std::vector<rtc::bench::Contender> contenders;
      contenders.push_back({[&] { ours(true, false); }});
      contenders.push_back({[&] { ours(false, false); }});
      const std::size_t first_other = shadow ? 2 : 3;
      if (!shadow) contenders.push_back({[&] { ours(true, true); }});
      for (const auto& o : others) {
        OtherIsa* x = o.get();
        contenders.push_back({[&, x] {
          trace_stream(*x->kernels, *fs, x->stream, shadow, true, x->hits, x->occ, false, shadow_order, &x->tally);
        }});
      }
      const std::size_t first_embree = contenders.size();
      for (EmbreeRun& e : embree_runs) {
        EmbreeRun* x = &e;
        contenders.push_back({[&, x] {
          tbb::parallel_for(std::size_t{0}, x->stream.chunk_begin.size() - 1, [&](std::size_t c) {
            const std::size_t first = x->stream.chunk_begin[c], n = x->stream.chunk_begin[c + 1] - first;
            if (shadow) {
              embree->occluded(x->stream.rays.data() + first, x->occ.data() + first, n, x->mode);
            } else {
              embree->intersect(x->stream.rays.data() + first, x->hits.data() + first, n, x->mode);
            }
          });
        }});
      }
      // --ab-kd-*: the second tree's packets and single rays, last.
      const std::size_t first_ab = contenders.size();
      std::vector<RayHit> hits_ab, hits_ab_single;
      std::vector<std::uint8_t> occ_ab, occ_ab_single;
      rtc::ShadowOrderTally tally_ab, tally_ab_single;
      if (fs_ab) {
        contenders.push_back({[&] {
          trace_stream(kernels, *fs_ab, s, shadow, true, hits_ab, occ_ab, false, shadow_order, &tally_ab);
        }});
        contenders.push_back({[&] {
          trace_stream(kernels, *fs_ab, s, shadow, false, hits_ab_single, occ_ab_single, false, shadow_order,
                       &tally_ab_single);
        }});
      }
      // --ab-shadow-order: the packets again in another order, last.
      const std::size_t ab_order_index = contenders.size();
      std::vector<std::uint8_t> occ_ab_order;
      std::vector<RayHit> scratch_ab_order;
      rtc::ShadowOrderTally tally_ab_order;
      if (shadow && ab_shadow_order) {
        contenders.push_back({[&] {
          trace_stream(kernels, *fs, s, true, true, scratch_ab_order, occ_ab_order, false, *ab_shadow_order,
                       &tally_ab_order);
        }});
      }
      // Each contender's timed pass follows an untimed pass of its own, so that every one is
      // timed with its own structure in the caches, as in a renderer tracing frame after frame.
      // Without it a contender starts with the caches of the one before: Embree's 4-, 8- and
      // 16-wide modes those of another Embree mode over the same BVH, rtc's packets those of
      // Embree-16. That cost rtc's packets 3-7% against Embree-16 on spd-balls at 2 threads
      // (tests/bench/results/trace_experiments.md, session 43).
      if (!no_warm_up) {
        for (rtc::bench::Contender& c : contenders) c.untimed = c.fn;
      }
      const std::vector<std::vector<double>> times = rtc::bench::time_rounds_ms(reps, contenders);
      const double ms_packet = rtc::bench::median_of(times[0]);
      if (shadow && ab_shadow_order) {
        std::uint64_t differ = 0;
        for (std::size_t i = 0; i < s.rays.size(); ++i) {
          if (s.pixel[i] >= 0) differ += (occ[i] != 0) != (occ_ab_order[i] != 0);
        }
        const double ratio = rtc::bench::paired_ratio(times[0], times[ab_order_index]);
        const double mrays = static_cast<double>(s.real) / rtc::bench::median_of(times[ab_order_index]) / 1e3;
        out["ab_shadow_order"] = {{"order", rtc::shadow_order_name(*ab_shadow_order)},
                                  {"mrays_per_s", mrays},
                                  {"speed_vs_first_paired", ratio},
                                  {"answers_differ", differ}};
        ab_order_differ = ab_order_differ || differ != 0;
        if (!json) {
          std::printf("  %-7s packets in shadow order %s: %.2f M rays/s (%.3fx the %s order's, paired)%s\n",
                      mode.c_str(), rtc::shadow_order_name(*ab_shadow_order), mrays, ratio,
                      rtc::shadow_order_name(shadow_order), differ != 0 ? ", ANSWERS DIFFER" : "");
        }
      }
      const double ms_single = rtc::bench::median_of(times[1]);
      if (fs_ab) {
        // The same answers from both trees, bit for bit, else the comparison is void. (The
        // refined pass shares `scratch`: the packets' own hits again first.)
        ours(true, false);
        std::uint64_t differ = 0;
        for (std::size_t i = 0; i < s.rays.size(); ++i) {
          if (s.pixel[i] < 0) continue;
          if (shadow) {
            differ += (occ[i] != 0) != (occ_ab[i] != 0) || (occ_single[i] != 0) != (occ_ab_single[i] != 0);
          } else {
            // A miss has no distance or weights to compare.
            const RayHit& a = scratch[i];
            for (const RayHit* b : {&hits_ab[i], &scratch_single[i], &hits_ab_single[i]}) {
              differ += a.prim != b->prim ||
                        (a.prim != rtc::kNoHit &&
                         (std::bit_cast<std::uint32_t>(a.t) != std::bit_cast<std::uint32_t>(b->t) ||
                          std::bit_cast<std::uint32_t>(a.beta) != std::bit_cast<std::uint32_t>(b->beta) ||
                          std::bit_cast<std::uint32_t>(a.gamma) != std::bit_cast<std::uint32_t>(b->gamma)));
            }
          }
        }
        const rtc::KdBuildStats& kd_ab = fs_ab->geometry->single_tree().stats();
        const double rays = static_cast<double>(s.real);
        // Speed of the second tree over the first's, paired round by round (time a / time b).
        const double packet_ratio = rtc::bench::paired_ratio(times[0], times[first_ab]);
        const double single_ratio = rtc::bench::paired_ratio(times[1], times[first_ab + 1]);
        const double mrays = rays / rtc::bench::median_of(times[first_ab]) / 1e3;
        const double mrays_single = rays / rtc::bench::median_of(times[first_ab + 1]) / 1e3;
        out["ab"] = {{"kd_leaf_box_saving", ab_options.leaf_box_saving},
                     {"kd_empty_cut", ab_options.empty_cut},
                     {"kd_exact_below", ab_options.exact_below},
                     {"kd_binned_root_above", ab_options.binned_root_above},
                     {"kd_blocks", kd_ab.blocks},
                     {"kd_footprint", ab_options.footprint_pixels},
                     {"kd_mask_below", ab_options.effective_mask_below()},
                     {"kd_max_depth_limit", ab_options.max_depth},
                     {"kd_traversal_cost", ab_options.traversal_cost},
                     {"kd_intersection_cost", ab_options.intersection_cost},
                     {"kd_empty_bonus", ab_options.empty_bonus},
                     {"kd_nodes", kd_ab.nodes},
                     {"kd_max_depth", kd_ab.max_depth},
                     {"kd_tris_per_leaf", kd_ab.mean_tris_per_leaf},
                     {"build_ms", kd_ab.build_ms},
                     {"kd_sah_cost", kd_ab.sah_cost},
                     {"kd_leaf_boxes", kd_ab.leaf_boxes},
                     {"mrays_per_s", mrays},
                     {"mrays_per_s_single", mrays_single},
                     {"speed_vs_first_paired", packet_ratio},
                     {"speed_vs_first_single_paired", single_ratio},
                     {"answers_differ", differ}};
        ab_differ = ab_differ || differ != 0;
        if (!json) {
          std::printf("  %-7s tree with --kd-leaf-box-saving %g --kd-empty-cut %g --kd-exact-below %d "
                      "--kd-binned-root-above %d --kd-footprint %g "
                      "--kd-mask-below %d --kd-max-depth %d (%llu nodes, depth %d, %.2f triangles per non-empty "
                      "leaf): packets %.2f M rays/s (%.3fx the first tree's, paired), single rays %.2f "
                      "(%.3fx)%s\n",
                      mode.c_str(), static_cast<double>(ab_options.leaf_box_saving),
                      static_cast<double>(ab_options.empty_cut), ab_options.exact_below, ab_options.binned_root_above,
                      static_cast<double>(ab_options.footprint_pixels), ab_options.effective_mask_below(),
                      ab_options.max_depth, static_cast<unsigned long long>(kd_ab.nodes), kd_ab.max_depth,
                      kd_ab.mean_tris_per_leaf, mrays,
                      packet_ratio, mrays_single, single_ratio, differ != 0 ? ", ANSWERS DIFFER" : "");
        }
      }

      if constexpr (rtc::kWalkStats) {
        // Stats builds: the walks' counts over `reps` passes of each kernel, outside the timing,
        // and the distinct lines of the tree that one pass of each reads (its footprint).
        const rtc::KdTree& tree = fs->geometry->single_tree();
        const auto track = [&] {
          rtc::track_walk_footprint(tree.nodes().data(), tree.nodes().size_bytes(), tree.leaf_records().data(),
                                    tree.leaf_records().size_bytes());
        };
        rtc::reset_walk_stats();
        track();
        for (int r = 0; r < reps; ++r) ours(true, false);
        const rtc::WalkFootprint packet_footprint = rtc::walk_footprint();
        // A packet pass walks packets and, for octant groups of one lane, single rays.
        const rtc::WalkStats packet_walks = rtc::walk_stats(true, shadow);
        const rtc::WalkStats lone_walks = rtc::walk_stats(false, shadow);
        rtc::reset_walk_stats();
        track();
        for (int r = 0; r < reps; ++r) ours(false, false);
        const rtc::WalkFootprint single_footprint = rtc::walk_footprint();
        rtc::stop_walk_footprint();
        const rtc::WalkStats single_walks = rtc::walk_stats(false, shadow);
        const auto footprint_json = [](const rtc::WalkFootprint& f) {
          return nlohmann::json{{"node_lines", f.node_lines}, {"record_lines", f.record_lines}};
        };
        out["footprint_packets"] = footprint_json(packet_footprint);
        out["footprint_single"] = footprint_json(single_footprint);
        out["walks_packets"] = walk_json(packet_walks);
        out["walks_packet_lone_lanes"] = walk_json(lone_walks);
        out["walks_single"] = walk_json(single_walks);
        if (!json) {
          std::printf("  %-7s walks of %d-wide packets: %s\n", mode.c_str(), kernels.packet_width,
                      packet_walks.to_string().c_str());
          std::printf("          lone lanes of those: %s\n          single rays: %s\n", lone_walks.to_string().c_str(),
                      single_walks.to_string().c_str());
          std::printf("          footprint (distinct lines of the tree read): packets %.2f MB of nodes, %.2f MB of "
                      "leaf slots; single rays %.2f MB, %.2f MB\n",
                      packet_footprint.node_mb(), packet_footprint.record_mb(), single_footprint.node_mb(),
                      single_footprint.record_mb());
        }
      }
      const double rays = static_cast<double>(s.real);
      out["rays"] = s.real;
      out["frame_ms"] = ms_packet;
      out["mrays_per_s"] = rays / ms_packet / 1e3;
      out["mrays_per_s_single"] = rays / ms_single / 1e3;
      if (!json) {
        std::printf("  %-7s rtc %d-wide packets: %8.2f M rays/s (%.1f ms for %llu rays); single rays: %.2f M rays/s\n",
                    mode.c_str(), kernels.packet_width, rays / ms_packet / 1e3, ms_packet,
                    static_cast<unsigned long long>(s.real), rays / ms_single / 1e3);
      }
      if (shadow && shadow_order == rtc::ShadowOrder::Auto) {
        // What auto's tally of the packets' walks learnt over all repetitions: the time stamp
        // counter's ticks per timed ray in each order, and the order it settled on.
        nlohmann::json walks = nlohmann::json::object();
        std::string line;
        for (int w = 0; w < rtc::kShadowWalks; ++w) {
          const rtc::ShadowOrder order = rtc::shadow_order_of(static_cast<rtc::ShadowWalk>(w));
          const std::uint64_t n = tally_packets.rays[w].load(), t = tally_packets.ticks[w].load();
          const double per_ray = n > 0 ? static_cast<double>(t) / static_cast<double>(n) : 0.0;
          walks[rtc::shadow_order_name(order)] = {{"timed_rays", n}, {"ticks_per_ray", per_ray}};
          line += fmt::format("{}{} {:.0f} ticks per ray ({} timed rays)", w > 0 ? ", " : "",
                              rtc::shadow_order_name(order), per_ray, n);
        }
        // No preference yet (no shadow rays, or too few for auto to settle): "none".
        const std::uint8_t p = tally_packets.preferred.load();
        const char* preferred = p < rtc::ShadowOrderChooser::kAutoWalks.size()
                                    ? rtc::shadow_order_name(rtc::shadow_order_of(rtc::ShadowOrderChooser::kAutoWalks[p]))
                                    : "none";
        walks["preferred"] = preferred;
        out["shadow_walks"] = walks;
        if (!json) std::printf("          auto's packet walks: %s; settled on %s\n", line.c_str(), preferred);
      }
      if (!shadow) {
        // Primary hits with their distances refined too, as rtc's stream API reports them (the
        // headline figure up to 2026-11-22).
        const double ms_refined = rtc::bench::median_of(times[2]);
        out["mrays_per_s_refined"] = rays / ms_refined / 1e3;
        if (!json) {
          std::printf("          with distances refined in double: %.2f M rays/s (%.1f ms)\n", rays / ms_refined / 1e3,
                      ms_refined);
        }
      }
      nlohmann::json per_isa = nlohmann::json::object();
      per_isa[std::string(rtc::isa_name(isa))] = {{"packet_width", kernels.packet_width}, {"mrays_per_s", rays / ms_packet / 1e3}};
      for (std::size_t i = 0; i < others.size(); ++i) {
        const OtherIsa& o = *others[i];
        const double ms2 = rtc::bench::median_of(times[first_other + i]);
        const double m2 = static_cast<double>(o.stream.real) / ms2 / 1e3;
        per_isa[std::string(rtc::isa_name(o.isa))] = {{"packet_width", o.kernels->packet_width}, {"mrays_per_s", m2}};
        if (!json) {
          std::printf("          rtc %s %d-wide packets: %8.2f M rays/s (%.1f ms)\n",
                      std::string(rtc::isa_name(o.isa)).c_str(), o.kernels->packet_width, m2, ms2);
        }
      }
      out["isas"] = per_isa;
      if (compare) {
        nlohmann::json emb = nlohmann::json::object();
        double best = 0.0;
        std::size_t best_index = first_embree;
        for (std::size_t i = 0; i < embree_runs.size(); ++i) {
          const EmbreeRun& e = embree_runs[i];
          const RayStream& es = e.stream;
          const double ms = rtc::bench::median_of(times[first_embree + i]);
          const double mrays = rays / ms / 1e3;
          if (mrays > best) {
            best = mrays;
            best_index = first_embree + i;
          }
          nlohmann::json m = {{"mrays_per_s", mrays}, {"frame_ms", ms}};
          if (shadow) {
            std::uint64_t agree = 0, n_real = 0;
            for (std::size_t k = 0; k < es.rays.size(); ++k) {
              if (es.pixel[k] < 0) continue;
              ++n_real;
              agree += (e.occ[k] != 0) == (occ[k] != 0);
            }
            m["occlusion_agreement"] = n_real ? static_cast<double>(agree) / static_cast<double>(n_real) : 1.0;
          } else {
            const std::vector<RayHit> theirs = by_pixel(es, e.hits, pixels);
            const std::vector<RayQuery> pr = rays_by_pixel(es, pixels);
            // With --tiles, only the pixels of the tiles traced (the others hold no ray on either side).
            const rtc::test::HitComparison c =
                tile_share.whole()
                    ? rtc::test::compare_hits(fs->geometry->positions, fs->geometry->triangles, pr, our_pixels, theirs)
                    : rtc::test::compare_hits(fs->geometry->positions, fs->geometry->triangles, at_pixels(pr, traced),
                                              at_pixels(our_pixels, traced), at_pixels(theirs, traced));
            m["hit_miss_agreement"] = c.hit_miss_agreement();
            m["same_triangle"] = c.same_prim;
            m["max_rel_dt"] = c.max_rel_t_same_prim;
            m["ties"] = c.ties;
            m["unexplained"] = c.bad_ties + c.same_prim_t_bad;
            if (!json && e.mode == EmbreeMode::Single) std::printf("          agreement: %s\n", c.summary().c_str());
          }
          emb[EmbreeScene::mode_name(e.mode)] = m;
          if (!json) {
            std::printf("          %-9s: %8.2f M rays/s (%.1f ms)%s\n", EmbreeScene::mode_name(e.mode).c_str(), mrays,
                        ms,
                        shadow ? fmt::format(", occlusion agreement {:.4f}%",
                                             100.0 * m["occlusion_agreement"].get<double>()).c_str()
                               : "");
          }
        }
        // Against Embree's fastest mode: the ratio of the medians, and the median of the ratios
        // of the two times taken in the same round (steadier on a busy machine).
        const double paired = rtc::bench::paired_ratio(times[best_index], times[0]);
        const std::string best_mode = EmbreeScene::mode_name(embree_runs[best_index - first_embree].mode);
        out["embree"] = emb;
        out["embree_best_mrays_per_s"] = best;
        out["embree_best_mode"] = best_mode;
        out["ratio_vs_embree_best"] = (rays / ms_packet / 1e3) / best;
        out["ratio_vs_embree_best_paired"] = paired;
        if (!json) {
          std::printf("          rtc / best Embree (%s): %.2fx (medians), %.2fx (paired by round)\n", best_mode.c_str(),
                      (rays / ms_packet / 1e3) / best, paired);
        }
      }
    } else {
      rtc::RenderOptions ro;
      ro.isa = isa;
      ro.kd = kd_options;
      ro.kd_clip = kd_options.clip ? rtc::KdClip::On : rtc::KdClip::Off;
      ro.aovs = !no_aovs;
      ro.specialise = !no_specialise;
      ro.skip_empty = !no_skip_empty;
      ro.shadow_order = shadow_order;
      // A renderer with its first frame prepared (untimed), and the frame rendered as the contender.
      auto frame_contender = [&](const rtc::RenderOptions& options, rtc::TileRayCounts& frame_counts,
                                 rtc::Image& image) {
        auto renderer = std::make_shared<rtc::Renderer>(scene, options);
        std::shared_ptr<const rtc::FrameState> state = renderer->prepare(scene.animation.frame_begin);
        return rtc::bench::Contender{[renderer, state, &frame_counts, &image] {
          frame_counts = rtc::TileRayCounts{};
          image = renderer->render_frame(*state, 32, nullptr, &frame_counts);
        }};
      };
      // The same renderer and shading code with every ray traced by Embree's packet calls.
      const rtc::ExternalTracer tracer{embree.get(), &embree_intersect, &embree_occluded};
      rtc::RenderOptions eo = ro;
      eo.tracer = &tracer;
      rtc::TileRayCounts counts, ecounts;
      rtc::Image ours, theirs;
      double ms = 0.0, ems = 0.0, frame_paired = 0.0;
      rtc::reset_trace_ticks();  // the tally of this mode's frames (RTC_TRACE_TICKS builds)
      const std::uint64_t tsc_start = rtc::read_tsc();
      rtc::Timer tsc_timer;
      if (kernel_ab) {
        // General and specialised kernels, without and with empty-space skipping, one frame of
        // each in turn per repetition (so slow spells of a busy machine hit all four alike), all
        // on one prepared frame (the renderer's trees), in 32 x 32 tiles as render_frame does.
        struct Config {
          const char* name;
          bool specialise, skip_empty;
          std::vector<double> ms;
          rtc::Image image;
          rtc::TileRayCounts counts;
        };
        Config configs[] = {{"general", false, false, {}, {}, {}},
                            {"specialised", true, false, {}, {}, {}},
                            {"general_skip", false, true, {}, {}, {}},
                            {"specialised_skip", true, true, {}, {}, {}}};
        rtc::Renderer renderer(scene, ro);
        const std::shared_ptr<const rtc::FrameState> state = renderer.prepare(scene.animation.frame_begin);
        const rtc::RenderKernels& tile_kernels = rtc::render_kernels(isa);
        const auto render_with = [&](Config& c) {
          const rtc::FrameState& st = *state;
          constexpr int kTileSize = 32;
          const int tiles_x = (st.width + kTileSize - 1) / kTileSize, tiles_y = (st.height + kTileSize - 1) / kTileSize;
          rtc::Image frame(st.width, st.height, ro.aovs, ro.aovs);
          tbb::enumerable_thread_specific<rtc::TileRayCounts> thread_counts;
          tbb::parallel_for(0, tiles_x * tiles_y, [&](int t) {
            const int x0 = (t % tiles_x) * kTileSize, y0 = (t / tiles_x) * kTileSize;
            const int w = std::min(kTileSize, st.width - x0), h = std::min(kTileSize, st.height - y0);
            rtc::Image tile(w, h, ro.aovs, ro.aovs);
            tile_kernels.render_tile(st, x0, y0, w, h, rtc::TileKernelOptions{ro.packets, c.specialise, c.skip_empty},
                                     tile, thread_counts.local(), nullptr);
            frame.blit(tile, x0, y0);
          });
          c.counts = rtc::TileRayCounts{};
          for (const rtc::TileRayCounts& tc : thread_counts) c.counts += tc;
          c.image = std::move(frame);
        };
        for (int r = 0; r < ab_reps; ++r) {
          for (Config& c : configs) c.ms.push_back(rtc::bench::time_once_ms([&] { render_with(c); }));
        }
        bool same = true;
        for (const Config& c : configs) same = same && rtc::image_hash(c.image) == rtc::image_hash(configs[0].image);
        // Medians of each configuration's times, and medians of its time over the general
        // kernel's in the same repetition (paired, so a slow spell cancels out); of an even
        // --ab-reps the mean of the middle two, as every other figure here (median_of).
        nlohmann::json ab = nlohmann::json::object(), ab_min = nlohmann::json::object(),
                       ab_ratio = nlohmann::json::object(), ab_rep = nlohmann::json::object();
        for (const Config& c : configs) {
          ab_rep[c.name] = c.ms;  // every repetition's time, in order
          ab[c.name] = rtc::bench::median_of(c.ms);
          ab_min[c.name] = *std::min_element(c.ms.begin(), c.ms.end());
          ab_ratio[c.name] = rtc::bench::paired_ratio(c.ms, configs[0].ms);
        }
        out["kernel_ab_reps"] = ab_reps;
        out["kernel_ab_ms"] = ab;
        out["kernel_ab_min_ms"] = ab_min;
        out["kernel_ab_ratio"] = ab_ratio;
        out["kernel_ab_rep_ms"] = ab_rep;
        out["kernel_ab_same_pixels"] = same;
        out["primary_skipped_fraction"] =
            static_cast<double>(configs[3].counts.primary_skipped) / static_cast<double>(configs[3].counts.primary);
        if (!json) {
          std::printf("  full    kernels (median of %d interleaved; paired ratio to general): general %.1f ms, "
                      "specialised %.1f ms (%.3f), general + skip %.1f ms (%.3f), specialised + skip %.1f ms (%.3f); "
                      "%.1f%% of primary rays skipped; pixels %s\n",
                      ab_reps, ab["general"].get<double>(), ab["specialised"].get<double>(),
                      ab_ratio["specialised"].get<double>(), ab["general_skip"].get<double>(),
                      ab_ratio["general_skip"].get<double>(), ab["specialised_skip"].get<double>(),
                      ab_ratio["specialised_skip"].get<double>(), 100.0 * out["primary_skipped_fraction"].get<double>(),
                      same ? "identical" : "DIFFER");
        }
        if (!same) {
          std::fprintf(stderr, "rtc-bench: error: the kernels gave different pixels\n");
          return 4;
        }
        // The figures below are the default configuration's (specialised, skipping).
        const Config& chosen = configs[(ro.specialise ? 1 : 0) + (ro.skip_empty ? 2 : 0)];
        counts = chosen.counts;
        ours = chosen.image;
        ms = ab[chosen.name].get<double>();
        if (compare) {
          ems = rtc::bench::median_of(rtc::bench::time_rounds_ms(reps, {frame_contender(eo, ecounts, theirs)})[0]);
        }
      } else {
        // rtc's frame and the Embree renderer's take turns, round by round.
        std::vector<rtc::bench::Contender> frames = {frame_contender(ro, counts, ours)};
        if (compare) frames.push_back(frame_contender(eo, ecounts, theirs));
        const std::vector<std::vector<double>> times = rtc::bench::time_rounds_ms(reps, frames);
        ms = rtc::bench::median_of(times[0]);
        if (compare) {
          ems = rtc::bench::median_of(times[1]);
          frame_paired = rtc::bench::paired_ratio(times[1], times[0]);
        }
      }
      out["rays"] = counts.total();
      out["primary_rays"] = counts.primary;
      out["primary_skipped"] = counts.primary_skipped;
      out["shadow_rays"] = counts.shadow;
      out["reflection_rays"] = counts.reflection;
      out["reflection_regrouped"] = counts.reflection_regrouped;
      out["frame_ms"] = ms;
      out["mrays_per_s"] = static_cast<double>(counts.total()) / ms / 1e3;
      out["max_depth"] = fs->settings.max_depth;
      out["spp"] = fs->settings.spp;
      out["aovs"] = ro.aovs;
      out["features"] = rtc::describe(fs->features);
      out["kernel"] = rtc::render_kernels(isa).kernel_name(
          *fs, rtc::TileKernelOptions{ro.packets, ro.specialise, ro.skip_empty}, ro.aovs);
      out["specialise"] = ro.specialise;
      out["skip_empty"] = ro.skip_empty;
      if (!json) {
        std::printf("  full    rtc Whitted frame: %.1f ms, %.2f M rays/s (%llu primary, %llu of them skipped as empty "
                    "space, %llu shadow, %llu reflection, %llu of them regrouped; depth %d); features: %s; "
                    "kernel: %s\n",
                    ms, static_cast<double>(counts.total()) / ms / 1e3,
                    static_cast<unsigned long long>(counts.primary), static_cast<unsigned long long>(counts.primary_skipped),
                    static_cast<unsigned long long>(counts.shadow), static_cast<unsigned long long>(counts.reflection),
                    static_cast<unsigned long long>(counts.reflection_regrouped), fs->settings.max_depth,
                    rtc::describe(fs->features).c_str(), out["kernel"].get<std::string>().c_str());
      }
      if (compare) {
        std::uint64_t differ = 0;
        for (std::size_t i = 0; i < ours.rgba.size(); i += 4) {
          for (int k = 0; k < 3; ++k) {
            if (std::fabs(ours.rgba[i + k] - theirs.rgba[i + k]) > 1.0f / 255.0f) {
              ++differ;
              break;
            }
          }
        }
        const double frac = static_cast<double>(differ) / static_cast<double>(ours.rgba.size() / 4);
        out["embree_frame_ms"] = ems;
        out["embree_rays"] = ecounts.total();
        out["ratio_vs_embree_frame"] = ems / ms;
        // Paired by round (0 with --kernel-ab, whose kernels take turns among themselves only).
        out["ratio_vs_embree_frame_paired"] = frame_paired;
        out["embree_frame_pixels_differing"] = frac;
        if (!json) {
          std::printf("          embree renderer (same shading, Embree packet calls of up to %d rays): %.1f ms (%llu rays); "
                      "rtc is %.2fx its speed (medians%s); %.4f%% of pixels differ by more than 1/255\n",
                      kernels.packet_width, ems, static_cast<unsigned long long>(ecounts.total()), ems / ms,
                      frame_paired > 0.0 ? fmt::format("; {:.2f}x paired by round", frame_paired).c_str()
                                         : "; not paired: with --kernel-ab the Embree renderer runs after the kernels",
                      100.0 * frac);
        }
      }
      if (rtc::kTraceTicks && kernel_ab) {
        // rtc's rows would mix four kernels (with and without empty-space skipping) against the
        // Embree renderer's one.
        if (!json) std::printf("          trace calls: not tallied with --kernel-ab\n");
      } else if (rtc::kTraceTicks) {
        // Both sides rendered `reps` frames. The counter's rate, from the frames' own span, turns
        // frame times into ticks (the rest of a frame: its time less its trace calls).
        out["trace_ticks_tsc_ghz"] =
            static_cast<double>(rtc::read_tsc() - tsc_start) / (tsc_timer.elapsed_ms() * 1e6);
        out["trace_ticks"] = trace_ticks_json(rtc::trace_ticks(), kernels.packet_width, static_cast<double>(reps));
        if (!json) print_trace_ticks(out["trace_ticks"], compare);
      }
    }
    if (json) std::printf("%s\n", out.dump().c_str());
  }
  if (ab_order_differ) {
    std::fprintf(stderr, "rtc-bench: error: shadow orders %s and %s gave different answers\n",
                 rtc::shadow_order_name(shadow_order), rtc::shadow_order_name(*ab_shadow_order));
  }
  if (ab_differ) {
    std::fprintf(stderr,
                 "rtc-bench: error: with --kd-leaf-box-saving %g and %g, --kd-empty-cut %g and %g, --kd-exact-below "
                 "%d and %d, --kd-binned-root-above %d and %d, --kd-footprint %g and %g, --kd-mask-below %d and %d, "
                 "--kd-max-depth %d and %d the answers differ (between the trees, or between packets and single "
                 "rays)\n",
                 static_cast<double>(kd_options.leaf_box_saving), static_cast<double>(ab_options.leaf_box_saving),
                 static_cast<double>(kd_options.empty_cut), static_cast<double>(ab_options.empty_cut),
                 kd_options.exact_below, ab_options.exact_below, kd_options.binned_root_above,
                 ab_options.binned_root_above, static_cast<double>(kd_options.footprint_pixels),
                 static_cast<double>(ab_options.footprint_pixels), kd_options.effective_mask_below(),
                 ab_options.effective_mask_below(), kd_options.max_depth, ab_options.max_depth);
  }
  if (ab_differ || ab_order_differ) return 4;
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rtc-bench: error: %s\n", e.what());
    return 1;
  }
}
