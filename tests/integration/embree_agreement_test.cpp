// rtc's tracer against Embree 3 as the oracle: every view of ../shared/scenes (skipped when the
// folder is absent) and generated scenes, primary rays exactly as in CAMERA.md; with Wald's
// triangle test, and with the watertight one on a few views and the generated scenes.
//   hit/miss agree on >= 99.99% of pixels; the same triangle => relative t difference <= 1e-5;
//   different triangles => a verified tie (equal t, shared vertex or both on an edge), < 0.1%.
#include <gtest/gtest.h>

#include <cctype>
#include <cstdio>
#include <cstring>
#include <cmath>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "common/accel/trace.h"
#include "common/base/isa.h"
#include "common/render/renderer.h"
#include "common/scene/load.h"
#include "tests/support/embree_oracle.h"
#include "tests/support/hit_compare.h"

namespace rtc {
namespace {

void check_against_embree(const Scene& scene, const std::string& label) {
  const auto fs = build_frame_state(scene, scene.animation.frame_begin, scene.settings, KdBuildOptions{});
  const std::vector<RayQuery> rays = test::pixel_centre_rays(fs->camera_rays);
  std::vector<RayHit> ours(rays.size()), single(rays.size()), theirs(rays.size());
  trace_kernels().intersect(fs->geometry->single_tree(), rays.data(), single.data(), rays.size(), false);
  refine_hit_distances(fs->geometry->positions, fs->geometry->triangles, rays.data(), single.data(), rays.size());
  // Every ISA this CPU runs, with its packets as pixel blocks (2x2, 4x2, 4x4), gives the single
  // rays' bits.
  for (const Isa isa : compiled_isas()) {
    if (!cpu_supports(isa)) continue;
    const TraceKernels& k = trace_kernels(isa);
    const int bw = packet_block_width(k.packet_width), bh = k.packet_width / bw;
    std::vector<RayQuery> blocked;
    std::vector<std::size_t> index;
    for (int y = 0; y < fs->height; y += bh) {
      for (int x = 0; x < fs->width; x += bw) {
        for (int i = 0; i < k.packet_width; ++i) {
          const int px = std::min(x + i % bw, fs->width - 1), py = std::min(y + i / bw, fs->height - 1);
          const std::size_t j = static_cast<std::size_t>(py) * static_cast<std::size_t>(fs->width) + static_cast<std::size_t>(px);
          blocked.push_back(rays[j]);
          index.push_back(j);
        }
      }
    }
    std::vector<RayHit> blocked_hits(blocked.size());
    k.intersect(fs->geometry->single_tree(), blocked.data(), blocked_hits.data(), blocked.size(), true);
    for (std::size_t i = 0; i < blocked.size(); ++i) ours[index[i]] = blocked_hits[i];
    refine_hit_distances(fs->geometry->positions, fs->geometry->triangles, rays.data(), ours.data(), rays.size());
    for (std::size_t i = 0; i < rays.size(); ++i) {
      ASSERT_EQ(std::memcmp(&ours[i], &single[i], sizeof(RayHit)), 0)
          << label << ": " << isa_name(isa) << " packet and single ray differ for " << test::describe_ray(rays[i]);
    }
  }

  const test::EmbreeScene embree(fs->geometry->positions, fs->geometry->triangles);
  embree.intersect(rays.data(), theirs.data(), rays.size(), test::EmbreeMode::Single);
  const test::HitComparison c = test::compare_hits(fs->geometry->positions, fs->geometry->triangles, rays, ours, theirs);
  std::printf("%s (%zu triangles): %s\n", label.c_str(), fs->geometry->triangles.size(), c.summary().c_str());
  for (std::size_t i : c.examples) {
    ADD_FAILURE() << label << ": pixel " << i % static_cast<std::size_t>(fs->width) << ","
                  << i / static_cast<std::size_t>(fs->width) << " " << test::describe_ray(rays[i])
                  << " rtc prim " << ours[i].prim << " t " << ours[i].t << ", embree prim " << theirs[i].prim
                  << " t " << theirs[i].t;
  }
  EXPECT_GE(c.hit_miss_agreement(), 0.9999) << label << ": " << c.summary();
  // Visibility may differ only where a ray grazes an edge, and then rarely.
  EXPECT_EQ(c.hit_miss_disagree, c.hit_miss_on_edge) << label << ": " << c.summary();
  EXPECT_LE(c.edge_disagreement(), 1e-4) << label << ": " << c.summary();
  EXPECT_EQ(c.same_prim_t_bad, 0u) << label << ": " << c.summary();
  EXPECT_EQ(c.bad_ties, 0u) << label << ": " << c.summary();
  EXPECT_LT(c.tie_fraction(), 0.001) << label << ": " << c.summary();
}

class SharedView : public ::testing::TestWithParam<const char*> {};

TEST_P(SharedView, AgreesWithEmbree) {
  const std::filesystem::path view = std::filesystem::path(RTC_SHARED_SCENES) / GetParam();
  if (!std::filesystem::exists(view)) GTEST_SKIP() << view << " is absent (the shared scene pack is not here)";
  check_against_embree(load_scene(view), GetParam());
}

std::string view_test_name(const ::testing::TestParamInfo<const char*>& info) {
  std::string s = info.param;
  for (char& c : s) {
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  }
  return s;
}

INSTANTIATE_TEST_SUITE_P(
    Scenes, SharedView,
    ::testing::Values("bunny/view.json", "spd-teapot/view.json", "spd-tetra/view.json", "spd-mount/view.json",
                      "radiance-office/view.json", "spd-gears/view.json", "spd-tetra-s8/view.json",
                      "gltf-samples/view.json", "gltf-samples/view-BoxTextured.json",
                      "gltf-samples/view-Wuson.json", "spd-balls-s3/view.json", "radiance-cabin/view.json",
                      "spd-tree/view.json", "spd-rings/view.json", "spd-balls/view.json",
                      "spd-mount-s10/view.json"),
    view_test_name);

// The watertight test (RenderSettings::intersector), same thresholds.
class SharedViewWatertight : public ::testing::TestWithParam<const char*> {};

TEST_P(SharedViewWatertight, AgreesWithEmbree) {
  const std::filesystem::path view = std::filesystem::path(RTC_SHARED_SCENES) / GetParam();
  if (!std::filesystem::exists(view)) GTEST_SKIP() << view << " is absent (the shared scene pack is not here)";
  Scene scene = load_scene(view);
  scene.settings.intersector = Intersector::Watertight;
  check_against_embree(scene, std::string(GetParam()) + " watertight");
}

INSTANTIATE_TEST_SUITE_P(Scenes, SharedViewWatertight,
                         ::testing::Values("bunny/view.json", "spd-teapot/view.json", "radiance-office/view.json",
                                           "spd-gears/view.json", "spd-balls-s3/view.json", "spd-tree/view.json"),
                         view_test_name);

TEST(GeneratedScene, DefaultSceneAgreesWithEmbree) { check_against_embree(default_scene(), "default scene"); }

TEST(GeneratedScene, DefaultSceneWatertightAgreesWithEmbree) {
  Scene scene = default_scene();
  scene.settings.intersector = Intersector::Watertight;
  check_against_embree(scene, "default scene watertight");
}

// A field of closed UV spheres of many sizes over a floor, plus a cloud of random slivers, seen
// from a camera that also looks along the floor: shared edges, slivers, grazing rays.
Scene generated_scene(std::uint32_t seed) {
  SCOPED_TRACE("seed " + std::to_string(seed));
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  Mesh mesh;
  auto add_sphere = [&](glm::vec3 c, float r, int seg) {
    const auto base = static_cast<unsigned>(mesh.positions.size());
    for (int i = 0; i <= seg; ++i) {
      for (int j = 0; j < 2 * seg; ++j) {
        const float th = 3.14159265f * static_cast<float>(i) / static_cast<float>(seg);
        const float ph = 3.14159265f * static_cast<float>(j) / static_cast<float>(seg);
        mesh.positions.push_back(c + r * glm::vec3(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph)));
      }
    }
    const auto ring = static_cast<unsigned>(2 * seg);
    for (int i = 0; i < seg; ++i) {
      for (unsigned j = 0; j < ring; ++j) {
        const unsigned a = base + static_cast<unsigned>(i) * ring + j, b = base + static_cast<unsigned>(i) * ring + (j + 1) % ring;
        if (i > 0) mesh.triangles.emplace_back(a, b, a + ring);
        if (i < seg - 1) mesh.triangles.emplace_back(b, b + ring, a + ring);
      }
    }
  };
  for (int k = 0; k < 40; ++k) {
    add_sphere(glm::vec3(u(rng) * 4.0f, u(rng) * 0.5f + 0.6f, u(rng) * 4.0f), 0.1f + 0.4f * (u(rng) + 1.0f), 8 + k % 12);
  }
  for (int k = 0; k < 2000; ++k) {
    const glm::vec3 c(u(rng) * 4.0f, u(rng) + 1.0f, u(rng) * 4.0f);
    const auto base = static_cast<unsigned>(mesh.positions.size());
    mesh.positions.push_back(c);
    mesh.positions.push_back(c + glm::vec3(u(rng), u(rng), u(rng)) * 0.3f);
    mesh.positions.push_back(c + glm::vec3(u(rng), u(rng), u(rng)) * 0.01f);
    mesh.triangles.emplace_back(base, base + 1, base + 2);
  }
  const auto base = static_cast<unsigned>(mesh.positions.size());
  mesh.positions.insert(mesh.positions.end(), {{-6, 0, -6}, {6, 0, -6}, {6, 0, 6}, {-6, 0, 6}});
  mesh.triangles.emplace_back(base, base + 2, base + 1);
  mesh.triangles.emplace_back(base, base + 3, base + 2);
  mesh.material_ids.assign(mesh.triangles.size(), 0);
  for (std::uint32_t i = 0; i < mesh.triangles.size(); ++i) mesh.source_index.push_back(i);
  Scene s;
  s.name = "generated";
  s.meshes.push_back(std::move(mesh));
  s.materials.emplace_back();
  s.camera.eye = {7.0f, 1.2f, 6.0f};
  s.camera.look_at = {0.0f, 0.5f, 0.0f};
  s.camera.up = {0.0f, 1.0f, 0.0f};
  s.camera.vfov_deg = 50.0f;
  s.width = 400;
  s.height = 300;
  return s;
}

TEST(GeneratedScene, SpheresAndSliversAgreeWithEmbree) {
  for (std::uint32_t seed : {1u, 2u}) check_against_embree(generated_scene(seed), "generated seed " + std::to_string(seed));
}

TEST(GeneratedScene, SpheresAndSliversWatertightAgreeWithEmbree) {
  for (std::uint32_t seed : {1u, 2u}) {
    Scene scene = generated_scene(seed);
    scene.settings.intersector = Intersector::Watertight;
    check_against_embree(scene, "generated seed " + std::to_string(seed) + " watertight");
  }
}

}  // namespace
}  // namespace rtc
