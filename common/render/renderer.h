// The tile renderer every worker runs: Whitted shading over the packet kd-tree tracer.
#pragma once

#include <memory>
#include <optional>
#include <vector>

#include "common/accel/kd_tree.h"
#include "common/base/isa.h"
#include "common/image/image.h"
#include "common/render/frame_state.h"
#include "common/render/render_kernels.h"
#include "common/scene/scene.h"

namespace rtc {

class ProgressBar;
class MarkRecorder;

/// How to render; none of these change a pixel except `settings` (the time/accuracy trade).
struct RenderOptions {
  std::optional<RenderSettings> settings;  ///< empty: the scene's own
  std::optional<Isa> isa;                  ///< empty: best_isa()
  bool packets = true;                     ///< false: the single-ray (N = 1) kernels
  KdBuildOptions kd;  ///< `kd.clip` is decided by `kd_clip` below
  KdClip kd_clip = KdClip::Auto;
  bool aovs = true;                        ///< fill Image::depth and Image::normal
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
  /// kd-tree; when no mesh moved since the last call, geometry and tree are reused. Calls to
  /// prepare() must not overlap each other, but may overlap render_tile() on states returned
  /// earlier (a worker prepares the next frame while its threads trace the current one).
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
};

/// KdBuildOptions::clip for `scene` under `clip` (Auto: on unless a mesh track has more than
/// one key, i.e. unless the tree is rebuilt as frames go by).
[[nodiscard]] bool kd_clip_for(const Scene& scene, KdClip clip);

/// Builds the world-space state of `frame` (no reuse). Exposed for tools and tests. The tree uses
/// `kd`, except that `settings.intersector` decides KdBuildOptions::watertight.
[[nodiscard]] std::shared_ptr<FrameState> build_frame_state(const Scene& scene, int frame,
                                                            const RenderSettings& settings,
                                                            const KdBuildOptions& kd);

}  // namespace rtc
