// One frame of a scene, ready to trace: world-space geometry and kd-trees (shared between frames
// whose meshes did not move), camera, lights, materials, settings.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "common/accel/kd_tree.h"
#include "common/accel/trace.h"
#include "common/base/error.h"
#include "common/math/aabb.h"
#include "common/math/camera.h"
#include "common/math/frustum_cull.h"
#include "common/scene/scene.h"

namespace rtc {

/// The affine map taking world-space rays into a kd-tree's space: point p -> m p + t, direction
/// d -> m d, so a ray's parameter t (and its [t_min, t_max]) is the same in both spaces and
/// hits from trees in different spaces compare directly.
struct TreeSpace {
  bool identity = true;       ///< world space: rays go in as they are
  glm::mat3 m{1.0f};          ///< object_from_world's linear part
  glm::vec3 t{0.0f};          ///< object_from_world's translation
  Aabb world_bounds;          ///< a world-space box around everything the tree holds (padded)
};

/// FrameGeometry's allocator: its value-initialisation (vector::resize(n)) leaves trivial
/// elements as they are. The arrays are resized on one thread and then written once each in
/// parallel, and zero-filling them first cost spd-rings' build 11-14 ms of serial page faults
/// and stores (33 MB). (Taking them from alloc_pages, as huge pages kept for the next frame, made
/// repeated builds ~2% faster but first builds in a fresh process 3-16% slower: on this VM a
/// huge page's first touch costs more after the memory went back to the host. Not kept;
/// build_experiments.md, session 39.)
template <class T>
struct DefaultInitAllocator : std::allocator<T> {
  using value_type = T;
  template <class U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  DefaultInitAllocator() = default;
  template <class U>
  DefaultInitAllocator(const DefaultInitAllocator<U>& /*other*/) noexcept {}  // NOLINT: as std::allocator
  template <class U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};
/// A vector whose resize(n) leaves the new elements uninitialised (DefaultInitAllocator).
template <class T>
using UninitVector = std::vector<T, DefaultInitAllocator<T>>;

/// World-space triangles of one pose of the meshes, and their kd-trees. Immutable; shared by
/// every frame in which no mesh moved. Shading data (normals, materials) are kept apart from
/// the 48-byte triangle records in the trees and touched only for hits.
struct FrameGeometry {
  UninitVector<glm::vec3> positions;        ///< world space
  UninitVector<glm::vec3> normals;          ///< world space, one per position (zero when none)
  UninitVector<glm::uvec3> triangles;       ///< into positions
  UninitVector<std::uint32_t> material_ids; ///< per triangle, valid indices into the materials
  UninitVector<std::uint8_t> smooth;        ///< per triangle: 1 = interpolate vertex normals
  UninitVector<std::uint32_t> source_index; ///< per triangle: id in input-file order (all meshes)
  /// At least one. Renderer::prepare: trees[0] over the meshes that never move (built once and
  /// shared by every frame; possibly empty), then one per moving mesh in mesh order (shared
  /// with the previous frame when that mesh did not move). build_frame_state, or a renderer
  /// with RenderOptions::split_static_trees off: one tree over everything. Every tree reports
  /// the triangle's index in the arrays above as its id, whichever tree holds it; a ray goes
  /// through all of them (closest hit: the nearest, equal t to the higher id).
  std::vector<std::shared_ptr<const KdTree>> trees;
  /// Empty, or one per tree: where a tree lives. A moving mesh's tree may be built once over
  /// its object-space vertices and shared by every frame (RenderOptions::instance_moving_meshes;
  /// Wald, Benthin, Slusallek 2003): rays are taken into its space for the traversal instead
  /// of the tree being rebuilt whenever the mesh moves. Trees without an entry, or with an
  /// identity one, are in world space.
  std::vector<TreeSpace> spaces;
  /// trees[0] holds only meshes that never move (moving_meshes): a ray it blocks is blocked in
  /// every frame of the animation, so temporal coherence need not mark that shadow ray.
  bool first_tree_static = false;

  /// The tree when there is exactly one (static scenes, build_frame_state); RTC_CHECK fails
  /// otherwise. For tools and tests that trace a tree directly.
  [[nodiscard]] const KdTree& single_tree() const {
    RTC_CHECK(trees.size() == 1 && trees[0] != nullptr && space(0) == nullptr,
              "FrameGeometry::single_tree: the geometry has several trees (or none, or one in object space)");
    return *trees[0];
  }
  /// Tree i's space, null when it is in world space.
  [[nodiscard]] const TreeSpace* space(std::size_t i) const {
    return i < spaces.size() && !spaces[i].identity ? &spaces[i] : nullptr;
  }
};

/// Another tracer to route every ray through, keeping rtc's shading: rtc-bench uses it to time
/// an Embree-based renderer with the same shading code. Callbacks must be thread-safe; `rays`
/// come in groups of at most 4 coherent rays (one packet's active lanes).
struct ExternalTracer {
  void* context = nullptr;
  void (*intersect)(void* context, const RayQuery* rays, RayHit* hits, std::size_t count) = nullptr;
  void (*occluded)(void* context, const RayQuery* rays, std::uint8_t* occluded, std::size_t count) = nullptr;
};

/// What a frame's shading can need, found once per FrameState (analyse_frame, renderer.h). The
/// tile kernels are specialised to some of it (render_kernels.h); the rest is reported only.
/// The defaults say "everything", which the general kernel handles.
struct FrameFeatures {
  bool lights = true;  ///< at least one light: shadow rays
  /// A material can spawn a mirror ray: reflective, max3(specular) >= min_weight and > 0, and
  /// max_depth > 0.
  bool reflections = true;
  bool highlights = true;      ///< a material has max3(specular) > 0: Phong highlights (with lights)
  bool single_sample = false;  ///< spp == 1
  bool background = true;      ///< the background colour is not black
  bool ambient = true;         ///< the ambient colour or some material's emission is not black

  bool operator==(const FrameFeatures&) const = default;
};

/// Everything a tile render of one frame reads. Immutable once built; share it between
/// threads freely.
struct FrameState {
  int frame = 0;
  int width = 0, height = 0;
  Camera camera;
  CameraRays camera_rays{Camera{}, 1, 1};
  std::shared_ptr<const FrameGeometry> geometry;
  std::vector<Material> materials;  ///< at least one
  std::vector<PointLight> lights;   ///< world space
  glm::vec3 background{0.0f};
  glm::vec3 ambient{0.0f};
  RenderSettings settings;
  const ExternalTracer* tracer = nullptr;  ///< null: rtc's own kd-tree kernels
  FrameFeatures features;  ///< from analyse_frame
  FrustumCull cull;        ///< primary rays against frame_bounds, from analyse_frame (default: culls nothing)
};

}  // namespace rtc
