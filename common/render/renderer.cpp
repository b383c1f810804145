// Renderer: per-frame world-space state, kd-trees (one built once over the static meshes, one
// per moving mesh rebuilt when it moves), tile dispatch to the per-ISA kernels.
#include "common/render/renderer.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <optional>
#include <span>
#include <string>

#include <spdlog/spdlog.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "common/base/error.h"
#include "common/base/progress.h"
#include "common/base/timer.h"
#include "common/render/render_kernels.h"

namespace rtc {

#ifdef RTC_HAVE_ISA_SSE42
namespace isa_sse42 {
const RenderKernels& render_kernels_for_isa();
}
#endif
#ifdef RTC_HAVE_ISA_AVX2
namespace isa_avx2 {
const RenderKernels& render_kernels_for_isa();
}
#endif
#ifdef RTC_HAVE_ISA_AVX512
namespace isa_avx512 {
const RenderKernels& render_kernels_for_isa();
}
#endif

const RenderKernels& render_kernels(Isa isa) {
  require_cpu_support(isa);
  switch (isa) {
#ifdef RTC_HAVE_ISA_SSE42
    case Isa::Sse42:
      return isa_sse42::render_kernels_for_isa();
#endif
#ifdef RTC_HAVE_ISA_AVX2
    case Isa::Avx2:
      return isa_avx2::render_kernels_for_isa();
#endif
#ifdef RTC_HAVE_ISA_AVX512
    case Isa::Avx512:
      return isa_avx512::render_kernels_for_isa();
#endif
    default:
      break;
  }
  throw_isa_not_compiled(isa);
}

namespace {

// fn(begin, end) over [0, n) in ranges of at least kFlattenGrain elements, in parallel: each
// element is written once from its own inputs, so the arrays are the same whatever the split.
// A million-triangle scene's flattening took ~10 ms on one thread, 2% of its kd-tree build.
constexpr std::size_t kFlattenGrain = 16384;
template <class Fn>
void for_ranges(std::size_t n, Fn&& fn) {
  if (n <= kFlattenGrain) {
    fn(std::size_t{0}, n);
    return;
  }
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, kFlattenGrain),
                    [&](const tbb::blocked_range<std::size_t>& r) { fn(r.begin(), r.end()); });
}

// World-space positions and normals of one mesh placed by `world_from_object`, written from
// g.positions[v_base] on. Transforms are applied in double and rounded once, so an identity
// placement reproduces the file's coordinates exactly and a placement gives the same bits
// whenever it is applied.
void place_mesh(const Mesh& m, const glm::mat4& world_from_object, std::size_t v_base, FrameGeometry& g) {
  const glm::dmat4 world(world_from_object);
  const glm::dmat3 normal_matrix = glm::transpose(glm::inverse(glm::dmat3(world)));
  const bool identity = world == glm::dmat4(1.0);
  const bool has_normals = m.normals.size() == m.positions.size() && !m.normals.empty();
  for_ranges(m.positions.size(), [&](std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i) {
      g.positions[v_base + i] =
          identity ? m.positions[i] : glm::vec3(world * glm::dvec4(glm::dvec3(m.positions[i]), 1.0));
      if (has_normals) {
        const glm::dvec3 n = normal_matrix * glm::dvec3(m.normals[i]);
        const double len = glm::length(n);
        g.normals[v_base + i] = len > 0.0 ? glm::vec3(n / len) : glm::vec3(0.0f);
      } else {
        g.normals[v_base + i] = glm::vec3(0.0f);
      }
    }
  });
}

// World-space geometry of all meshes at one pose, in mesh order: triangle i of the arrays is
// the triangle id every tree reports.
void flatten(const Scene& scene, const FramePose& pose, FrameGeometry& g) {
  std::size_t vertex_count = 0, tri_count = 0;
  for (const Mesh& m : scene.meshes) {
    vertex_count += m.positions.size();
    tri_count += m.triangles.size();
  }
  // Left uninitialised here (UninitVector) and written once each below, in parallel.
  g.positions.resize(vertex_count);
  g.normals.resize(vertex_count);
  g.triangles.resize(tri_count);
  g.material_ids.resize(tri_count);
  g.smooth.resize(tri_count);
  g.source_index.resize(tri_count);
  std::size_t v_base = 0, t_base = 0;
  std::uint64_t source_base = 0;
  for (std::size_t mi = 0; mi < scene.meshes.size(); ++mi) {
    const Mesh& m = scene.meshes[mi];
    place_mesh(m, pose.world_from_object.at(mi), v_base, g);
    const bool has_normals = m.normals.size() == m.positions.size() && !m.normals.empty();
    for_ranges(m.triangles.size(), [&](std::size_t begin, std::size_t end) {
      for (std::size_t t = begin; t < end; ++t) {
        g.triangles[t_base + t] = m.triangles[t] + glm::uvec3(static_cast<unsigned>(v_base));
        const std::uint32_t mat = t < m.material_ids.size() ? m.material_ids[t] : 0u;
        g.material_ids[t_base + t] = mat < scene.materials.size() ? mat : 0u;
        g.smooth[t_base + t] = has_normals ? 1 : 0;
        const std::uint64_t src = t < m.source_index.size() ? m.source_index[t] : t;
        g.source_index[t_base + t] = static_cast<std::uint32_t>(source_base + src);
      }
    });
    source_base += m.triangles.size() + m.dropped_degenerate;
    v_base += m.positions.size();
    t_base += m.triangles.size();
  }
}

// The same as flatten() at `pose`, given `previous`, the geometry of an earlier pose of the
// same scene, and the placement it was flattened at: the pose-independent arrays and the
// vertices of meshes that did not move are copied (the same bits), the others placed again.
void reflatten(const Scene& scene, const FramePose& pose, const FrameGeometry& previous,
               const std::vector<glm::mat4>& previous_world_from_object, FrameGeometry& g) {
  g.positions = previous.positions;
  g.normals = previous.normals;
  g.triangles = previous.triangles;
  g.material_ids = previous.material_ids;
  g.smooth = previous.smooth;
  g.source_index = previous.source_index;
  std::size_t v_base = 0;
  for (std::size_t mi = 0; mi < scene.meshes.size(); ++mi) {
    if (pose.world_from_object.at(mi) != previous_world_from_object.at(mi)) {
      place_mesh(scene.meshes[mi], pose.world_from_object[mi], v_base, g);
    }
    v_base += scene.meshes[mi].positions.size();
  }
}

}  // namespace

Aabb frame_bounds(const FrameGeometry& geometry) {
  Aabb box;
  for (std::size_t k = 0; k < geometry.trees.size(); ++k) {
    const std::shared_ptr<const KdTree>& tree = geometry.trees[k];
    if (tree == nullptr || tree->empty()) continue;
    const TreeSpace* space = geometry.space(k);
    box.extend(space != nullptr ? space->world_bounds : tree->bounds());
  }
  return box;
}

void analyse_frame(FrameState& fs) {
  const auto max3 = [](const glm::vec3& a) { return std::max(a.x, std::max(a.y, a.z)); };
  const auto black = [](const glm::vec3& a) { return a == glm::vec3(0.0f); };
  FrameFeatures f;
  f.lights = !fs.lights.empty();
  f.reflections = false;
  f.highlights = false;
  f.ambient = !black(fs.ambient);
  for (const Material& m : fs.materials) {
    // The kernels' own test for a mirror ray off a primary hit (weight 1 x specular); no
    // material passing it means no reflection ray at any depth.
    const float w = max3(glm::vec3(1.0f) * m.specular);
    f.reflections =
        f.reflections || (m.reflective && fs.settings.max_depth > 0 && w >= fs.settings.min_weight && w > 0.0f);
    f.highlights = f.highlights || max3(m.specular) > 0.0f;
    f.ambient = f.ambient || !black(m.emission);
  }
  f.single_sample = fs.settings.spp <= 1;
  f.background = !black(fs.background);
  fs.features = f;
  fs.cull = fs.geometry ? FrustumCull(fs.camera_rays, frame_bounds(*fs.geometry)) : FrustumCull();
}

std::string describe(const FrameFeatures& f) {
  std::string out;
  const auto add = [&out](bool on, const char* name) {
    if (!on) return;
    if (!out.empty()) out += ' ';
    out += name;
  };
  add(f.lights, "lights");
  add(f.reflections, "reflections");
  add(f.highlights, "highlights");
  add(f.background, "background");
  add(f.ambient, "ambient");
  add(f.single_sample, "spp=1");
  return out.empty() ? "none" : out;
}

namespace {

// Where a tree over a mesh's object-space vertices (bounds `object_box`) lies when the mesh is
// placed by `world_from_object`: the inverse map for the rays, and a world box around the
// object box's corners, padded by 1e-5 of the magnitudes involved (far beyond the rounding of
// the transforms; FrustumCull adds its own margin). Empty when the map has no finite inverse
// (a mesh scaled to nothing): then the caller builds a world-space tree.
std::optional<TreeSpace> tree_space_for(const glm::mat4& world_from_object, const Aabb& object_box) {
  const glm::dmat4 world(world_from_object);
  const double det = glm::determinant(glm::dmat3(world));
  if (!std::isfinite(det) || det == 0.0) return std::nullopt;
  const glm::dmat4 inv = glm::inverse(world);
  TreeSpace space;
  space.identity = false;
  space.m = glm::mat3(glm::dmat3(inv));
  space.t = glm::vec3(glm::dvec3(inv[3]));
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) {
      if (!std::isfinite(space.m[c][r])) return std::nullopt;
    }
    if (!std::isfinite(space.t[c])) return std::nullopt;
  }
  if (object_box.empty()) return space;
  glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
  double magnitude = 0.0;
  for (int c = 0; c < 8; ++c) {
    const glm::dvec3 p((c & 1) ? object_box.hi.x : object_box.lo.x, (c & 2) ? object_box.hi.y : object_box.lo.y,
                       (c & 4) ? object_box.hi.z : object_box.lo.z);
    const glm::dvec3 w(world * glm::dvec4(p, 1.0));
    lo = glm::min(lo, w);
    hi = glm::max(hi, w);
    magnitude = std::max({magnitude, glm::length(p), glm::length(w)});
  }
  const double pad = 1e-5 * (magnitude + glm::length(glm::dvec3(world[3])));
  const auto down = [](double v) { return std::nextafter(static_cast<float>(v), -std::numeric_limits<float>::infinity()); };
  const auto up = [](double v) { return std::nextafter(static_cast<float>(v), std::numeric_limits<float>::infinity()); };
  space.world_bounds.lo = glm::vec3(down(lo.x - pad), down(lo.y - pad), down(lo.z - pad));
  space.world_bounds.hi = glm::vec3(up(hi.x + pad), up(hi.y + pad), up(hi.z + pad));
  return space;
}

// Everything of a frame but its geometry.
std::shared_ptr<FrameState> frame_state_at(const Scene& scene, const FramePose& pose, const RenderSettings& settings) {
  check_render_settings(settings);
  auto fs = std::make_shared<FrameState>();
  fs->frame = pose.frame;
  fs->width = scene.width;
  fs->height = scene.height;
  fs->camera = pose.camera;
  fs->camera_rays = CameraRays(pose.camera, scene.width, scene.height);
  fs->materials = scene.materials;
  if (fs->materials.empty()) fs->materials.emplace_back();
  fs->lights = pose.lights;
  fs->background = scene.background;
  fs->ambient = scene.ambient;
  fs->settings = settings;
  return fs;
}

// A tree over `triangles` (into `positions`) that reports triangle i as id first_id + i: one
// mesh's triangles, whose ids are their indices over all meshes (FrameGeometry::triangles).
std::shared_ptr<const KdTree> build_mesh_tree(std::span<const glm::vec3> positions,
                                              std::span<const glm::uvec3> triangles, std::size_t first_id,
                                              const KdBuildOptions& options) {
  std::vector<std::uint32_t> ids(triangles.size());
  for (std::size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<std::uint32_t>(first_id + i);
  return std::make_shared<const KdTree>(KdTree::build(positions, triangles, options, ids));
}

}  // namespace

bool kd_clip_for(KdClip clip, bool rebuilt_per_frame) {
  if (clip != KdClip::Auto) return clip == KdClip::On;
  return !rebuilt_per_frame;
}

bool kd_clip_for(const Scene& scene, KdClip clip) {
  const std::vector<bool> moving = moving_meshes(scene);
  return kd_clip_for(clip, std::find(moving.begin(), moving.end(), true) != moving.end());
}

void aim_kd_build(KdBuildOptions& kd, const CameraRays& rays) {
  // A row's step on the image plane at unit distance, as the rays are made (image_b is affine).
  const double slope = rays.image_b(0.0) - rays.image_b(1.0);
  kd.pixel_slope = std::isfinite(slope) && slope > 0.0 ? static_cast<float>(slope) : 0.0f;
  kd.footprint_eye = glm::vec3(rays.eye());
}

std::shared_ptr<FrameState> build_frame_state(const Scene& scene, int frame, const RenderSettings& settings,
                                              const KdBuildOptions& kd) {
  const FramePose pose = pose_at(scene, frame);
  auto fs = frame_state_at(scene, pose, settings);
  auto geometry = std::make_shared<FrameGeometry>();
  flatten(scene, pose, *geometry);
  KdBuildOptions tree_options = kd;
  aim_kd_build(tree_options, fs->camera_rays);
  tree_options.watertight = settings.intersector == Intersector::Watertight;  // the setting decides
  geometry->trees.push_back(
      std::make_shared<const KdTree>(KdTree::build(geometry->positions, geometry->triangles, tree_options)));
  const std::vector<bool> moving = moving_meshes(scene);
  geometry->first_tree_static = std::find(moving.begin(), moving.end(), true) == moving.end();
  fs->geometry = std::move(geometry);
  analyse_frame(*fs);
  return fs;
}

Renderer::Renderer(Scene scene, RenderOptions options)
    : scene_(std::move(scene)), options_(std::move(options)), isa_(options_.isa.value_or(best_isa())) {
  (void)render_kernels(isa_);  // fail now, not in the first tile
  check_render_settings(options_.settings.value_or(scene_.settings));
  (void)CameraRays(scene_.camera, scene_.width, scene_.height);
  moving_ = moving_meshes(scene_);
  shadow_tally_count_ = 2 * scene_.lights.size();
  shadow_tally_ = std::make_unique<ShadowOrderTally[]>(shadow_tally_count_);
}

std::shared_ptr<const FrameState> Renderer::prepare(int frame) {
  if (last_ && last_->frame == frame) return last_;
  const FramePose pose = pose_at(scene_, frame);
  // Share the geometry and trees when no mesh moved: camera-only and light-only animations
  // then cost no rebuild and no copy.
  if (last_ && last_world_from_object_ == pose.world_from_object) {
    auto fs = std::make_shared<FrameState>(*last_);  // shares last_->geometry
    fs->frame = frame;
    fs->camera = pose.camera;
    fs->camera_rays = CameraRays(pose.camera, scene_.width, scene_.height);
    fs->lights = pose.lights;
    analyse_frame(*fs);
    last_ = std::move(fs);
    spdlog::debug("frame {}: no mesh moved, geometry and kd-trees reused", frame);
    return last_;
  }
  const RenderSettings settings = options_.settings.value_or(scene_.settings);
  auto fs = frame_state_at(scene_, pose, settings);
  fs->tracer = options_.tracer;
  Timer flatten_timer;
  auto geometry = std::make_shared<FrameGeometry>();
  if (last_) {
    reflatten(scene_, pose, *last_->geometry, last_world_from_object_, *geometry);
  } else {
    flatten(scene_, pose, *geometry);
  }
  const double flatten_ms = flatten_timer.elapsed_ms();

  KdBuildOptions kd = options_.kd;
  aim_kd_build(kd, fs->camera_rays);
  kd.watertight = settings.intersector == Intersector::Watertight;  // the setting decides
  Timer build_timer;
  int built = 0;
  if (!options_.split_static_trees) {
    kd.clip = kd_clip_for(scene_, options_.kd_clip);
    geometry->trees.push_back(
        std::make_shared<const KdTree>(KdTree::build(geometry->positions, geometry->triangles, kd)));
    ++built;
    geometry->first_tree_static = std::find(moving_.begin(), moving_.end(), true) == moving_.end();
    spdlog::debug("frame {}: one tree over all meshes: {}", frame, geometry->trees[0]->stats().to_string());
  } else {
    // The trees' ids number all triangles: the limit of one tree over all of them applies.
    if (geometry->triangles.size() >= (1u << 30)) throw Error("kd-tree: more than 2^30 triangles");
    const FrameGeometry& g = *geometry;
    if (!static_tree_) {
      // The static meshes' triangles, placed as at every frame (moving_meshes), with their ids.
      std::vector<glm::uvec3> triangles;
      std::vector<std::uint32_t> ids;
      std::size_t t_base = 0;
      for (std::size_t mi = 0; mi < scene_.meshes.size(); ++mi) {
        const std::size_t count = scene_.meshes[mi].triangles.size();
        if (!moving_[mi]) {
          triangles.insert(triangles.end(), g.triangles.begin() + static_cast<std::ptrdiff_t>(t_base),
                           g.triangles.begin() + static_cast<std::ptrdiff_t>(t_base + count));
          for (std::size_t t = 0; t < count; ++t) ids.push_back(static_cast<std::uint32_t>(t_base + t));
        }
        t_base += count;
      }
      KdBuildOptions static_kd = kd;
      static_kd.clip = kd_clip_for(options_.kd_clip, false);
      static_tree_ = std::make_shared<const KdTree>(KdTree::build(g.positions, triangles, static_kd, ids));
      static_world_from_object_ = pose.world_from_object;
      ++built;
      spdlog::debug("frame {}: static meshes' tree: {}", frame, static_tree_->stats().to_string());
    }
    for (std::size_t mi = 0; mi < scene_.meshes.size(); ++mi) {
      RTC_CHECK(moving_[mi] || pose.world_from_object[mi] == static_world_from_object_[mi],
                "Renderer: a mesh that moving_meshes() calls static moved");
    }
    geometry->trees.push_back(static_tree_);
    geometry->first_tree_static = true;
    KdBuildOptions moving_kd = kd;
    moving_kd.clip = kd_clip_for(options_.kd_clip, true);
    if (options_.instance_moving_meshes) {
      geometry->spaces.resize(1);  // the static tree: world space
      object_trees_.resize(scene_.meshes.size());
    }
    std::size_t t_base = 0, moving_index = 0;
    for (std::size_t mi = 0; mi < scene_.meshes.size(); ++mi) {
      const Mesh& mesh = scene_.meshes[mi];
      const std::size_t count = mesh.triangles.size();
      if (moving_[mi]) {
        ++moving_index;  // this mesh's tree is trees[moving_index], in every frame
        std::optional<TreeSpace> space;
        if (options_.instance_moving_meshes) {
          if (object_trees_[mi] == nullptr) {
            // Built once over the file's vertices, so clipped like the static tree.
            KdBuildOptions object_kd = kd;
            object_kd.clip = kd_clip_for(options_.kd_clip, false);
            object_kd.pixel_slope = 0.0f;  // in object space, for every frame's pose: no view to aim at
            object_trees_[mi] = build_mesh_tree(mesh.positions, mesh.triangles, t_base, object_kd);
            ++built;
            spdlog::debug("frame {}: mesh {} ({}) object-space tree, built once: {}", frame, mi, mesh.name,
                          object_trees_[mi]->stats().to_string());
          }
          space = tree_space_for(pose.world_from_object[mi], object_trees_[mi]->bounds());
        }
        if (space) {
          geometry->trees.push_back(object_trees_[mi]);
          geometry->spaces.push_back(*space);
        } else if (last_ && pose.world_from_object[mi] == last_world_from_object_[mi] &&
                   last_->geometry->space(moving_index) == nullptr) {
          geometry->trees.push_back(last_->geometry->trees.at(moving_index));
          if (!geometry->spaces.empty()) geometry->spaces.emplace_back();
        } else {
          if (!geometry->spaces.empty()) geometry->spaces.emplace_back();
          geometry->trees.push_back(build_mesh_tree(
              g.positions, std::span<const glm::uvec3>(g.triangles).subspan(t_base, count), t_base, moving_kd));
          ++built;
          spdlog::debug("frame {}: mesh {} ({}) tree: {}", frame, mi, scene_.meshes[mi].name,
                        geometry->trees.back()->stats().to_string());
        }
      }
      t_base += count;
    }
  }
  spdlog::debug("frame {}: flattened in {:.1f} ms; built {} of {} kd-trees in {:.1f} ms", frame, flatten_ms, built,
                geometry->trees.size(), build_timer.elapsed_ms());
  fs->geometry = std::move(geometry);
  analyse_frame(*fs);
  last_ = std::move(fs);
  last_world_from_object_ = pose.world_from_object;
  return last_;
}

void Renderer::render_tile(const FrameState& state, int x0, int y0, int w, int h, Image& out,
                           TileRayCounts* counts, MarkRecorder* marks) const {
  if (w <= 0 || h <= 0 || x0 < 0 || y0 < 0 || std::int64_t{x0} + w > state.width ||
      std::int64_t{y0} + h > state.height) {
    throw Error("render_tile: tile (" + std::to_string(x0) + ", " + std::to_string(y0) + ", " +
                std::to_string(w) + "x" + std::to_string(h) + ") is outside the " +
                std::to_string(state.width) + "x" + std::to_string(state.height) + " frame");
  }
  if (out.width != w || out.height != h || (options_.aovs && out.depth.empty())) {
    out = Image(w, h, options_.aovs, options_.aovs);
  }
  TileRayCounts local;
  const TileKernelOptions k{options_.packets,      options_.specialise, options_.skip_empty,
                            options_.shadow_order, shadow_tally_.get(), shadow_tally_count_};
  render_kernels(isa_).render_tile(state, x0, y0, w, h, k, out, local, marks);
  if (counts != nullptr) *counts += local;
}

Image Renderer::render_frame(const FrameState& state, int tile_size, ProgressBar* progress,
                             TileRayCounts* counts) const {
  if (tile_size <= 0) throw Error("tile size must be positive, got " + std::to_string(tile_size));
  Image frame(state.width, state.height, options_.aovs, options_.aovs);
  const std::int64_t tiles_x = (std::int64_t{state.width} + tile_size - 1) / tile_size;
  const std::int64_t tiles_y = (std::int64_t{state.height} + tile_size - 1) / tile_size;
  tbb::enumerable_thread_specific<TileRayCounts> thread_counts;
  tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, tiles_x * tiles_y, 1), [&](const auto& r) {
    Image tile;
    TileRayCounts& mine = thread_counts.local();
    for (std::int64_t t = r.begin(); t != r.end(); ++t) {
      const int x0 = static_cast<int>((t % tiles_x) * tile_size), y0 = static_cast<int>((t / tiles_x) * tile_size);
      const int w = std::min(tile_size, state.width - x0), h = std::min(tile_size, state.height - y0);
      render_tile(state, x0, y0, w, h, tile, &mine);
      frame.blit(tile, x0, y0);
      if (progress != nullptr) progress->add(static_cast<std::uint64_t>(w) * static_cast<std::uint64_t>(h));
    }
  });
  if (counts != nullptr) {
    for (const TileRayCounts& c : thread_counts) *counts += c;
  }
  return frame;
}

}  // namespace rtc
