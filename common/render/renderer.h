// The tile renderer every worker runs: Whitted shading over the packet kd-tree tracer.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/accel/kd_tree.h"
#include "common/base/isa.h"
#include "common/image/image.h"
#include "common/math/aabb.h"
#include "common/render/frame_state.h"
#include "common/render/render_kernels.h"
#include "common/scene/scene.h"

namespace rtc {

class ProgressBar;
class MarkRecorder;

/// How to render; none of these change a pixel except `settings` (the time/accuracy trade) and
/// `instance_moving_meshes` (float rounding on moving meshes).
struct RenderOptions {
  std::optional<RenderSettings> settings;  ///< empty: the scene's own
  std::optional<Isa> isa;                  ///< empty: best_isa()
  bool packets = true;                     ///< false: the single-ray (N = 1) kernels
  KdBuildOptions kd;  ///< `kd.clip` is decided by `kd_clip` below
  KdClip kd_clip = KdClip::Auto;
  /// One kd-tree over the meshes that never move (built once, shared by every frame) and one
  /// per moving mesh (rebuilt only for frames where that mesh moved); false: one tree over all
  /// meshes, rebuilt whenever any of them moves. The same pixels either way (tests compare
  /// them); false is for those tests and for timing the difference.
  bool split_static_trees = true;
  /// With split_static_trees: each moving mesh's tree is built once over its object-space
  /// vertices and rays are taken into that space (FrameGeometry::spaces), so a mesh that moves
  /// costs no rebuild (Wald, Benthin, Slusallek 2003). false: its tree is rebuilt in world space
  /// whenever it moves, giving the bits of one tree over everything. The two differ only by the
  /// float rounding of the ray transform, i.e. in a few edge pixels (tests bound it); every
  /// process rendering one animation must use the same value (workers use the default).
  bool instance_moving_meshes = true;
  bool aovs = true;                        ///< fill Image::depth and Image::normal
  /// Tile kernels specialised to the frame's features (FrameState::features); false: the general
  /// kernel, which tests for every feature as it goes. The same pixels either way.
  bool specialise = true;
  /// Primary rays that provably miss the geometry's bounds (FrameState::cull) are not traced;
  /// whole tiles and packets of them get the background as a miss would. The same pixels and
  /// temporal marks either way.
  bool skip_empty = true;
  /// The order of shadow rays' kd-tree walks (TileKernelOptions::shadow_order); the same pixels
  /// in every order.
  ShadowOrder shadow_order = ShadowOrder::Auto;
  /// Route every ray through another tracer (benchmarks only; null: rtc's kd-tree). Must
  /// outlive the renderer.
  const ExternalTracer* tracer = nullptr;
};

/// Renders tiles of frames of one scene. A pixel's value is a pure function of (scene, frame,
/// pixel, settings): not of the tile size, the thread count, the ISA, packets or the process.
class Renderer {
 public:
  /// Throws rtc::Error for an unusable scene (bad camera) or an unavailable ISA.
  Renderer(Scene scene, RenderOptions options = {});

  [[nodiscard]] const Scene& scene() const { return scene_; }
  [[nodiscard]] Isa isa() const { return isa_; }
  [[nodiscard]] const RenderOptions& options() const { return options_; }

  /// Evaluates the animation at `frame`, flattens the meshes to world space and builds the
  /// kd-trees (FrameGeometry::trees): the static meshes' tree on the first call only, a moving
  /// mesh's tree only when that mesh moved since the last call (see
  /// RenderOptions::split_static_trees). When no mesh moved since the last call, geometry and
  /// trees are reused as they are. Logs the trees built and their build times at debug level.
  /// Calls to prepare() must not overlap each other, but may overlap render_tile() on states
  /// returned earlier (a worker prepares the next frame while its threads trace the current one).
  std::shared_ptr<const FrameState> prepare(int frame);

  /// Renders pixels [x0, x0 + w) x [y0, y0 + h) of the prepared frame into `out`, which is
  /// resized to w x h. Thread-safe; no allocation beyond `out`. Adds the rays traced to
  /// `counts` when given; records the voxels its rays cross in `marks` when given (one
  /// recorder per thread; common/render/temporal.h). Marks never change a pixel.
  void render_tile(const FrameState& state, int x0, int y0, int w, int h, Image& out,
                   TileRayCounts* counts = nullptr, MarkRecorder* marks = nullptr) const;

  /// The whole frame in square tiles of `tile_size`, in parallel (TBB); `progress` (optional)
  /// advances by the number of pixels of each finished tile; `counts` (optional) gets the rays.
  [[nodiscard]] Image render_frame(const FrameState& state, int tile_size = 32,
                                   ProgressBar* progress = nullptr, TileRayCounts* counts = nullptr) const;

 private:
  Scene scene_;
  RenderOptions options_;
  Isa isa_;
  std::shared_ptr<const FrameState> last_;
  std::vector<glm::mat4> last_world_from_object_;  ///< the mesh placement last_ was built for
  std::vector<bool> moving_;                       ///< per mesh: moving_meshes(scene_)
  std::shared_ptr<const KdTree> static_tree_;      ///< split_static_trees: built by the first prepare()
  std::vector<glm::mat4> static_world_from_object_;  ///< the placement static_tree_ was built at
  /// instance_moving_meshes: per mesh, its object-space tree (null for static meshes), built by
  /// the first prepare()
  std::vector<std::shared_ptr<const KdTree>> object_trees_;
  /// What shadow packets took in each walk order, per light (TileKernelOptions::shadow_tally),
  /// over every tile and frame this renderer traces; written by render_tile's threads.
  std::unique_ptr<ShadowOrderTally[]> shadow_tally_;
  std::size_t shadow_tally_count_ = 0;
};

/// KdBuildOptions::clip under `clip` for a tree built once (`rebuilt_per_frame` false: Auto
/// means on) or rebuilt as frames go by (true: Auto means off, since the build then costs as
/// much as the tracing it speeds up). On and Off apply to every tree.
[[nodiscard]] bool kd_clip_for(KdClip clip, bool rebuilt_per_frame);

/// KdBuildOptions::clip under `clip` for one tree over all of `scene`'s meshes, which is rebuilt
/// per frame when a mesh moves (moving_meshes): what build_frame_state's callers and a renderer
/// without RenderOptions::split_static_trees use.
[[nodiscard]] bool kd_clip_for(const Scene& scene, KdClip clip);

/// Points `kd`'s view-aware SAH at the camera `rays` are made from (KdBuildOptions::footprint_eye,
/// and pixel_slope: a pixel's height at unit distance; footprint_pixels says whether it is used).
void aim_kd_build(KdBuildOptions& kd, const CameraRays& rays);

/// The box every primary ray that can hit anything passes through: the union of the bounds of
/// the frame's kd-trees (KdTree::bounds(), or TreeSpace::world_bounds for a tree in object
/// space; empty when there is nothing to hit).
[[nodiscard]] Aabb frame_bounds(const FrameGeometry& geometry);

/// Fills fs.features and fs.cull from the rest of `fs` (geometry, camera, lights, materials,
/// settings, background, ambient). build_frame_state and Renderer::prepare call it; call it
/// again after changing any of those.
void analyse_frame(FrameState& fs);

/// The features that are present, e.g. "lights reflections highlights background ambient spp=1"
/// ("none" when none is).
[[nodiscard]] std::string describe(const FrameFeatures& features);

/// Builds the world-space state of `frame` (no reuse) with one tree over all meshes. Exposed
/// for tools and tests. The tree uses `kd`, except that `settings.intersector` decides
/// KdBuildOptions::watertight.
[[nodiscard]] std::shared_ptr<FrameState> build_frame_state(const Scene& scene, int frame,
                                                            const RenderSettings& settings,
                                                            const KdBuildOptions& kd);

}  // namespace rtc
