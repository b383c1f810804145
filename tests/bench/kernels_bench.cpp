// rtc-micro-bench: Google Benchmark timings of the tracer's pieces on the built-in scene: kd-tree
// build, closest-hit and occlusion rays (4-wide packets against single rays) and one 64x64
// tile render. Speed is reported here, never asserted (not part of ctest).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/accel/kd_tree.h"
#include "common/accel/trace.h"
#include "common/base/isa.h"
#include "common/image/image.h"
#include "common/render/frame_state.h"
#include "common/render/renderer.h"
#include "common/render/shading.h"
#include "common/scene/load.h"

namespace {

constexpr int kFrame = 0;
constexpr int kTileSize = 64;

/// A ray stream in packet order: every `packet_width` consecutive rays are one packet; lanes
/// with nothing to trace repeat a real ray of their packet and are not counted in `real`.
struct RayStream {
  std::vector<rtc::RayQuery> rays;
  std::int64_t real = 0;
};

/// The built-in scene's frame 0, built once and shared by every benchmark.
struct Fixture {
  rtc::Scene scene;
  std::shared_ptr<const rtc::FrameState> state;
  const rtc::TraceKernels* kernels = nullptr;
  RayStream primary;  ///< one ray per pixel in 2x2 pixel blocks (whole packets at width 4 or 8)
  RayStream shadow;   ///< from the primary hits to each light, as the renderer makes them
};

// Primary rays of the CAMERA.md convention, grouped in 2x2 pixel blocks (a 4-wide packet).
RayStream primary_rays(const rtc::FrameState& fs) {
  RayStream s;
  for (int by = 0; by < fs.height; by += 2) {
    for (int bx = 0; bx < fs.width; bx += 2) {
      const std::size_t first = s.rays.size();
      for (int i = 0; i < 4; ++i) {
        const int x = bx + i % 2, y = by + i / 2;
        if (x < fs.width && y < fs.height) {
          const rtc::Ray r = fs.camera_rays.ray(x, y);
          s.rays.push_back(rtc::RayQuery{r.origin, 0.0f, r.dir, std::numeric_limits<float>::infinity()});
          ++s.real;
        } else {
          s.rays.push_back(s.rays[first]);
        }
      }
    }
  }
  return s;
}

// Shadow rays from each 2x2 block's hits to one light at a time, with rtc's own surface and
// shadow-ray code (common/render/shading.h): the occlusion queries a frame really makes.
RayStream shadow_rays(const rtc::FrameState& fs, const RayStream& primary, const std::vector<rtc::RayHit>& hits) {
  RayStream s;
  for (const rtc::PointLight& light : fs.lights) {
    for (std::size_t b = 0; b < primary.rays.size(); b += 4) {
      std::optional<rtc::RayQuery> lanes[4];
      int first_real = -1;
      for (int i = 0; i < 4; ++i) {
        const std::size_t k = b + static_cast<std::size_t>(i);
        if (hits[k].prim == rtc::kNoHit) continue;
        const rtc::SurfaceSample surface =
            rtc::surface_at(fs, primary.rays[k].dir, hits[k].prim, hits[k].beta, hits[k].gamma);
        if (const std::optional<rtc::ShadowRay> ray = rtc::shadow_ray(surface, light)) {
          lanes[i] = ray->ray;
          if (first_real < 0) first_real = i;
        }
      }
      if (first_real < 0) continue;
      for (const std::optional<rtc::RayQuery>& lane : lanes) {
        s.rays.push_back(lane.value_or(*lanes[first_real]));
        s.real += lane.has_value() ? 1 : 0;
      }
    }
  }
  return s;
}

const Fixture& fixture() {
  static const Fixture f = [] {
    Fixture out;
    out.scene = rtc::default_scene();
    out.state = rtc::build_frame_state(out.scene, kFrame, out.scene.settings, rtc::KdBuildOptions{});
    out.kernels = &rtc::trace_kernels();
    out.primary = primary_rays(*out.state);
    std::vector<rtc::RayHit> hits(out.primary.rays.size());
    out.kernels->intersect(out.state->geometry->single_tree(), out.primary.rays.data(), hits.data(), hits.size(), true);
    out.shadow = shadow_rays(*out.state, out.primary, hits);
    return out;
  }();
  return f;
}

// "sse4.2, 4-wide" or "sse4.2, single rays": which kernels the figure is for.
void add_context(benchmark::State& state, const Fixture& f, bool packets) {
  state.SetLabel(std::string(rtc::isa_name(f.kernels->isa)) +
                 (packets ? ", " + std::to_string(f.kernels->packet_width) + "-wide" : ", single rays"));
}

// state.range(0): build threads (0: all cores). Items are triangles.
void BM_KdTreeBuild(benchmark::State& state) {
  const Fixture& f = fixture();
  const rtc::FrameGeometry& g = *f.state->geometry;
  rtc::KdBuildOptions options;
  options.threads = static_cast<int>(state.range(0));
  for (auto _ : state) {
    rtc::KdTree tree = rtc::KdTree::build(g.positions, g.triangles, options);
    benchmark::DoNotOptimize(tree.nodes().data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(g.triangles.size()));
  state.counters["nodes"] = static_cast<double>(g.single_tree().stats().nodes);
}
BENCHMARK(BM_KdTreeBuild)->ArgName("threads")->Arg(1)->Arg(0)->Unit(benchmark::kMillisecond)->UseRealTime();

// Flattening the scene to world space plus the build: what Renderer::prepare costs per frame
// when a mesh moved.
void BM_FrameStateBuild(benchmark::State& state) {
  const Fixture& f = fixture();
  for (auto _ : state) {
    std::shared_ptr<rtc::FrameState> fs =
        rtc::build_frame_state(f.scene, kFrame, f.scene.settings, rtc::KdBuildOptions{});
    benchmark::DoNotOptimize(fs.get());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(f.scene.triangle_count()));
}
BENCHMARK(BM_FrameStateBuild)->Unit(benchmark::kMillisecond)->UseRealTime();

// Closest hit of every primary ray of the frame on one thread. Items are rays.
void BM_ClosestHit(benchmark::State& state, bool packets) {
  const Fixture& f = fixture();
  add_context(state, f, packets);
  std::vector<rtc::RayHit> hits(f.primary.rays.size());
  for (auto _ : state) {
    f.kernels->intersect(f.state->geometry->single_tree(), f.primary.rays.data(), hits.data(), hits.size(), packets);
    benchmark::DoNotOptimize(hits.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * f.primary.real);
}
BENCHMARK_CAPTURE(BM_ClosestHit, packets, true)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_ClosestHit, single, false)->Unit(benchmark::kMillisecond);

// Occlusion (any hit, t in (0, 1)) of the frame's shadow rays on one thread. Items are rays.
void BM_Occluded(benchmark::State& state, bool packets) {
  const Fixture& f = fixture();
  add_context(state, f, packets);
  std::vector<std::uint8_t> occluded(f.shadow.rays.size());
  for (auto _ : state) {
    f.kernels->occluded(f.state->geometry->single_tree(), f.shadow.rays.data(), occluded.data(), occluded.size(),
                        packets);
    benchmark::DoNotOptimize(occluded.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * f.shadow.real);
}
BENCHMARK_CAPTURE(BM_Occluded, packets, true)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Occluded, single, false)->Unit(benchmark::kMillisecond);

// One 64x64 tile from the middle of the frame, fully shaded (Whitted: primary, shadow and
// reflection rays), on one thread. Items are all rays traced.
void BM_RenderTile(benchmark::State& state, bool packets) {
  const Fixture& f = fixture();
  add_context(state, f, packets);
  rtc::RenderOptions options;
  options.packets = packets;
  const rtc::Renderer renderer(f.scene, options);
  const int x0 = (f.state->width - kTileSize) / 2, y0 = (f.state->height - kTileSize) / 2;
  rtc::Image tile(kTileSize, kTileSize, true, true);
  rtc::TileRayCounts counts;
  for (auto _ : state) {
    renderer.render_tile(*f.state, x0, y0, kTileSize, kTileSize, tile, &counts);
    benchmark::DoNotOptimize(tile.rgba.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(counts.total()));
  state.counters["rays_per_tile"] =
      static_cast<double>(counts.total()) / static_cast<double>(std::max<std::int64_t>(state.iterations(), 1));
}
BENCHMARK_CAPTURE(BM_RenderTile, packets, true)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_RenderTile, single, false)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
