// Per-ISA tile kernels behind rtc::Renderer, chosen at run time.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "common/accel/shadow_order.h"
#include "common/base/isa.h"

namespace rtc {

struct FrameState;
struct Image;
class MarkRecorder;

/// Rays traced for a tile, by kind (added to, not reset).
struct TileRayCounts {
  std::uint64_t primary = 0;  ///< camera rays, one per pixel and sample (skipped ones included)
  std::uint64_t shadow = 0;
  std::uint64_t reflection = 0;
  /// Of `primary`, those that never entered the kd-tree: their tile or packet provably misses
  /// the geometry's bounds (TileKernelOptions::skip_empty).
  std::uint64_t primary_skipped = 0;
  /// Of `reflection`, those a packet left to the tile's queue of scattered bounces, traced later
  /// in packets regrouped from the whole tile (render_kernels.cpp, Bounces).
  std::uint64_t reflection_regrouped = 0;
  TileRayCounts& operator+=(const TileRayCounts& o) {
    primary += o.primary;
    shadow += o.shadow;
    reflection += o.reflection;
    primary_skipped += o.primary_skipped;
    reflection_regrouped += o.reflection_regrouped;
    return *this;
  }
  [[nodiscard]] std::uint64_t total() const { return primary + shadow + reflection; }
};

/// Position of sample `s` inside a pixel: sample 0 is the centre (CAMERA.md), later ones follow
/// the R2 low-discrepancy sequence. Computed in double from the sample index only, so every
/// renderer (and the double-precision reference) places its samples the same way.
inline void sample_offset(int s, double& sx, double& sy) {
  constexpr double kA1 = 0.7548776662466927, kA2 = 0.5698402909980532;
  sx = std::fmod(0.5 + kA1 * s, 1.0);
  sy = std::fmod(0.5 + kA2 * s, 1.0);
}

/// How a tile is traced; none of it changes a pixel (RenderOptions has the same fields).
struct TileKernelOptions {
  bool packets = true;     ///< false: the single-ray (N = 1) kernels
  bool specialise = true;  ///< the kernel specialised to FrameState::features; false: the general one
  bool skip_empty = true;  ///< skip primary rays that FrameState::cull says miss everything
  /// The order of shadow rays' kd-tree walks (ShadowOrder; the same pixels in every order):
  /// Auto chooses between dense and far per run of packets (a light's over the tile) from the
  /// time each took (ShadowOrderChooser).
  ShadowOrder shadow_order = ShadowOrder::Auto;
  /// Optional, with Auto: tallies shared by tiles and threads, [2 * light + (1 for the shadow
  /// rays of mirror bounces)]; lights past `shadow_tally_count / 2` have no tally, so their
  /// walks start near-first, untimed (ShadowOrderChooser without a tally).
  ShadowOrderTally* shadow_tally = nullptr;
  std::size_t shadow_tally_count = 0;
};

/// Entry points of one ISA. `render_tile` writes pixels [x0, x0+w) x [y0, y0+h) of the
/// frame into `out` (already w x h; depth/normal filled when present); `marks` (optional)
/// records the voxels the rays cross (common/render/temporal.h).
struct RenderKernels {
  Isa isa = Isa::Sse42;
  void (*render_tile)(const FrameState& state, int x0, int y0, int w, int h, const TileKernelOptions& options,
                      Image& out, TileRayCounts& counts, MarkRecorder* marks) = nullptr;
  /// Which instantiation render_tile runs for `state` with `options` and AOV channels or not:
  /// "general", "ray-cast" (no lights, no mirrors) or "ray-cast+aovs".
  const char* (*kernel_name)(const FrameState& state, const TileKernelOptions& options, bool aovs) = nullptr;
  /// out[i] = det_powf(x[i], e[i]) for i < count as the tile kernels compute the Phong
  /// highlight, several lanes at once (for tests: the same bits as det_powf).
  void (*highlight_powers)(const float* x, const float* e, float* out, std::size_t count) = nullptr;
};

/// Kernels for `isa`; throws rtc::Error when not compiled in or not supported by this CPU.
[[nodiscard]] const RenderKernels& render_kernels(Isa isa);

}  // namespace rtc
