// Temporal coherence (common/render/temporal.h): the recorder marks every voxel a ray crosses,
// the tracker's plans, and, above all, every frame of an animation rendered incrementally is
// bit-identical to a full render of that frame.
#include <gtest/gtest.h>

#include <algorithm>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <tbb/global_control.h>

#include "common/base/isa.h"
#include "common/image/image.h"
#include "common/render/renderer.h"
#include "common/render/temporal.h"
#include "common/render/temporal_render.h"
#include "common/scene/load.h"

namespace rtc {
namespace {

const std::filesystem::path kScenes = std::filesystem::path(RTC_TEST_DATA) / "scenes";

constexpr float kInf = std::numeric_limits<float>::infinity();

bool same_bits(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0);
}

std::uint32_t voxel_of(const MarkGrid& g, const glm::dvec3& p) {
  int idx[3];
  for (int k = 0; k < 3; ++k) {
    const double cell = (g.hi[k] - g.lo[k]) / g.dims[k];
    idx[k] = std::clamp(static_cast<int>(std::floor((p[k] - g.lo[k]) / cell)), 0, g.dims[k] - 1);
  }
  return static_cast<std::uint32_t>(idx[0] + g.dims.x * (idx[1] + g.dims.y * idx[2]));
}

bool inside(const MarkGrid& g, const glm::dvec3& p) {
  for (int k = 0; k < 3; ++k) {
    if (p[k] < g.lo[k] || p[k] > g.hi[k]) return false;
  }
  return true;
}

TEST(MarkRecorder, MarksEveryVoxelItsSegmentsCross) {
  MarkGrid g;
  g.lo = glm::dvec3(-1.0, -2.0, 0.5);
  g.hi = glm::dvec3(3.0, 1.0, 2.5);
  g.dims = glm::ivec3(16, 12, 8);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> pos(-4.0f, 5.0f), len(0.0f, 8.0f);
  MarkRecorder rec(g);
  for (int trial = 0; trial < 3000; ++trial) {
    // A group of 1 to 16 rays: coherent (shared origin, close directions) or scattered.
    const int n = 1 + trial % 16;
    const bool coherent = trial % 3 != 0;
    glm::vec3 org[16], dir[16];
    float t_end[16];
    const glm::vec3 base_org(pos(rng), pos(rng), pos(rng));
    const glm::vec3 base_dir(pos(rng), pos(rng), pos(rng));
    for (int i = 0; i < n; ++i) {
      org[i] = coherent ? base_org : glm::vec3(pos(rng), pos(rng), pos(rng));
      dir[i] = coherent ? base_dir + 0.05f * glm::vec3(pos(rng), pos(rng), pos(rng))
                        : glm::vec3(pos(rng), pos(rng), pos(rng));
      if (trial % 7 == 0) dir[i].y = 0.0f;  // axis-parallel
      t_end[i] = trial % 5 == 0 ? std::numeric_limits<float>::infinity() : len(rng);
    }
    if (trial % 2 == 0) {
      rec.path(n, org, dir, t_end);
    } else {
      // The kernels' entry: the group reduced to boxes first (rays one by one when it says so).
      glm::vec3 o_lo(kInf), o_hi(-kInf), d_lo(kInf), d_hi(-kInf);
      float t_max = 0.0f;
      for (int i = 0; i < n; ++i) {
        o_lo = glm::min(o_lo, org[i]), o_hi = glm::max(o_hi, org[i]);
        d_lo = glm::min(d_lo, dir[i]), d_hi = glm::max(d_hi, dir[i]);
        t_max = std::max(t_max, t_end[i]);
      }
      if (!rec.path_box(o_lo, o_hi, d_lo, d_hi, t_max)) rec.path(n, org, dir, t_end);
    }
    TileMarks m;
    rec.take(m);
    ASSERT_TRUE(std::is_sorted(m.path.begin(), m.path.end()));
    ASSERT_TRUE(m.shadow.empty());
    for (int i = 0; i < n; ++i) {
      const double t_max = std::isfinite(t_end[i]) ? t_end[i] : 100.0;
      for (int s = 0; s <= 4000; ++s) {
        const double t = t_max * s / 4000.0;
        const glm::dvec3 p = glm::dvec3(org[i]) + t * glm::dvec3(dir[i]);
        if (!inside(g, p)) continue;
        const std::uint32_t v = voxel_of(g, p);
        ASSERT_TRUE(std::binary_search(m.path.begin(), m.path.end(), v))
            << "trial " << trial << " ray " << i << " t " << t << " crosses voxel " << v << " unmarked";
      }
    }
  }
}

TEST(MarkRecorder, MarksEveryVoxelItsShadowSegmentsCross) {
  MarkGrid g;
  g.lo = glm::dvec3(-1.0, -2.0, 0.5);
  g.hi = glm::dvec3(3.0, 1.0, 2.5);
  g.dims = glm::ivec3(16, 12, 8);
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> pos(-4.0f, 5.0f);
  MarkRecorder rec(g);
  for (int trial = 0; trial < 3000; ++trial) {
    // Surface points (clustered or scattered) towards one light, as a shadow packet is.
    const int n = 1 + trial % 16;
    const glm::vec3 light(pos(rng), pos(rng), pos(rng));
    const glm::vec3 centre(pos(rng), pos(rng), pos(rng));
    glm::vec3 org[16], dir[16];
    float t_end[16];
    for (int i = 0; i < n; ++i) {
      org[i] = trial % 2 ? centre + 0.1f * glm::vec3(pos(rng), pos(rng), pos(rng)) : glm::vec3(pos(rng), pos(rng), pos(rng));
      dir[i] = light - org[i];
      t_end[i] = 1.0f;
    }
    if (trial % 4 < 2) {
      rec.shadow(n, org, dir, t_end);
    } else {
      glm::vec3 a_lo(kInf), a_hi(-kInf), b_lo(kInf), b_hi(-kInf);
      for (int i = 0; i < n; ++i) {
        const glm::vec3 b = org[i] + dir[i] * t_end[i];
        a_lo = glm::min(a_lo, org[i]), a_hi = glm::max(a_hi, org[i]);
        b_lo = glm::min(b_lo, b), b_hi = glm::max(b_hi, b);
      }
      if (!rec.shadow_box(a_lo, a_hi, b_lo, b_hi)) rec.shadow(n, org, dir, t_end);
    }
    TileMarks m;
    rec.take(m);
    ASSERT_TRUE(m.path.empty());
    for (int i = 0; i < n; ++i) {
      for (int s = 0; s <= 4000; ++s) {
        const double t = s / 4000.0;
        const glm::dvec3 p = glm::dvec3(org[i]) + t * glm::dvec3(dir[i]);
        if (!inside(g, p)) continue;
        const std::uint32_t v = voxel_of(g, p);
        ASSERT_TRUE(std::binary_search(m.shadow.begin(), m.shadow.end(), v))
            << "trial " << trial << " shadow ray " << i << " t " << t << " crosses voxel " << v << " unmarked";
      }
    }
  }
}

TEST(MarkGrid, CoversEveryPoseOfTheMovingMeshes) {
  const Scene scene = default_scene();
  const MarkGrid g = mark_grid_for(scene);
  ASSERT_FALSE(g.empty());
  EXPECT_NO_THROW(check_mark_grid(g, "test"));
  for (int f = scene.animation.frame_begin - 2; f <= scene.animation.frame_end + 2; ++f) {
    const FramePose pose = pose_at(scene, std::max(f, 0));
    for (const MeshTrack& track : scene.animation.meshes) {
      const Mesh& mesh = scene.meshes[track.mesh];
      const glm::dmat4 world(pose.world_from_object[track.mesh]);
      for (const glm::vec3& p : mesh.positions) {
        const glm::dvec3 w(world * glm::dvec4(glm::dvec3(p), 1.0));
        ASSERT_TRUE(inside(g, w)) << "frame " << f << ": vertex of mesh " << track.mesh << " outside the grid";
      }
    }
  }
  Scene still = default_scene();
  still.animation.meshes.clear();
  EXPECT_TRUE(mark_grid_for(still).empty());
}

// Only the frames rendered count: a key far outside them does not widen the grid, and the
// grid still holds every pose of those frames; a range where nothing moves needs no grid.
TEST(MarkGrid, CoversTheFramesRenderedNotKeysOutsideThem) {
  const Scene scene = default_scene();
  const int begin = scene.animation.frame_begin, end = scene.animation.frame_end;
  Scene far = scene;
  ASSERT_FALSE(far.animation.meshes.empty());
  MeshTrack& track = far.animation.meshes[0];
  ASSERT_GE(track.keys.size(), 2u);
  TransformKey away = track.keys.back();
  ASSERT_LT(away.frame, end + 1000);
  away.frame = end + 1000;
  away.transform.translate += glm::vec3(600.0f, 0.0f, 0.0f);
  track.keys.push_back(away);
  const MarkGrid whole = mark_grid_for(far);  // the whole animation: out to x + 600
  const MarkGrid rendered = mark_grid_for(far, kDefaultMarkCells, begin, end);
  EXPECT_GT(whole.hi.x - whole.lo.x, 500.0);
  EXPECT_LT(rendered.hi.x - rendered.lo.x, 100.0);
  for (int f = begin; f <= end; ++f) {
    const FramePose pose = pose_at(far, f);
    for (const MeshTrack& t : far.animation.meshes) {
      const glm::dmat4 world(pose.world_from_object[t.mesh]);
      for (const glm::vec3& p : far.meshes[t.mesh].positions) {
        ASSERT_TRUE(inside(rendered, glm::dvec3(world * glm::dvec4(glm::dvec3(p), 1.0))))
            << "frame " << f << ": vertex of mesh " << t.mesh << " outside the grid";
      }
    }
  }
  // Frames after the last of the scene's own keys but before the far one do see it move.
  EXPECT_GT(mark_grid_for(far, kDefaultMarkCells, end + 10, end + 20).hi.x, rendered.hi.x + 5.0);
  // One frame, or frames where every track holds a key's pose, need none.
  EXPECT_TRUE(mark_grid_for(scene, kDefaultMarkCells, begin, begin).empty());
  EXPECT_TRUE(mark_grid_for(scene, kDefaultMarkCells, end + 5, end + 50).empty());
}

// --mark-cells takes up to 256, but a cubic region has 2^21 voxels at 128 a side: the grid
// gets fewer cells rather than failing the check (it used to throw "mark grid has 2146689 voxels").
TEST(MarkGrid, ManyCellsOnACubicRegionStayWithinTheVoxelLimit) {
  Scene scene = default_scene();
  MeshTrack& track = scene.animation.meshes.at(0);
  track.keys = {track.keys.front(), track.keys.front()};
  track.keys[1].frame = track.keys[0].frame + 10;
  track.keys[1].transform.translate += glm::vec3(4.0f, 4.0f, 4.0f);  // a diagonal: about a cube
  for (const int cells : {128, 129, 200, kMaxMarkCellsPerAxis}) {
    const MarkGrid g = mark_grid_for(scene, cells);
    EXPECT_NO_THROW(check_mark_grid(g, "test")) << cells << " cells";
    EXPECT_LE(g.voxel_count(), kMaxMarkVoxels) << cells << " cells";
    EXPECT_GE(std::max({g.dims.x, g.dims.y, g.dims.z}), 120) << cells << " cells";
  }
}

// Auto: on unless the camera moves over the frames rendered.
TEST(TemporalMode, AutoLooksAtTheFramesRenderedOnly) {
  Scene scene = default_scene();
  scene.animation.camera = {CameraKey{0, scene.camera}, CameraKey{5, scene.camera}, CameraKey{6, scene.camera}};
  scene.animation.camera[0].camera.eye += glm::vec3(0.5f, 0, 0);  // moves over frames 0-5, then holds
  EXPECT_FALSE(temporal_for(scene, TemporalMode::Auto));
  EXPECT_FALSE(temporal_for(scene, TemporalMode::Auto, 0, 19));
  EXPECT_FALSE(temporal_for(scene, TemporalMode::Auto, 4, 5));
  EXPECT_TRUE(temporal_for(scene, TemporalMode::Auto, 5, 19));
  EXPECT_TRUE(temporal_for(scene, TemporalMode::Auto, 8, 19));
  EXPECT_TRUE(temporal_for(scene, TemporalMode::On, 0, 19));
  EXPECT_FALSE(temporal_for(scene, TemporalMode::Off, 8, 19));
  // A key inside the frames that differs, though both ends agree.
  scene.animation.camera[0].camera = scene.camera;
  scene.animation.camera[1].camera.eye += glm::vec3(0.5f, 0, 0);
  EXPECT_FALSE(temporal_for(scene, TemporalMode::Auto, 0, 10));
  EXPECT_TRUE(temporal_for(scene, TemporalMode::Auto, 6, 10));
  // --loop (a frame-rate run) over frames where nothing at all moves: off, else as without it.
  Scene still = default_scene();
  EXPECT_TRUE(temporal_for(still, TemporalMode::Auto, still.animation.frame_begin, still.animation.frame_end, true));
  still.animation.meshes.clear();
  still.animation.lights.clear();
  EXPECT_FALSE(anything_moves(still, still.animation.frame_begin, still.animation.frame_end));
  EXPECT_FALSE(temporal_for(still, TemporalMode::Auto, still.animation.frame_begin, still.animation.frame_end, true));
  EXPECT_TRUE(temporal_for(still, TemporalMode::Auto, still.animation.frame_begin, still.animation.frame_end, false));
  EXPECT_TRUE(temporal_for(still, TemporalMode::On, still.animation.frame_begin, still.animation.frame_end, true));
}

// choose_temporal: temporal_for over a run, with the reason it is off that rtc-master and
// rtc-render log (and one frame, which it needs none for, off whatever the mode).
TEST(TemporalMode, ChoiceSaysWhyItIsOff) {
  Scene scene = default_scene();
  scene.animation.camera = {CameraKey{0, scene.camera}, CameraKey{5, scene.camera}};
  scene.animation.camera[0].camera.eye += glm::vec3(0.5f, 0, 0);  // moves over frames 0-5
  const auto choice = [&](const Scene& s, TemporalMode mode, int first, int last, bool loop) {
    const TemporalChoice c = choose_temporal(s, mode, first, last, loop);
    EXPECT_EQ(c.on, temporal_for(s, mode, first, last, loop) && (last > first || loop));
    EXPECT_EQ(c.on, c.why_off.empty());
    EXPECT_EQ(c.moves, anything_moves(s, first, last));
    return c.why_off;
  };
  EXPECT_EQ(choice(scene, TemporalMode::Auto, 0, 9, false), "the camera moves over the frames rendered");
  EXPECT_EQ(choice(scene, TemporalMode::Auto, 6, 9, false), "");
  EXPECT_EQ(choice(scene, TemporalMode::On, 0, 9, false), "");
  EXPECT_EQ(choice(scene, TemporalMode::Off, 6, 9, false), "--temporal off");
  EXPECT_EQ(choice(scene, TemporalMode::On, 6, 6, false), "one frame");
  // A --loop over one frame: the same frame again and again, nothing moves between them.
  EXPECT_EQ(choice(scene, TemporalMode::Auto, 6, 6, true).rfind("--loop over frames where nothing moves", 0), 0u);
  Scene still = default_scene();
  still.animation.meshes.clear();
  still.animation.lights.clear();
  EXPECT_EQ(choice(still, TemporalMode::Auto, 0, 9, true).rfind("--loop over frames where nothing moves", 0), 0u);
  EXPECT_EQ(choice(still, TemporalMode::Auto, 0, 9, false), "");
}

// A retraced tile's old marks are replaced (Jevans 3.3.1), by a difference walk over the two
// ascending lists: the tracker ends in the state a fresh one given the new marks has, and
// lists that are not ascending (a peer's) take the slow path to the same state.
TEST(TemporalTracker, RetracedMarksReplaceTheOldOnes) {
  const Scene scene = default_scene();
  const MarkGrid g = mark_grid_for(scene);
  TileMarks everything, half, none;
  for (std::uint32_t v = 0; v < g.voxel_count(); ++v) {
    everything.path.push_back(v);
    everything.shadow.push_back(v);
    if (v % 2 == 0) half.path.push_back(v);
  }
  TileMarks reversed = everything;
  std::reverse(reversed.path.begin(), reversed.path.end());
  // Route 1: everything, then retraced for frame 1 with half.
  TemporalTracker a(scene, g, 1);
  TemporalPlan pa = a.plan(0);
  (void)a.done(0, pa.id, &everything);
  pa = a.plan(1);
  ASSERT_EQ(pa.dirty[0], TemporalPlan::kTrace) << "the sphere moved through voxels the tile crossed";
  (void)a.done(0, pa.id, &half);
  // Route 2: half from the start (kept for frame 1 or traced again with half).
  TemporalTracker b(scene, g, 1);
  TemporalPlan pb = b.plan(0);
  (void)b.done(0, pb.id, &half);
  pb = b.plan(1);
  if (pb.dirty[0] == TemporalPlan::kTrace) (void)b.done(0, pb.id, &half);
  for (int frame = 2; frame < 6; ++frame) {
    pa = a.plan(frame);
    pb = b.plan(frame);
    EXPECT_EQ(pa.dirty, pb.dirty) << "frame " << frame;
    EXPECT_EQ(pa.by_path, pb.by_path) << "frame " << frame;
    EXPECT_EQ(pa.by_shadow, 0u) << "frame " << frame << ": the shadow marks of the first trace were reset";
    if (pa.dirty[0] == TemporalPlan::kTrace) (void)a.done(0, pa.id, &half);
    if (pb.dirty[0] == TemporalPlan::kTrace) (void)b.done(0, pb.id, &half);
  }
  // Emptied by a retrace: nothing moving dirties it any more.
  TemporalTracker c(scene, g, 1);
  TemporalPlan pc = c.plan(0);
  (void)c.done(0, pc.id, &everything);
  pc = c.plan(1);
  ASSERT_EQ(pc.dirty[0], TemporalPlan::kTrace);
  (void)c.done(0, pc.id, &none);
  EXPECT_EQ(c.plan(2).dirty[0], TemporalPlan::kKeep);
  // Not ascending: still replaces (clear, then set).
  TemporalTracker d(scene, g, 1);
  TemporalPlan pd = d.plan(0);
  (void)d.done(0, pd.id, &none);
  pd = d.plan(0);
  EXPECT_EQ(pd.dirty[0], TemporalPlan::kKeep);
  TemporalTracker e(scene, g, 1);
  TemporalPlan pe = e.plan(0);
  (void)e.done(0, pe.id, &half);
  pe = e.plan(1);
  ASSERT_EQ(pe.dirty[0], TemporalPlan::kTrace) << "half the grid's voxels, and the sphere moves through them";
  (void)e.done(0, pe.id, &reversed);
  EXPECT_EQ(e.plan(2).dirty[0], TemporalPlan::kTrace) << "the unsorted list's voxels count";
}

TEST(TemporalTracker, PlansFollowWhatMoved) {
  Scene scene = default_scene();
  const MarkGrid g = mark_grid_for(scene);
  TemporalTracker t(scene, g, 4);
  TemporalPlan p = t.plan(0);
  EXPECT_TRUE(p.full);
  EXPECT_EQ(p.dirty_count, 4u);
  // Tile 0 saw nothing that moves; tile 1 crossed voxel 0; tile 2 shaded; tile 3 not back yet.
  TileMarks none, crossed, shaded, everything;
  crossed.path = {0};
  shaded.shaded = true;
  for (std::uint32_t v = 0; v < g.voxel_count(); ++v) everything.path.push_back(v);
  EXPECT_TRUE(t.done(0, p.id, &none).empty());
  EXPECT_TRUE(t.done(1, p.id, &crossed).empty());
  EXPECT_TRUE(t.done(2, p.id, &shaded).empty());
  const std::uint64_t first = p.id;
  p = t.plan(0);  // the same frame again: nothing moved
  EXPECT_FALSE(p.full);
  EXPECT_EQ(p.dirty, (std::vector<std::uint8_t>{0, 0, 0, TemporalPlan::kWait})) << "tile 3 waits for its trace";
  EXPECT_EQ(p.waiting, 1u);
  const std::vector<TemporalDecision> d = t.done(3, first, &none);
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].plan, p.id);
  EXPECT_EQ(d[0].tile, 3u);
  EXPECT_FALSE(d[0].trace) << "nothing moved: it keeps the pixels just traced";
  EXPECT_TRUE(t.done(3, first, &none).empty()) << "a second report of the same trace is ignored";
  p = t.plan(0);
  EXPECT_EQ(p.dirty_count, 0u);
  EXPECT_EQ(p.waiting, 0u);

  // Frames in flight while the sphere moves: plans b and c wait on a tile out for plan a;
  // its marks cross everything, so b traces it and c waits for that trace.
  TemporalTracker ft(scene, g, 1);
  const TemporalPlan pa = ft.plan(0), pb = ft.plan(1), pc = ft.plan(2);
  EXPECT_EQ(pb.dirty[0], TemporalPlan::kWait);
  EXPECT_EQ(pc.dirty[0], TemporalPlan::kWait);
  std::vector<TemporalDecision> da = ft.done(0, pa.id, &everything);
  ASSERT_EQ(da.size(), 1u);
  EXPECT_EQ(da[0].plan, pb.id);
  EXPECT_TRUE(da[0].trace);
  std::vector<TemporalDecision> db = ft.done(0, pb.id, &none);  // now it sees nothing that moves
  ASSERT_EQ(db.size(), 1u);
  EXPECT_EQ(db[0].plan, pc.id);
  EXPECT_FALSE(db[0].trace);

  // A trace that never reports (null marks): the waiting plan traces it.
  TemporalTracker nt(scene, g, 1);
  const TemporalPlan na = nt.plan(0), nb = nt.plan(0);
  const std::vector<TemporalDecision> dn = nt.done(0, na.id, nullptr);
  ASSERT_EQ(dn.size(), 1u);
  EXPECT_EQ(dn[0].plan, nb.id);
  EXPECT_TRUE(dn[0].trace);

  // A light moves (and no mesh): the tiles that shaded a hit.
  scene.animation.meshes.clear();
  scene.animation.lights.push_back(LightTrack{0, {LightKey{0, scene.lights[0].position},
                                                  LightKey{10, scene.lights[0].position + glm::vec3(1, 0, 0)}}});
  TemporalTracker lt(scene, g, 3);
  p = lt.plan(0);
  (void)lt.done(0, p.id, &none);
  (void)lt.done(1, p.id, &crossed);
  (void)lt.done(2, p.id, &shaded);
  p = lt.plan(5);
  EXPECT_EQ(p.dirty, (std::vector<std::uint8_t>{0, 0, 1}));
  EXPECT_EQ(p.by_light, 1u);

  // The camera moves: everything.
  Scene moving = default_scene();
  moving.animation.camera = {CameraKey{0, moving.camera}, CameraKey{10, moving.camera}};
  moving.animation.camera[1].camera.eye += glm::vec3(0.5f, 0, 0);
  TemporalTracker ct(moving, mark_grid_for(moving), 2);
  p = ct.plan(0);
  (void)ct.done(0, p.id, &none);
  (void)ct.done(1, p.id, &none);
  p = ct.plan(3);
  EXPECT_TRUE(p.full);
  EXPECT_EQ(p.dirty_count, 2u);
  EXPECT_NE(p.why.find("camera"), std::string::npos);
}

/// Renders every frame of `scene` incrementally and in full; requires the same bits in colour,
/// depth and normals, and returns the tiles traced over all frames after the first.
std::uint64_t expect_incremental_equals_full(const Scene& scene, int tile, bool packets, std::uint64_t* total_tiles,
                                             std::optional<Isa> isa = std::nullopt) {
  RenderOptions o;
  o.packets = packets;
  o.isa = isa;
  Renderer r(scene, o);
  TemporalFrames tf(r, tile);
  std::uint64_t traced = 0;
  *total_tiles = 0;
  for (int f = scene.animation.frame_begin; f <= scene.animation.frame_end; ++f) {
    const auto state = r.prepare(f);
    TemporalFrames::Report report;
    const Image& inc = tf.render(*state, &report);
    const Image full = r.render_frame(*state, tile);
    EXPECT_TRUE(same_bits(inc.rgba, full.rgba)) << scene.name << " frame " << f << ": colour differs";
    EXPECT_TRUE(same_bits(inc.depth, full.depth)) << scene.name << " frame " << f << ": depth differs";
    EXPECT_TRUE(same_bits(inc.normal, full.normal)) << scene.name << " frame " << f << ": normals differ";
    if (f > scene.animation.frame_begin) {
      traced += report.plan.dirty_count;
      *total_tiles += report.tiles;
    }
  }
  return traced;
}

TEST(TemporalFrames, DefaultSceneEveryFrameEqualsAFullRender) {
  Scene scene = default_scene();
  scene.width = 160;
  scene.height = 120;
  for (const bool packets : {true, false}) {
    std::uint64_t total = 0;
    const std::uint64_t traced = expect_incremental_equals_full(scene, 16, packets, &total);
    EXPECT_LT(traced, total) << "some tiles kept (the sphere is small)";
  }
}

TEST(TemporalFrames, TestAnimationsEveryFrameEqualsAFullRender) {
  int scenes = 0;
  for (const auto& entry : std::filesystem::directory_iterator(kScenes)) {
    if (entry.path().extension() != ".json") continue;
    ++scenes;
    const Scene scene = load_scene(entry.path());
    std::uint64_t total = 0;
    const std::uint64_t traced = expect_incremental_equals_full(scene, 16, true, &total);
    std::printf("%s: %llu of %llu tiles retraced after the first frame\n", entry.path().filename().c_str(),
                static_cast<unsigned long long>(traced), static_cast<unsigned long long>(total));
    EXPECT_LT(traced, total) << entry.path() << ": nothing was kept";
  }
  EXPECT_GE(scenes, 4) << "test animations missing from " << kScenes;
}

TEST(TemporalFrames, EveryIsasKernelsRecordMarksThatKeepFramesExact) {
  // The kernels reduce each packet's boxes for the recorder with their own SIMD width (2x2,
  // 4x2 and 4x4 packets): marks too narrow at any width would leave a stale tile behind.
  int tried = 0;
  for (const Isa isa : compiled_isas()) {
    if (!cpu_supports(isa)) {
      std::printf("this CPU lacks %s, not tried\n", std::string(isa_name(isa)).c_str());
      continue;
    }
    ++tried;
    for (const char* name : {"crossing.json", "mirror.json", "shadow_only.json"}) {
      const Scene scene = load_scene(kScenes / name);
      std::uint64_t total = 0;
      const std::uint64_t traced = expect_incremental_equals_full(scene, 16, true, &total, isa);
      EXPECT_LT(traced, total) << name << " " << isa_name(isa) << ": nothing was kept";
    }
  }
  EXPECT_GE(tried, 1);
}

TEST(TemporalFrames, MovingCameraTracesEverything) {
  Scene scene = default_scene();
  scene.width = 64;
  scene.height = 48;
  scene.animation.frame_end = 3;
  scene.animation.camera = {CameraKey{0, scene.camera}, CameraKey{3, scene.camera}};
  scene.animation.camera[1].camera.eye += glm::vec3(0.3f, 0.1f, 0);
  Renderer r(scene);
  TemporalFrames tf(r, 16);
  for (int f = 0; f <= 3; ++f) {
    TemporalFrames::Report report;
    const auto state = r.prepare(f);
    const Image& inc = tf.render(*state, &report);
    EXPECT_TRUE(report.plan.full);
    EXPECT_TRUE(same_bits(inc.rgba, r.render_frame(*state, 16).rgba));
  }
}

}  // namespace
}  // namespace rtc
