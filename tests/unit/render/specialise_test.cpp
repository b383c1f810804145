// Kernels specialised to a frame's features and empty-space skipping (issue 7, parts 1 and 2):
// the same bits as the general kernel tracing every ray, on scenes covering each feature
// combination and views that look partly or wholly past the geometry, at every ISA this CPU
// runs, with packets and single rays; the features found; the rays skipped; temporal marks
// unchanged by skipping.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <iterator>
#include <limits>
#include <memory>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <tbb/global_control.h>

#include "common/image/image.h"
#include "common/math/det_math.h"
#include "common/math/frustum_cull.h"
#include "common/render/render_kernels.h"
#include "common/render/renderer.h"
#include "common/render/temporal.h"
#include "common/scene/load.h"

namespace rtc {
namespace {

Scene small_default() {
  Scene s = default_scene();
  s.width = 96;
  s.height = 72;
  return s;
}

Scene without_lights(Scene s) {
  s.lights.clear();
  s.animation.lights.clear();
  return s;
}

Scene without_mirrors(Scene s) {
  for (Material& m : s.materials) m.reflective = false;
  return s;
}

Scene looking_at(Scene s, glm::vec3 eye, glm::vec3 look_at) {
  s.camera.eye = eye;
  s.camera.look_at = look_at;
  return s;
}

struct Variant {
  std::string name;
  Scene scene;
  bool aovs = true;
};

// Every feature combination the kernels are specialised to, and views partly or wholly past
// the scene's bounds (with the eye beside the bounds, so some corners lie behind it, and far
// away in front of them).
std::vector<Variant> variants() {
  const Scene base = small_default();
  Scene spp2 = base;
  spp2.settings.spp = 2;
  Scene neither_spp3 = without_lights(without_mirrors(base));
  neither_spp3.settings.spp = 3;
  Scene no_depth = base;
  no_depth.settings.max_depth = 0;  // mirrors that spawn no rays
  return {
      {"default", base, true},
      {"default_no_aovs", base, false},
      {"no_lights", without_lights(base), true},
      {"no_mirrors", without_mirrors(base), true},
      {"no_mirrors_no_aovs", without_mirrors(base), false},
      {"neither", without_lights(without_mirrors(base)), true},
      {"neither_no_aovs", without_lights(without_mirrors(base)), false},
      {"neither_spp3", neither_spp3, true},
      {"max_depth_0_no_lights", without_lights(no_depth), true},
      {"spp2", spp2, true},
      {"half_sky", looking_at(base, {0.0f, 3.4f, 9.0f}, {0.0f, 3.4f, 0.0f}), true},
      {"half_sky_neither_spp3", looking_at(neither_spp3, {0.0f, 3.4f, 9.0f}, {0.0f, 3.4f, 0.0f}), true},
      {"far_half_sky", looking_at(spp2, {0.0f, 6.0f, 30.0f}, {5.0f, 6.0f, 0.0f}), true},
      {"all_sky", looking_at(base, {0.0f, 3.4f, 9.0f}, {0.0f, 3.4f, 20.0f}), true},
      {"all_sky_neither_no_aovs", looking_at(without_lights(without_mirrors(base)), {0.0f, 3.4f, 9.0f},
                                             {0.0f, 3.4f, 20.0f}),
       false},
  };
}

struct Rendered {
  std::string hash;
  TileRayCounts counts;
};

// The frame in tiles through the kernels of `isa` directly, one thread: one FrameState serves
// every kernel choice.
Rendered render(const FrameState& fs, Isa isa, const TileKernelOptions& k, bool aovs, int tile) {
  Image frame(fs.width, fs.height, aovs, aovs);
  Rendered out;
  for (int y0 = 0; y0 < fs.height; y0 += tile) {
    for (int x0 = 0; x0 < fs.width; x0 += tile) {
      const int w = std::min(tile, fs.width - x0), h = std::min(tile, fs.height - y0);
      Image t(w, h, aovs, aovs);
      render_kernels(isa).render_tile(fs, x0, y0, w, h, k, t, out.counts, nullptr);
      frame.blit(t, x0, y0);
    }
  }
  out.hash = image_hash(frame);
  return out;
}

// Through Renderer (RenderOptions reach the kernels; a tree for the static meshes and one per
// moving mesh, so frame_bounds is a union).
Rendered render(const Variant& v, bool packets, bool specialise, bool skip_empty, int frame = 0) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
  RenderOptions o;
  o.packets = packets;
  o.aovs = v.aovs;
  o.specialise = specialise;
  o.skip_empty = skip_empty;
  Renderer r(v.scene, o);
  const auto fs = r.prepare(frame);
  Rendered out;
  out.hash = image_hash(r.render_frame(*fs, 16, nullptr, &out.counts));
  return out;
}

TEST(Specialise, FeaturesFoundOncePerFrame) {
  const Scene base = small_default();
  const auto features = [](const Scene& s) { return Renderer(s).prepare(0)->features; };
  const FrameFeatures all = features(base);
  EXPECT_TRUE(all.lights && all.reflections && all.highlights && all.background && all.ambient && all.single_sample);
  EXPECT_FALSE(features(without_lights(base)).lights);
  EXPECT_FALSE(features(without_mirrors(base)).reflections);
  EXPECT_TRUE(features(without_mirrors(base)).highlights);  // red plastic, and the former mirrors
  Scene shallow = base;
  shallow.settings.max_depth = 0;
  EXPECT_FALSE(features(shallow).reflections);
  Scene weak = base;
  weak.settings.min_weight = 0.95f;  // above every mirror's max3(specular)
  EXPECT_FALSE(features(weak).reflections);
  Scene dark = base;
  dark.background = glm::vec3(0.0f);
  dark.ambient = glm::vec3(0.0f);
  dark.settings.spp = 4;
  const FrameFeatures d = features(dark);
  EXPECT_FALSE(d.background || d.ambient || d.single_sample);
  EXPECT_EQ(describe(features(without_lights(without_mirrors(dark)))), "highlights");

  // The kernel each gets.
  const auto kernel = [](const Scene& s, bool specialise, bool aovs) {
    const auto fs = build_frame_state(s, 0, s.settings, KdBuildOptions{});
    return std::string(render_kernels(best_isa()).kernel_name(*fs, TileKernelOptions{true, specialise, true}, aovs));
  };
  const Scene neither = without_lights(without_mirrors(base));
  EXPECT_EQ(kernel(neither, true, true), "ray-cast+aovs");
  EXPECT_EQ(kernel(neither, true, false), "ray-cast");
  EXPECT_EQ(kernel(neither, false, false), "general");
  EXPECT_EQ(kernel(without_lights(shallow), true, true), "ray-cast+aovs");
  EXPECT_EQ(kernel(base, true, true), "general");
  EXPECT_EQ(kernel(without_lights(base), true, false), "general");
  EXPECT_EQ(kernel(without_mirrors(base), true, true), "no-mirror+aovs");
  EXPECT_EQ(kernel(without_mirrors(base), true, false), "no-mirror");
  EXPECT_EQ(kernel(without_mirrors(base), false, false), "general");
  EXPECT_EQ(kernel(shallow, true, false), "no-mirror");  // no reflection ray can be traced

  // A frame that reuses the last one's geometry (the camera moved) is analysed again.
  Scene moving = without_mirrors(base);
  moving.animation.meshes.clear();
  moving.animation.frame_end = 1;
  Camera away = moving.camera;
  away.look_at = {0.0f, 3.4f, 20.0f};
  away.eye = {0.0f, 3.4f, 9.0f};
  moving.animation.camera = {CameraKey{0, moving.camera}, CameraKey{1, away}};
  Renderer r(moving);
  const auto first = r.prepare(0);
  const auto second = r.prepare(1);
  ASSERT_EQ(first->geometry.get(), second->geometry.get());
  EXPECT_FALSE(first->cull.misses(0, 0, moving.width, moving.height));
  EXPECT_TRUE(second->cull.misses(0, 0, moving.width, moving.height));
}

TEST(Specialise, SamePixelsAsTheGeneralKernelAtEveryIsaWithAndWithoutSkipping) {
  for (const Variant& v : variants()) {
    const auto fs = build_frame_state(v.scene, 0, v.scene.settings, KdBuildOptions{});
    const Rendered reference = render(*fs, Isa::Sse42, TileKernelOptions{false, false, false}, v.aovs, 32);
    EXPECT_EQ(reference.counts.primary_skipped, 0u) << v.name;
    for (const Isa isa : compiled_isas()) {
      if (!cpu_supports(isa)) {
        std::printf("%s: this CPU lacks %s, not tried\n", v.name.c_str(), std::string(isa_name(isa)).c_str());
        continue;
      }
      for (const bool packets : {true, false}) {
        // Tiles of 13 leave partial packets at their edges.
        for (const TileKernelOptions k : {TileKernelOptions{packets, false, false}, TileKernelOptions{packets, true, false},
                                          TileKernelOptions{packets, false, true}, TileKernelOptions{packets, true, true}}) {
          const Rendered got = render(*fs, isa, k, v.aovs, 13);
          EXPECT_EQ(got.hash, reference.hash) << v.name << ", " << isa_name(isa) << ", packets " << packets
                                              << ", specialise " << k.specialise << ", skip " << k.skip_empty;
          EXPECT_EQ(got.counts.primary, reference.counts.primary) << v.name;
          EXPECT_EQ(got.counts.shadow, reference.counts.shadow) << v.name;
          EXPECT_EQ(got.counts.reflection, reference.counts.reflection) << v.name;
          if (!k.skip_empty) {
            EXPECT_EQ(got.counts.primary_skipped, 0u) << v.name;
          }
        }
      }
    }
  }
}

// Shadow rays' kd-tree walks from the ray's origin, from the light's end, or as a tally of the
// packets' times picks per run (ShadowOrder): the same pixels. Tiles of 13 make short runs, so
// Auto's runs alternate between the orders at first; its tally must show both were traced.
TEST(Specialise, SamePixelsInEveryShadowOrder) {
  int with_lights = 0;
  for (const Variant& v : variants()) {
    if (v.scene.lights.empty()) continue;
    ++with_lights;
    const auto fs = build_frame_state(v.scene, 0, v.scene.settings, KdBuildOptions{});
    const Rendered reference = render(*fs, Isa::Sse42, TileKernelOptions{false, false, false}, v.aovs, 32);
    for (const Isa isa : compiled_isas()) {
      if (!cpu_supports(isa)) continue;
      for (const bool packets : {true, false}) {
        for (const ShadowOrder order : {ShadowOrder::Near, ShadowOrder::Far, ShadowOrder::Dense, ShadowOrder::Auto}) {
          const std::size_t count = 2 * fs->lights.size();
          const auto tally = std::make_unique<ShadowOrderTally[]>(count);
          const Rendered got = render(*fs, isa, TileKernelOptions{packets, true, true, order, tally.get(), count},
                                      v.aovs, 13);
          EXPECT_EQ(got.hash, reference.hash) << v.name << ", " << isa_name(isa) << ", packets " << packets
                                              << ", shadow order " << shadow_order_name(order);
          EXPECT_EQ(got.counts.shadow, reference.counts.shadow) << v.name;
          std::uint64_t rays[kShadowWalks] = {0, 0, 0};
          for (std::size_t k = 0; k < count; ++k) {
            for (int w = 0; w < kShadowWalks; ++w) rays[w] += tally[k].rays[w].load();
          }
          if (order == ShadowOrder::Auto && reference.counts.shadow > 0) {  // all_sky: none
            for (const ShadowWalk w : ShadowOrderChooser::kAutoWalks) {
              EXPECT_GT(rays[static_cast<int>(w)], 0u) << v.name << ", walk " << static_cast<int>(w);
            }
            EXPECT_EQ(rays[static_cast<int>(ShadowWalk::Near)], 0u) << v.name;
          } else {
            EXPECT_EQ(std::accumulate(std::begin(rays), std::end(rays), std::uint64_t{0}), 0u) << v.name;
          }
        }
      }
    }
  }
  EXPECT_GT(with_lights, 0);
}

TEST(Specialise, SkipsPrimaryRaysOnlyWhereTheViewMissesTheScene) {
  const auto skipped_fraction = [](const Variant& v, bool packets) {
    const Rendered r = render(v, packets, true, true);
    EXPECT_EQ(r.hash, render(v, packets, false, false).hash) << v.name << ", packets " << packets;
    return static_cast<double>(r.counts.primary_skipped) / static_cast<double>(r.counts.primary);
  };
  for (const Variant& v : variants()) {
    for (const bool packets : {true, false}) {
      const double f = skipped_fraction(v, packets);
      std::printf("%s, packets %d: %.3f of primary rays skipped\n", v.name.c_str(), packets ? 1 : 0, f);
      if (v.name.rfind("all_sky", 0) == 0) {
        EXPECT_EQ(f, 1.0) << v.name;
      } else if (v.name.find("half_sky") != std::string::npos) {
        EXPECT_GT(f, 0.25) << v.name;
        EXPECT_LT(f, 0.75) << v.name;
      } else {
        EXPECT_GT(f, 0.05) << v.name << ": the default view's top rows see only sky";
        EXPECT_LT(f, 0.5) << v.name;
      }
    }
  }
}

/// The variant of that name (by name, not index: the list grows).
Variant variant(const std::string& name) {
  for (Variant& v : variants()) {
    if (v.name == name) return v;
  }
  ADD_FAILURE() << "no variant " << name;
  return variants().front();
}

TEST(Specialise, SamePixelsWhenTheMovingMeshRisesIntoTheSkyTiles) {
  // At frame 12 the gold sphere hops to its highest: the union of the trees' bounds grows.
  const Variant v = variant("half_sky");
  const Rendered low = render(v, true, true, true, 0), high = render(v, true, true, true, 12);
  EXPECT_LT(high.counts.primary_skipped, low.counts.primary_skipped);
  EXPECT_EQ(high.hash, render(v, true, false, false, 12).hash);
  EXPECT_EQ(render(v, false, true, true, 12).hash, high.hash);
}

TEST(Specialise, EmptySceneSkipsEveryRay) {
  Scene s = small_default();
  for (Mesh& m : s.meshes) {
    m.triangles.clear();
    m.material_ids.clear();
    m.source_index.clear();
  }
  s.animation.meshes.clear();
  const Variant v{"empty", s, true};
  const Rendered skipped = render(v, true, true, true);
  EXPECT_EQ(skipped.counts.primary_skipped, skipped.counts.primary);
  EXPECT_EQ(skipped.hash, render(v, true, false, false).hash);
}

// Skipped primary rays are still marked (to infinity) for temporal coherence: a moving mesh may
// enter the space they looked through. Every tile's marks are the same with and without skipping.
TEST(Specialise, SkippedRaysLeaveTheSameTemporalMarks) {
  for (const Variant& v : {variant("default"), variant("half_sky"), variant("far_half_sky")}) {
    const MarkGrid grid = mark_grid_for(v.scene);
    ASSERT_FALSE(grid.empty()) << v.name << ": the default scene's gold sphere moves";
    for (const bool packets : {true, false}) {
      std::vector<TileMarks> marks[2];
      TileRayCounts counts[2];
      for (const bool skip : {false, true}) {
        RenderOptions o;
        o.packets = packets;
        o.skip_empty = skip;
        Renderer r(v.scene, o);
        const auto fs = r.prepare(0);
        MarkRecorder recorder(grid);
        Image tile;
        for (int y0 = 0; y0 < fs->height; y0 += 16) {
          for (int x0 = 0; x0 < fs->width; x0 += 16) {
            r.render_tile(*fs, x0, y0, std::min(16, fs->width - x0), std::min(16, fs->height - y0), tile,
                          &counts[skip], &recorder);
            marks[skip].emplace_back();
            recorder.take(marks[skip].back());
          }
        }
      }
      EXPECT_GT(counts[1].primary_skipped, 0u) << v.name;
      ASSERT_EQ(marks[0].size(), marks[1].size());
      for (std::size_t t = 0; t < marks[0].size(); ++t) {
        EXPECT_EQ(marks[0][t], marks[1][t]) << v.name << ", packets " << packets << ", tile " << t;
      }
    }
  }
}


// The tile kernels compute the Phong highlight's power for a light's lit lanes in one batch,
// eight lanes to a vector of doubles (common/math/det_math_lanes.h). Every lane must get
// det_powf's bits, at every ISA, for any batch length, including the inputs det_powf settles
// early (e = 0, x <= 0, x >= 1, NaN, infinities) and powers below the smallest float.
TEST(HighlightPowers, EveryIsaGivesDetPowfsBits) {
  std::mt19937 rng(41);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::vector<float> x, e;
  const float specials_x[] = {0.0f, -0.0f, -0.5f, 1.0f, 1.5f, 1e-45f, 1e-38f, 0x1.fffffep-1f, 0.5f, 0.70710677f,
                              0.70710683f, std::numeric_limits<float>::quiet_NaN(),
                              std::numeric_limits<float>::infinity()};
  const float specials_e[] = {0.0f, 1e-45f, 1.0f, 2.0f, 10.0f, 64.0f, 128.0f, 1e4f, 1e5f, 3e38f,
                              std::numeric_limits<float>::infinity(), std::numeric_limits<float>::quiet_NaN(),
                              -1.0f};
  for (float a : specials_x) {
    for (float b : specials_e) {
      x.push_back(a);
      e.push_back(b);
    }
  }
  for (int i = 0; i < 20000; ++i) {
    x.push_back(unit(rng));
    e.push_back(i % 4 == 0 ? unit(rng) * 200.0f : static_cast<float>(1 + i % 97));
  }
  std::vector<float> want(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) want[i] = det_powf(x[i], e[i]);
  int tried = 0;
  for (const Isa isa : compiled_isas()) {
    if (!cpu_supports(isa)) continue;
    ++tried;
    const RenderKernels& k = render_kernels(isa);
    ASSERT_NE(k.highlight_powers, nullptr);
    // Whole, in batches of 1..17 (tails of every length), and the specials alone.
    for (const std::size_t batch : {x.size(), std::size_t{1}, std::size_t{3}, std::size_t{8}, std::size_t{13},
                                    std::size_t{16}, std::size_t{17}}) {
      std::vector<float> got(x.size(), -1.0f);
      for (std::size_t first = 0; first < x.size(); first += batch) {
        const std::size_t n = std::min(batch, x.size() - first);
        k.highlight_powers(x.data() + first, e.data() + first, got.data() + first, n);
      }
      for (std::size_t i = 0; i < x.size(); ++i) {
        std::uint32_t a, b;
        std::memcpy(&a, &want[i], 4);
        std::memcpy(&b, &got[i], 4);
        ASSERT_EQ(a, b) << isa_name(isa) << ", batch " << batch << ": det_powf(" << x[i] << ", " << e[i]
                        << ") = " << want[i] << ", the batch gave " << got[i];
      }
    }
  }
  EXPECT_GE(tried, 1);
}

}  // namespace
}  // namespace rtc
