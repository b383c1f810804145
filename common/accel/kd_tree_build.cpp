// SAH kd-tree build. Big nodes take their plane from a binned SAH over triangle references
// (Shevtsov, Soupikov, Kapustin 2007, section 3), binned and partitioned in parallel near the
// root; subtrees of at most a few thousand references take the exact O(N log N) event sweep of
// Wald & Havran 2006 in flat buffers kept between builds, with straddling triangles clipped to each
// child ("perfect splits", section 4.3); subtrees of at most 64 references (256 without
// clipping) finish with the same SAH over bit masks of their references (Zhou, Hou, Wang, Guo
// 2008, section 4.3), without further clipping. Parallel over subtrees (TBB).
#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <exception>
#include <limits>
#include <memory>
#include <mutex>
#include <new>
#include <numeric>
#include <optional>
#include <sstream>

#include <immintrin.h>
#include <sys/mman.h>

#include <fmt/format.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/task_group.h>
#include <tbb/task_arena.h>

#include "common/accel/kd_tree.h"
#include "common/base/error.h"
#include "common/base/isa.h"
#include "common/base/timer.h"

namespace rtc {
namespace {

// Event type order within one position does not matter to the sweep below (it counts a whole
// group of equal positions at once), so merged lists need only be sorted by position.
enum EventType : std::uint32_t { kEnd = 0, kPlanar = 1, kStart = 2 };

struct Event {
  float pos;
  std::uint32_t code;  // reference (index into the subtree's triangle list) << 2 | type
  [[nodiscard]] std::uint32_t ref() const { return code >> 2; }
  [[nodiscard]] std::uint32_t type() const { return code & 3u; }
};
static_assert(sizeof(Event) == 8);

enum Side : std::uint8_t { kLeft = 0, kRight = 1, kBoth = 2 };
// Whether a reference of side s is kept by the left or right child, as arithmetic on the
// encoding above (comparisons compile to branches that the sides' random order mispredicts):
// with clipping only one-sided references (a straddler's events are kept by its keep bits,
// StraddlerKeep, or made anew), without every reference not wholly on the other side.
[[gnu::always_inline]] inline std::size_t only_left(std::uint32_t s) { return 1u >> s; }
[[gnu::always_inline]] inline std::size_t only_right(std::uint32_t s) { return s & 1u; }
[[gnu::always_inline]] inline std::size_t not_right(std::uint32_t s) { return ~s & 1u; }
[[gnu::always_inline]] inline std::size_t not_left(std::uint32_t s) { return (s + 1u) >> 1; }

struct SplitChoice {
  int axis = -1;
  float pos = 0.0f;
  bool planar_left = true;
  float cost = std::numeric_limits<float>::infinity();
};

// Binned SAH resolution and the node size below which the exact sweep takes over. Against
// the exact sweep everywhere (spd-mount-s10, 2.1 M triangles, one thread): 7.1 s -> 2.9 s,
// SAH cost 83.4 -> 84.0; radiance-cabin 1.5 s -> 0.7 s, SAH 81.3 -> 80.0. 64 bins cost the
// same time but up to 9% more SAH (spd-balls-s3); 16384 or 65536 gain no quality.
constexpr int kBins = 256;
// The most references the bit-mask stage (MaskBuilder) takes: two 64-bit words.
constexpr int kMaskWords = 4;
constexpr std::size_t kMaxMaskRefs = 64 * kMaskWords;

// footprint_length's cap: an eighth of a pixel.
constexpr float kFootprintSteps = 8.0f;
// The widest footprint a build takes, in pixels (KdBuildOptions::footprint_pixels is clamped to
// it): far wider than any packet, and small enough that no grown length overflows.
constexpr float kMaxFootprintPixels = 1e6f;

// What every node of one build shares. In the binned top levels a reference's bounds in a
// node are its triangle's bounds clamped to the node's box; in the exact sweep they are the
// bounds of the triangle clipped to the node's box (clipped_bounds()).
struct BuildContext {
  const KdBuildOptions& options;
  const RawArray<Aabb>& tri_box;
  std::span<const glm::vec3> positions;
  std::span<const glm::uvec3> triangles;
  int max_depth = 0;
  int bins = 0;                 // binned SAH resolution per axis
  std::size_t exact_below = 0;  // nodes with at most this many references sweep exactly
  std::size_t binned_root_above = 0;  // KdBuildOptions::binned_root_above, at most exact_below
  float sah_scale = 1.0f;       // see sah_scale_for()
  bool clip = true;             // KdBuildOptions::clip
  std::size_t mask_below = 0;   // KdBuildOptions::mask_below, at most kMaxMaskRefs
  // The vector code the build takes (build_isa()). avx512: the event sweep's SAH, split,
  // classification and small sorts and TriangleClip's rounding take their AVX-512 code (the
  // bit-mask stage's plane scan too, with VPOPCNTDQ); avx2 (also set with avx512): their AVX2
  // code where they have one.
  bool avx512 = false;
  bool avx2 = false;
  float leaf_box_saving = 0.0f;  // KdBuildOptions::leaf_box_saving (0: no LeafBox)
  // Blocks of more references than this (a quarter of the triangles, at 2 threads or more)
  // make their event lists and sweep their large nodes' three axes side by side
  // (kSideBySideSetUp): until such a block's first fork the other threads may have nothing to
  // do (a scene of at most KdBuildOptions::binned_root_above triangles is one block; above it
  // up to exact_below, two).
  std::size_t side_by_side_above = 0;
  std::size_t threads = 1;  // build_threads()
  // The view-aware SAH (KdBuildOptions::footprint_pixels): a pixel's width per unit of distance
  // from `eye`, footprint_length's `grow` (0: the plain SAH), and the largest node it applies to.
  float pixel_slope = 0.0f;
  float footprint_grow = 0.0f;
  std::size_t footprint_max_refs = 0;
  glm::vec3 eye{0.0f};
  // The build's work in hand: top nodes and blocks being built or waiting for a thread, and
  // forked children; a builder waiting for its fork's child does not count. Fewer than
  // `threads` means a thread has nothing to do, and then any block's next large enough split
  // forks (BlockBuilder::fork, idle()).
  mutable std::atomic<std::size_t> work{0};

  // Whether some thread has no work now.
  [[nodiscard]] bool idle() const { return threads > 1 && work.load(std::memory_order_relaxed) < threads; }
};

// The threads a build may use (KdBuildOptions::threads or TBB's own limit).
std::size_t build_threads() {
  return std::min(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism),
                  static_cast<std::size_t>(std::max(tbb::this_task_arena::max_concurrency(), 1)));
}

// The vector code a build takes: KdBuildOptions::simd, up to its simd_limit, as far as the CPU
// goes (AVX-512 F, DQ, VL and BW or AVX2 with FMA and BMI2, as the tracer's kernels).
Isa build_isa(const KdBuildOptions& options) {
  static const bool avx512 = cpu_supports(Isa::Avx512), avx2 = cpu_supports(Isa::Avx2);
  if (!options.simd) return Isa::Sse42;
  if (options.simd_limit >= Isa::Avx512 && avx512) return Isa::Avx512;
  if (options.simd_limit >= Isa::Avx2 && avx2) return Isa::Avx2;
  return Isa::Sse42;
}

// The lanes of an 8-wide step with `left` elements still to go (all 8 from 8 on).
inline __mmask8 lanes8(std::size_t left) {
  return left >= 8 ? __mmask8{0xFF} : static_cast<__mmask8>((1u << left) - 1u);
}

// SAH areas are computed with every length multiplied by this power of two: 1 for scenes whose
// extent lies in [2^-30, 2^30] (exact, so those trees are unchanged), otherwise the scale that
// brings the root's largest extent to [1, 2). Without it a scene 1e30 across overflows the
// area to inf (SAH cost NaN: one leaf of everything) and one 1e-30 across underflows it to 0.
float sah_scale_for(const Aabb& root) {
  const glm::vec3 e = root.extent();
  const float m = std::max({e.x, e.y, e.z});
  if (!(m > 0.0f) || !std::isfinite(m) || (m >= 0x1p-30f && m <= 0x1p30f)) return 1.0f;
  return std::ldexp(1.0f, -std::ilogb(m));
}

float scaled_area(const Aabb& box, float scale) {
  if (box.empty()) return 0.0f;
  const glm::vec3 e = box.extent() * scale;
  return 2.0f * (e.x * e.y + e.y * e.z + e.z * e.x);
}

// What the SAH takes of a node besides its box: with a view-aware SAH (KdBuildOptions::
// footprint_pixels F > 0, a node of at most footprint_max_refs references) the lengths
// footprint_length adds to its extents, `cap` and `grow`; its extents in the SAH's scaled
// lengths with them added, and 1 / its area from those. Otherwise `grow` is 0, and every length
// and the area are the plain SAH's to the bit.
struct SahFrame {
  float inv_area = 0.0f;
  float cap = 0.0f;
  float grow = 0.0f;
  glm::vec3 extent{0.0f};
};

// A length `x` of a box as the view-aware SAH counts it: x + grow min(x, cap). With cap an
// eighth of a pixel at the node's distance from the eye and grow 8 F, every length of an
// eighth of a pixel or more is F pixels longer (a packet of rays is traced as one: it crosses a
// box when any part of its footprint does), and shorter ones 1 + 8 F times as long, so that a
// flat or needle-thin box is not made as likely to be crossed as a pixel-wide one.
inline float footprint_length(float x, float cap, float grow) { return x + grow * std::min(x, cap); }

// footprint_length, 16 lengths at once (the same operations).
[[gnu::target("avx512f")]] inline __m512 footprint_length16(__m512 x, __m512 cap, __m512 grow) {
  return _mm512_add_ps(x, _mm512_mul_ps(grow, _mm512_maskz_min_ps(0xFFFF, x, cap)));  // maskz: GCC 12 warns on min_ps
}

// The SAH's view of a node of `count` references in `box` (see SahFrame).
SahFrame sah_frame(const BuildContext& ctx, const Aabb& box, std::size_t count) {
  SahFrame f;
  if (ctx.footprint_grow > 0.0f && count <= ctx.footprint_max_refs) {
    // The distance in the SAH's scaled lengths, in double: no overflow or underflow for a scene
    // 1e30 or 1e-30 across (sah_scale_for) or an eye far from it.
    const glm::dvec3 d = glm::dvec3(glm::max(glm::max(box.lo - ctx.eye, ctx.eye - box.hi), glm::vec3(0.0f))) *
                         static_cast<double>(ctx.sah_scale);
    const float cap = static_cast<float>(static_cast<double>(ctx.pixel_slope) * glm::length(d) / kFootprintSteps);
    if (std::isfinite(cap)) f.cap = cap, f.grow = ctx.footprint_grow;  // an eye too far: the plain SAH
  }
  glm::vec3& e = f.extent;
  e = box.extent() * ctx.sah_scale;
  for (int a = 0; a < 3; ++a) e[a] = footprint_length(e[a], f.cap, f.grow);
  f.inv_area = 1.0f / (2.0f * (e.x * e.y + e.y * e.z + e.z * e.x));
  return f;
}

// SAH cost of cutting `box` at `pos` along `axis` (Wald & Havran 2006, section 3), with the
// areas of the two halves written as the box's cross-section plus the cut length times the
// perimeter of that cross-section.
class SahAxis {
 public:
  // With a footprint every length is footprint_length's: the cross-section's from the frame, the
  // cut length's in cost().
  SahAxis(const KdBuildOptions& options, const Aabb& box, int axis, const SahFrame& frame, float scale)
      : lo_(box.lo[axis]), hi_(box.hi[axis]), k_t_(options.traversal_cost),
        k_i_(options.intersection_cost * frame.inv_area), bonus_(1.0f - options.empty_bonus), scale_(scale),
        cap_(frame.cap), grow_(frame.grow) {
    const float du = frame.extent[(axis + 1) % 3], dv = frame.extent[(axis + 2) % 3];
    cross_ = du * dv;
    perimeter_ = du + dv;
  }
  [[nodiscard]] float cost(float pos, std::size_t n_left, std::size_t n_right) const {
    const float area_left = 2.0f * (cross_ + footprint_length((pos - lo_) * scale_, cap_, grow_) * perimeter_);
    const float area_right = 2.0f * (cross_ + footprint_length((hi_ - pos) * scale_, cap_, grow_) * perimeter_);
    float c = k_t_ + k_i_ * (area_left * static_cast<float>(n_left) + area_right * static_cast<float>(n_right));
    if (n_left == 0 || n_right == 0) c *= bonus_;
    return c;
  }

  // Public for the vector code (scan_planes_avx512, best_on_axis_avx512), which does cost()'s
  // operations in its order, 8 or 16 planes at a time.
  float lo_, hi_, k_t_, k_i_, bonus_, scale_, cap_, grow_, cross_ = 0, perimeter_ = 0;
};

// Clipping straddling triangles ("perfect splits", Wald & Havran 2006, section 4.3). The
// bounds computed here are never smaller than the exact intersection: Sutherland-Hodgman in
// double against the node's planes (a point on a plane counts as inside, so a triangle lying
// in a face survives), the result widened by far more than the double rounding of its clip
// steps (2^-40 of the largest magnitude involved; a polygon kept from split to split down a
// block takes at most 6 + 60 steps, each off by about 2^-52 of the magnitude), rounded outward
// to float and intersected with the clamped box. Where a clip comes out empty (a triangle that only touches
// the box, or rounding) the clamped box is kept: a reference is never dropped here. `bounds`
// are the reference's bounds so far (its triangle's box at first); results lie inside them, so
// a reference's bounds only shrink down the tree and its events never grow in number.
class TriangleClip {
 public:
  static constexpr int kMaxVerts = 32;  // 3 + one per plane exactly; rounding could add more

  // Clips triangle `tri` to `box`; false when the polygon could overflow its buffer or a
  // magnitude is not finite (the caller keeps clamped boxes then).
  bool clip(const BuildContext& ctx, std::uint32_t tri, const Aabb& box) {
    if (!set_pad(ctx, tri, box)) return false;
    const Aabb& t = ctx.tri_box[tri];
    glm::dvec3* poly = a_.data();
    glm::dvec3* next = b_.data();
    const glm::uvec3 idx = ctx.triangles[tri];
    n_ = 3;
    for (int k = 0; k < 3; ++k) poly[k] = glm::dvec3(ctx.positions[idx[k]]);
    for (int plane = 0; plane < 6 && n_ > 0; ++plane) {
      const int axis = plane >> 1;
      const bool upper = plane & 1;
      // The polygon lies inside the triangle's box: a plane that box does not cross changes
      // nothing (most planes, for triangles small against the node).
      if (upper ? t.hi[axis] <= box.hi[axis] : t.lo[axis] >= box.lo[axis]) continue;
      if (2 * n_ > kMaxVerts) return false;
      const double bound = upper ? box.hi[axis] : box.lo[axis];
      auto inside = [&](const glm::dvec3& v) { return upper ? v[axis] <= bound : v[axis] >= bound; };
      int m_out = 0;
      for (int i = 0; i < n_; ++i) {
        const glm::dvec3& a = poly[i];
        const glm::dvec3& b = poly[i + 1 == n_ ? 0 : i + 1];
        const bool in_a = inside(a), in_b = inside(b);
        if (in_a) next[m_out++] = a;
        if (in_a != in_b) next[m_out++] = cut(a, b, axis, bound);
      }
      n_ = m_out;
      std::swap(poly, next);
    }
    poly_ = poly;
    return true;
  }

  // Bounds of the clipped polygon, inside `clamped` (the reference's bounds clamped to the box).
  [[nodiscard]] Aabb bounds(const Aabb& clamped) const {
    if (n_ == 0) return clamped;
    glm::dvec3 lo(kInf), hi(-kInf);
    for (int i = 0; i < n_; ++i) {
      lo = glm::min(lo, poly_[i]);
      hi = glm::max(hi, poly_[i]);
    }
    return round_out(lo, hi, clamped);
  }

  // Takes polygon [poly, poly + n) of triangle `tri` (kept from an earlier split, where it was
  // the triangle clipped to that node's part of the box) in place of clip()'s; false where
  // clip() would have given up on the magnitudes (the caller keeps clamped boxes then).
  bool take(const BuildContext& ctx, std::uint32_t tri, const Aabb& box, const glm::dvec3* poly, int n) {
    if (!set_pad(ctx, tri, box)) return false;
    poly_ = poly;
    n_ = n;
    return true;
  }

  // Bounds of the clipped polygon's parts on either side of the plane `axis` = `p` (one more
  // clip step for each), inside `left_clamped` and `right_clamped`. The parts themselves are
  // appended to `out` (left, then right: a vertex in the plane goes to both, as does the
  // point where an edge crosses it), where `left_part` and `right_part` find them (count 0
  // for a part of more than kMaxVerts vertices, not kept). `out` must have room for
  // kSplitRoom more without reallocating: poly_ may lie in it.
  static constexpr std::size_t kSplitRoom = 4 * kMaxVerts;
  template <class PolyRef>
  void split(int axis, float p, const Aabb& left_clamped, const Aabb& right_clamped, Aabb& left, Aabb& right,
             std::vector<glm::dvec3>& out, PolyRef& left_part, PolyRef& right_part) const {
    glm::dvec3 llo(kInf), lhi(-kInf), rlo(kInf), rhi(-kInf);
    int nl = 0, nr = 0;
    const double bound = p;
    const auto at = static_cast<std::uint32_t>(out.size());
    glm::dvec3 rpart[2 * kMaxVerts];
    for (int i = 0; i < n_; ++i) {
      const glm::dvec3& a = poly_[i];
      const glm::dvec3& b = poly_[i + 1 == n_ ? 0 : i + 1];
      if (a[axis] <= bound) {
        llo = glm::min(llo, a), lhi = glm::max(lhi, a), ++nl;
        out.push_back(a);
      }
      if (a[axis] >= bound) {
        rlo = glm::min(rlo, a), rhi = glm::max(rhi, a);
        rpart[nr++] = a;
      }
      if ((a[axis] < bound && b[axis] > bound) || (a[axis] > bound && b[axis] < bound)) {
        const glm::dvec3 x = cut(a, b, axis, bound);
        llo = glm::min(llo, x), lhi = glm::max(lhi, x), ++nl;
        out.push_back(x);
        rlo = glm::min(rlo, x), rhi = glm::max(rhi, x);
        rpart[nr++] = x;
      }
    }
    left = nl > 0 ? round_out(llo, lhi, left_clamped) : left_clamped;
    right = nr > 0 ? round_out(rlo, rhi, right_clamped) : right_clamped;
    out.insert(out.end(), rpart, rpart + nr);
    left_part = PolyRef{at, nl <= kMaxVerts ? static_cast<std::uint32_t>(nl) : 0u};
    right_part = PolyRef{at + static_cast<std::uint32_t>(nl), nr <= kMaxVerts ? static_cast<std::uint32_t>(nr) : 0u};
  }

 private:
  static constexpr double kInf = std::numeric_limits<double>::infinity();

  // round_out's pad for triangle `tri` in `box` (2^-40 of the largest magnitude of either's
  // bounds) and its code; false where a magnitude is not finite.
  bool set_pad(const BuildContext& ctx, std::uint32_t tri, const Aabb& box) {
    const Aabb& t = ctx.tri_box[tri];
    const glm::dvec3 mag = glm::max(glm::max(glm::abs(glm::dvec3(t.lo)), glm::abs(glm::dvec3(t.hi))),
                                    glm::max(glm::abs(glm::dvec3(box.lo)), glm::abs(glm::dvec3(box.hi))));
    const double m = std::max({mag.x, mag.y, mag.z});
    if (!std::isfinite(m)) return false;
    pad_ = std::ldexp(m, -40);
    vector_ = ctx.avx512 ? kRoundAvx512 : (ctx.avx2 ? kRoundAvx2 : kRoundScalar);
    return true;
  }

  // The point on a-b at `bound` on `axis`. The component is put in place by selects: written
  // through x[axis], it went to the stack, and the vertex's copy then waited for that store
  // (18% of clip()'s samples on spd-rings).
  static glm::dvec3 cut(const glm::dvec3& a, const glm::dvec3& b, int axis, double bound) {
    const double f = (bound - a[axis]) / (b[axis] - a[axis]);
    const glm::dvec3 x = a + f * (b - a);
    return glm::dvec3(axis == 0 ? bound : x.x, axis == 1 ? bound : x.y, axis == 2 ? bound : x.z);
  }

  // The largest float at or below lo - pad and the smallest at or above hi + pad on each axis,
  // inside `clamped` (which it returns where they leave no room).
  [[nodiscard]] Aabb round_out(const glm::dvec3& lo, const glm::dvec3& hi, const Aabb& clamped) const {
    float l[4], h[4];
    if (vector_ == kRoundAvx512) {
      round_out_avx512(lo, hi, pad_, l, h);
    } else if (vector_ == kRoundAvx2) {
      round_out_avx2(lo, hi, pad_, l, h);
    } else {
      for (int axis = 0; axis < 3; ++axis) {
        l[axis] = static_cast<float>(lo[axis] - pad_);
        if (static_cast<double>(l[axis]) > lo[axis] - pad_) {
          l[axis] = std::nextafter(l[axis], -std::numeric_limits<float>::infinity());
        }
        h[axis] = static_cast<float>(hi[axis] + pad_);
        if (static_cast<double>(h[axis]) < hi[axis] + pad_) {
          h[axis] = std::nextafter(h[axis], std::numeric_limits<float>::infinity());
        }
      }
    }
    Aabb out;
    for (int axis = 0; axis < 3; ++axis) {
      out.lo[axis] = std::max(l[axis], clamped.lo[axis]);
      out.hi[axis] = std::min(h[axis], clamped.hi[axis]);
      if (!(out.lo[axis] <= out.hi[axis])) return clamped;
    }
    return out;
  }

  // round_out's floats with the conversions' own rounding (AVX-512's embedded rounding: toward
  // -inf for the low ends, +inf for the high ones) instead of converting to nearest and
  // stepping: the same floats, as no flush-to-zero mode is ever set.
  [[gnu::target("avx512f")]] static void round_out_avx512(const glm::dvec3& lo, const glm::dvec3& hi, double pad,
                                                          float l[4], float h[4]) {
    const __m512d p = _mm512_set1_pd(pad);
    const __m512d down = _mm512_sub_pd(_mm512_setr_pd(lo.x, lo.y, lo.z, 0.0, 0.0, 0.0, 0.0, 0.0), p);
    const __m512d up = _mm512_add_pd(_mm512_setr_pd(hi.x, hi.y, hi.z, 0.0, 0.0, 0.0, 0.0, 0.0), p);
    // (The maskz forms: GCC 12's unmasked one reads an undefined vector, which -Werror rejects.)
    _mm_storeu_ps(l, _mm256_castps256_ps128(
                         _mm512_maskz_cvt_roundpd_ps(0x0F, down, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC)));
    _mm_storeu_ps(h, _mm256_castps256_ps128(
                         _mm512_maskz_cvt_roundpd_ps(0x0F, up, _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC)));
  }

  // round_out's scalar code on AVX2: converted to nearest, and where that went past the bound
  // (the float read back as a double is above lo - pad or below hi + pad) stepped one float
  // toward -inf or +inf in its bits (nextafter: from +-0 to the smallest denormal of the other
  // sign; from +-inf to +-FLT_MAX). The same floats, as no flush-to-zero mode is ever set.
  [[gnu::target("avx2")]] static void round_out_avx2(const glm::dvec3& lo, const glm::dvec3& hi, double pad, float l[4],
                                                     float h[4]) {
    const __m256d p = _mm256_set1_pd(pad);
    const __m256d down = _mm256_sub_pd(_mm256_setr_pd(lo.x, lo.y, lo.z, 0.0), p);
    const __m256d up = _mm256_add_pd(_mm256_setr_pd(hi.x, hi.y, hi.z, 0.0), p);
    const __m128 fl = _mm256_cvtpd_ps(down), fh = _mm256_cvtpd_ps(up);
    const __m128i bl = _mm_castps_si128(fl), bh = _mm_castps_si128(fh);
    const __m128i one = _mm_set1_epi32(1);
    // Toward -inf: the bits -1 for a positive float, +1 for a negative one; toward +inf the reverse.
    const __m128i toward_up = _mm_or_si128(_mm_srai_epi32(bl, 31), one);
    __m128i stepped_l = _mm_sub_epi32(bl, toward_up);
    stepped_l = _mm_blendv_epi8(stepped_l, _mm_set1_epi32(static_cast<int>(0x80000001u)),
                                _mm_castps_si128(_mm_cmpeq_ps(fl, _mm_setzero_ps())));
    __m128i stepped_h = _mm_add_epi32(bh, _mm_or_si128(_mm_srai_epi32(bh, 31), one));
    stepped_h = _mm_blendv_epi8(stepped_h, one, _mm_castps_si128(_mm_cmpeq_ps(fh, _mm_setzero_ps())));
    // Where the float read back went past the bound: the four 64-bit compares as 32-bit lanes.
    const __m256i low_halves = _mm256_setr_epi32(0, 2, 4, 6, 0, 0, 0, 0);
    const __m128i past_l = _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(
        _mm256_castpd_si256(_mm256_cmp_pd(_mm256_cvtps_pd(fl), down, _CMP_GT_OQ)), low_halves));
    const __m128i past_h = _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(
        _mm256_castpd_si256(_mm256_cmp_pd(_mm256_cvtps_pd(fh), up, _CMP_LT_OQ)), low_halves));
    _mm_storeu_ps(l, _mm_castsi128_ps(_mm_blendv_epi8(bl, stepped_l, past_l)));
    _mm_storeu_ps(h, _mm_castsi128_ps(_mm_blendv_epi8(bh, stepped_h, past_h)));
  }

  enum RoundOut { kRoundScalar, kRoundAvx2, kRoundAvx512 };

  std::array<glm::dvec3, kMaxVerts> a_, b_;
  const glm::dvec3* poly_ = nullptr;
  int n_ = 0;
  double pad_ = 0;
  RoundOut vector_ = kRoundScalar;  // round_out's code (BuildContext::avx512, avx2)
};

Aabb clamp_box(const Aabb& bounds, const Aabb& box) {
  Aabb c;
  c.lo = glm::max(bounds.lo, box.lo);
  c.hi = glm::min(bounds.hi, box.hi);
  return c;
}

// `b` with -0 written as +0 (x + 0 is +0 for either zero), as add_events writes positions.
Aabb signless(Aabb b) {
  b.lo += glm::vec3(0.0f);
  b.hi += glm::vec3(0.0f);
  return b;
}

// Bounds of triangle `tri` clipped to `box`, inside `bounds` (see TriangleClip).
Aabb clipped_bounds(const BuildContext& ctx, std::uint32_t tri, const Aabb& box, const Aabb& bounds) {
  const Aabb& t = ctx.tri_box[tri];
  const Aabb clamped = clamp_box(bounds, box);
  if (glm::all(glm::greaterThanEqual(t.lo, box.lo)) && glm::all(glm::lessThanEqual(t.hi, box.hi))) return clamped;
  TriangleClip clip;
  if (!clip.clip(ctx, tri, box)) return clamped;
  return clip.bounds(clamped);
}

// Asks for what clipped_bounds() reads of triangle `tri`: its box, its vertex indices and,
// `vertices`, its vertices (which need the indices: callers ask for those further ahead).
// The build walks a node's references in order, but their triangles lie anywhere in the
// scene's arrays, and each read waited on memory (spd-mount-s10: 2.1 M triangles).
inline void prefetch_triangle(const BuildContext& ctx, std::uint32_t tri, bool vertices) {
  __builtin_prefetch(&ctx.tri_box[tri]);
  if (!vertices) {
    __builtin_prefetch(&ctx.triangles[tri]);
    return;
  }
  const glm::uvec3 idx = ctx.triangles[tri];
  for (int k = 0; k < 3; ++k) __builtin_prefetch(&ctx.positions[idx[k]]);
}

// A subtree swept exactly, laid out as the final tree will be (children adjacent, depth
// first, left before right) but with node and reference indices local to the block.
struct Block {
  // A reference that is a leaf's LeafBox slot: this bit and the box's index in `boxes`
  // (triangle indices are below 2^30).
  static constexpr std::uint32_t kBoxSlot = 1u << 31;

  std::vector<KdNode> nodes;  // the subtree's root at 0
  std::vector<std::uint32_t> refs;
  std::vector<Aabb> boxes;  // the leaves' boxes (kBoxSlot), not yet widened
  std::uint64_t leaves = 0;
  std::uint64_t empty_leaves = 0;
  std::uint64_t forks = 0;  // BlockBuilder::fork
  int max_depth = 0;
  double cost_area = 0;  // SAH cost times the area of the tree's root box
  // A forked child's subtree (BlockBuilder::fork) keeps its SAH cost terms in order instead of
  // summing them, and its parent adds them where its own sum has got to: the same float sum,
  // term by term, as one builder makes, so the cost does not depend on where blocks forked.
  bool keep_terms = false;
  std::vector<double> terms;

  void add_cost(double term) {
    if (keep_terms) {
      terms.push_back(term);
    } else {
      cost_area += term;
    }
  }

  // Empty, keeping the arrays' room, for a forked child's subtree (its SAH terms kept).
  void reset_for_fork() {
    nodes.clear();
    refs.clear();
    boxes.clear();
    terms.clear();
    keep_terms = true;
    leaves = empty_leaves = forks = 0;
    max_depth = 0;
    cost_area = 0;
  }

  // Makes nodes[index] a leaf over triangles tris[local[i]] (`local` ascending, so the leaf's
  // triangles are too), and adds its `count` references' share of the SAH cost. `content`: the
  // triangles' bounds in the leaf's cell `cell`; a slot for it goes before the first reference
  // where it saves at least `box_saving` (> 0) triangle tests per visit by the SAH's estimate
  // (KdBuildOptions::leaf_box_saving).
  void add_leaf(std::size_t index, std::span<const std::uint32_t> tris, std::span<const std::uint32_t> local,
                std::size_t count, float area, float intersection_cost, const Aabb& content, const Aabb& cell,
                float box_saving) {
    bool boxed = false;
    if (box_saving > 0.0f && !local.empty() && !content.empty()) {
      const float cell_area = cell.area();
      const float miss = cell_area > 0.0f ? 1.0f - std::min(content.area() / cell_area, 1.0f) : 0.0f;
      boxed = static_cast<float>(local.size()) * miss >= box_saving;
    }
    if (boxed) {
      refs.push_back(kBoxSlot | static_cast<std::uint32_t>(boxes.size()));
      boxes.push_back(content);
    }
    nodes[index] = KdNode::leaf(refs.size(), static_cast<std::uint32_t>(local.size()), boxed);
    for (std::uint32_t i : local) refs.push_back(tris[i]);
    ++leaves;
    if (local.empty()) ++empty_leaves;
    add_cost(static_cast<double>(intersection_cost) * static_cast<double>(area) * static_cast<double>(count));
  }
};

// A growable stack of events that leaves its contents uninitialised (a vector would zero
// every child list before writing it).
class EventArena {
 public:
  [[nodiscard]] std::size_t bytes() const { return capacity_ * sizeof(Event); }
  std::size_t alloc(std::size_t n) {
    if (size_ + n > capacity_) grow(size_ + n);
    const std::size_t offset = size_;
    size_ += n;
    return offset;
  }
  [[nodiscard]] Event* at(std::size_t offset) { return data_.get() + offset; }
  [[nodiscard]] const Event* at(std::size_t offset) const { return data_.get() + offset; }
  [[nodiscard]] std::size_t mark() const { return size_; }
  void release(std::size_t mark) { size_ = mark; }

 private:
  void grow(std::size_t need) {
    const std::size_t capacity = std::max(need, 2 * capacity_);
    std::unique_ptr<Event[]> data(new Event[capacity]);
    if (size_ > 0) std::memcpy(data.get(), data_.get(), size_ * sizeof(Event));
    data_ = std::move(data);
    capacity_ = capacity;
  }
  std::unique_ptr<Event[]> data_;
  std::size_t size_ = 0, capacity_ = 0;
};

// A set of the bit-mask stage's references (MaskBuilder) in W 64-bit words: reference k is
// bit k % 64 of word k / 64.
template <int W>
struct MaskBits {
  std::uint64_t w[W] = {};
  MaskBits operator&(const MaskBits& o) const {
    MaskBits r;
    for (int i = 0; i < W; ++i) r.w[i] = w[i] & o.w[i];
    return r;
  }
  MaskBits operator|(const MaskBits& o) const {
    MaskBits r;
    for (int i = 0; i < W; ++i) r.w[i] = w[i] | o.w[i];
    return r;
  }
  MaskBits& operator|=(const MaskBits& o) { return *this = *this | o; }
  [[nodiscard]] MaskBits and_not(const MaskBits& o) const {  // *this & ~o
    MaskBits r;
    for (int i = 0; i < W; ++i) r.w[i] = w[i] & ~o.w[i];
    return r;
  }
  [[nodiscard]] bool none() const {
    std::uint64_t any = 0;
    for (int i = 0; i < W; ++i) any |= w[i];
    return any == 0;
  }
  void set(std::uint32_t bit) { w[bit >> 6] |= std::uint64_t{1} << (bit & 63u); }
  // The first `n` references.
  static MaskBits first(std::size_t n) {
    MaskBits r;
    for (int i = 0; i < W; ++i) {
      const std::size_t in_word = std::min<std::size_t>(n - std::min<std::size_t>(n, 64u * static_cast<unsigned>(i)), 64);
      r.w[i] = in_word == 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << in_word) - 1;
    }
    return r;
  }
};

// One block's buffers (leased from ScratchPool for the block's run), reused by the blocks
// that lease them later.
struct Scratch {
  EventArena arena;
  // A reference's Side in the node being split; with clipping, a straddler's keep bits
  // (StraddlerKeep) above it once the split axis's lists are made.
  std::vector<std::uint32_t> side;
  std::vector<Event> sort_buffer;
  std::vector<std::uint32_t> leaf;
  std::vector<std::uint64_t> sort_bits;  // sort_distinct's bitmap, all zero between calls
  // Each reference's bounds in the node being split (clipped at the block's root, then where it
  // straddles a split), with -0 written as +0 as in its events (add_events).
  std::vector<Aabb> bounds;
  // A straddler's polygon (its triangle clipped to the node's cell) in `polys`: count 0 for
  // none kept (the triangle is clipped to the cell where it next straddles a split).
  struct PolyRef {
    std::uint32_t offset = 0, count = 0;
  };
  std::vector<PolyRef> poly_at;    // each reference's, in the node being split
  std::vector<glm::dvec3> polys;   // a stack: a node's parts above its entry size, dropped at its exit
  struct Restore {
    std::uint32_t ref;
    Aabb before, right;  // its bounds in the parent; in the right child
    PolyRef poly_before, poly_right;
  };
  std::vector<Restore> restore;  // the straddlers of the nodes on the path to the present one
  std::vector<std::uint32_t> straddlers;     // one split's references on both sides
  std::vector<std::uint32_t> slot;           // a reference's bit in the bit-mask stage
  std::vector<Aabb> clip_left, clip_right;   // a split's straddlers clipped to either child
  std::vector<PolyRef> poly_left, poly_right;  // ... and their polygons there
  TriangleClip clip;
  std::vector<Event> kept_left[3], kept_right[3];  // each axis's events of one-sided references
  std::vector<Event> new_left, new_right;    // ... and the straddlers' regenerated ones
  // The bit-mask stage (MaskBuilder): a subtree root's references and each axis's planes.
  // One axis's planes in ascending position, as arrays (the vector scan loads 8 of each at
  // once), followed by kMaskPad planes at +inf that no node takes.
  // A mask of up to 128 references is two words, word w holding references 64w..64w+63; a
  // subtree of at most 64 uses word 0 only. Each word of a plane's masks has its own array.
  struct MaskPlanes {
    static constexpr std::size_t kMaskPad = 16;  // scan_planes_avx512 reads 16 planes at a time
    std::vector<float> pos;
    std::vector<std::uint64_t> below[kMaskWords];   // references that start (or lie) below the plane
    std::vector<std::uint64_t> above[kMaskWords];   // ... that end (or lie) above it
    std::vector<std::uint64_t> planar[kMaskWords];  // ... that lie in it
    std::vector<std::uint64_t> owners[kMaskWords];  // ... with an event at it (only those planes are candidates)
    std::size_t size = 0;                           // planes before the padding
    bool any_planar = false;                        // whether any plane has a planar reference
    // Room for `most` planes of W words and the padding; no planes yet.
    template <int W>
    void start(std::size_t most) {
      const std::size_t n = most + kMaskPad;
      if (pos.size() < n) pos.resize(n);
      for (int w = 0; w < W; ++w) {
        for (std::vector<std::uint64_t>* v : {&below[w], &above[w], &planar[w], &owners[w]}) {
          if (v->size() < n) v->resize(n);
        }
      }
      size = 0;
      any_planar = false;
    }
    template <int W>
    void push(float p, const MaskBits<W>& b, const MaskBits<W>& a, const MaskBits<W>& pl, const MaskBits<W>& o) {
      pos[size] = p;
      for (int w = 0; w < W; ++w) {
        below[w][size] = b.w[w];
        above[w][size] = a.w[w];
        planar[w][size] = pl.w[w];
        owners[w][size] = o.w[w];
        any_planar |= pl.w[w] != 0;
      }
      ++size;
    }
    template <int W>
    void finish() {
      for (std::size_t i = size; i < size + kMaskPad; ++i) {
        pos[i] = std::numeric_limits<float>::infinity();
        for (int w = 0; w < W; ++w) below[w][i] = above[w][i] = planar[w][i] = owners[w][i] = 0;
      }
    }
    template <int W>
    [[nodiscard]] MaskBits<W> below_at(std::size_t i) const { return at<W>(below, i); }
    template <int W>
    [[nodiscard]] MaskBits<W> above_at(std::size_t i) const { return at<W>(above, i); }
    template <int W>
    [[nodiscard]] MaskBits<W> planar_at(std::size_t i) const { return at<W>(planar, i); }
    template <int W>
    [[nodiscard]] MaskBits<W> owners_at(std::size_t i) const { return at<W>(owners, i); }
    template <int W>
    static MaskBits<W> at(const std::vector<std::uint64_t> (&words)[kMaskWords], std::size_t i) {
      MaskBits<W> m;
      for (int w = 0; w < W; ++w) m.w[w] = words[w][i];
      return m;
    }
  };
  struct MaskTask {
    std::uint64_t mask[kMaskWords];
    std::uint32_t index;
    int depth;
    Aabb box;
    std::uint32_t from[3];  // each axis's first plane above box.lo
  };
  std::vector<std::uint32_t> mask_refs;  // bit -> index into the block's triangle list
  MaskPlanes mask_planes[3];
  std::vector<MaskTask> mask_stack;
  Block part;  // a forked child's subtree (BlockBuilder::fork), spliced into its parent's block

  // What the buffers hold (their capacity), for ScratchPool's limit.
  [[nodiscard]] std::size_t bytes() const {
    std::size_t n = arena.bytes();
    const auto add = [&n](const auto& v) { n += v.capacity() * sizeof(v[0]); };
    add(side), add(sort_buffer), add(leaf), add(sort_bits), add(bounds), add(restore), add(straddlers), add(slot);
    add(clip_left), add(clip_right), add(new_left), add(new_right), add(mask_refs), add(mask_stack);
    add(poly_at), add(polys), add(poly_left), add(poly_right);
    add(part.nodes), add(part.refs), add(part.boxes), add(part.terms);
    for (int axis = 0; axis < 3; ++axis) {
      add(kept_left[axis]), add(kept_right[axis]);
      const MaskPlanes& p = mask_planes[axis];
      add(p.pos);
      for (std::size_t w = 0; w < kMaskWords; ++w) add(p.below[w]), add(p.above[w]), add(p.planar[w]), add(p.owners[w]);
    }
    return n;
  }
};

// Scratch buffers kept from one block to the next and from one build to the next. Fresh
// buffers in every build cost a small scene's build most of its time in page faults (bunny,
// 3,674 triangles: 746 faults, about 2 ms of a 5 ms build), and a moving mesh's tree is
// rebuilt frame after frame. A block takes one for its whole run, and a fork one for its
// right child where one is spare (BlockBuilder::fork: a fork makes a new set only while there
// are at most as many as threads); a buffer set above kKeep bytes is freed instead of kept,
// and so is one a failed block leaves behind.
class ScratchPool {
 public:
  static constexpr std::size_t kKeep = std::size_t{64} << 20;

  // A set of buffers for one block, given back when it goes out of scope; `spare`: only a set
  // the pool has spare (see spare()), else none (check with has()).
  class Lease {
   public:
    explicit Lease(ScratchPool& pool, bool spare = false)
        : pool_(pool), scratch_(spare ? pool.spare() : pool.take()) {}
    Lease(const Lease&) = delete;
    Lease& operator=(const Lease&) = delete;
    ~Lease() {
      if (!scratch_) return;
      // Unwinding: a block stopped half-way may leave buffers whose invariants do not hold
      // (sort_bits all zero), so they are not kept.
      if (std::uncaught_exceptions() == exceptions_) {
        pool_.give(std::move(scratch_));
      } else {
        pool_.drop(std::move(scratch_));
      }
    }
    [[nodiscard]] bool has() const { return scratch_ != nullptr; }
    Scratch& operator*() const { return *scratch_; }

   private:
    ScratchPool& pool_;
    std::unique_ptr<Scratch> scratch_;
    int exceptions_ = std::uncaught_exceptions();
  };

  // Never destroyed: a build from another static object's destructor still finds it.
  static ScratchPool& instance() {
    static ScratchPool* const pool = new ScratchPool;
    return *pool;
  }

 private:
  std::unique_ptr<Scratch> take() {
    const std::lock_guard lock(mutex_);
    return take_locked();
  }
  // A set for a fork's child: a kept one, or a new one while there are at most as many sets as
  // threads may build (build_threads()); none otherwise. A fork is worth it where another
  // thread is idle or soon will be: with one set per thread busy, one more lets a block fork
  // a child that the thread finishing first takes up (Wuson at 2 threads: 3 forks instead of
  // 1, 0.87-0.89x the build time; bunny, spd-teapot, spd-mount within noise). So a first build
  // grows at most one set beyond one per thread.
  std::unique_ptr<Scratch> spare() {
    const std::size_t threads = build_threads();
    const std::lock_guard lock(mutex_);
    if (free_.empty() && live_ > threads) return nullptr;
    return take_locked();
  }
  std::unique_ptr<Scratch> take_locked() {
    if (!free_.empty()) {
      std::unique_ptr<Scratch> s = std::move(free_.back());
      free_.pop_back();
      return s;
    }
    std::unique_ptr<Scratch> s = std::make_unique<Scratch>();
    ++live_;
    return s;
  }
  // Keeps `s` (or frees it: above kKeep bytes, or when keeping it fails).
  void give(std::unique_ptr<Scratch> s) noexcept {
    if (s->bytes() > kKeep) return drop(std::move(s));
    try {
      const std::lock_guard lock(mutex_);
      free_.push_back(std::move(s));
    } catch (...) {  // no room for the pointer: s is freed
      drop(std::move(s));
    }
  }
  void drop(std::unique_ptr<Scratch> s) noexcept {
    s.reset();
    const std::lock_guard lock(mutex_);
    --live_;
  }

  std::mutex mutex_;
  std::vector<std::unique_ptr<Scratch>> free_;
  std::size_t live_ = 0;  // sets in existence: kept or leased
};

std::uint32_t sort_key(float pos) {
  const auto u = std::bit_cast<std::uint32_t>(pos);
  return (u & 0x80000000u) ? ~u : (u | 0x80000000u);  // unsigned order = float order
}

float from_sort_key(std::uint32_t key) {
  return std::bit_cast<float>((key & 0x80000000u) ? (key & 0x7FFFFFFFu) : ~key);
}

// Sorts distinct indices below `limit` ascending by setting them in a bitmap and reading it
// back in order: a pass over the list and one over the bitmap words its range covers, instead
// of a comparison sort. `bits` is all zero between calls (each word read is cleared).
void sort_distinct(std::vector<std::uint32_t>& v, std::size_t limit, std::vector<std::uint64_t>& bits) {
  if (v.size() < 16) {
    std::sort(v.begin(), v.end());
    return;
  }
  const std::size_t words = (limit + 63) / 64;
  if (bits.size() < words) bits.resize(words);
  std::uint32_t lo = std::numeric_limits<std::uint32_t>::max(), hi = 0;
  for (const std::uint32_t x : v) {
    bits[x >> 6] |= std::uint64_t{1} << (x & 63u);
    lo = std::min(lo, x);
    hi = std::max(hi, x);
  }
  std::size_t k = 0;
  for (std::uint32_t w = lo >> 6; w <= hi >> 6; ++w) {
    for (std::uint64_t m = bits[w]; m != 0; m &= m - 1) v[k++] = 64 * w + static_cast<std::uint32_t>(std::countr_zero(m));
    bits[w] = 0;
  }
  RTC_DCHECK(k == v.size(), "sort_distinct: repeated index");
}

// sort_events below 64 events on AVX-512: each event's place is its rank, the number of events
// with a smaller key (the key as below) plus those with an equal key before it, counted 8 events
// against one at a time (n x n/8 compares), and the events are scattered to their places. The
// same order as sorting the keys (ties are identical events, left in input order).
[[gnu::target("avx512f,avx512dq,avx512vl,avx2")]] void sort_small_events_avx512(Event* ev, std::size_t n) {
  alignas(64) std::uint64_t key[64];
  alignas(64) Event out[64];
  const std::size_t regs = (n + 7) / 8;
  const __m512i low_half = _mm512_set1_epi64(0xFFFFFFFF), sign = _mm512_set1_epi64(0x80000000);
  for (std::size_t r = 0; r < regs; ++r) {
    const std::size_t i = 8 * r;
    const __mmask8 live = lanes8(n - i);
    const __m512i v = _mm512_maskz_loadu_epi64(live, ev + i);
    // sort_key of the low half (the position): flip all bits of a negative, the sign of a
    // positive; then the halves swapped, so the key is sort_key(pos) << 32 | code.
    const __m512i flip = _mm512_and_si512(_mm512_or_si512(_mm512_maskz_srai_epi32(0xFFFF, v, 31), sign), low_half);
    _mm512_store_si512(key + i, _mm512_maskz_ror_epi64(0xFF, _mm512_xor_si512(v, flip), 32));
  }
  const __m512i one = _mm512_set1_epi64(1), lane = _mm512_setr_epi64(0, 1, 2, 3, 4, 5, 6, 7);
  for (std::size_t r = 0; r < regs; ++r) {
    const std::size_t i = 8 * r;
    const __mmask8 live = lanes8(n - i);
    const __m512i k = _mm512_load_si512(key + i);
    __m512i rank = _mm512_setzero_si512();
    for (std::size_t j = 0; j < i; ++j) {  // events before these: counted when not greater
      rank = _mm512_mask_add_epi64(rank, _mm512_cmpge_epu64_mask(k, _mm512_set1_epi64(static_cast<long long>(key[j]))),
                                   rank, one);
    }
    const std::size_t block_end = std::min(n, i + 8);
    for (std::size_t j = i; j < block_end; ++j) {  // among these: the earlier ones when equal
      const __m512i b = _mm512_set1_epi64(static_cast<long long>(key[j]));
      const __mmask8 before = _mm512_cmpgt_epu64_mask(lane, _mm512_set1_epi64(static_cast<long long>(j - i)));
      rank = _mm512_mask_add_epi64(
          rank, _mm512_cmpgt_epu64_mask(k, b) | (_mm512_cmpeq_epu64_mask(k, b) & before), rank, one);
    }
    for (std::size_t j = block_end; j < n; ++j) {  // events after these: counted when smaller
      rank = _mm512_mask_add_epi64(rank, _mm512_cmpgt_epu64_mask(k, _mm512_set1_epi64(static_cast<long long>(key[j]))),
                                   rank, one);
    }
    _mm512_mask_i64scatter_epi64(out, live, rank, _mm512_maskz_loadu_epi64(live, ev + i), 8);
  }
  std::memcpy(ev, out, n * sizeof(Event));
}

// sort_small_events_avx512 on AVX2: the 64-bit keys compared as signed (their top bit flipped),
// 8 events against one per step in two vectors of 4 (equal keys ranked in input order); the
// ranks then place the events.
[[gnu::target("avx2")]] void sort_small_events_avx2(Event* ev, std::size_t n) {
  alignas(32) std::int64_t key[64];
  alignas(32) std::int64_t rank[64];
  alignas(32) Event out[64];
  const std::size_t padded = (n + 7) & ~std::size_t{7};
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint64_t k = std::uint64_t{sort_key(ev[i].pos)} << 32 | ev[i].code;
    key[i] = static_cast<std::int64_t>(k ^ (std::uint64_t{1} << 63));
  }
  for (std::size_t i = n; i < padded; ++i) key[i] = std::numeric_limits<std::int64_t>::max();  // ranks unused
  for (std::size_t i = 0; i < padded; i += 8) {
    const __m256i k0 = _mm256_load_si256(reinterpret_cast<const __m256i*>(key + i));
    const __m256i k1 = _mm256_load_si256(reinterpret_cast<const __m256i*>(key + i + 4));
    // Counted as (their key greater) - 1 per event before these, when equal too; (their key
    // greater) among these, when equal too for lanes after the event; (their key greater) after.
    __m256i r0 = _mm256_set1_epi64x(static_cast<long long>(i)), r1 = r0;
    for (std::size_t j = 0; j < i; ++j) {
      const __m256i b = _mm256_set1_epi64x(key[j]);
      r0 = _mm256_add_epi64(r0, _mm256_cmpgt_epi64(b, k0));
      r1 = _mm256_add_epi64(r1, _mm256_cmpgt_epi64(b, k1));
    }
    const __m256i lane0 = _mm256_setr_epi64x(0, 1, 2, 3), lane1 = _mm256_setr_epi64x(4, 5, 6, 7);
    for (std::size_t j = i; j < std::min(n, i + 8); ++j) {
      const __m256i b = _mm256_set1_epi64x(key[j]);
      const __m256i at = _mm256_set1_epi64x(static_cast<long long>(j - i));
      const __m256i tie0 = _mm256_and_si256(_mm256_cmpeq_epi64(k0, b), _mm256_cmpgt_epi64(lane0, at));
      const __m256i tie1 = _mm256_and_si256(_mm256_cmpeq_epi64(k1, b), _mm256_cmpgt_epi64(lane1, at));
      r0 = _mm256_sub_epi64(r0, _mm256_or_si256(_mm256_cmpgt_epi64(k0, b), tie0));
      r1 = _mm256_sub_epi64(r1, _mm256_or_si256(_mm256_cmpgt_epi64(k1, b), tie1));
    }
    for (std::size_t j = i + 8; j < n; ++j) {
      const __m256i b = _mm256_set1_epi64x(key[j]);
      r0 = _mm256_sub_epi64(r0, _mm256_cmpgt_epi64(k0, b));
      r1 = _mm256_sub_epi64(r1, _mm256_cmpgt_epi64(k1, b));
    }
    _mm256_store_si256(reinterpret_cast<__m256i*>(rank + i), r0);
    _mm256_store_si256(reinterpret_cast<__m256i*>(rank + i + 4), r1);
  }
  for (std::size_t i = 0; i < n; ++i) out[rank[i]] = ev[i];
  std::memcpy(ev, out, n * sizeof(Event));
}

// Sorts events by position: LSD radix sort over the key bits that differ between events (a
// small node's positions share their top bits), in 1 to 4 digits of at most 11 bits, as many
// and as wide as cost least for this many events (each digit costs a pass over the events and
// one over its buckets: a small list sorts on narrow digits). Stable, so the result depends
// only on the input order, whatever the digits. Below 64 events: by (position, code), with
// AVX-512 or AVX2 (BuildContext) by rank, else with std::sort on 64-bit keys; the same order.
void sort_events(Event* ev, std::size_t n, std::vector<Event>& buffer, const BuildContext& ctx) {
  // Nothing to order; and an empty list may come as a null pointer, which the small sorts'
  // memcpy must not be given (UBSan: "null pointer passed as argument 1").
  if (n < 2) return;
  if (n < 64 && ctx.avx512) {
    sort_small_events_avx512(ev, n);
    return;
  }
  if (n < 64 && ctx.avx2) {
    sort_small_events_avx2(ev, n);
    return;
  }
  if (n < 64) {
    // By position, then code, as one 64-bit key each: integer compares instead of a float
    // comparison with a tie branch. sort_key orders floats as < does except -0 before +0,
    // and events hold no -0 (add_events writes +0).
    std::uint64_t key[64];
    for (std::size_t i = 0; i < n; ++i) key[i] = std::uint64_t{sort_key(ev[i].pos)} << 32 | ev[i].code;
    std::sort(key, key + n);
    for (std::size_t i = 0; i < n; ++i) {
      ev[i] = Event{from_sort_key(static_cast<std::uint32_t>(key[i] >> 32)), static_cast<std::uint32_t>(key[i])};
    }
    return;
  }
  const std::uint32_t key0 = sort_key(ev[0].pos);
  std::uint32_t differ = 0;
  for (std::size_t i = 0; i < n; ++i) differ |= sort_key(ev[i].pos) ^ key0;
  if (differ == 0) return;
  const int span = 32 - std::countl_zero(differ);  // bits [0, span) decide the order
  constexpr int kMaxDigits = 4, kMaxBits = 11;
  int digits = 0, width = 0;
  std::size_t best = std::numeric_limits<std::size_t>::max();
  for (int d = (span + kMaxBits - 1) / kMaxBits; d <= std::min(span, kMaxDigits); ++d) {
    const int w = (span + d - 1) / d;
    const std::size_t cost = static_cast<std::size_t>(d) * (n + (std::size_t{1} << w));
    if (cost < best) best = cost, digits = d, width = w;
  }
  const std::uint32_t digit_mask = (1u << width) - 1u;
  std::array<std::array<std::uint32_t, 1u << kMaxBits>, kMaxDigits> count;
  for (int d = 0; d < digits; ++d) std::fill_n(count[d].begin(), std::size_t{1} << width, 0u);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t k = sort_key(ev[i].pos);
    for (int d = 0; d < digits; ++d) ++count[d][(k >> (d * width)) & digit_mask];
  }
  if (buffer.size() < n) buffer.resize(n);
  Event* from = ev;
  Event* to = buffer.data();
  for (int d = 0; d < digits; ++d) {
    const int shift = d * width;
    if (count[d][(key0 >> shift) & digit_mask] == n) continue;  // every key has this digit
    std::uint32_t sum = 0;
    for (std::uint32_t b = 0; b <= digit_mask; ++b) {
      const std::uint32_t here = count[d][b];
      count[d][b] = sum;
      sum += here;
    }
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t digit = (sort_key(from[i].pos) >> shift) & digit_mask;
      to[count[d][digit]++] = from[i];
    }
    std::swap(from, to);
  }
  if (from != ev) std::memcpy(ev, from, n * sizeof(Event));
}

// The sweep over an axis's sorted events (Wald & Havran 2006, section 4.2), one group of equal
// positions at a time from ev[i] until i reaches `until` (a group that goes past it is taken
// whole); returns where it stopped, always at the start of a group. `n_left` references start
// and `n_right` end at or beyond ev[i]; both are moved past the groups swept.
[[gnu::always_inline]] inline std::size_t sweep_groups(const Event* ev, std::size_t i, std::size_t size,
                                                       std::size_t until, const SahAxis& sah, int axis,
                                                       std::size_t& n_left, std::size_t& n_right, SplitChoice& best) {
  while (i < until) {
    const float pos = ev[i].pos;
    std::size_t n_end = 0, n_planar = 0, n_start = 0;
    for (; i < size && ev[i].pos == pos; ++i) {
      const std::uint32_t t = ev[i].type();
      n_end += t == kEnd;
      n_planar += t == kPlanar;
      n_start += t == kStart;
    }
    n_right -= n_planar + n_end;
    if (pos > sah.lo_ && pos < sah.hi_) {
      // Without planar events both sides cost the same (most groups in most scenes).
      const float cost_left = sah.cost(pos, n_left + n_planar, n_right);
      const float cost_right = n_planar > 0 ? sah.cost(pos, n_left, n_right + n_planar) : cost_left;
      const bool planar_left = cost_left <= cost_right;
      const float cost = planar_left ? cost_left : cost_right;
      if (cost < best.cost) best = SplitChoice{axis, pos, planar_left, cost};
    }
    n_left += n_start + n_planar;
  }
  return i;
}

// The position of the group of equal positions that ends at ev[last], as sweep_groups takes it:
// its first event's. Equal positions have equal bits except +0 and -0, which may share a group
// where events hold -0 (TopBuilder::refine's window takes positions as they are); the sort
// puts -0 first.
[[gnu::always_inline]] inline float group_pos(const Event* ev, std::size_t last) {
  if (ev[last].pos != 0.0f) return ev[last].pos;
  std::size_t first = last;
  while (first > 0 && ev[first - 1].pos == 0.0f) --first;
  return ev[first].pos;
}

// Of 16 lanes' cheapest planes (`cost`, and `at`, where each lies in the list), the lane of the
// cheapest, and of equal ones the earliest, as a scan in list order taking only strictly cheaper
// planes would pick; -1 where none costs less than `limit`. No lane's cost is NaN.
[[gnu::target("avx512f")]] inline int cheapest_lane(__m512 cost, __m512i at, float limit) {
  constexpr __mmask16 all = 0xFFFF;  // the zero-masking forms, as in simd.h (GCC 12)
  __m512 c = _mm512_maskz_min_ps(all, cost, _mm512_maskz_shuffle_f32x4(all, cost, cost, _MM_SHUFFLE(1, 0, 3, 2)));
  c = _mm512_maskz_min_ps(all, c, _mm512_maskz_shuffle_f32x4(all, c, c, _MM_SHUFFLE(2, 3, 0, 1)));
  c = _mm512_maskz_min_ps(all, c, _mm512_maskz_permute_ps(all, c, _MM_SHUFFLE(1, 0, 3, 2)));
  c = _mm512_maskz_min_ps(all, c, _mm512_maskz_permute_ps(all, c, _MM_SHUFFLE(2, 3, 0, 1)));  // all the cheapest
  if (!(_mm512_cvtss_f32(c) < limit)) return -1;
  const __mmask16 cheapest = _mm512_cmp_ps_mask(cost, c, _CMP_EQ_OQ);
  __m512i a = _mm512_mask_blend_epi32(cheapest, _mm512_set1_epi32(std::numeric_limits<int>::max()), at);
  a = _mm512_maskz_min_epi32(all, a, _mm512_maskz_shuffle_i32x4(all, a, a, _MM_SHUFFLE(1, 0, 3, 2)));
  a = _mm512_maskz_min_epi32(all, a, _mm512_maskz_shuffle_i32x4(all, a, a, _MM_SHUFFLE(2, 3, 0, 1)));
  a = _mm512_maskz_min_epi32(all, a, _mm512_maskz_shuffle_epi32(all, a, _MM_PERM_BADC));
  a = _mm512_maskz_min_epi32(all, a, _mm512_maskz_shuffle_epi32(all, a, _MM_PERM_CDAB));  // all the earliest
  return std::countr_zero(static_cast<unsigned>(cheapest & _mm512_cmpeq_epi32_mask(at, a)));
}

// The AVX-512 code's lanes' cheapest planes, 16 lanes: each lane keeps the earliest of its
// cheapest (strictly cheaper replaces), and take() picks the cheapest lane, the earliest of equal
// ones (cheapest_lane), as a scan in list order would. Shared by the event sweep
// (best_on_axis_avx512) and the bit-mask stage's plane scan (scan_planes_avx512), as LaneBests8
// is by their AVX2 forms.
struct LaneBests16 {
  __m512 cost;
  __m512i at = _mm512_setzero_si512();
  __mmask16 planar_left = 0;

  [[gnu::target("avx512f")]] explicit LaneBests16(float limit) : cost(_mm512_set1_ps(limit)) {}

  // Planes i..i+15 where `lanes` is set, their costs and the lanes that put their planar
  // references on the left.
  [[gnu::target("avx512f"), gnu::always_inline]] void update(__mmask16 lanes, std::size_t i, __m512 costs,
                                                             __mmask16 planar) {
    const __mmask16 better = lanes & _mm512_cmp_ps_mask(costs, cost, _CMP_LT_OQ);
    cost = _mm512_mask_mov_ps(cost, better, costs);
    const __m512i lane = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    at = _mm512_mask_mov_epi32(at, better, _mm512_add_epi32(_mm512_set1_epi32(static_cast<int>(i)), lane));
    planar_left = static_cast<__mmask16>((planar_left & ~better) | (planar & better));
  }

  // The cheapest plane below `limit` (the earliest of equal ones) as the split along `axis` at
  // pos(index), and its index; SIZE_MAX (split unchanged) where there is none.
  template <typename Pos>
  [[gnu::target("avx512f")]] std::size_t take(float limit, int axis, Pos pos, SplitChoice& split) const {
    const int j = cheapest_lane(cost, at, limit);
    if (j < 0) return SIZE_MAX;
    alignas(64) float costs[16];
    alignas(64) int where[16];
    _mm512_store_ps(costs, cost);
    _mm512_store_si512(where, at);
    const auto index = static_cast<std::size_t>(where[j]);
    split = SplitChoice{axis, pos(index), ((planar_left >> j) & 1u) != 0, costs[j]};
    return index;
  }
};

// SahAxis::cost for 16 candidate planes at once, its float operations in its order (so the
// same bits): each plane's cost with its planar references on the left, (left_planar, right),
// and on the right, (left, right_planar), and the cheaper where `has_planar` (ties to the left);
// `planar_left` gets the lanes that put them on the left. The counts as floats (the two callers
// hold them as 32- or 64-bit integers). Shared by the event sweep (best_on_axis_avx512) and the
// bit-mask stage's plane scan (scan_planes_avx512), as SahCosts8 is by their AVX2 forms.
struct SahCosts16 {
  __m512 lo, hi, scale, perimeter, cross, cap, grow, two, k_t, k_i, bonus, zero;

  [[gnu::target("avx512f")]] explicit SahCosts16(const SahAxis& sah)
      : lo(_mm512_set1_ps(sah.lo_)),
        hi(_mm512_set1_ps(sah.hi_)),
        scale(_mm512_set1_ps(sah.scale_)),
        perimeter(_mm512_set1_ps(sah.perimeter_)),
        cross(_mm512_set1_ps(sah.cross_)),
        cap(_mm512_set1_ps(sah.cap_)),
        grow(_mm512_set1_ps(sah.grow_)),
        two(_mm512_set1_ps(2.0f)),
        k_t(_mm512_set1_ps(sah.k_t_)),
        k_i(_mm512_set1_ps(sah.k_i_)),
        bonus(_mm512_set1_ps(sah.bonus_)),
        zero(_mm512_setzero_ps()) {}

  [[gnu::target("avx512f")]] __m512 cost(__m512 pos, __m512 left_planar, __m512 right, __m512 left,
                                         __m512 right_planar, __mmask16 has_planar, __mmask16& planar_left) const {
    const __m512 area_left = area(_mm512_sub_ps(pos, lo)), area_right = area(_mm512_sub_ps(hi, pos));
    const __m512 cost_left = with_bonus(area_left, area_right, left_planar, right);
    const __m512 cost_right =
        _mm512_mask_blend_ps(has_planar, cost_left, with_bonus(area_left, area_right, left, right_planar));
    planar_left = _mm512_cmp_ps_mask(cost_left, cost_right, _CMP_LE_OQ);
    return _mm512_mask_blend_ps(planar_left, cost_right, cost_left);
  }

  // cost() where no plane has planar references (most planes in most scenes): its cost_left,
  // the same bits.
  [[gnu::target("avx512f")]] __m512 cost_without_planar(__m512 pos, __m512 left, __m512 right) const {
    return with_bonus(area(_mm512_sub_ps(pos, lo)), area(_mm512_sub_ps(hi, pos)), left, right);
  }

 private:
  // A half's area from its cut length (unscaled): 2 (cross + footprint_length(length) perimeter).
  [[gnu::target("avx512f")]] __m512 area(__m512 length) const {
    return _mm512_mul_ps(
        two, _mm512_add_ps(cross, _mm512_mul_ps(footprint_length16(_mm512_mul_ps(length, scale), cap, grow), perimeter)));
  }

  // k_t + k_i (area_left a + area_right b), times the empty-space bonus where a or b is 0.
  [[gnu::target("avx512f")]] __m512 with_bonus(__m512 area_left, __m512 area_right, __m512 a, __m512 b) const {
    const __m512 c =
        _mm512_add_ps(k_t, _mm512_mul_ps(k_i, _mm512_add_ps(_mm512_mul_ps(area_left, a), _mm512_mul_ps(area_right, b))));
    const __mmask16 empty_side = _mm512_cmp_ps_mask(a, zero, _CMP_EQ_OQ) | _mm512_cmp_ps_mask(b, zero, _CMP_EQ_OQ);
    return _mm512_mask_mul_ps(c, empty_side, c, bonus);
  }
};

// Lane j gets lane j - K, zeros below. The zero-masking forms, as in simd.h (GCC 12's plain ones
// trip -Wmaybe-uninitialized).
template <int K>
[[gnu::target("avx512f,avx512dq,avx512vl,avx512bw,avx2,popcnt"), gnu::always_inline]] inline __m512i shift_up16(__m512i v) {
  return _mm512_maskz_alignr_epi32(0xFFFF, v, _mm512_setzero_si512(), 16 - K);
}

// Inclusive prefix sums over the 16 lanes.
[[gnu::target("avx512f,avx512dq,avx512vl,avx512bw,avx2,popcnt"), gnu::always_inline]] inline __m512i prefix_sums16(__m512i v) {
  v = _mm512_add_epi32(v, shift_up16<1>(v));
  v = _mm512_add_epi32(v, shift_up16<2>(v));
  v = _mm512_add_epi32(v, shift_up16<4>(v));
  return _mm512_add_epi32(v, shift_up16<8>(v));
}

// Each lane's value at its group's start, carried up to the group's other lanes by a running
// maximum (the counts it carries only grow along the list), and at least `open`, the value at
// the start of the group left open by the 16 before, for the lanes before the first start.
[[gnu::target("avx512f,avx512dq,avx512vl,avx512bw,avx2,popcnt"), gnu::always_inline]] inline __m512i carry_group_start16(
    __mmask16 group_start, __m512i value, int open) {
  __m512i g = _mm512_maskz_mov_epi32(group_start, value);
  g = _mm512_maskz_max_epi32(0xFFFF, g, shift_up16<1>(g));
  g = _mm512_maskz_max_epi32(0xFFFF, g, shift_up16<2>(g));
  g = _mm512_maskz_max_epi32(0xFFFF, g, shift_up16<4>(g));
  g = _mm512_maskz_max_epi32(0xFFFF, g, shift_up16<8>(g));
  return _mm512_maskz_max_epi32(0xFFFF, g, _mm512_set1_epi32(open));
}

// sweep_groups 16 events at a time. An event ends its group where the next event's position
// differs. Prefix sums over the 16 count the starts and planars before each event (what
// n_left will be) and the ends and planars up to it (what n_right loses); a running maximum
// over the group starts carries each group's first count to its end, where its SAH costs are
// SahAxis::cost()'s float operations in its order (separate multiplies and adds, as
// -ffp-contract=off compiles the scalar code), so the same bits. Where no event of the 16 is
// planar and the group left open by the 16 before holds none either (most steps in most
// scenes), only one cost is computed, the same as either. Each lane keeps the cheapest group
// that ended in it, the earliest of equal ones, and the cheapest of the 16 lanes (the earliest
// of equal ones) is taken at the end (cheapest_lane): the plane the scalar sweep takes, with no
// branch per 16 on which groups beat the split so far.
// A group may run on into the next 16. Lanes past the end are NaN, which equals nothing.
// The zero-masking forms, as in simd.h (GCC 12's plain ones trip -Wmaybe-uninitialized).
[[gnu::target("avx512f,avx512dq,avx512vl,avx512bw,avx2,popcnt")]] SplitChoice best_on_axis_avx512(
    const SahAxis& sah, const Event* ev, std::size_t size, std::size_t n_left, std::size_t n_right, int axis) {
  SplitChoice best;
  const __m512i even = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
  const __m512i odd = _mm512_setr_epi32(1, 3, 5, 7, 9, 11, 13, 15, 17, 19, 21, 23, 25, 27, 29, 31);
  const __m512i one = _mm512_set1_epi32(1), three = _mm512_set1_epi32(3);
  const __m512i end_type = _mm512_set1_epi32(kEnd), planar_type = _mm512_set1_epi32(kPlanar);
  const __m512i start_type = _mm512_set1_epi32(kStart), low10 = _mm512_set1_epi32(0x3FF);
  const SahCosts16 costs16(sah);
  const float nan_value = std::numeric_limits<float>::quiet_NaN();
  const __m512 nan = _mm512_set1_ps(nan_value);
  // Running counts before the 16: starts and planars (n_left), planars, and n_right less the
  // ends and planars so far; the n_left and planar count at the start of the open group.
  int left_base = static_cast<int>(n_left), planar_base = 0, right_base = static_cast<int>(n_right);
  int group_left = 0, group_planar = 0;
  float prev = nan_value;
  // Each lane's cheapest plane so far: its cost, its group's last event and whether its planar
  // references go left.
  LaneBests16 bests(best.cost);
  for (std::size_t i = 0; i < size; i += 16) {
    const std::size_t rest = size - i;
    const __mmask16 live = rest >= 16 ? __mmask16{0xFFFF} : static_cast<__mmask16>((1u << rest) - 1u);
    const __m512i a = _mm512_maskz_loadu_epi64(static_cast<__mmask8>(live), ev + i);
    const __m512i b = _mm512_maskz_loadu_epi64(static_cast<__mmask8>(live >> 8), ev + i + 8);
    const __m512 pos = _mm512_mask_blend_ps(live, nan, _mm512_castsi512_ps(_mm512_permutex2var_epi32(a, even, b)));
    const __m512i pos_i = _mm512_castps_si512(pos);
    const float next_pos = rest > 16 ? ev[i + 16].pos : nan_value;
    const __m512 next = _mm512_castsi512_ps(
        _mm512_maskz_alignr_epi32(0xFFFF, _mm512_set1_epi32(std::bit_cast<int>(next_pos)), pos_i, 1));
    const __m512 before = _mm512_castsi512_ps(
        _mm512_maskz_alignr_epi32(0xFFFF, pos_i, _mm512_set1_epi32(std::bit_cast<int>(prev)), 15));
    const __mmask16 group_end = live & _mm512_cmp_ps_mask(pos, next, _CMP_NEQ_UQ);
    const __mmask16 group_start = live & _mm512_cmp_ps_mask(pos, before, _CMP_NEQ_UQ);
    const __m512i type = _mm512_and_si512(_mm512_permutex2var_epi32(a, odd, b), three);
    const __mmask16 is_planar = live & _mm512_cmpeq_epi32_mask(type, planar_type);
    const __mmask16 sp = (live & _mm512_cmpeq_epi32_mask(type, start_type)) | is_planar;
    const __mmask16 ep = (live & _mm512_cmpeq_epi32_mask(type, end_type)) | is_planar;
    // Inclusive prefix sums over the 16 (at most 16 each): starts and planars in bits 0-9,
    // planars in 10-19, ends and planars in 20-29.
    __m512i sums = _mm512_add_epi32(
        _mm512_add_epi32(_mm512_maskz_mov_epi32(sp, one), _mm512_maskz_mov_epi32(is_planar, _mm512_set1_epi32(1 << 10))),
        _mm512_maskz_mov_epi32(ep, _mm512_set1_epi32(1 << 20)));
    sums = prefix_sums16(sums);
    const __m512i sp_incl = _mm512_and_si512(sums, low10);
    const __m512i ep_incl = _mm512_maskz_srli_epi32(0xFFFF, sums, 20);
    // Before each event: n_left and the planars so far; kept at the group starts and carried
    // up by a running maximum (both only grow along the list).
    const __m512i left_before =
        _mm512_sub_epi32(_mm512_add_epi32(_mm512_set1_epi32(left_base), sp_incl), _mm512_maskz_mov_epi32(sp, one));
    const __m512i left = carry_group_start16(group_start, left_before, group_left);  // n_left before the group
    const __m512i right = _mm512_sub_epi32(_mm512_set1_epi32(right_base), ep_incl);  // n_right after it
    const __mmask16 inside = group_end & _mm512_cmp_ps_mask(pos, costs16.lo, _CMP_GT_OQ) &
                             _mm512_cmp_ps_mask(pos, costs16.hi, _CMP_LT_OQ);
    if (inside != 0) {
      __mmask16 planar_left;
      __m512 cost;
      if (is_planar == 0 && group_planar == planar_base) {
        // No group ending in these 16 holds a planar event (most of them in most scenes):
        // both sides' costs are the same, SahCosts16::cost's cost_left.
        cost = costs16.cost_without_planar(pos, _mm512_maskz_cvtepi32_ps(0xFFFF, left),
                                           _mm512_maskz_cvtepi32_ps(0xFFFF, right));
        planar_left = 0xFFFF;
      } else {
        const __m512i planar_incl = _mm512_add_epi32(
            _mm512_set1_epi32(planar_base), _mm512_and_si512(_mm512_maskz_srli_epi32(0xFFFF, sums, 10), low10));
        const __m512i planar_before = _mm512_sub_epi32(planar_incl, _mm512_maskz_mov_epi32(is_planar, one));
        // The group's planars (at its end).
        const __m512i planar =
            _mm512_sub_epi32(planar_incl, carry_group_start16(group_start, planar_before, group_planar));
        cost = costs16.cost(pos, _mm512_maskz_cvtepi32_ps(0xFFFF, _mm512_add_epi32(left, planar)),
                            _mm512_maskz_cvtepi32_ps(0xFFFF, right), _mm512_maskz_cvtepi32_ps(0xFFFF, left),
                            _mm512_maskz_cvtepi32_ps(0xFFFF, _mm512_add_epi32(right, planar)),
                            _mm512_test_epi32_mask(planar, planar), planar_left);
      }
      bests.update(inside, i, cost, planar_left);
    }
    // The open group's counts from the masks, not from gl and gp: the next 16 need not wait
    // for this one's running maximum.
    if (group_start != 0) {
      const unsigned before_last = (1u << (31 - std::countl_zero(static_cast<unsigned>(group_start)))) - 1u;
      group_left = left_base + std::popcount(sp & before_last);
      group_planar = planar_base + std::popcount(is_planar & before_last);
    }
    left_base += std::popcount(static_cast<unsigned>(sp));
    planar_base += std::popcount(static_cast<unsigned>(is_planar));
    right_base -= std::popcount(static_cast<unsigned>(ep));
    if (rest > 16) prev = ev[i + 15].pos;
  }
  // The cheapest plane, the earliest of equal ones: each lane holds the earliest of its own.
  bests.take(best.cost, axis, [ev](std::size_t k) { return group_pos(ev, k); }, best);
  return best;
}

// best_on_axis_avx512's lanes' cheapest planes for the AVX2 code, 8 lanes: each lane keeps the
// earliest of its cheapest (strictly cheaper replaces), and take() picks the cheapest lane, the
// earliest of equal ones, as a scan in list order would.
struct LaneBests8 {
  __m256 cost;
  __m256i at = _mm256_setzero_si256();
  __m256 planar_left = _mm256_setzero_ps();

  [[gnu::target("avx2")]] explicit LaneBests8(float limit) : cost(_mm256_set1_ps(limit)) {}

  // Planes i..i+7 where `lanes` (a bit per lane) is set, their costs and planar sides.
  [[gnu::target("avx2")]] void update(unsigned lanes, std::size_t i, __m256 costs, __m256 planar) {
    const __m256i bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    const __m256i in = _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(static_cast<int>(lanes)), bits), bits);
    const __m256 better = _mm256_and_ps(_mm256_castsi256_ps(in), _mm256_cmp_ps(costs, cost, _CMP_LT_OQ));
    cost = _mm256_blendv_ps(cost, costs, better);
    const __m256i index =
        _mm256_add_epi32(_mm256_set1_epi32(static_cast<int>(i)), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
    at = _mm256_castps_si256(_mm256_blendv_ps(_mm256_castsi256_ps(at), _mm256_castsi256_ps(index), better));
    planar_left = _mm256_blendv_ps(planar_left, planar, better);
  }

  // The cheapest plane below `limit` (the earliest of equal ones) as the split along `axis` at
  // pos(index), and its index; SIZE_MAX (split unchanged) where there is none.
  template <typename Pos>
  [[gnu::target("avx2")]] std::size_t take(float limit, int axis, Pos pos, SplitChoice& split) const {
    alignas(32) float costs[8];
    alignas(32) int where[8];
    _mm256_store_ps(costs, cost);
    _mm256_store_si256(reinterpret_cast<__m256i*>(where), at);
    int j = -1;
    for (int k = 0; k < 8; ++k) {
      if (costs[k] < limit || (j >= 0 && costs[k] == limit && where[k] < where[j])) j = k, limit = costs[k];
    }
    if (j < 0) return SIZE_MAX;
    const auto index = static_cast<std::size_t>(where[j]);
    const unsigned sides = static_cast<unsigned>(_mm256_movemask_ps(planar_left));
    split = SplitChoice{axis, pos(index), ((sides >> j) & 1u) != 0, costs[j]};
    return index;
  }
};

// SahAxis::cost for 8 candidate planes at once, its float operations in its order (so the
// same bits): each plane's cost with its planar references on the left and on the right, and
// the cheaper (ties to the left); `planar_left` gets the lanes that put them on the left.
// `left`, `right` and `planar` are the planes' reference counts. Shared by the event sweep
// (best_on_axis_avx2) and the bit-mask stage's plane scan (scan_planes_avx2).
struct SahCosts8 {
  __m256 lo, hi, scale, perimeter, cross, cap, grow, two, k_t, k_i, bonus, zero;

  [[gnu::target("avx2")]] explicit SahCosts8(const SahAxis& sah)
      : lo(_mm256_set1_ps(sah.lo_)),
        hi(_mm256_set1_ps(sah.hi_)),
        scale(_mm256_set1_ps(sah.scale_)),
        perimeter(_mm256_set1_ps(sah.perimeter_)),
        cross(_mm256_set1_ps(sah.cross_)),
        cap(_mm256_set1_ps(sah.cap_)),
        grow(_mm256_set1_ps(sah.grow_)),
        two(_mm256_set1_ps(2.0f)),
        k_t(_mm256_set1_ps(sah.k_t_)),
        k_i(_mm256_set1_ps(sah.k_i_)),
        bonus(_mm256_set1_ps(sah.bonus_)),
        zero(_mm256_setzero_ps()) {}

  [[gnu::target("avx2")]] __m256 cost(__m256 pos, __m256i left, __m256i right, __m256i planar,
                                      __m256& planar_left) const {
    const __m256 has_planar = _mm256_castsi256_ps(
        _mm256_xor_si256(_mm256_cmpeq_epi32(planar, _mm256_setzero_si256()), _mm256_set1_epi32(-1)));
    const __m256 area_left = area(_mm256_sub_ps(pos, lo)), area_right = area(_mm256_sub_ps(hi, pos));
    // (a, b) = (left + planar, right), then (left, right + planar).
    const __m256 cost_left = with_bonus(area_left, area_right, _mm256_cvtepi32_ps(_mm256_add_epi32(left, planar)),
                                        _mm256_cvtepi32_ps(right));
    const __m256 cost_right = _mm256_blendv_ps(
        cost_left,
        with_bonus(area_left, area_right, _mm256_cvtepi32_ps(left), _mm256_cvtepi32_ps(_mm256_add_epi32(right, planar))),
        has_planar);
    planar_left = _mm256_cmp_ps(cost_left, cost_right, _CMP_LE_OQ);
    return _mm256_blendv_ps(cost_right, cost_left, planar_left);
  }

  // cost() where no plane has planar references: its cost_left, the same bits.
  [[gnu::target("avx2")]] __m256 cost_without_planar(__m256 pos, __m256i left, __m256i right) const {
    return with_bonus(area(_mm256_sub_ps(pos, lo)), area(_mm256_sub_ps(hi, pos)), _mm256_cvtepi32_ps(left),
                      _mm256_cvtepi32_ps(right));
  }

 private:
  // footprint_length, 8 lengths at once.
  [[gnu::target("avx2")]] __m256 length(__m256 x) const {
    return _mm256_add_ps(x, _mm256_mul_ps(grow, _mm256_min_ps(x, cap)));
  }
  // A half's area from its cut length (unscaled): 2 (cross + footprint_length(length) perimeter).
  [[gnu::target("avx2")]] __m256 area(__m256 length_unscaled) const {
    return _mm256_mul_ps(two, _mm256_add_ps(cross, _mm256_mul_ps(length(_mm256_mul_ps(length_unscaled, scale)), perimeter)));
  }
  // k_t + k_i (area_left a + area_right b), times the empty-space bonus where a or b is 0.
  [[gnu::target("avx2")]] __m256 with_bonus(__m256 area_left, __m256 area_right, __m256 a, __m256 b) const {
    const __m256 c =
        _mm256_add_ps(k_t, _mm256_mul_ps(k_i, _mm256_add_ps(_mm256_mul_ps(area_left, a), _mm256_mul_ps(area_right, b))));
    const __m256 empty_side = _mm256_or_ps(_mm256_cmp_ps(a, zero, _CMP_EQ_OQ), _mm256_cmp_ps(b, zero, _CMP_EQ_OQ));
    return _mm256_blendv_ps(c, _mm256_mul_ps(c, bonus), empty_side);
  }
};

// Lane j gets lane j - K, zeros below: an alignr on the vector and its low half moved up (the
// shift crosses the two 128-bit halves).
template <int K>
[[gnu::target("avx2,popcnt"), gnu::always_inline]] inline __m256i shift_up8(__m256i v) {
  const __m256i low_half_up = _mm256_permute2x128_si256(v, v, 0x08);
  if constexpr (K == 4) return low_half_up;
  else return _mm256_alignr_epi8(v, low_half_up, 16 - 4 * K);
}

// Inclusive prefix sums over the 8 lanes.
[[gnu::target("avx2,popcnt"), gnu::always_inline]] inline __m256i prefix_sums8(__m256i v) {
  v = _mm256_add_epi32(v, shift_up8<1>(v));
  v = _mm256_add_epi32(v, shift_up8<2>(v));
  return _mm256_add_epi32(v, shift_up8<4>(v));
}

// carry_group_start16 for 8 lanes; `start` is -1 in the lanes that start a group.
[[gnu::target("avx2,popcnt"), gnu::always_inline]] inline __m256i carry_group_start8(__m256i start, __m256i value,
                                                                                    int open) {
  __m256i g = _mm256_and_si256(start, value);
  g = _mm256_max_epi32(g, shift_up8<1>(g));
  g = _mm256_max_epi32(g, shift_up8<2>(g));
  g = _mm256_max_epi32(g, shift_up8<4>(g));
  return _mm256_max_epi32(g, _mm256_set1_epi32(open));
}

// best_on_axis_avx512 8 events at a time, for CPUs with AVX2 but not AVX-512: the same prefix
// sums and running maxima over the 8 (prefix_sums8, carry_group_start8), the same float
// operations in SahAxis::cost()'s order, one cost where no event of the 8 (nor of the group left
// open) is planar, and the same cheapest plane per lane, picked at the end (LaneBests8). The
// last, partial 8 are copied out with padding events (NaN positions, type 3, which is no event
// type).
[[gnu::target("avx2,popcnt")]] SplitChoice best_on_axis_avx2(const SahAxis& sah, const Event* ev, std::size_t size,
                                                           std::size_t n_left, std::size_t n_right, int axis) {
  SplitChoice best;
  const __m256i deinterleave = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
  const __m256i next_lane = _mm256_setr_epi32(1, 2, 3, 4, 5, 6, 7, 7);
  const __m256i previous_lane = _mm256_setr_epi32(0, 0, 1, 2, 3, 4, 5, 6);
  const __m256i one = _mm256_set1_epi32(1), three = _mm256_set1_epi32(3);
  const __m256i end_type = _mm256_set1_epi32(kEnd), planar_type = _mm256_set1_epi32(kPlanar);
  const __m256i start_type = _mm256_set1_epi32(kStart), low10 = _mm256_set1_epi32(0x3FF);
  const __m256i planar_one = _mm256_set1_epi32(1 << 10), end_one = _mm256_set1_epi32(1 << 20);
  const SahCosts8 sah8(sah);
  const float nan_value = std::numeric_limits<float>::quiet_NaN();
  int left_base = static_cast<int>(n_left), planar_base = 0, right_base = static_cast<int>(n_right);
  int group_left = 0, group_planar = 0;
  float prev = nan_value;
  LaneBests8 bests(best.cost);
  alignas(32) Event tail[8];
  for (std::size_t i = 0; i < size; i += 8) {
    const std::size_t rest = size - i;
    const Event* e = ev + i;
    unsigned live = 0xFF;
    if (rest < 8) {
      for (std::size_t j = 0; j < 8; ++j) tail[j] = j < rest ? e[j] : Event{nan_value, 3u};
      e = tail;
      live = (1u << rest) - 1u;
    }
    const __m256i* in = reinterpret_cast<const __m256i*>(e);
    const __m256i a = _mm256_permutevar8x32_epi32(_mm256_loadu_si256(in), deinterleave);
    const __m256i b = _mm256_permutevar8x32_epi32(_mm256_loadu_si256(in + 1), deinterleave);
    const __m256 pos = _mm256_castsi256_ps(_mm256_permute2x128_si256(a, b, 0x20));
    const __m256i type = _mm256_and_si256(_mm256_permute2x128_si256(a, b, 0x31), three);
    const float next_pos = rest > 8 ? ev[i + 8].pos : nan_value;
    const __m256 next = _mm256_blend_ps(_mm256_permutevar8x32_ps(pos, next_lane), _mm256_set1_ps(next_pos), 0x80);
    const __m256 before = _mm256_blend_ps(_mm256_permutevar8x32_ps(pos, previous_lane), _mm256_set1_ps(prev), 0x01);
    const __m256 start_v = _mm256_cmp_ps(pos, before, _CMP_NEQ_UQ);
    const unsigned group_end = live & static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(pos, next, _CMP_NEQ_UQ)));
    const unsigned group_start = live & static_cast<unsigned>(_mm256_movemask_ps(start_v));
    const __m256i planar_v = _mm256_cmpeq_epi32(type, planar_type);
    const __m256i sp_v = _mm256_or_si256(_mm256_cmpeq_epi32(type, start_type), planar_v);
    const __m256i ep_v = _mm256_or_si256(_mm256_cmpeq_epi32(type, end_type), planar_v);
    // Inclusive prefix sums over the 8: starts and planars in bits 0-9, planars in 10-19, ends
    // and planars in 20-29.
    __m256i sums = _mm256_add_epi32(_mm256_and_si256(sp_v, one), _mm256_and_si256(planar_v, planar_one));
    sums = _mm256_add_epi32(sums, _mm256_and_si256(ep_v, end_one));
    sums = prefix_sums8(sums);
    const __m256i sp_incl = _mm256_and_si256(sums, low10);
    const __m256i ep_incl = _mm256_srli_epi32(sums, 20);
    // Before each event: n_left and the planars so far (sp_v and planar_v are -1 where set);
    // kept at the group starts and carried up by a running maximum.
    const __m256i left_before = _mm256_add_epi32(_mm256_add_epi32(_mm256_set1_epi32(left_base), sp_incl), sp_v);
    const __m256i start_i = _mm256_castps_si256(start_v);
    const __m256i left = carry_group_start8(start_i, left_before, group_left);  // n_left before the group
    const __m256i right = _mm256_sub_epi32(_mm256_set1_epi32(right_base), ep_incl);  // n_right after it
    const __m256 in_box = _mm256_and_ps(_mm256_cmp_ps(pos, sah8.lo, _CMP_GT_OQ), _mm256_cmp_ps(pos, sah8.hi, _CMP_LT_OQ));
    const unsigned inside = group_end & static_cast<unsigned>(_mm256_movemask_ps(in_box));
    const unsigned is_planar = static_cast<unsigned>(_mm256_movemask_ps(_mm256_castsi256_ps(planar_v)));
    if (inside != 0) {
      __m256 planar_left_v;
      __m256 cost;
      if (is_planar == 0 && group_planar == planar_base) {
        // No group ending in these 8 holds a planar event: SahCosts8::cost's cost_left.
        cost = sah8.cost_without_planar(pos, left, right);
        planar_left_v = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
      } else {
        const __m256i planar_incl =
            _mm256_add_epi32(_mm256_set1_epi32(planar_base), _mm256_and_si256(_mm256_srli_epi32(sums, 10), low10));
        const __m256i planar_before = _mm256_add_epi32(planar_incl, planar_v);
        // The group's planars (at its end).
        const __m256i planar = _mm256_sub_epi32(planar_incl, carry_group_start8(start_i, planar_before, group_planar));
        cost = sah8.cost(pos, left, right, planar, planar_left_v);
      }
      bests.update(inside, i, cost, planar_left_v);
    }
    // The open group's counts from the masks (the next 8 need not wait for this one's maxima).
    const unsigned sp = static_cast<unsigned>(_mm256_movemask_ps(_mm256_castsi256_ps(sp_v)));
    const unsigned ep = static_cast<unsigned>(_mm256_movemask_ps(_mm256_castsi256_ps(ep_v)));
    if (group_start != 0) {
      const unsigned before_last = (1u << (31 - std::countl_zero(group_start))) - 1u;
      group_left = left_base + std::popcount(sp & before_last);
      group_planar = planar_base + std::popcount(is_planar & before_last);
    }
    left_base += std::popcount(sp);
    planar_base += std::popcount(is_planar);
    right_base -= std::popcount(ep);
    if (rest > 8) prev = ev[i + 7].pos;
  }
  bests.take(best.cost, axis, [ev](std::size_t k) { return group_pos(ev, k); }, best);
  return best;
}

// One sweep over an axis's sorted events. The events may be a window of the axis: `n_left`
// references start and `n_right` end beyond everything before it. With options.simd, 16 events
// at a time where the CPU has AVX-512; the same split either way.
SplitChoice best_on_axis(const BuildContext& ctx, const Event* ev, std::size_t size, std::size_t n_left,
                         std::size_t n_right, const Aabb& box, int axis, const SahFrame& frame) {
  if (!(box.hi[axis] > box.lo[axis])) return SplitChoice{};
  const SahAxis sah(ctx.options, box, axis, frame, ctx.sah_scale);
  // The vector sweeps hold event indices as 32-bit lanes.
  const bool vector = size < static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()) - 16;
  if (ctx.avx512 && vector) return best_on_axis_avx512(sah, ev, size, n_left, n_right, axis);
  if (ctx.avx2 && vector) return best_on_axis_avx2(sah, ev, size, n_left, n_right, axis);
  SplitChoice best;
  sweep_groups(ev, 0, size, size, sah, axis, n_left, n_right, best);
  return best;
}

// Popcount with the POPCNT instruction where the CPU has one: MaskBuilder::build is compiled
// twice, once for it, and both copies build the same tree.
[[gnu::always_inline]] inline int popcount64(std::uint64_t x) { return std::popcount(x); }
template <int W>
[[gnu::always_inline]] inline int popcount_bits(const MaskBits<W>& m) {
  int n = 0;
  for (int i = 0; i < W; ++i) n += popcount64(m.w[i]);
  return n;
}

// One axis's candidate planes for the node `mask` of the bit-mask stage: planes [from, ...)
// that lie below `hi` and where one of the node's references has an event. A plane whose SAH
// cost is below split.cost becomes the split (the lowest plane wins a tie, and an earlier
// axis's split one of this axis), `chosen` its index.
template <int W>
[[gnu::always_inline]] inline void scan_planes(const Scratch::MaskPlanes& planes, std::size_t from, float hi,
                                               const MaskBits<W>& mask, const SahAxis& sah, int axis,
                                               SplitChoice& split, std::size_t& chosen) {
  for (std::size_t i = from; planes.pos[i] < hi; ++i) {  // the padding at +inf ends it
    if ((planes.owners_at<W>(i) & mask).none()) continue;
    const std::size_t n_left = static_cast<std::size_t>(popcount_bits(planes.below_at<W>(i) & mask));
    const std::size_t n_right = static_cast<std::size_t>(popcount_bits(planes.above_at<W>(i) & mask));
    const std::size_t n_planar = static_cast<std::size_t>(popcount_bits(planes.planar_at<W>(i) & mask));
    const float pos = planes.pos[i];
    const float cost_left = sah.cost(pos, n_left + n_planar, n_right);
    const float cost_right = n_planar > 0 ? sah.cost(pos, n_left, n_right + n_planar) : cost_left;
    const bool planar_left = cost_left <= cost_right;
    const float cost = planar_left ? cost_left : cost_right;
    if (cost < split.cost) {
      split = SplitChoice{axis, pos, planar_left, cost};
      chosen = i;
    }
  }
}

// Whether scan_planes_avx512 runs here: AVX-512 (F, DQ, VL) with VPOPCNTDQ.
bool mask_scan_avx512() {
  static const bool ok = cpu_supports(Isa::Avx512) && __builtin_cpu_supports("avx512vpopcntdq");
  return ok;
}

// scan_planes 16 planes at a time: the three popcounts of each plane with VPOPCNTDQ and SahAxis::
// cost()'s float operations in its order (separate multiplies and adds, as -ffp-contract=off
// compiles the scalar code), so the same costs bit for bit; where no plane of the subtree has a
// planar reference (MaskPlanes::any_planar), one cost per plane. Each lane keeps its cheapest
// plane below the split so far and the cheapest lane is taken at the end (cheapest_lane, as in
// best_on_axis_avx512), so the plane scan_planes takes, ties to the lowest.
// The zero-masking forms, as in simd.h (GCC 12's plain ones trip -Wmaybe-uninitialized).
// Planes i..i+7's popcounts of `words` & `m`, the words' counts summed.
template <int W>
[[gnu::target("avx512f,avx512dq,avx512vl,avx512vpopcntdq,avx2,popcnt"), gnu::always_inline]] inline __m512i mask_counts(
    const std::vector<std::uint64_t> (&words)[kMaskWords], std::size_t i, const __m512i* m) {
  __m512i n = _mm512_maskz_popcnt_epi64(0xFF, _mm512_and_si512(_mm512_loadu_si512(words[0].data() + i), m[0]));
  for (int w = 1; w < W; ++w) {
    n = _mm512_add_epi64(n,
                         _mm512_maskz_popcnt_epi64(0xFF, _mm512_and_si512(_mm512_loadu_si512(words[w].data() + i), m[w])));
  }
  return n;
}

// Two halves of 8 planes' 64-bit counts as 16 floats, planes i..i+7 in the low half.
[[gnu::target("avx512f,avx512dq,avx512vl,avx512vpopcntdq,avx2,popcnt"), gnu::always_inline]] inline __m512 counts_as_floats(
    __m512i low, __m512i high) {
  return _mm512_insertf32x8(_mm512_castps256_ps512(_mm512_maskz_cvtepi64_ps(0xFF, low)),
                            _mm512_maskz_cvtepi64_ps(0xFF, high), 1);
}

// 16 planes per step: two halves of 8 planes' counts (counts_as_floats), so the costs are
// computed 16 at a time. With two words (W = 2) each count is the sum of the two words' popcounts.
template <int W>
[[gnu::target("avx512f,avx512dq,avx512vl,avx512vpopcntdq,avx2,popcnt")]] void scan_planes_avx512(
    const Scratch::MaskPlanes& planes, std::size_t from, float hi, const MaskBits<W>& mask, const SahAxis& sah,
    int axis, SplitChoice& split, std::size_t& chosen) {
  __m512i m[W];
  for (int w = 0; w < W; ++w) m[w] = _mm512_set1_epi64(static_cast<long long>(mask.w[w]));
  const __m512 v_hi = _mm512_set1_ps(hi);
  const SahCosts16 costs16(sah);
  // A mask of 16 planes from two of 8: planes i..i+7 in the low byte.
  const auto joined = [](__mmask8 low, __mmask8 high) {
    return static_cast<__mmask16>(static_cast<unsigned>(low) | (static_cast<unsigned>(high) << 8));
  };
  // Each lane's cheapest plane below the split so far (as in best_on_axis_avx512).
  LaneBests16 bests(split.cost);
  for (std::size_t i = from;; i += 16) {  // the padding at +inf ends it
    const __m512 pos = _mm512_loadu_ps(planes.pos.data() + i);
    const __mmask16 in_range = _mm512_cmp_ps_mask(pos, v_hi, _CMP_LT_OQ);
    if (in_range == 0) break;
    __mmask8 owned_low = 0, owned_high = 0;
    for (int w = 0; w < W; ++w) {
      owned_low |= _mm512_test_epi64_mask(_mm512_loadu_si512(planes.owners[w].data() + i), m[w]);
      owned_high |= _mm512_test_epi64_mask(_mm512_loadu_si512(planes.owners[w].data() + i + 8), m[w]);
    }
    const __mmask16 valid = in_range & joined(owned_low, owned_high);
    if (valid != 0) {
      const __m512i left_low = mask_counts<W>(planes.below, i, m), left_high = mask_counts<W>(planes.below, i + 8, m);
      const __m512i right_low = mask_counts<W>(planes.above, i, m);
      const __m512i right_high = mask_counts<W>(planes.above, i + 8, m);
      __mmask16 planar_left = 0xFFFF;
      __m512 best;
      if (!planes.any_planar) {
        best = costs16.cost_without_planar(pos, counts_as_floats(left_low, left_high),
                                           counts_as_floats(right_low, right_high));
      } else {
        const __m512i planar_low = mask_counts<W>(planes.planar, i, m);
        const __m512i planar_high = mask_counts<W>(planes.planar, i + 8, m);
        const __mmask16 has_planar =
            joined(_mm512_test_epi64_mask(planar_low, planar_low), _mm512_test_epi64_mask(planar_high, planar_high));
        best = costs16.cost(
            pos, counts_as_floats(_mm512_add_epi64(left_low, planar_low), _mm512_add_epi64(left_high, planar_high)),
            counts_as_floats(right_low, right_high), counts_as_floats(left_low, left_high),
            counts_as_floats(_mm512_add_epi64(right_low, planar_low), _mm512_add_epi64(right_high, planar_high)),
            has_planar, planar_left);
      }
      bests.update(valid, i, best, planar_left);
    }
    if (in_range != 0xFFFF) break;
  }
  const std::size_t taken = bests.take(split.cost, axis, [&planes](std::size_t k) { return planes.pos[k]; }, split);
  if (taken != SIZE_MAX) chosen = taken;
}

// scan_planes_avx512 for CPUs with AVX2 but without AVX-512 VPOPCNTDQ: the popcounts of 4
// planes' words at a time by nibble lookups (PSHUFB) summed per plane (PSADBW), two such halves
// packed into 8 counts, then the same float operations in SahAxis::cost()'s order and the same
// cheapest plane per lane, picked at the end (LaneBests8).
template <int W>
[[gnu::target("avx2,popcnt"), gnu::always_inline]] inline __m256i mask_counts_avx2(
    const std::vector<std::uint64_t> (&words)[kMaskWords], std::size_t i, const __m256i* m) {
  const __m256i lut = _mm256_setr_epi8(0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4, 0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2,
                                       3, 2, 3, 3, 4);
  const __m256i low4 = _mm256_set1_epi8(0x0F);
  __m256i bytes = _mm256_setzero_si256();  // at most 8 per word and byte
  for (int w = 0; w < W; ++w) {
    const __m256i v = _mm256_and_si256(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(words[w].data() + i)), m[w]);
    const __m256i low = _mm256_shuffle_epi8(lut, _mm256_and_si256(v, low4));
    const __m256i high = _mm256_shuffle_epi8(lut, _mm256_and_si256(_mm256_srli_epi16(v, 4), low4));
    bytes = _mm256_add_epi8(bytes, _mm256_add_epi8(low, high));
  }
  return _mm256_sad_epu8(bytes, _mm256_setzero_si256());
}

// Planes i..i+7's counts as 8 32-bit lanes (each below 2^31).
template <int W>
[[gnu::target("avx2,popcnt"), gnu::always_inline]] inline __m256i mask_counts8_avx2(
    const std::vector<std::uint64_t> (&words)[kMaskWords], std::size_t i, const __m256i* m) {
  const __m256i lo = mask_counts_avx2<W>(words, i, m), hi = mask_counts_avx2<W>(words, i + 4, m);
  return _mm256_permutevar8x32_epi32(_mm256_blend_epi32(lo, _mm256_slli_epi64(hi, 32), 0xAA),
                                     _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7));
}

template <int W>
[[gnu::target("avx2,popcnt")]] void scan_planes_avx2(const Scratch::MaskPlanes& planes, std::size_t from, float hi,
                                                   const MaskBits<W>& mask, const SahAxis& sah, int axis,
                                                   SplitChoice& split, std::size_t& chosen) {
  __m256i m[W];
  for (int w = 0; w < W; ++w) m[w] = _mm256_set1_epi64x(static_cast<long long>(mask.w[w]));
  const __m256 v_hi = _mm256_set1_ps(hi);
  const SahCosts8 sah8(sah);
  const __m256i zero_i = _mm256_setzero_si256();
  LaneBests8 bests(split.cost);  // as best_on_axis_avx2
  for (std::size_t i = from;; i += 8) {  // the padding at +inf ends it
    const __m256 pos = _mm256_loadu_ps(planes.pos.data() + i);
    const unsigned in_range = static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(pos, v_hi, _CMP_LT_OQ)));
    if (in_range == 0) break;
    __m256i owned_lo = zero_i, owned_hi = zero_i;
    for (int w = 0; w < W; ++w) {
      const __m256i* o = reinterpret_cast<const __m256i*>(planes.owners[w].data() + i);
      owned_lo = _mm256_or_si256(owned_lo, _mm256_and_si256(_mm256_loadu_si256(o), m[w]));
      owned_hi = _mm256_or_si256(owned_hi, _mm256_and_si256(_mm256_loadu_si256(o + 1), m[w]));
    }
    const unsigned unowned =
        static_cast<unsigned>(_mm256_movemask_pd(_mm256_castsi256_pd(_mm256_cmpeq_epi64(owned_lo, zero_i)))) |
        static_cast<unsigned>(_mm256_movemask_pd(_mm256_castsi256_pd(_mm256_cmpeq_epi64(owned_hi, zero_i)))) << 4;
    const unsigned valid = in_range & ~unowned;
    if (valid != 0) {
      const __m256i n_left = mask_counts8_avx2<W>(planes.below, i, m);
      const __m256i n_right = mask_counts8_avx2<W>(planes.above, i, m);
      __m256 planar_left_v = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
      const __m256 best = planes.any_planar
                              ? sah8.cost(pos, n_left, n_right, mask_counts8_avx2<W>(planes.planar, i, m), planar_left_v)
                              : sah8.cost_without_planar(pos, n_left, n_right);
      bests.update(valid, i, best, planar_left_v);
    }
    if (in_range != 0xFF) break;
  }
  const std::size_t taken = bests.take(split.cost, axis, [&planes](std::size_t k) { return planes.pos[k]; }, split);
  if (taken != SIZE_MAX) chosen = taken;
}

// BlockBuilder::node's classification of the references by their events on the split axis at
// `p`, 8 events at a time: a start writes "right" (at or above p) or "both", an end at or below
// p "left", a planar event its side. The writes are one scatter per 8 events; a scatter writes
// its lanes in order, so where a reference's start and end fall in the same 8, the end's write
// comes last, as in the scalar loop.
[[gnu::target("avx512f,avx512dq,avx512vl,avx2")]] void classify_events_avx512(const Event* ev, std::size_t size,
                                                                            std::uint32_t* side, float p,
                                                                            bool planar_left) {
  const __m256 plane = _mm256_set1_ps(p);
  const __m256i three = _mm256_set1_epi32(3), start_type = _mm256_set1_epi32(kStart);
  const __m256i end_type = _mm256_set1_epi32(kEnd), planar_type = _mm256_set1_epi32(kPlanar);
  const __m256i left_side = _mm256_set1_epi32(kLeft), right_side = _mm256_set1_epi32(kRight);
  const __m256i both_sides = _mm256_set1_epi32(kBoth);
  const __mmask8 planar_left_mask = planar_left ? 0xFF : 0x00;
  for (std::size_t i = 0; i < size; i += 8) {
    const __mmask8 live = lanes8(size - i);
    const __m512i v = _mm512_maskz_loadu_epi64(live, ev + i);
    const __m256 pos = _mm256_castsi256_ps(_mm512_maskz_cvtepi64_epi32(0xFF, v));  // the low halves
    const __m256i code = _mm512_maskz_cvtepi64_epi32(0xFF, _mm512_maskz_srli_epi64(0xFF, v, 32));
    const __m256i ref = _mm256_srli_epi32(code, 2);
    const __m256i type = _mm256_and_si256(code, three);
    const __mmask8 start = live & _mm256_cmpeq_epi32_mask(type, start_type);
    const __mmask8 end = live & _mm256_cmpeq_epi32_mask(type, end_type);
    const __mmask8 planar = live & _mm256_cmpeq_epi32_mask(type, planar_type);
    const __mmask8 ge = _mm256_cmp_ps_mask(pos, plane, _CMP_GE_OQ);
    const __mmask8 le = _mm256_cmp_ps_mask(pos, plane, _CMP_LE_OQ);
    const __mmask8 planar_to_left = _mm256_cmp_ps_mask(pos, plane, _CMP_LT_OQ) |
                                    (_mm256_cmp_ps_mask(pos, plane, _CMP_EQ_OQ) & planar_left_mask);
    const __mmask8 to_right = (start & ge) | (planar & ~planar_to_left);
    const __mmask8 to_left = (end & le) | (planar & planar_to_left);
    __m256i value = _mm256_mask_mov_epi32(both_sides, to_right, right_side);
    value = _mm256_mask_mov_epi32(value, to_left, left_side);
    _mm256_mask_i32scatter_epi32(side, start | to_left | to_right, ref, value, 4);
  }
}

// What split_events_avx512 wrote: events kept on either side, how many of them are not ends
// (one per reference), and straddlers.
struct SplitCounts {
  std::size_t left = 0, right = 0, left_refs = 0, right_refs = 0, straddlers = 0;
};

// BlockBuilder::node's split of one axis's events by each reference's side, 8 events at a time:
// the sides gathered, the events kept on either side compressed into `left` and `right` in
// order (each store writes 8 events, so both have room for 8 more than they keep). With
// clipping, one-sided references' events go to their side and a straddler's (side kBoth): on
// the split axis its start to the left and its end to the right; on the other axes where its
// keep bits (above the side in the same word, StraddlerKeep) say. Without clipping, one-sided
// references' events go to their side and every other to both. On the split axis the
// one-sided references are counted and, given `straddlers`, the references whose start lies
// on both sides written there (in event order).
[[gnu::target("avx512f,avx512dq,avx512vl,avx512bw,avx2,popcnt")]] SplitCounts split_events_avx512(
    const Event* ev, std::size_t size, const std::uint32_t* side, bool clip, bool split_axis, Event* left,
    Event* right, std::uint32_t* straddlers, int axis) {
  SplitCounts out;
  const __m256i left_side = _mm256_set1_epi32(kLeft);
  const __m256i right_side = _mm256_set1_epi32(kRight), both_sides = _mm256_set1_epi32(kBoth);
  const __m512i three = _mm512_set1_epi64(3), end_type = _mm512_set1_epi64(kEnd);
  const __m512i start_type = _mm512_set1_epi64(kStart);
  const __m256i one = _mm256_set1_epi32(1), four = _mm256_set1_epi32(4), low2 = _mm256_set1_epi32(3);
  const __m256i axis_shift = _mm256_set1_epi32(2 + 4 * axis);
  for (std::size_t i = 0; i < size; i += 8) {
    const __mmask8 live = lanes8(size - i);
    const __m512i v = _mm512_maskz_loadu_epi64(live, ev + i);
    const __m512i ref = _mm512_maskz_srli_epi64(0xFF, v, 34);  // code >> 2, code in the high half
    const __m256i word = _mm512_mask_i64gather_epi32(_mm256_setzero_si256(), live, ref, side, 4);
    const __m256i where = _mm256_and_si256(word, low2);  // the Side; above it a straddler's keep bits
    const __m512i type = _mm512_and_si512(_mm512_maskz_srli_epi64(0xFF, v, 32), three);
    const __mmask8 is_end = _mm512_cmpeq_epi64_mask(type, end_type);
    const __mmask8 both = live & _mm256_cmpeq_epi32_mask(where, both_sides);
    __mmask8 to_left =
        live & (clip ? _mm256_cmpeq_epi32_mask(where, left_side) : _mm256_cmpneq_epi32_mask(where, right_side));
    __mmask8 to_right =
        live & (clip ? _mm256_cmpeq_epi32_mask(where, right_side) : _mm256_cmpneq_epi32_mask(where, left_side));
    const __mmask8 one_left = to_left, one_right = to_right;
    if (clip && split_axis) {  // a straddler's start stays on the left, its end on the right (StraddlerKeep)
      to_left |= both & ~is_end;
      to_right |= both & is_end;
    } else if (clip) {
      const __m256i at = _mm256_srlv_epi32(word, _mm256_mask_add_epi32(axis_shift, is_end, axis_shift, one));
      to_left |= both & _mm256_test_epi32_mask(at, one);
      to_right |= both & _mm256_test_epi32_mask(at, four);
    }
    _mm512_storeu_si512(left + out.left, _mm512_maskz_compress_epi64(to_left, v));
    _mm512_storeu_si512(right + out.right, _mm512_maskz_compress_epi64(to_right, v));
    out.left += static_cast<std::size_t>(std::popcount(static_cast<unsigned>(to_left)));
    out.right += static_cast<std::size_t>(std::popcount(static_cast<unsigned>(to_right)));
    if (split_axis) {
      const __mmask8 not_end = live & ~is_end;
      out.left_refs += static_cast<std::size_t>(std::popcount(static_cast<unsigned>(one_left & not_end)));
      out.right_refs += static_cast<std::size_t>(std::popcount(static_cast<unsigned>(one_right & not_end)));
      if (straddlers != nullptr) {
        const __mmask8 straddles =
            live & _mm512_cmpeq_epi64_mask(type, start_type) & _mm256_cmpeq_epi32_mask(where, both_sides);
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(straddlers + out.straddlers),
                            _mm512_maskz_cvtepi64_epi32(0xFF, _mm512_maskz_compress_epi64(straddles, ref)));
        out.straddlers += static_cast<std::size_t>(std::popcount(static_cast<unsigned>(straddles)));
      }
    }
  }
  return out;
}

// The small-node stage (Zhou, Hou, Wang, Guo 2008, "Real-time KD-tree construction on
// graphics hardware", section 4.3): a subtree of at most 256 references (one to four 64-bit
// words), handed over by BlockBuilder with its sorted event lists, numbers its references and
// turns each distinct event position into a plane with four masks (references below, above,
// in it, and with an event at it). A node is then a mask: its SAH counts at a plane are
// popcounts of the node's mask with the plane's, so a node costs a few instructions per plane
// and word and no lists are split. This is the event sweep of BlockBuilder without clipping: the same
// candidate planes (those where one of the node's references has an event), the same counts,
// costs and ties, the same depth-first layout; only straddling triangles keep the bounds they
// had at the subtree's root instead of being clipped to every node below it.
class MaskBuilder {
 public:
  MaskBuilder(const BuildContext& ctx, Scratch& scratch, std::span<const std::uint32_t> tris, Block& out)
      : ctx_(ctx), s_(scratch), tris_(tris), out_(out) {}

  // Builds the subtree at out_.nodes[index] from a node's sorted event lists.
  void run(std::size_t index, const Event* const ev[3], const std::size_t len[3], const Aabb& box, int depth) {
    std::vector<std::uint32_t>& refs = s_.mask_refs;
    refs.clear();
    for (std::size_t i = 0; i < len[0]; ++i) {
      if (ev[0][i].type() != kEnd) refs.push_back(ev[0][i].ref());
    }
    RTC_DCHECK(refs.size() <= kMaxMaskRefs, "bit-mask stage: too many references");
    if (refs.size() <= 64) {
      run_words<1>(index, ev, len, box, depth);
    } else if (refs.size() <= 128) {
      run_words<2>(index, ev, len, box, depth);
    } else if (refs.size() <= 192) {
      run_words<3>(index, ev, len, box, depth);
    } else {
      run_words<4>(index, ev, len, box, depth);
    }
  }

 private:
  static constexpr std::size_t kNone = ~std::size_t{0};
  enum Scan { kScanScalar, kScanAvx2, kScanAvx512 };

  // The index of an axis's first plane above `x`.
  static std::uint32_t first_plane_above(const Scratch::MaskPlanes& planes, float x) {
    return static_cast<std::uint32_t>(
        std::upper_bound(planes.pos.begin(), planes.pos.begin() + static_cast<std::ptrdiff_t>(planes.size), x) -
        planes.pos.begin());
  }

  template <int W>
  void run_words(std::size_t index, const Event* const ev[3], const std::size_t len[3], const Aabb& box, int depth) {
    using Bits = MaskBits<W>;
    std::vector<std::uint32_t>& refs = s_.mask_refs;
    // Bits in ascending reference order, so a leaf's set bits list its triangles ascending.
    sort_distinct(refs, tris_.size(), s_.sort_bits);
    std::vector<std::uint32_t>& slot = s_.slot;
    if (slot.size() < tris_.size()) slot.resize(tris_.size());
    for (std::size_t b = 0; b < refs.size(); ++b) slot[refs[b]] = static_cast<std::uint32_t>(b);
    const Bits all = Bits::first(refs.size());
    for (int axis = 0; axis < 3; ++axis) {
      Scratch::MaskPlanes& planes = s_.mask_planes[axis];
      planes.start<W>(len[axis]);
      if constexpr (W > 1) {
        Bits below, gone;  // started (or planar) before the plane; ended at or before it
        for (std::size_t i = 0; i < len[axis];) {
          const float pos = ev[axis][i].pos;
          Bits start, end, planar;
          for (; i < len[axis] && ev[axis][i].pos == pos; ++i) {
            const std::uint32_t bit = slot[ev[axis][i].ref()];
            switch (ev[axis][i].type()) {
              case kStart:
                start.set(bit);
                break;
              case kEnd:
                end.set(bit);
                break;
              default:
                planar.set(bit);
            }
          }
          gone |= end | planar;
          planes.push<W>(pos, below, all.and_not(gone), planar, start | end | planar);
          below |= start | planar;
        }
        planes.finish<W>();
        continue;
      }
      // One word: one plane per group of equal positions without a branch per event. Every
      // event writes its group's plane as it stands so far at index k, and the group's last
      // event keeps it (k moves on) and folds the group into `below` and `gone`. (With more
      // words the four writes per word and event cost more than the branches they save.)
      std::uint64_t below = 0, gone = 0;             // started (or planar) before the plane; ended before it
      std::uint64_t start = 0, end = 0, planar = 0;  // the present group's
      std::uint64_t any_planar = 0;
      const Event* e = ev[axis];
      const std::size_t n = len[axis];
      std::size_t k = 0;
      for (std::size_t i = 0; i < n; ++i) {
        const std::uint64_t one = std::uint64_t{1} << slot[e[i].ref()];
        const std::uint32_t type = e[i].type();
        start |= one & (std::uint64_t{0} - (type == kStart));
        end |= one & (std::uint64_t{0} - (type == kEnd));
        planar |= one & (std::uint64_t{0} - (type == kPlanar));
        const float pos = e[i].pos;
        const bool last = i + 1 == n || e[i + 1].pos != pos;
        const std::uint64_t keep = std::uint64_t{0} - last;
        planes.pos[k] = pos;
        planes.below[0][k] = below;
        planes.above[0][k] = all.w[0] & ~(gone | end | planar);
        planes.planar[0][k] = planar;
        planes.owners[0][k] = start | end | planar;
        any_planar |= planar;
        below |= (start | planar) & keep;
        gone |= (end | planar) & keep;
        start &= ~keep;
        end &= ~keep;
        planar &= ~keep;
        k += last;
      }
      planes.size = k;
      planes.any_planar = any_planar != 0;
      planes.finish<W>();
    }
    if (ctx_.avx512 && mask_scan_avx512()) {
      build_vector<W>(index, all, box, depth);
    } else if (ctx_.avx2) {
      build_avx2<W>(index, all, box, depth);
    } else if (__builtin_cpu_supports("popcnt")) {
      build_popcnt<W>(index, all, box, depth);
    } else {
      build_portable<W>(index, all, box, depth);
    }
  }

  template <int W>
  [[gnu::target("popcnt")]] void build_vector(std::size_t index, const MaskBits<W>& mask, const Aabb& box, int depth) {
    build<kScanAvx512, W>(index, mask, box, depth);
  }
  template <int W>
  [[gnu::target("popcnt")]] void build_avx2(std::size_t index, const MaskBits<W>& mask, const Aabb& box, int depth) {
    build<kScanAvx2, W>(index, mask, box, depth);
  }
  template <int W>
  [[gnu::target("popcnt")]] void build_popcnt(std::size_t index, const MaskBits<W>& mask, const Aabb& box, int depth) {
    build<kScanScalar, W>(index, mask, box, depth);
  }
  template <int W>
  void build_portable(std::size_t index, const MaskBits<W>& mask, const Aabb& box, int depth) {
    build<kScanScalar, W>(index, mask, box, depth);
  }

  // Depth first with an explicit stack (left child popped first), so children are placed
  // exactly where BlockBuilder::node's recursion would place them. kScan: each axis's planes
  // are scanned by scan_planes_avx512, scan_planes_avx2 or scan_planes; all choose the same planes.
  template <Scan kScan, int W>
  [[gnu::always_inline]] inline void build(std::size_t root, const MaskBits<W>& root_mask, const Aabb& root_box,
                                           int root_depth) {
    using Bits = MaskBits<W>;
    const auto task_of = [](const Bits& m, std::size_t index, int depth, const Aabb& box, const std::uint32_t from[3]) {
      Scratch::MaskTask t{{}, static_cast<std::uint32_t>(index), depth, box, {from[0], from[1], from[2]}};
      for (int w = 0; w < W; ++w) t.mask[w] = m.w[w];
      return t;
    };
    const KdBuildOptions& options = ctx_.options;
    std::vector<Scratch::MaskTask>& stack = s_.mask_stack;
    stack.clear();
    // A child's box starts where its parent's does but on the split axis of a right child,
    // whose box starts at the chosen plane: its first plane above is the next one (the
    // planes' positions ascend strictly).
    std::uint32_t root_from[3];
    for (int axis = 0; axis < 3; ++axis) root_from[axis] = first_plane_above(s_.mask_planes[axis], root_box.lo[axis]);
    stack.push_back(task_of(root_mask, root, root_depth, root_box, root_from));
    while (!stack.empty()) {
      const Scratch::MaskTask task = stack.back();
      stack.pop_back();
      Bits mask;
      for (int w = 0; w < W; ++w) mask.w[w] = task.mask[w];
      const Aabb& box = task.box;
      const std::size_t count = static_cast<std::size_t>(popcount_bits(mask));
      out_.max_depth = std::max(out_.max_depth, task.depth);
      const float area = scaled_area(box, ctx_.sah_scale);
      SplitChoice split;
      std::size_t chosen = kNone;  // the split's plane, in s_.mask_planes[split.axis]
      if (task.depth < ctx_.max_depth && count > static_cast<std::size_t>(options.leaf_size) && area > 0.0f) {
        const SahFrame frame = sah_frame(ctx_, box, count);
        for (int axis = 0; axis < 3; ++axis) {
          const float lo = box.lo[axis], hi = box.hi[axis];
          if (!(hi > lo)) continue;
          const SahAxis sah(options, box, axis, frame, ctx_.sah_scale);
          const Scratch::MaskPlanes& planes = s_.mask_planes[axis];
          const std::size_t from = task.from[axis];
          RTC_DCHECK(from == first_plane_above(planes, lo), "bit-mask stage: a node's first plane");
          if constexpr (kScan == kScanAvx512) {
            scan_planes_avx512<W>(planes, from, hi, mask, sah, axis, split, chosen);
          } else if constexpr (kScan == kScanAvx2) {
            scan_planes_avx2<W>(planes, from, hi, mask, sah, axis, split, chosen);
          } else {
            scan_planes<W>(planes, from, hi, mask, sah, axis, split, chosen);
          }
        }
      }
      if (chosen == kNone || !(split.cost < options.intersection_cost * static_cast<float>(count))) {
        leaf<W>(task.index, mask, count, area, box);
        continue;
      }
      out_.add_cost(static_cast<double>(options.traversal_cost) * static_cast<double>(area));
      // Below the plane, or in it on the side the split chose, go left; above it, or in it
      // otherwise, right; straddlers both.
      const Scratch::MaskPlanes& plane = s_.mask_planes[split.axis];
      const Bits in_plane = plane.planar_at<W>(chosen);
      const Bits left = mask & (split.planar_left ? plane.below_at<W>(chosen) | in_plane : plane.below_at<W>(chosen));
      const Bits right = mask & (split.planar_left ? plane.above_at<W>(chosen) : plane.above_at<W>(chosen) | in_plane);
      const std::size_t first = out_.nodes.size();
      out_.nodes.resize(first + 2);
      out_.nodes[task.index] = KdNode::inner(first, split.axis, split.pos);
      Aabb left_box = box, right_box = box;
      left_box.hi[split.axis] = split.pos;
      right_box.lo[split.axis] = split.pos;
      const int depth = task.depth + 1;
      std::uint32_t right_from[3] = {task.from[0], task.from[1], task.from[2]};
      right_from[split.axis] = static_cast<std::uint32_t>(chosen + 1);
      stack.push_back(task_of(right, first + 1, depth, right_box, right_from));
      stack.push_back(task_of(left, first, depth, left_box, task.from));
    }
  }

  // `box`: the leaf's cell. Its LeafBox bounds the references' bounds at the subtree's root
  // (they are not clipped below it) within the cell.
  template <int W>
  void leaf(std::size_t index, const MaskBits<W>& mask, std::size_t count, float area, const Aabb& box) {
    std::vector<std::uint32_t>& local = s_.leaf;
    local.clear();
    for (int w = 0; w < W; ++w) {
      for (std::uint64_t m = mask.w[w]; m != 0; m &= m - 1) {
        local.push_back(s_.mask_refs[64u * static_cast<unsigned>(w) + static_cast<unsigned>(std::countr_zero(m))]);
      }
    }
    Aabb content;
    for (std::uint32_t i : local) content.extend(s_.bounds[i]);
    out_.add_leaf(index, tris_, local, count, area, ctx_.options.intersection_cost, clamp_box(content, box), box,
                  ctx_.leaf_box_saving);
  }

  const BuildContext& ctx_;
  Scratch& s_;
  std::span<const std::uint32_t> tris_;
  Block& out_;
};

// A block that is a large part of a small scene (BlockBuilder::side_by_side_) of at least this
// many references clips its triangles and makes its three event lists side by side, and its
// nodes of at least this many sweep their three axes side by side: until its first fork the
// other threads have nothing to do.
constexpr std::size_t kSideBySideSetUp = 1024;

// How far ahead a block's loops over triangles to clip ask for their vertices (and twice as far
// for their boxes and vertex indices): prefetch_triangle.
constexpr std::size_t kTriAhead = 8;

// A sort buffer per thread, for the event lists such a block makes side by side.
std::vector<Event>& tl_sort_buffer() {
  thread_local std::vector<Event> buffer;
  return buffer;
}

// Sweeps one subtree exactly: three event lists sorted once at its root (each triangle clipped
// to the block's box), then each node splits its sorted lists into its children's (Wald &
// Havran 2006, section 4.3): one-sided references keep their events in order, straddling ones
// are clipped to either child and their few new events sorted and merged in.
class BlockBuilder {
 public:
  BlockBuilder(const BuildContext& ctx, Scratch& scratch, std::span<const std::uint32_t> tris, Block& out)
      : ctx_(ctx), s_(scratch), tris_(tris), out_(out), side_by_side_(tris.size() > ctx.side_by_side_above) {}

  void run(const Aabb& box, int depth) {
    const std::size_t n = tris_.size();
    s_.arena.release(0);
    if (s_.side.size() < n) s_.side.resize(n);
    std::size_t off[3], len[3];
    std::vector<Aabb>& bounds = s_.bounds;
    bounds.resize(n);
    const auto clip_range = [&](std::size_t from, std::size_t to) {
      for (std::size_t i = from; i < to; ++i) {
        if (i + 2 * kTriAhead < to) prefetch_triangle(ctx_, tris_[i + 2 * kTriAhead], false);
        if (ctx_.clip && i + kTriAhead < to) prefetch_triangle(ctx_, tris_[i + kTriAhead], true);
        const Aabb& t = ctx_.tri_box[tris_[i]];
        bounds[i] = signless(ctx_.clip ? clipped_bounds(ctx_, tris_[i], box, t) : clamp_box(t, box));
      }
    };
    for (int axis = 0; axis < 3; ++axis) off[axis] = s_.arena.alloc(2 * n);
    const auto make_list = [&](int axis, std::vector<Event>& sort_buffer) {
      Event* ev = s_.arena.at(off[axis]);
      std::size_t m = 0;
      for (std::size_t i = 0; i < n; ++i) m += add_events(ev + m, bounds[i], axis, static_cast<std::uint32_t>(i));
      sort_events(ev, m, sort_buffer, ctx_);
      len[axis] = m;
    };
    if (side_by_side_ && n >= kSideBySideSetUp) {
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 512),
                        [&](const tbb::blocked_range<std::size_t>& r) { clip_range(r.begin(), r.end()); });
      tbb::parallel_invoke([&] { make_list(0, s_.sort_buffer); }, [&] { make_list(1, tl_sort_buffer()); },
                           [&] { make_list(2, tl_sort_buffer()); });
    } else {
      clip_range(0, n);
      for (int axis = 0; axis < 3; ++axis) make_list(axis, s_.sort_buffer);
    }
    s_.restore.clear();
    s_.poly_at.assign(n, Scratch::PolyRef{});
    s_.polys.clear();
    out_.nodes.assign(1, KdNode{});
    node(0, off, len, n, box, depth);
  }

  // Builds the subtree of another block's node whose lists and bounds fork() put in this
  // builder's buffers (lists at `off`), exactly as that block's builder would have gone on.
  void run_prepared(const std::size_t off[3], const std::size_t len[3], std::size_t count, const Aabb& box,
                    int depth) {
    if (s_.side.size() < tris_.size()) s_.side.resize(tris_.size());
    s_.restore.clear();
    out_.nodes.assign(1, KdNode{});
    node(0, off, len, count, box, depth);
  }

 private:
  // Writes the events of a reference with bounds `b` (inside the node's box) along `axis`, but
  // for those that `kept` says stay where they are (a straddler's part's 2 keep bits,
  // StraddlerKeep: start or planar event, end); returns how many (0 to 2).
  // Positions are written with -0 as +0 (x + 0 is +0 for either zero): both compare equal, so
  // which one a group of events at zero started with would otherwise decide the sign of a
  // split plane there, and that first event depends on which references a node holds.
  static std::size_t add_events(Event* ev, const Aabb& b, int axis, std::uint32_t ref, std::uint32_t kept = 0) {
    const std::uint32_t code = ref << 2;
    const float lo = b.lo[axis] + 0.0f, hi = b.hi[axis] + 0.0f;
    if (lo == hi) {
      if ((kept & 1u) != 0) return 0;
      ev[0] = Event{lo, code | kPlanar};
      return 1;
    }
    std::size_t n = 0;
    if ((kept & 1u) == 0) ev[n++] = Event{lo, code | kStart};
    if ((kept & 2u) == 0) ev[n++] = Event{hi, code | kEnd};
    return n;
  }

  // StraddlerKeep: which of a straddler's events its parts keep unchanged, 4 bits per axis at
  // 4 * axis: the left part's start (or planar event), its end, the right part's start (or
  // planar event), its end. A part keeps an event where it has one at the same position as
  // before: both not planar with the same lower (upper) bound, or both planar at the same
  // position. The rest are made anew (add_events with the part's bits) and merged in. (On spd-rings 55% of
  // a straddler's events on the other axes, and on the split axis its start on the left and
  // its end on the right, stay.) Where an event stays, it keeps its place in the list rather
  // than following the kept events of its position: nothing in the build depends on the order
  // of events at one position.
  static std::uint32_t straddler_keep(const Aabb& before, const Aabb& left, const Aabb& right) {
    std::uint32_t bits = 0;
    for (int axis = 0; axis < 3; ++axis) {
      const bool planar = before.lo[axis] == before.hi[axis];
      const Aabb* part[2] = {&left, &right};
      for (int c = 0; c < 2; ++c) {
        const Aabb& b = *part[c];
        const bool part_planar = b.lo[axis] == b.hi[axis];
        std::uint32_t k = 0;
        if (planar && part_planar) {
          k = b.lo[axis] == before.lo[axis] ? 1u : 0u;
        } else if (!planar && !part_planar) {
          k = (b.lo[axis] == before.lo[axis] ? 1u : 0u) | (b.hi[axis] == before.hi[axis] ? 2u : 0u);
        }
        bits |= k << (4 * axis + 2 * c);
      }
    }
    return bits;
  }
  // The keep bits the split axis's lists assume: the left part's start, the right part's end.
  static constexpr std::uint32_t keep_split_axis(int axis) { return 0x9u << (4 * axis); }


  void node(std::size_t index, const std::size_t off[3], const std::size_t len[3], std::size_t count, const Aabb& box,
            int depth) {
    if (ctx_.mask_below > 0 && count <= ctx_.mask_below) {
      const Event* const ev[3] = {s_.arena.at(off[0]), s_.arena.at(off[1]), s_.arena.at(off[2])};
      MaskBuilder(ctx_, s_, tris_, out_).run(index, ev, len, box, depth);
      return;
    }
    const KdBuildOptions& options = ctx_.options;
    out_.max_depth = std::max(out_.max_depth, depth);
    const float area = scaled_area(box, ctx_.sah_scale);
    SplitChoice split;
    if (depth < ctx_.max_depth && count > static_cast<std::size_t>(options.leaf_size) && area > 0.0f) {
      const SahFrame frame = sah_frame(ctx_, box, count);
      split = wide_empty_cut(off, len, count, box, frame);
      if (split.axis < 0) {
        SplitChoice c[3];
        const auto sweep = [&](int axis) {
          c[axis] = best_on_axis(ctx_, s_.arena.at(off[axis]), len[axis], 0, count, box, axis, frame);
        };
        if (side_by_side_ && count >= kSideBySideSetUp) {
          tbb::parallel_invoke([&] { sweep(0); }, [&] { sweep(1); }, [&] { sweep(2); });
        } else {
          for (int axis = 0; axis < 3; ++axis) sweep(axis);
        }
        for (int axis = 0; axis < 3; ++axis) {
          if (c[axis].cost < split.cost) split = c[axis];  // the earliest axis wins a tie
        }
      }
    }
    if (split.axis < 0 || !(split.cost < options.intersection_cost * static_cast<float>(count))) {
      leaf(index, off, len, count, area, box);
      return;
    }
    out_.add_cost(static_cast<double>(options.traversal_cost) * static_cast<double>(area));

    const float p = split.pos;
    const int full_side = one_sided(s_.arena.at(off[split.axis]), len[split.axis], p, split.planar_left);
    if (full_side >= 0) {
      cut_off_empty(index, full_side, off, len, count, box, split.axis, p, depth);
      return;
    }
    // Classify every reference by its events on the split axis. A start precedes its own end
    // (start < end for a non-planar reference), so the start sets "both" or "right" first.
    std::uint32_t* side = s_.side.data();
    const bool vector = ctx_.avx512;
    if (vector) {
      classify_events_avx512(s_.arena.at(off[split.axis]), len[split.axis], side, p, split.planar_left);
    } else {
      // A start writes kRight (at or above p) or kBoth, an end at or below p kLeft (above p
      // it writes back what its start wrote), a planar event its side; as masks, not branches.
      static_assert(kLeft == 0 && kRight == 1 && kBoth == 2);
      const Event* ev = s_.arena.at(off[split.axis]);
      const std::uint32_t planar_left = split.planar_left;
      for (std::size_t i = 0; i < len[split.axis]; ++i) {
        const Event e = ev[i];
        const std::uint32_t t = e.type(), ref = e.ref();
        const std::uint32_t at_or_above = e.pos >= p, at_or_below = e.pos <= p;
        const std::uint32_t planar_side = 1u - ((e.pos < p) | ((e.pos == p) & planar_left));
        const std::uint32_t end_side = side[ref] & (at_or_below - 1u);
        side[ref] = ((2u - at_or_above) & (0u - (t == kStart))) | (planar_side & (0u - (t == kPlanar))) |
                    (end_side & (0u - (t == kEnd)));
      }
    }
    Aabb left_box = box, right_box = box;
    left_box.hi[split.axis] = p;
    right_box.lo[split.axis] = p;

    // Perfect splits (Wald & Havran 2006, sections 4.3 and 5): each straddling reference is
    // clipped to both children's boxes (its polygon kept for their own splits); the events of
    // its parts that moved are made anew, sorted and merged into the lists the other
    // references (and its unmoved events, StraddlerKeep) keep in order. The split axis's pass
    // comes first: it collects the straddlers (with clipping) and counts each child's one-sided
    // references; their order does not matter (sorted below).
    std::vector<std::uint32_t>& straddlers = s_.straddlers;
    straddlers.clear();
    std::size_t n_kept_left[3], n_kept_right[3];
    std::size_t left_refs = 0, right_refs = 0;
    // One axis's events split by the references' sides into the kept lists (StraddlerKeep: with
    // clipping a straddler's events stay where its parts keep them unchanged).
    const auto split_lists = [&](int axis) {
      const Event* ev = s_.arena.at(off[axis]);
      const std::size_t size = len[axis];
      const bool split_axis = axis == split.axis;
      std::vector<Event>& kept_left = s_.kept_left[axis];
      std::vector<Event>& kept_right = s_.kept_right[axis];
      if (kept_left.size() < size + 8) kept_left.resize(size + 8);  // room for a vector store's 8
      if (kept_right.size() < size + 8) kept_right.resize(size + 8);
      if (vector) {
        if (split_axis && ctx_.clip) straddlers.resize(size / 2 + 8);
        const SplitCounts c = split_events_avx512(ev, size, side, ctx_.clip, split_axis, kept_left.data(),
                                                  kept_right.data(),
                                                  split_axis && ctx_.clip ? straddlers.data() : nullptr, axis);
        n_kept_left[axis] = c.left;
        n_kept_right[axis] = c.right;
        if (split_axis) {
          if (ctx_.clip) straddlers.resize(c.straddlers);
          left_refs = c.left_refs;
          right_refs = c.right_refs;
        }
        return;
      }
      Event* l = kept_left.data();
      Event* r = kept_right.data();
      // Every event is written to both lists and kept where its side says. Without clipping a
      // straddler's events are kept by both, unchanged: events outside a child's box count the
      // same as clamped ones, and stay in order. With clipping, on the split axis a straddler's
      // start is kept on the left and its end on the right, and every reference is written to
      // the straddlers too, kept there at its start when it lies on both sides; on the other
      // axes its events are kept where its keep bits say (types and sides as arithmetic).
      static_assert(kStart == 2 && kBoth == 2 && kEnd == 0);
      if (split_axis && ctx_.clip) {
        straddlers.resize(size / 2 + 1);  // a start per reference at most
        std::uint32_t* out = straddlers.data();
        std::size_t k = 0;
        for (std::size_t i = 0; i < size; ++i) {
          const Event e = ev[i];
          const std::uint32_t s = side[e.ref()];
          const std::uint32_t both = s >> 1, end = e.type() == kEnd;
          *l = e;
          *r = e;
          l += only_left(s) | (both & (end ^ 1u));
          r += only_right(s) | (both & end);
          left_refs += only_left(s) & (end ^ 1u);
          right_refs += only_right(s) & (end ^ 1u);
          out[k] = e.ref();
          k += (e.code >> 1) & both & 1u;  // a start (type 2, no type 3) of a kBoth reference
        }
        straddlers.resize(k);
      } else if (ctx_.clip) {
        for (std::size_t i = 0; i < size; ++i) {
          const Event e = ev[i];
          const std::uint32_t word = side[e.ref()], s = word & 3u;
          const std::uint32_t both = s >> 1;
          const std::uint32_t at = word >> (2 + 4 * axis + (e.type() == kEnd ? 1 : 0));
          *l = e;
          *r = e;
          l += only_left(s) | (both & at & 1u);
          r += only_right(s) | (both & (at >> 2) & 1u);
        }
      } else {
        for (std::size_t i = 0; i < size; ++i) {
          const Event e = ev[i];
          const std::uint32_t s = side[e.ref()];
          *l = e;
          *r = e;
          l += not_right(s);
          r += not_left(s);
        }
      }
      n_kept_left[axis] = static_cast<std::size_t>(l - kept_left.data());
      n_kept_right[axis] = static_cast<std::size_t>(r - kept_right.data());
      if (split_axis && !ctx_.clip) {
        for (std::size_t i = 0; i < n_kept_left[axis]; ++i) left_refs += kept_left[i].type() != kEnd;
        for (std::size_t i = 0; i < n_kept_right[axis]; ++i) right_refs += kept_right[i].type() != kEnd;
      }
    };
    split_lists(split.axis);
    std::sort(straddlers.begin(), straddlers.end());  // new events independent of list order
    std::vector<Aabb>& bounds = s_.bounds;
    std::vector<Aabb>& clip_left = s_.clip_left;
    std::vector<Aabb>& clip_right = s_.clip_right;
    clip_left.resize(straddlers.size());
    clip_right.resize(straddlers.size());
    // The triangle is clipped to the node where it first straddles a split; one more step
    // splits the polygon in two, and each child keeps its part for its own splits.
    TriangleClip& clip = s_.clip;
    std::vector<Scratch::PolyRef>& poly_left = s_.poly_left;
    std::vector<Scratch::PolyRef>& poly_right = s_.poly_right;
    poly_left.resize(straddlers.size());
    poly_right.resize(straddlers.size());
    std::vector<glm::dvec3>& polys = s_.polys;
    const std::size_t poly_mark = polys.size();
    for (std::size_t k = 0; k < straddlers.size(); ++k) {
      const std::uint32_t ref = straddlers[k];
      const Scratch::PolyRef kept = s_.poly_at[ref];
      if (k + 2 * kTriAhead < straddlers.size()) prefetch_triangle(ctx_, tris_[straddlers[k + 2 * kTriAhead]], false);
      if (k + kTriAhead < straddlers.size() && s_.poly_at[straddlers[k + kTriAhead]].count == 0) {
        prefetch_triangle(ctx_, tris_[straddlers[k + kTriAhead]], true);
      }
      const std::uint32_t tri = tris_[ref];
      const Aabb& current = bounds[ref];
      const Aabb left_clamped = clamp_box(current, left_box);
      const Aabb right_clamped = clamp_box(current, right_box);
      // Room for both parts before the kept polygon's address is taken (it may lie in polys).
      if (polys.capacity() < polys.size() + TriangleClip::kSplitRoom) {
        polys.reserve(std::max(2 * polys.capacity(), polys.size() + TriangleClip::kSplitRoom));
      }
      const bool have = kept.count > 0 && ctx_.options.keep_clipped_polygons
                            ? clip.take(ctx_, tri, box, polys.data() + kept.offset, static_cast<int>(kept.count))
                            : clip.clip(ctx_, tri, box);
      if (have) {
        clip.split(split.axis, p, left_clamped, right_clamped, clip_left[k], clip_right[k], polys, poly_left[k],
                   poly_right[k]);
      } else {
        clip_left[k] = left_clamped;
        clip_right[k] = right_clamped;
        poly_left[k] = poly_right[k] = Scratch::PolyRef{};
      }
    }

    const std::size_t left_count = straddlers.size() + left_refs, right_count = straddlers.size() + right_refs;
    // Which of each straddler's events its parts keep (StraddlerKeep); the split axis's lists
    // kept its start on the left and its end on the right, and lose them where that was wrong.
    bool drop = false;
    if (ctx_.clip) {
      for (std::size_t k = 0; k < straddlers.size(); ++k) {
        const std::uint32_t ref = straddlers[k];
        const std::uint32_t bits = ctx_.options.keep_unmoved_events
                                       ? straddler_keep(bounds[ref], signless(clip_left[k]), signless(clip_right[k]))
                                       : 0u;  // all made anew: the split axis's kept ones taken out again
        side[ref] = kBoth | bits << 2;
        drop |= (bits & keep_split_axis(split.axis)) != keep_split_axis(split.axis);
      }
    }
    for (int axis = 0; axis < 3; ++axis) {
      if (axis != split.axis) split_lists(axis);
    }
    if (drop) {  // rare: a part's bound on the split axis moved in its last bit
      const int a = split.axis;
      const auto kept_unless = [&](std::vector<Event>& list, std::size_t& n, std::uint32_t type, std::uint32_t bit) {
        std::size_t m = 0;
        for (std::size_t i = 0; i < n; ++i) {
          const Event e = list[i];
          const std::uint32_t word = side[e.ref()];
          const bool gone = (word & 3u) == kBoth && e.type() == type && ((word >> (2 + bit)) & 1u) == 0;
          list[m] = e;
          m += gone ? 0 : 1;
        }
        n = m;
      };
      kept_unless(s_.kept_left[a], n_kept_left[a], kStart, 4 * a);
      kept_unless(s_.kept_right[a], n_kept_right[a], kEnd, 4 * a + 3);
    }

    const std::size_t mark = s_.arena.mark();
    std::size_t left_off[3], right_off[3], left_len[3], right_len[3];
    // Clipping never grows a reference's bounds, so it never has more events than before.
    for (int axis = 0; axis < 3; ++axis) {
      left_off[axis] = s_.arena.alloc(len[axis]);
      right_off[axis] = s_.arena.alloc(len[axis]);
    }
    const auto by_pos = [](const Event& x, const Event& y) { return x.pos < y.pos; };
    for (int axis = 0; axis < 3; ++axis) {
      std::vector<Event>& new_left = s_.new_left;
      std::vector<Event>& new_right = s_.new_right;
      new_left.resize(2 * straddlers.size());
      new_right.resize(2 * straddlers.size());
      std::size_t n_new_left = 0, n_new_right = 0;
      for (std::size_t k = 0; k < straddlers.size(); ++k) {
        const std::uint32_t bits = side[straddlers[k]] >> (2 + 4 * axis);
        n_new_left += add_events(new_left.data() + n_new_left, clip_left[k], axis, straddlers[k], bits & 3u);
        n_new_right +=
            add_events(new_right.data() + n_new_right, clip_right[k], axis, straddlers[k], (bits >> 2) & 3u);
      }
      sort_events(new_left.data(), n_new_left, s_.sort_buffer, ctx_);
      sort_events(new_right.data(), n_new_right, s_.sort_buffer, ctx_);
      const Event* kept_left = s_.kept_left[axis].data();
      const Event* kept_right = s_.kept_right[axis].data();
      Event* l_end = std::merge(kept_left, kept_left + n_kept_left[axis], new_left.data(),
                                new_left.data() + n_new_left, s_.arena.at(left_off[axis]), by_pos);
      Event* r_end = std::merge(kept_right, kept_right + n_kept_right[axis], new_right.data(),
                                new_right.data() + n_new_right, s_.arena.at(right_off[axis]), by_pos);
      left_len[axis] = static_cast<std::size_t>(l_end - s_.arena.at(left_off[axis]));
      right_len[axis] = static_cast<std::size_t>(r_end - s_.arena.at(right_off[axis]));
      RTC_DCHECK(left_len[axis] <= len[axis] && right_len[axis] <= len[axis], "clipping grew a reference");
    }

    const std::size_t first = out_.nodes.size();
    out_.nodes.resize(first + 2);
    out_.nodes[index] = KdNode::inner(first, split.axis, p);
    // The straddlers' bounds in the left child, then in the right, then back to these.
    const std::size_t restore = s_.restore.size();
    for (std::size_t k = 0; k < straddlers.size(); ++k) {
      const std::uint32_t ref = straddlers[k];
      s_.restore.push_back(Scratch::Restore{ref, bounds[ref], signless(clip_right[k]), s_.poly_at[ref], poly_right[k]});
      bounds[ref] = signless(clip_left[k]);
      s_.poly_at[ref] = poly_left[k];
    }
    const std::size_t restore_end = s_.restore.size();
    std::optional<ScratchPool::Lease> spare;
    if (left_count >= kForkAbove && right_count >= kForkAbove && ctx_.idle()) {
      spare.emplace(ScratchPool::instance(), true);
    }
    if (spare && spare->has()) {
      fork(first, left_off, left_len, left_count, left_box, right_off, right_len, right_count, right_box, depth + 1,
           restore, restore_end, **spare);
    } else {
      node(first, left_off, left_len, left_count, left_box, depth + 1);
      for (std::size_t k = restore; k < restore_end; ++k) {
        bounds[s_.restore[k].ref] = s_.restore[k].right;
        s_.poly_at[s_.restore[k].ref] = s_.restore[k].poly_right;
      }
      node(first + 1, right_off, right_len, right_count, right_box, depth + 1);
    }
    for (std::size_t k = restore; k < restore_end; ++k) {
      bounds[s_.restore[k].ref] = s_.restore[k].before;
      s_.poly_at[s_.restore[k].ref] = s_.restore[k].poly_before;
    }
    s_.restore.resize(restore);
    s_.polys.resize(poly_mark);
    s_.arena.release(mark);
  }

  // Both children of a split, where each holds at least this many references, some thread is
  // idle (BuildContext::idle) and a set of buffers is spare, are built side by side, the right
  // one as a block of its own: the same subtrees, nodes, references and SAH cost terms in the
  // same places and order as one builder makes them. Up to session 33 only blocks of more than
  // a quarter of the scene forked, at children of 512 and whenever a set was spare; forking only
  // for an idle thread, in any block, at 256 took 0.94x the time on bunny and 0.96x on
  // radiance-office at 2 threads (the last block no longer builds alone), the other views
  // within 2%; at 128 Wuson took 1.10x (build_experiments.md, session 34).
  static constexpr std::size_t kForkAbove = 256;

  // The children (left, right) at nodes `first` and `first + 1`, their lists in this builder's
  // arena, the straddlers' bounds in the left child in s_.bounds and in the right one in
  // s_.restore[restore, restore_end). The right child is built as a task of its own from
  // copies of its lists and bounds in `child` (copied first: the left child's lists may move
  // this builder's arena), the left one here meanwhile; the right one's subtree is then spliced
  // in after the left one's.
  void fork(std::size_t first, const std::size_t left_off[3], const std::size_t left_len[3], std::size_t left_count,
            const Aabb& left_box, const std::size_t right_off[3], const std::size_t right_len[3],
            std::size_t right_count, const Aabb& right_box, int depth, std::size_t restore, std::size_t restore_end,
            Scratch& child) {
    child.part.reset_for_fork();
    child.arena.release(0);
    std::size_t off[3];
    for (int axis = 0; axis < 3; ++axis) {
      off[axis] = child.arena.alloc(right_len[axis]);
      if (right_len[axis] > 0) {
        std::memcpy(child.arena.at(off[axis]), s_.arena.at(right_off[axis]), right_len[axis] * sizeof(Event));
      }
    }
    // The bounds of the child's own references only (each has one start or planar event per
    // axis), so a fork costs its child's size, not its block's.
    if (child.bounds.size() < tris_.size()) child.bounds.resize(tris_.size());
    const Event* ev = child.arena.at(off[0]);
    if (child.poly_at.size() < tris_.size()) child.poly_at.resize(tris_.size());
    child.polys.clear();
    const auto copy_poly = [&](Scratch::PolyRef from) {
      const auto at = static_cast<std::uint32_t>(child.polys.size());
      child.polys.insert(child.polys.end(), s_.polys.begin() + from.offset, s_.polys.begin() + from.offset + from.count);
      return Scratch::PolyRef{at, from.count};
    };
    for (std::size_t i = 0; i < right_len[0]; ++i) {
      if (ev[i].type() != kEnd) {
        child.bounds[ev[i].ref()] = s_.bounds[ev[i].ref()];
        // (This split's straddlers get their right parts below.)
        if ((s_.side[ev[i].ref()] & 3u) != kBoth) child.poly_at[ev[i].ref()] = copy_poly(s_.poly_at[ev[i].ref()]);
      }
    }
    for (std::size_t k = restore; k < restore_end; ++k) {
      child.bounds[s_.restore[k].ref] = s_.restore[k].right;
      child.poly_at[s_.restore[k].ref] = copy_poly(s_.restore[k].poly_right);
    }

    tbb::task_group right;
    ctx_.work.fetch_add(1, std::memory_order_relaxed);
    right.run([&] {
      BlockBuilder(ctx_, child, tris_, child.part).run_prepared(off, right_len, right_count, right_box, depth);
      ctx_.work.fetch_sub(1, std::memory_order_relaxed);
    });
    try {
      node(first, left_off, left_len, left_count, left_box, depth);
    } catch (...) {
      right.cancel();
      right.wait();
      throw;
    }
    ctx_.work.fetch_sub(1, std::memory_order_relaxed);  // waiting, or building the child itself
    right.wait();
    ctx_.work.fetch_add(1, std::memory_order_relaxed);
    // A build whose other task threw is cancelled, and the child may not have run: that build
    // ends in the other task's exception, not in a splice of nothing.
    if (child.part.nodes.empty()) throw Error("kd-tree build cancelled");
    splice(first + 1, child.part);
    ++out_.forks;
  }

  // Appends a child's block to this one, its root at node `slot`, the rest after this block's
  // nodes and references so far (where this builder would have put them).
  void splice(std::size_t slot, const Block& part) {
    const std::uint64_t node_base = out_.nodes.size();
    const std::uint64_t ref_base = out_.refs.size();
    const auto box_base = static_cast<std::uint32_t>(out_.boxes.size());
    const auto relocate = [&](KdNode n) {
      if (n.is_leaf()) return KdNode::leaf(n.prim_offset() + ref_base, n.tri_count(), n.has_box());
      return KdNode::inner(n.left() - 1 + node_base, n.axis(), n.split);
    };
    out_.nodes[slot] = relocate(part.nodes[0]);
    for (std::size_t i = 1; i < part.nodes.size(); ++i) out_.nodes.push_back(relocate(part.nodes[i]));
    for (const std::uint32_t r : part.refs) {
      out_.refs.push_back((r & Block::kBoxSlot) != 0 ? Block::kBoxSlot | ((r & ~Block::kBoxSlot) + box_base) : r);
    }
    out_.boxes.insert(out_.boxes.end(), part.boxes.begin(), part.boxes.end());
    out_.leaves += part.leaves;
    out_.empty_leaves += part.empty_leaves;
    out_.forks += part.forks;
    out_.max_depth = std::max(out_.max_depth, part.max_depth);
    for (const double t : part.terms) out_.add_cost(t);
  }

  // The side every reference of the node lies on for the plane `axis` = `p` (`ev`: that axis's
  // sorted events), as the classification below would put it: 0 left, 1 right, -1 neither (some
  // on each side or on both). A reference goes right when it has an event above p (a start at
  // p has its end above) or lies in p without planar_left, left when it has one below p (an
  // end at p has its start below) or lies in p with planar_left.
  static int one_sided(const Event* ev, std::size_t n, float p, bool planar_left) {
    if (n == 0) return -1;
    const auto planar_at_p = [&](std::size_t i, std::ptrdiff_t step) {
      for (; i < n && ev[i].pos == p; i += static_cast<std::size_t>(step)) {  // i wraps past 0 to >= n
        if (ev[i].type() == kPlanar) return true;
      }
      return false;
    };
    if (ev[0].pos > p || (ev[0].pos == p && !(planar_left && planar_at_p(0, 1)))) return 1;
    if (ev[n - 1].pos < p || (ev[n - 1].pos == p && !(!planar_left && planar_at_p(n - 1, -1)))) return 0;
    return -1;
  }

  // KdBuildOptions::empty_cut: the plane at the references' bound that leaves the widest empty
  // gap (as a fraction of the cell's extent; the earliest axis, then the lower side, wins a
  // tie) where that gap is at least empty_cut and the cut's SAH cost is below a leaf's. The
  // first and last events of each axis's sorted list are the references' bounds there. Planar
  // references at the plane stay with the rest (planar_left: true at the upper bound), so every
  // reference goes to one side and cut_off_empty takes the cut. No cut: axis -1.
  [[nodiscard]] SplitChoice wide_empty_cut(const std::size_t off[3], const std::size_t len[3], std::size_t count,
                                           const Aabb& box, const SahFrame& frame) const {
    const KdBuildOptions& options = ctx_.options;
    if (!(options.empty_cut <= 1.0f)) return SplitChoice{};
    float widest = 0.0f;
    int axis = -1;
    bool upper = false;
    for (int a = 0; a < 3; ++a) {
      const float extent = box.hi[a] - box.lo[a];
      if (len[a] == 0 || !(extent > 0.0f)) continue;
      const Event* ev = s_.arena.at(off[a]);
      const float below = (ev[0].pos - box.lo[a]) / extent, above = (box.hi[a] - ev[len[a] - 1].pos) / extent;
      if (below > widest) widest = below, axis = a, upper = false;
      if (above > widest) widest = above, axis = a, upper = true;
    }
    if (axis < 0 || !(widest >= options.empty_cut)) return SplitChoice{};
    const Event* ev = s_.arena.at(off[axis]);
    const float p = upper ? ev[len[axis] - 1].pos : ev[0].pos;
    if (!(p > box.lo[axis] && p < box.hi[axis])) return SplitChoice{};
    const SahAxis sah(options, box, axis, frame, ctx_.sah_scale);
    const float cost = upper ? sah.cost(p, count, 0) : sah.cost(p, 0, count);
    if (!(cost < options.intersection_cost * static_cast<float>(count))) return SplitChoice{};
    return SplitChoice{axis, p, upper, cost};
  }

  // A split that cuts off empty space: the full child holds every reference with the bounds it
  // has here, so it takes the node's event lists as they are, with no classification, split or
  // merge. (On the large shared scenes 14-43% of the events the sweep's nodes handled were in
  // such nodes.) The empty child is a leaf.
  void cut_off_empty(std::size_t index, int full_side, const std::size_t off[3], const std::size_t len[3],
                     std::size_t count, const Aabb& box, int axis, float p, int depth) {
    const std::size_t first = out_.nodes.size();
    out_.nodes.resize(first + 2);
    out_.nodes[index] = KdNode::inner(first, axis, p);
    Aabb child[2] = {box, box};
    child[0].hi[axis] = p;
    child[1].lo[axis] = p;
    const std::size_t none[3] = {0, 0, 0};
    for (int c = 0; c < 2; ++c) {
      const bool full = c == full_side;
      node(first + static_cast<std::size_t>(c), off, full ? len : none, full ? count : 0, child[c], depth + 1);
    }
  }

  // `box`: the leaf's cell. Its references' bounds there (clipped where they straddle a split
  // above, clamped to the block's box without clipping) span each axis's sorted events, so the
  // first and last events give their union (the LeafBox), within the cell.
  void leaf(std::size_t index, const std::size_t off[3], const std::size_t len[3], std::size_t count, float area,
            const Aabb& box) {
    std::vector<std::uint32_t>& local = s_.leaf;
    local.clear();
    const Event* ev = s_.arena.at(off[0]);
    for (std::size_t i = 0; i < len[0]; ++i) {
      if (ev[i].type() != kEnd) local.push_back(ev[i].ref());  // one start or planar per reference
    }
    // The block's triangle list is ascending, so sorted local indices give sorted triangles.
    sort_distinct(local, tris_.size(), s_.sort_bits);
    Aabb content;
    for (int axis = 0; axis < 3 && len[axis] > 0; ++axis) {
      const Event* e = s_.arena.at(off[axis]);
      content.lo[axis] = std::max(e[0].pos, box.lo[axis]);
      content.hi[axis] = std::min(e[len[axis] - 1].pos, box.hi[axis]);
    }
    out_.add_leaf(index, tris_, local, count, area, ctx_.options.intersection_cost, content, box,
                  ctx_.leaf_box_saving);
  }

  const BuildContext& ctx_;
  Scratch& s_;
  std::span<const std::uint32_t> tris_;
  Block& out_;
  const bool side_by_side_;  // set-up and large sweeps side by side (BuildContext::side_by_side_above)
};

// TopBuilder::binned_split's bins of up to 16 references tris[0, count) at once: for each axis,
// the bin of the lower and of the upper bound of each one's box clamped to `box` (out[2 * axis]
// and out[2 * axis + 1], lane j for reference j). The scalar loop's float operations in its order
// (max or min with the node's bound, minus its lower bound, times the axis's scale, truncated,
// at most bins - 1), so the same bins: where a max or min picks the other of two equal values,
// they differ at most in the sign of zero, which gives the same bin. The boxes are gathered by
// 32-bit float indices, so triangle ids must stay below kVectorBinTris.
constexpr std::size_t kVectorBinTris = std::size_t{1} << 28;
[[gnu::target("avx512f,avx512dq,avx512vl,avx2")]] void bin_bounds16_avx512(const Aabb* tri_box,
                                                                         const std::uint32_t* tris, std::size_t count,
                                                                         const Aabb& box, const float* scale, int bins,
                                                                         std::int32_t (*out)[16]) {
  static_assert(sizeof(Aabb) == 6 * sizeof(float) && offsetof(Aabb, lo) == 0 && offsetof(Aabb, hi) == 12);
  const __mmask16 live = static_cast<__mmask16>((1u << count) - 1u);
  const __m512i idx = _mm512_mullo_epi32(_mm512_maskz_loadu_epi32(live, tris), _mm512_set1_epi32(6));
  const float* base = reinterpret_cast<const float*>(tri_box);
  const __m512i last = _mm512_set1_epi32(bins - 1);
  for (int axis = 0; axis < 3; ++axis) {
    const __m512 lo_bound = _mm512_set1_ps(box.lo[axis]), hi_bound = _mm512_set1_ps(box.hi[axis]);
    const __m512 sc = _mm512_set1_ps(scale[axis]);
    const __m512 t_lo = _mm512_mask_i32gather_ps(_mm512_setzero_ps(), live, _mm512_add_epi32(idx, _mm512_set1_epi32(axis)),
                                                 base, 4);
    const __m512 t_hi = _mm512_mask_i32gather_ps(_mm512_setzero_ps(), live,
                                                 _mm512_add_epi32(idx, _mm512_set1_epi32(3 + axis)), base, 4);
    const __m512 lo = _mm512_sub_ps(_mm512_maskz_max_ps(0xFFFF, t_lo, lo_bound), lo_bound);
    const __m512 hi = _mm512_sub_ps(_mm512_maskz_min_ps(0xFFFF, t_hi, hi_bound), lo_bound);
    _mm512_storeu_si512(out[2 * axis],
                        _mm512_maskz_min_epi32(0xFFFF, _mm512_maskz_cvttps_epi32(0xFFFF, _mm512_mul_ps(lo, sc)), last));
    _mm512_storeu_si512(out[2 * axis + 1],
                        _mm512_maskz_min_epi32(0xFFFF, _mm512_maskz_cvttps_epi32(0xFFFF, _mm512_mul_ps(hi, sc)), last));
  }
}

// A node above the exact blocks: an inner node with a binned plane, or a block.
struct TopNode {
  int axis = -1;  // -1: `block` holds the whole subtree
  float split = 0.0f;
  std::unique_ptr<TopNode> child[2];
  Block block;
  std::uint64_t nodes_below = 0;  // nodes of the subtree other than its root
  std::uint64_t refs = 0;         // references in the subtree's leaves
};

class TopBuilder {
 public:
  explicit TopBuilder(const BuildContext& ctx) : ctx_(ctx) {}

  // The caller counted this node in ctx_.work; the count is given back once its block is
  // built, or handed to its children.
  std::unique_ptr<TopNode> build(std::vector<std::uint32_t> tris, const Aabb& box, int depth) {
    auto node = std::make_unique<TopNode>();
    const std::size_t n = tris.size();
    SplitChoice split;
    const std::size_t binned_above = depth == 0 ? ctx_.binned_root_above : ctx_.exact_below;
    if (n > binned_above && depth < ctx_.max_depth && n > static_cast<std::size_t>(ctx_.options.leaf_size)) {
      split = binned_split(tris, box);
    }
    // A big node that no bin boundary pays to cut still gets the exact sweep's every plane.
    if (split.axis < 0 || !(split.cost < ctx_.options.intersection_cost * static_cast<float>(n))) {
      const ScratchPool::Lease scratch(ScratchPool::instance());
      BlockBuilder(ctx_, *scratch, tris, node->block).run(box, depth);
      ctx_.work.fetch_sub(1, std::memory_order_relaxed);
      node->nodes_below = node->block.nodes.size() - 1;
      node->refs = node->block.refs.size();
      return node;
    }
    node->axis = split.axis;
    node->split = split.pos;
    std::vector<std::uint32_t> left, right;
    partition(tris, box, split, left, right);
    tris = {};  // the parent's list is no longer needed

    Aabb left_box = box, right_box = box;
    left_box.hi[split.axis] = split.pos;
    right_box.lo[split.axis] = split.pos;
    ctx_.work.fetch_add(1, std::memory_order_relaxed);  // two children in this node's place
    if (n >= kParallelSubtree || n <= ctx_.exact_below) {
      tbb::parallel_invoke([&] { node->child[0] = build(std::move(left), left_box, depth + 1); },
                           [&] { node->child[1] = build(std::move(right), right_box, depth + 1); });
    } else {
      node->child[0] = build(std::move(left), left_box, depth + 1);
      node->child[1] = build(std::move(right), right_box, depth + 1);
    }
    // Cancelled (another task threw): that exception ends the build.
    if (!node->child[0] || !node->child[1]) throw Error("kd-tree build cancelled");
    node->nodes_below = 2 + node->child[0]->nodes_below + node->child[1]->nodes_below;
    node->refs = node->child[0]->refs + node->child[1]->refs;
    return node;
  }

 private:
  static constexpr int kMaxBins = 256;
  // Nodes this big are binned and partitioned in chunks of kChunk references in parallel, and
  // those from kParallelNode up in chunks of kSmallChunk (the top nodes of a scene of some
  // 10,000 triangles: radiance-office's root and its child, about 0.1 ms each, ran on one thread
  // while the other waited); per-chunk integer counts summed in chunk order keep the result
  // independent of threads and chunks.
  static constexpr std::size_t kLargeNode = 65536;
  static constexpr std::size_t kChunk = 16384;
  static constexpr std::size_t kParallelNode = 8192;
  static constexpr std::size_t kSmallChunk = 4096;
  // Subtrees this big are built as tasks of their own, and so are a small root's two halves
  // (binned for KdBuildOptions::binned_root_above, whatever their size).
  // (Only the top nodes above KdBuildOptions::exact_below, and such a root, reach this test, so
  // with the default 4096 every one of them is a task; lower values of exact_below make tasks
  // of their children down to this size.)
  static constexpr std::size_t kParallelSubtree = 1024;

  // The binning, refinement and partition loops read the boxes of a node's references,
  // scattered over the scene's array (24 bytes each, 50 MB for spd-mount-s10), one after another:
  // at reference i (of those before `end`), each loop asks for the box kBoxAhead references on.
  static constexpr std::size_t kBoxAhead = 32;
  void box_ahead(const std::vector<std::uint32_t>& tris, std::size_t i, std::size_t end) const {
    if (i + kBoxAhead < end) __builtin_prefetch(&ctx_.tri_box[tris[i + kBoxAhead]]);
  }

  struct Bins {
    std::uint32_t start[3][kMaxBins];  // references whose (clamped) lower bound is in the bin
    std::uint32_t end[3][kMaxBins];    // ... whose upper bound is in the bin
  };

  static std::size_t chunk_count(std::size_t n) {
    if (n >= kLargeNode) return (n + kChunk - 1) / kChunk;
    return n >= kParallelNode ? (n + kSmallChunk - 1) / kSmallChunk : 1;
  }

  // Binned SAH (Shevtsov et al. 2007, section 3.1): `bins` equal bins per axis; a reference
  // counts left of every boundary above its lower bound's bin and right of every boundary at
  // or below its upper bound's bin. The counts are estimates; partition() is exact.
  [[nodiscard]] SplitChoice binned_split(const std::vector<std::uint32_t>& tris, const Aabb& box) const {
    const float area = scaled_area(box, ctx_.sah_scale);
    if (!(area > 0.0f)) return SplitChoice{};
    const int bins = ctx_.bins;
    const glm::vec3 extent = box.extent();
    float scale[3];
    for (int axis = 0; axis < 3; ++axis) {
      scale[axis] = extent[axis] > 0.0f ? static_cast<float>(bins) / extent[axis] : 0.0f;
    }
    const std::size_t n = tris.size();
    const std::size_t chunks = chunk_count(n);
    std::vector<Bins> per_chunk(chunks);
    // Neighbouring references mostly fall into the same bins, and an increment of the bin the
    // one before just incremented waits for that store: references alternate between two sets
    // of counts, added up at the end.
    auto count = [&](std::size_t c) {
      Bins& b = per_chunk[c];
      Bins odd;
      std::memset(&b, 0, sizeof(Bins));
      std::memset(&odd, 0, sizeof(Bins));
      const auto add = [&](Bins& to, std::size_t i) {
        const Aabb& t = ctx_.tri_box[tris[i]];
        for (int axis = 0; axis < 3; ++axis) {
          const float lo = std::max(t.lo[axis], box.lo[axis]) - box.lo[axis];
          const float hi = std::min(t.hi[axis], box.hi[axis]) - box.lo[axis];
          ++to.start[axis][std::min(static_cast<int>(lo * scale[axis]), bins - 1)];
          ++to.end[axis][std::min(static_cast<int>(hi * scale[axis]), bins - 1)];
        }
      };
      const std::size_t end = std::min(n, (c + 1) * (n / chunks + 1));
      std::size_t i = c * (n / chunks + 1);
      if (ctx_.avx512 && ctx_.tri_box.size() <= kVectorBinTris) {
        alignas(64) std::int32_t at[6][16];
        for (; i < end; i += 16) {
          const std::size_t m = std::min<std::size_t>(16, end - i);
          // One box in four asked for: a node's triangle ids ascend, so near the root neighbouring
          // boxes share a line (2-3 a line); deeper down they do not (not measured against all 16).
          for (std::size_t j = 0; j < m; j += 4) box_ahead(tris, i + j, end);
          bin_bounds16_avx512(ctx_.tri_box.data(), tris.data() + i, m, box, scale, bins, at);
          for (std::size_t j = 0; j < m; ++j) {
            Bins& to = (j & 1u) != 0 ? odd : b;
            for (int axis = 0; axis < 3; ++axis) {
              ++to.start[axis][at[2 * axis][j]];
              ++to.end[axis][at[2 * axis + 1][j]];
            }
          }
        }
      }
      for (; i + 1 < end; i += 2) {
        box_ahead(tris, i, end);
        box_ahead(tris, i + 1, end);
        add(b, i);
        add(odd, i + 1);
      }
      if (i < end) add(b, i);
      for (int axis = 0; axis < 3; ++axis) {
        for (int k = 0; k < bins; ++k) {
          b.start[axis][k] += odd.start[axis][k];
          b.end[axis][k] += odd.end[axis][k];
        }
      }
    };
    if (chunks > 1) {
      tbb::parallel_for(std::size_t{0}, chunks, count);
      for (std::size_t c = 1; c < chunks; ++c) {
        for (int axis = 0; axis < 3; ++axis) {
          for (int i = 0; i < bins; ++i) {
            per_chunk[0].start[axis][i] += per_chunk[c].start[axis][i];
            per_chunk[0].end[axis][i] += per_chunk[c].end[axis][i];
          }
        }
      }
    } else {
      count(0);
    }
    const Bins& b = per_chunk[0];
    const SahFrame frame = sah_frame(ctx_, box, n);
    SplitChoice best[3];
    int best_bin[3] = {-1, -1, -1};
    for (int axis = 0; axis < 3; ++axis) {
      if (!(scale[axis] > 0.0f)) continue;
      const SahAxis sah(ctx_.options, box, axis, frame, ctx_.sah_scale);
      std::size_t n_left = 0, n_right = n;
      for (int i = 1; i < bins; ++i) {
        n_left += b.start[axis][i - 1];
        n_right -= b.end[axis][i - 1];
        const float pos = box.lo[axis] + extent[axis] * (static_cast<float>(i) / static_cast<float>(bins));
        if (!(pos > box.lo[axis] && pos < box.hi[axis])) continue;
        const float cost = sah.cost(pos, n_left, n_right);
        if (cost < best[axis].cost) {
          best[axis] = SplitChoice{axis, pos, true, cost};
          best_bin[axis] = i;
        }
      }
    }
    int axis_best = 0;
    for (int axis = 1; axis < 3; ++axis) {
      if (best[axis].cost < best[axis_best].cost) axis_best = axis;
    }
    // A root binned only for binned_root_above (a scene of one block, whose tree is otherwise
    // the exact sweep's) refines too, and so does every axis whose best bin costs within
    // kRefineNear of the best one's: its plane is then the exact sweep's wherever that lies
    // near such a bin (at the root every box lies in the node, so the binned counts are the
    // sweep's), the earliest axis winning a tie as there.
    const bool small_root = n <= ctx_.exact_below;
    for (int axis = 0; axis < 3; ++axis) {
      const bool near = small_root && best[axis].cost <= best[axis_best].cost * (1.0f + kRefineNear);
      if (axis != axis_best && !near) best_bin[axis] = -1;
    }
    if (n >= kRefineAbove || small_root) refine(tris, box, scale, b, best, best_bin);
    SplitChoice choice;
    for (const SplitChoice& s : best) {
      if (s.cost < choice.cost) choice = s;
    }
    // The window's positions are taken as they are, -0 too; the exact sweep writes +0 (add_events).
    if (small_root) choice.pos += 0.0f;
    return choice;
  }

  // A bin boundary rarely falls on the plane that pays most: on spd-tree the root's binned
  // cut missed the tree's side, x = -1.38532, by 0.004 (SAH cost 10.1 at K_T = 2; 7.8 with
  // this refinement). Nodes of at least kRefineAbove references also sweep exactly the event
  // positions in the kRefineBins bins on either side of the best boundary of the best axis
  // (and a small root, binned for binned_root_above, of every axis within kRefineNear of it).
  // Bin indices grow with position, so the counts binned below the window are exact for every
  // plane inside it. Refining every axis, or every binned node, gave the same spd-tree cost
  // and slower builds; near the root of spd-balls-s3 exact planes raise the SAH 10.2 -> 12.5.
  static constexpr int kRefineBins = 2;
  static constexpr float kRefineNear = 0.01f;
  static constexpr std::size_t kRefineAbove = 65536;

  void refine(const std::vector<std::uint32_t>& tris, const Aabb& box, const float* scale, const Bins& b,
              SplitChoice* best, const int* best_bin) const {
    const int bins = ctx_.bins;
    int first[3], last[3];  // window: bins first..last-1 of each axis
    for (int axis = 0; axis < 3; ++axis) {
      first[axis] = best_bin[axis] < 0 ? 0 : std::max(0, best_bin[axis] - kRefineBins);
      last[axis] = best_bin[axis] < 0 ? 0 : std::min(bins, best_bin[axis] + kRefineBins);
    }
    const std::size_t n = tris.size();
    const std::size_t chunks = chunk_count(n);
    const std::size_t per = n / chunks + 1;
    // Chunk c writes its window events at 2 per c, room for two per reference, in one
    // uninitialised array per axis; the chunks' events are then moved together in chunk order.
    // (Vectors grown by push_back and joined: this step of a one-thread spd-tree build took
    // 103 ms and 19.2 K page faults, as large blocks are fresh pages each time; now 74-77 ms and
    // 11.8 K, the pages the window's events and the sort's buffer fill.) Plain pages, not
    // RawArray's huge ones: the room no event is written to is then never touched.
    // An axis without a window has no array.
    std::array<std::unique_ptr<Event[]>, 3> events;
    for (int axis = 0; axis < 3; ++axis) {
      if (first[axis] != last[axis]) events[axis].reset(new Event[2 * per * chunks]);  // not initialised
    }
    std::vector<std::array<std::size_t, 3>> written(chunks);
    auto collect = [&](std::size_t c) {
      Event* out[3];
      for (int axis = 0; axis < 3; ++axis) out[axis] = events[axis] ? events[axis].get() + 2 * per * c : nullptr;
      const std::size_t end = std::min(n, (c + 1) * per);
      std::size_t m[3] = {0, 0, 0};
      for (std::size_t i = c * per; i < end; ++i) {
        box_ahead(tris, i, end);
        const Aabb& t = ctx_.tri_box[tris[i]];
        for (int axis = 0; axis < 3; ++axis) {
          if (!out[axis]) continue;
          const float lo = std::max(t.lo[axis], box.lo[axis]);
          const float hi = std::min(t.hi[axis], box.hi[axis]);
          const int lo_bin = std::min(static_cast<int>((lo - box.lo[axis]) * scale[axis]), bins - 1);
          const int hi_bin = std::min(static_cast<int>((hi - box.lo[axis]) * scale[axis]), bins - 1);
          if (lo == hi) {
            if (lo_bin >= first[axis] && lo_bin < last[axis]) out[axis][m[axis]++] = Event{lo, kPlanar};
            continue;
          }
          if (lo_bin >= first[axis] && lo_bin < last[axis]) out[axis][m[axis]++] = Event{lo, kStart};
          if (hi_bin >= first[axis] && hi_bin < last[axis]) out[axis][m[axis]++] = Event{hi, kEnd};
        }
      }
      for (int axis = 0; axis < 3; ++axis) written[c][axis] = m[axis];
    };
    if (chunks > 1) {
      tbb::parallel_for(std::size_t{0}, chunks, collect);
    } else {
      collect(0);
    }
    const SahFrame frame = sah_frame(ctx_, box, n);
    std::vector<Event> buffer;
    for (int axis = 0; axis < 3; ++axis) {
      Event* ev = events[axis].get();
      if (!ev) continue;
      std::size_t size = 0;
      for (std::size_t c = 0; c < chunks; ++c) {
        if (written[c][axis] > 0 && size != 2 * per * c) {
          std::memmove(ev + size, ev + 2 * per * c, written[c][axis] * sizeof(Event));
        }
        size += written[c][axis];
      }
      std::size_t n_left = 0, n_right = n;
      for (int i = 0; i < first[axis]; ++i) {
        n_left += b.start[axis][i];
        n_right -= b.end[axis][i];
      }
      // Equal events are interchangeable, so the sort's order among them cannot matter.
      sort_events(ev, size, buffer, ctx_);
      const SplitChoice exact = best_on_axis(ctx_, ev, size, n_left, n_right, box, axis, frame);
      if (exact.cost < best[axis].cost) best[axis] = exact;
    }
  }

  // A reference ending at or below the plane goes left, one starting at or above it right,
  // one lying in it to the side the split names, and the rest to both unless the triangle
  // clipped to the node (clipped_bounds(), conservative) lies on one side. The binned counts
  // above use clamped boxes: they only estimate. Order is kept, so every list stays ascending.
  void partition(const std::vector<std::uint32_t>& tris, const Aabb& box, const SplitChoice& split,
                 std::vector<std::uint32_t>& left, std::vector<std::uint32_t>& right) const {
    const std::size_t n = tris.size();
    const std::size_t chunks = chunk_count(n);
    const std::size_t per = n / chunks + 1;
    const int axis = split.axis;
    const float p = split.pos;
    std::vector<std::uint8_t> side(n);
    std::vector<std::size_t> n_left(chunks + 1, 0), n_right(chunks + 1, 0);
    auto classify = [&](std::size_t c) {
      std::size_t l = 0, r = 0;
      const std::size_t end = std::min(n, (c + 1) * per);
      for (std::size_t i = c * per; i < end; ++i) {
        box_ahead(tris, i, end);
        const Aabb& t = ctx_.tri_box[tris[i]];
        const float lo = t.lo[axis], hi = t.hi[axis];
        std::uint8_t s = kBoth;
        if (lo == hi && lo == p) {
          s = split.planar_left ? kLeft : kRight;
        } else if (hi <= p) {
          s = kLeft;
        } else if (lo >= p) {
          s = kRight;
        } else if (ctx_.clip) {
          // A straddling box: the triangle clipped to the node may still lie on one side
          // (a long diagonal triangle crossing the plane outside the node).
          const Aabb clipped = clipped_bounds(ctx_, tris[i], box, t);
          if (clipped.hi[axis] <= p && clipped.lo[axis] < p) {
            s = kLeft;
          } else if (clipped.lo[axis] >= p && clipped.hi[axis] > p) {
            s = kRight;
          }
        }
        side[i] = s;
        l += s != kRight;
        r += s != kLeft;
      }
      n_left[c + 1] = l;
      n_right[c + 1] = r;
    };
    if (chunks > 1) {
      tbb::parallel_for(std::size_t{0}, chunks, classify);
    } else {
      classify(0);
    }
    for (std::size_t c = 0; c < chunks; ++c) {
      n_left[c + 1] += n_left[c];
      n_right[c + 1] += n_right[c];
    }
    left.resize(n_left[chunks]);
    right.resize(n_right[chunks]);
    auto scatter = [&](std::size_t c) {
      std::uint32_t* l = left.data() + n_left[c];
      std::uint32_t* r = right.data() + n_right[c];
      for (std::size_t i = c * per; i < std::min(n, (c + 1) * per); ++i) {
        const std::uint8_t s = side[i];
        if (s != kRight) *l++ = tris[i];
        if (s != kLeft) *r++ = tris[i];
      }
    };
    if (chunks > 1) {
      tbb::parallel_for(std::size_t{0}, chunks, scatter);
    } else {
      scatter(0);
    }
  }

  const BuildContext& ctx_;
};

// A leaf's LeafBox: `box` widened by `pad` on every side.
LeafBox make_leaf_box(const Aabb& box, float pad) {
  LeafBox b{};
  b.lo_x = box.lo.x - pad;
  b.lo_y = box.lo.y - pad;
  b.lo_z = box.lo.z - pad;
  b.hi_x = box.hi.x + pad;
  b.hi_y = box.hi.y + pad;
  b.hi_z = box.hi.z + pad;
  b.k = 3;
  b.id = kLeafBoxRef;
  return b;
}

// Copies the blocks into the final arrays at the places a depth-first layout gives them; the
// sizes each subtree reported let both children be placed at once. A leaf's box slot gets
// kLeafBoxRef and its LeafBox record (`records`, the tree's leaf records; the triangles'
// records are copied in afterwards).
struct Placer {
  // Subtrees and blocks of more nodes (and, in a block, references) than this are placed in
  // parallel; radiance-office's 15 K nodes took 0.15 ms on one thread at 65,536.
  static constexpr std::size_t kInParallel = 8192;

  KdNode* nodes;
  std::uint32_t* refs;
  TriRecord* records;
  float box_pad;

  void place(const TopNode& t, std::uint64_t index, std::uint64_t node_base, std::uint64_t ref_base) const {
    if (t.axis < 0) {
      const std::vector<KdNode>& local = t.block.nodes;
      auto relocate = [&](KdNode n) {
        if (n.is_leaf()) return KdNode::leaf(n.prim_offset() + ref_base, n.tri_count(), n.has_box());
        return KdNode::inner(n.left() - 1 + node_base, n.axis(), n.split, local[n.left()].is_empty_leaf(),
                             local[n.left() + 1].is_empty_leaf());
      };
      nodes[index] = relocate(local[0]);
      const auto place_nodes = [&](std::size_t from, std::size_t to) {
        for (std::size_t i = from; i < to; ++i) nodes[node_base + i - 1] = relocate(local[i]);
      };
      const auto place_refs = [&](std::size_t from, std::size_t to) {
        for (std::size_t i = from; i < to; ++i) {
          const std::uint32_t r = t.block.refs[i];
          if ((r & Block::kBoxSlot) == 0) {
            refs[ref_base + i] = r;
          } else {
            refs[ref_base + i] = kLeafBoxRef;
            records[ref_base + i].box = make_leaf_box(t.block.boxes[r & ~Block::kBoxSlot], box_pad);
          }
        }
      };
      if (local.size() + t.block.refs.size() > kInParallel) {  // a small scene's one block, or a large block
        const auto range = [](std::size_t from, std::size_t to) {
          return tbb::blocked_range<std::size_t>(from, to, kInParallel / 2);
        };
        tbb::parallel_invoke(
            [&] { tbb::parallel_for(range(1, local.size()), [&](const auto& r) { place_nodes(r.begin(), r.end()); }); },
            [&] {
              tbb::parallel_for(range(0, t.block.refs.size()), [&](const auto& r) { place_refs(r.begin(), r.end()); });
            });
      } else {
        place_nodes(1, local.size());
        place_refs(0, t.block.refs.size());
      }
      return;
    }
    const TopNode& l = *t.child[0];
    const TopNode& r = *t.child[1];
    const auto empty_leaf = [](const TopNode& c) { return c.axis < 0 && c.block.nodes[0].is_empty_leaf(); };
    nodes[index] = KdNode::inner(node_base, t.axis, t.split, empty_leaf(l), empty_leaf(r));
    auto place_left = [&] { place(l, node_base, node_base + 2, ref_base); };
    auto place_right = [&] { place(r, node_base + 1, node_base + 2 + l.nodes_below, ref_base + l.refs); };
    if (t.nodes_below > kInParallel) {
      tbb::parallel_invoke(place_left, place_right);
    } else {
      place_left();
      place_right();
    }
  }
};

// Tree statistics in depth-first order, so the floating-point sums do not depend on threads.
void add_stats(const TopNode& t, const Aabb& box, int depth, const KdBuildOptions& options, float scale,
               KdBuildStats& stats, double& cost_area) {
  if (t.axis < 0) {
    stats.leaves += t.block.leaves;
    stats.empty_leaves += t.block.empty_leaves;
    stats.forks += t.block.forks;
    ++stats.blocks;
    stats.leaf_boxes += t.block.boxes.size();
    stats.max_depth = std::max(stats.max_depth, t.block.max_depth);
    cost_area += t.block.cost_area;
    return;
  }
  stats.max_depth = std::max(stats.max_depth, depth);
  cost_area += static_cast<double>(options.traversal_cost) * static_cast<double>(scaled_area(box, scale));
  Aabb left_box = box, right_box = box;
  left_box.hi[t.axis] = t.split;
  right_box.lo[t.axis] = t.split;
  add_stats(*t.child[0], left_box, depth + 1, options, scale, stats, cost_area);
  add_stats(*t.child[1], right_box, depth + 1, options, scale, stats, cost_area);
}

// KdBuildOptions::mark_denser over the placed tree: returns the chance that a ray crossing
// node i (cell `cell`) meets a triangle in it, and marks each inner node's denser child. The
// top `parallel_depth` levels split into tasks; the floats do not depend on them (each node's
// value comes from its own children's only).
double mark_denser(KdNode* nodes, const std::uint32_t* refs, const float* tri_area, std::uint32_t i, const Aabb& cell,
                   int parallel_depth) {
  const auto surface = [](const Aabb& b) {
    const glm::dvec3 d = glm::dvec3(b.hi) - glm::dvec3(b.lo);
    return 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x);
  };
  KdNode& n = nodes[i];
  const double cell_area = surface(cell);
  if (n.is_leaf()) {
    const std::uint32_t* r = refs + n.prim_offset();
    double area = 0.0;
    for (std::uint32_t k = 0, count = n.tri_count(); k < count; ++k) area += static_cast<double>(tri_area[r[k]]);
    if (area <= 0.0) return 0.0;
    return cell_area > 0.0 ? 1.0 - std::exp(-area / cell_area) : 1.0;
  }
  const int axis = n.axis();
  Aabb left = cell, right = cell;
  left.hi[axis] = n.split;
  right.lo[axis] = n.split;
  double alpha[2];
  if (parallel_depth > 0) {
    tbb::parallel_invoke([&] { alpha[0] = mark_denser(nodes, refs, tri_area, n.left(), left, parallel_depth - 1); },
                         [&] { alpha[1] = mark_denser(nodes, refs, tri_area, n.left() + 1, right, parallel_depth - 1); });
  } else {
    alpha[0] = mark_denser(nodes, refs, tri_area, n.left(), left, 0);
    alpha[1] = mark_denser(nodes, refs, tri_area, n.left() + 1, right, 0);
  }
  // The chance that a ray crossing this node crosses child c and meets a triangle there (a
  // flat cell's share as its parent's when the parent is flat too).
  const auto share = [&](const Aabb& child) {
    return cell_area > 0.0 ? std::min(surface(child) / cell_area, 1.0) : 1.0;
  };
  const double w0 = share(left) * alpha[0], w1 = share(right) * alpha[1];
  n.set_denser(w1 > w0 ? 1u : 0u);
  return 1.0 - (1.0 - w0) * (1.0 - w1);
}

constexpr std::size_t kHugePage = std::size_t{2} << 20;

// alloc_pages' alignment and size for a request: huge-page aligned from 2 MiB up, and a multiple
// of the alignment (aligned_alloc wants one; map_huge whole huge pages).
struct PageBlock {
  std::size_t align = 0, bytes = 0;
  PageBlock(std::size_t request, std::size_t min_align)
      : align(request >= kHugePage ? std::max(min_align, kHugePage) : min_align),
        bytes((request + align - 1) / align * align) {}
  [[nodiscard]] bool huge() const { return align >= kHugePage; }
};

// A fresh block of `bytes` (a multiple of kHugePage) at a 2 MiB boundary, straight from the
// kernel and asked for as transparent huge pages. Not from malloc: where malloc serves blocks
// this large from its heap (keep_freed_memory, process_memory.h), a block may reuse heap pages
// already faulted in one 4 KiB page at a time, which madvise does not turn into huge pages; a
// tree's nodes there made spd-tree's frames up to 1.5x slower at one thread (session 47).
void* map_huge(std::size_t bytes) {
  const std::size_t span = bytes + kHugePage;
  void* raw = ::mmap(nullptr, span, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (raw == MAP_FAILED) throw std::bad_alloc();
  const auto start = reinterpret_cast<std::uintptr_t>(raw);
  const std::uintptr_t aligned = (start + kHugePage - 1) & ~(std::uintptr_t{kHugePage} - 1);
  // The head is under kHugePage, so the tail (kHugePage less the head) is never empty.
  const std::size_t head = aligned - start, tail = span - head - bytes;
  if (head > 0) ::munmap(raw, head);
  ::munmap(reinterpret_cast<void*>(aligned + bytes), tail);
  void* p = reinterpret_cast<void*>(aligned);
  ::madvise(p, bytes, MADV_HUGEPAGE);
  return p;
}

// The huge blocks free_pages keeps (its comment), oldest first, and those lent out with their
// sizes (a kept block lent for a request may be up to twice as large). Never destroyed, as
// ScratchPool: a tree freed by another static object's destructor still finds it.
class PageCache {
 public:
  static PageCache& instance() {
    static PageCache* const cache = new PageCache;
    return *cache;
  }
  PageCache() { kept_.reserve(kPageCacheBlocks + 1); }
  // A block of at least `bytes`: a kept one of at most twice that, the smallest such, or a new
  // one.
  void* lend(std::size_t bytes, [[maybe_unused]] std::size_t align) {
    RTC_DCHECK(align <= kHugePage && bytes % kHugePage == 0, "PageCache: a block of whole huge pages");
    const std::lock_guard lock(mutex_);
    lent_.reserve(lent_.size() + 1);  // so that the push_back below cannot throw
    std::size_t best = kept_.size();
    for (std::size_t i = 0; i < kept_.size(); ++i) {
      const std::size_t b = kept_[i].bytes;
      if (b >= bytes && b / 2 <= bytes && (best == kept_.size() || b < kept_[best].bytes)) best = i;
    }
    Block block;
    if (best < kept_.size()) {
      block = kept_[best];
      total_ -= block.bytes;
      kept_.erase(kept_.begin() + static_cast<std::ptrdiff_t>(best));
      ++reused_;
    } else {
      block = {map_huge(bytes), bytes};
    }
    lent_.push_back(block);
    return block.p;
  }
  // Takes back a block of lend(), keeping it and freeing the oldest kept blocks beyond the
  // limits.
  void give(void* p) noexcept {
    const std::lock_guard lock(mutex_);
    const auto it = std::find_if(lent_.begin(), lent_.end(), [p](const Block& b) { return b.p == p; });
    if (it == lent_.end()) return;  // not lent here (never happens; its size is unknown)
    kept_.push_back(*it);  // never reallocates (the constructor's reserve)
    total_ += it->bytes;
    lent_.erase(it);
    std::size_t n = 0;
    while (n < kept_.size() && (kept_.size() - n > kPageCacheBlocks || total_ > kPageCacheBytes)) {
      total_ -= kept_[n].bytes;
      ::munmap(kept_[n].p, kept_[n].bytes);
      ++n;
    }
    kept_.erase(kept_.begin(), kept_.begin() + static_cast<std::ptrdiff_t>(n));
  }
  PageCacheStats stats() {
    const std::lock_guard lock(mutex_);
    return {kept_.size(), total_, reused_};
  }
  void release() noexcept {
    const std::lock_guard lock(mutex_);
    for (const Block& b : kept_) ::munmap(b.p, b.bytes);
    kept_.clear();
    total_ = 0;
  }

 private:
  struct Block {
    void* p = nullptr;
    std::size_t bytes = 0;
  };
  std::mutex mutex_;
  std::vector<Block> kept_, lent_;
  std::size_t total_ = 0;
  std::uint64_t reused_ = 0;
};

}  // namespace

void* alloc_pages(std::size_t bytes, std::size_t align) {
  const PageBlock block(bytes, align);
  if (block.huge()) return PageCache::instance().lend(block.bytes, block.align);
  void* p = std::aligned_alloc(block.align, block.bytes);
  if (p == nullptr) throw std::bad_alloc();
  return p;
}

void free_pages(void* p, std::size_t bytes, std::size_t align) noexcept {
  if (p == nullptr) return;
  if (PageBlock(bytes, align).huge()) {
    PageCache::instance().give(p);
  } else {
    std::free(p);
  }
}

PageCacheStats page_cache_stats() { return PageCache::instance().stats(); }

void release_page_cache() noexcept { PageCache::instance().release(); }

TriAccel make_tri_accel(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  // Computed in double, rounded once: the record is as exact as float storage allows.
  const glm::dvec3 A(a), B(b), C(c);
  const glm::dvec3 e1 = B - A, e2 = C - A;
  const glm::dvec3 n = glm::cross(e1, e2);
  TriAccel acc;
  const glm::dvec3 an = glm::abs(n);
  const int k = an.x >= an.y ? (an.x >= an.z ? 0 : 2) : (an.y >= an.z ? 1 : 2);
  if (!(an[k] > 0.0) || !std::isfinite(an[k])) return acc;  // zero area: k = 3, never hits
  const int u = (k + 1) % 3, v = (k + 2) % 3;
  acc.k = static_cast<std::uint32_t>(k);
  acc.n_u = static_cast<float>(n[u] / n[k]);
  acc.n_v = static_cast<float>(n[v] / n[k]);
  acc.n_d = static_cast<float>(glm::dot(n, A) / n[k]);
  // Solve h - A = beta e1 + gamma e2 in the (u, v) projection.
  const double det = e1[u] * e2[v] - e1[v] * e2[u];
  acc.b_nu = static_cast<float>(e2[v] / det);
  acc.b_nv = static_cast<float>(-e2[u] / det);
  acc.b_d = static_cast<float>((A[v] * e2[u] - A[u] * e2[v]) / det);
  acc.c_nu = static_cast<float>(-e1[v] / det);
  acc.c_nv = static_cast<float>(e1[u] / det);
  acc.c_d = static_cast<float>((e1[v] * A[u] - e1[u] * A[v]) / det);
  return acc;
}

namespace {

// make_tri_accel for eight triangles, its double operations lane by lane in its order (separate
// multiplies and adds, as -ffp-contract=off compiles it; the same comparisons for k, the same
// selects of u and v), so the same bits: a record took ~125 cycles of scalar code, most of them
// its nine double divisions. Lanes whose |n[k]| is zero or not finite get the default record,
// k = 3. (One exception to "the same bits", out of the loaders' reach since they reject NaN
// coordinates: a sum of two NaNs may keep the other one's payload than the scalar code's.)
[[gnu::target("avx512f,avx512dq,avx512vl,avx512bw,avx2,popcnt")]] void make_tri_accel_x8(const float (&v)[9][8],
                                                                                       TriRecord* out) {
  // (Lambdas would not inherit the target; macros, undefined below. The zero-masking forms, as
  // in best_on_axis_avx512.)
#define RTC_LOAD(i) _mm512_maskz_cvtps_pd(0xFF, _mm256_loadu_ps(v[i]))
#define RTC_MUL(x, y) _mm512_mul_pd(x, y)
#define RTC_SUB(x, y) _mm512_sub_pd(x, y)
  // Component k, u = k + 1 and v = k + 2 (mod 3) of (x, y, z).
#define RTC_AT_K(x, y, z) _mm512_mask_blend_pd(k0, _mm512_mask_blend_pd(k1, z, y), x)
#define RTC_AT_U(x, y, z) RTC_AT_K(y, z, x)
#define RTC_AT_V(x, y, z) RTC_AT_K(z, x, y)
  const __m512d ax = RTC_LOAD(0), ay = RTC_LOAD(1), az = RTC_LOAD(2);
  const __m512d e1x = RTC_SUB(RTC_LOAD(3), ax), e1y = RTC_SUB(RTC_LOAD(4), ay), e1z = RTC_SUB(RTC_LOAD(5), az);
  const __m512d e2x = RTC_SUB(RTC_LOAD(6), ax), e2y = RTC_SUB(RTC_LOAD(7), ay), e2z = RTC_SUB(RTC_LOAD(8), az);
  // glm::cross(e1, e2): (x.y y.z - y.y x.z, x.z y.x - y.z x.x, x.x y.y - y.x x.y).
  const __m512d nx = RTC_SUB(RTC_MUL(e1y, e2z), RTC_MUL(e2y, e1z));
  const __m512d ny = RTC_SUB(RTC_MUL(e1z, e2x), RTC_MUL(e2z, e1x));
  const __m512d nz = RTC_SUB(RTC_MUL(e1x, e2y), RTC_MUL(e2x, e1y));
  const __m512d anx = _mm512_abs_pd(nx), any = _mm512_abs_pd(ny), anz = _mm512_abs_pd(nz);
  // k = an.x >= an.y ? (an.x >= an.z ? 0 : 2) : (an.y >= an.z ? 1 : 2), NaN comparing false.
  const __mmask8 xy = _mm512_cmp_pd_mask(anx, any, _CMP_GE_OQ);
  const __mmask8 k0 = xy & _mm512_cmp_pd_mask(anx, anz, _CMP_GE_OQ);
  const __mmask8 k1 = static_cast<__mmask8>(~xy & _mm512_cmp_pd_mask(any, anz, _CMP_GE_OQ));
  const __m512d nk = RTC_AT_K(nx, ny, nz), ank = RTC_AT_K(anx, any, anz);
  const __mmask8 valid = _mm512_cmp_pd_mask(ank, _mm512_setzero_pd(), _CMP_GT_OQ) &
                         _mm512_cmp_pd_mask(ank, _mm512_set1_pd(std::numeric_limits<double>::infinity()), _CMP_LT_OQ);
  // glm::dot(n, A): the products' sum x + y, then + z.
  const __m512d dot = _mm512_add_pd(_mm512_add_pd(RTC_MUL(nx, ax), RTC_MUL(ny, ay)), RTC_MUL(nz, az));
  const __m512d e1u = RTC_AT_U(e1x, e1y, e1z), e1v = RTC_AT_V(e1x, e1y, e1z);
  const __m512d e2u = RTC_AT_U(e2x, e2y, e2z), e2v = RTC_AT_V(e2x, e2y, e2z);
  const __m512d au = RTC_AT_U(ax, ay, az), av = RTC_AT_V(ax, ay, az);
  const __m512d det = RTC_SUB(RTC_MUL(e1u, e2v), RTC_MUL(e1v, e2u));
  const __m512d sign = _mm512_set1_pd(-0.0);
  // Each field rounded to float once, zero in the lanes without a record (the default record's).
  const __m512d field[9] = {
      _mm512_div_pd(RTC_AT_U(nx, ny, nz), nk),
      _mm512_div_pd(RTC_AT_V(nx, ny, nz), nk),
      _mm512_div_pd(dot, nk),
      _mm512_div_pd(e2v, det),
      _mm512_div_pd(_mm512_xor_pd(e2u, sign), det),
      _mm512_div_pd(RTC_SUB(RTC_MUL(av, e2u), RTC_MUL(au, e2v)), det),
      _mm512_div_pd(_mm512_xor_pd(e1v, sign), det),
      _mm512_div_pd(e1u, det),
      _mm512_div_pd(RTC_SUB(RTC_MUL(e1v, au), RTC_MUL(e1u, av)), det),
  };
#undef RTC_LOAD
#undef RTC_MUL
#undef RTC_SUB
#undef RTC_AT_K
#undef RTC_AT_U
#undef RTC_AT_V
  alignas(32) float f[9][8];
  for (int i = 0; i < 9; ++i) _mm256_store_ps(f[i], _mm512_maskz_cvtpd_ps(valid, field[i]));
  for (int j = 0; j < 8; ++j) {
    TriAccel acc;
    if ((valid >> j) & 1u) {
      acc.k = ((k0 >> j) & 1u) != 0 ? 0u : ((k1 >> j) & 1u) != 0 ? 1u : 2u;
      acc.n_u = f[0][j], acc.n_v = f[1][j], acc.n_d = f[2][j];
      acc.b_nu = f[3][j], acc.b_nv = f[4][j], acc.b_d = f[5][j];
      acc.c_nu = f[6][j], acc.c_nv = f[7][j], acc.c_d = f[8][j];
    }
    out[j].wald = acc;
  }
}

}  // namespace

void make_tri_accels(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles, std::size_t first,
                     std::size_t count, TriRecord* out, Isa isa) {
  static const bool avx512 = cpu_supports(Isa::Avx512);
  std::size_t i = 0;
  if (isa == Isa::Avx512 && avx512) {
    float v[9][8];
    for (; i + 8 <= count; i += 8) {
      for (int j = 0; j < 8; ++j) {
        const glm::uvec3 t = triangles[first + i + static_cast<std::size_t>(j)];
        const glm::vec3 p[3] = {positions[t.x], positions[t.y], positions[t.z]};
        for (int c = 0; c < 9; ++c) v[c][j] = p[c / 3][c % 3];
      }
      make_tri_accel_x8(v, out + i);
    }
  }
  for (; i < count; ++i) {
    const glm::uvec3 t = triangles[first + i];
    out[i].wald = make_tri_accel(positions[t.x], positions[t.y], positions[t.z]);
  }
}

TriVerts make_tri_verts(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  TriVerts v{};
  v.k = 3;
  // Same zero-area rule as make_tri_accel, so both formats leave out the same triangles and
  // build the same tree.
  if (make_tri_accel(a, b, c).k == 3) return v;
  v.k = 0;
  v.ax = a.x, v.ay = a.y, v.az = a.z;
  v.bx = b.x, v.by = b.y, v.bz = b.z;
  v.cx = c.x, v.cy = c.y, v.cz = c.z;
  return v;
}

const char* kd_clip_name(KdClip clip) {
  switch (clip) {
    case KdClip::On:
      return "on";
    case KdClip::Off:
      return "off";
    default:
      return "auto";
  }
}

KdClip parse_kd_clip(std::string_view text) {
  if (text == "auto") return KdClip::Auto;
  if (text == "on") return KdClip::On;
  if (text == "off") return KdClip::Off;
  throw Error(fmt::format("kd-tree clipping must be auto, on or off, got \"{}\"", text));
}

std::string KdBuildStats::to_string() const {
  return fmt::format(
      "kd-tree: {} triangles ({} degenerate skipped) in {:.1f} ms, {} nodes, {} leaves ({} empty), "
      "max depth {}, {:.2f} triangles per non-empty leaf, {} refs, {} leaf boxes, SAH cost {:.2f}, {:.1f} MiB",
      triangles, degenerate, build_ms, nodes, leaves, empty_leaves, max_depth, mean_tris_per_leaf, prim_refs,
      leaf_boxes, sah_cost, static_cast<double>(bytes) / (1024.0 * 1024.0));
}

KdTree KdTree::build(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles,
                     const KdBuildOptions& options, std::span<const std::uint32_t> ids) {
  Timer timer;
  if (triangles.size() >= (1u << 30)) throw Error("kd-tree: more than 2^30 triangles");
  RTC_CHECK(ids.empty() || ids.size() == triangles.size(), "kd-tree: ids must be empty or one per triangle");
  std::unique_ptr<tbb::global_control> limit;
  if (options.threads > 0) {
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  static_cast<std::size_t>(options.threads));
  }

  KdTree tree;
  tree.stats_.triangles = triangles.size();
  tree.watertight_ = options.watertight;
  // Records in the order given, each written once below; the tree keeps only their copies in
  // leaf order (leaf_records_), made once the leaves are known.
  RawArray<TriRecord> records(triangles.size());
  RawArray<Aabb> tri_box(triangles.size());
  // Each triangle's area, for mark_denser.
  RawArray<float> tri_area(options.mark_denser ? triangles.size() : 0);
  // Chunks of kRecordChunk triangles, each with the box of its triangles and their count
  // (degenerate ones left out), merged in chunk order below: the root box a loop over the
  // triangles in order makes (the min and max keep the first of equal values), with no serial
  // pass over them (spd-mount-s10: 2.1 M triangles).
  constexpr std::size_t kRecordChunk = 1024;
  const std::size_t record_chunks = (triangles.size() + kRecordChunk - 1) / kRecordChunk;
  std::vector<Aabb> chunk_box(record_chunks);
  std::vector<std::size_t> chunk_valid(record_chunks, 0);
  const Isa isa = build_isa(options);
  tbb::parallel_for(std::size_t{0}, record_chunks, [&](std::size_t chunk) {
    const std::size_t begin = chunk * kRecordChunk;
    const std::size_t end = std::min(triangles.size(), (chunk + 1) * kRecordChunk);
    for (std::size_t i = begin; i != end; ++i) {
      const glm::uvec3 t = triangles[i];
      RTC_CHECK(t.x < positions.size() && t.y < positions.size() && t.z < positions.size(),
                "kd-tree: triangle index out of range (loaders validate indices)");
    }
    // Every byte of a record written (the array is not initialised): TriAccel's 48.
    static_assert(sizeof(TriAccel) == sizeof(TriRecord));
    if (!options.watertight) make_tri_accels(positions, triangles, begin, end - begin, &records[begin], isa);
    // The chunk's box and count, and each triangle's box, in locals, each stored once: chunk_box
    // and chunk_valid hold several chunks a cache line, and a store per triangle there bounced
    // the line between two threads on neighbouring chunks (bunny at 2 threads: this loop took
    // 0.08 ms on one thread, 0.16-0.35 ms on two).
    Aabb chunk_bounds;
    std::size_t valid = 0;
    for (std::size_t i = begin; i != end; ++i) {
      const std::uint32_t id = ids.empty() ? static_cast<std::uint32_t>(i) : ids[i];
      RTC_CHECK(id < 0x7FFFFFFFu, "kd-tree: triangle id must be below 2^31 - 1 (hits carry it as int32)");
      const glm::uvec3 t = triangles[i];
      const glm::vec3 a = positions[t.x], b = positions[t.y], c = positions[t.z];
      TriRecord& rec = records[i];
      if (options.watertight) {
        rec = TriRecord{};
        rec.watertight = make_tri_verts(a, b, c);
        rec.watertight.id = id;
      } else {
        rec.wald.id = id;
      }
      Aabb box;  // empty for a degenerate triangle
      if (rec.wald.k < 3) {  // valid in either format (TriRecord)
        box.extend(a);
        box.extend(b);
        box.extend(c);
      }
      tri_box[i] = box;
      if (options.mark_denser) {  // in double: a huge thin triangle's cross product overflows in float
        const glm::dvec3 da(a), db(b), dc(c);
        tri_area[i] = static_cast<float>(0.5 * glm::length(glm::cross(db - da, dc - da)));
      }
      if (!box.empty()) {  // as the tree's references are chosen below
        chunk_bounds.extend(box);
        ++valid;
      }
    }
    chunk_box[chunk] = chunk_bounds;
    chunk_valid[chunk] = valid;
  });

  Aabb root;
  std::size_t count = 0;
  for (std::size_t c = 0; c < record_chunks; ++c) {
    root.extend(chunk_box[c]);
    count += chunk_valid[c];
  }
  std::vector<std::uint32_t> tris(count);
  if (count == triangles.size()) {
    std::iota(tris.begin(), tris.end(), std::uint32_t{0});
  } else {
    std::size_t k = 0;
    for (std::size_t i = 0; i < triangles.size(); ++i) {
      if (!tri_box[i].empty()) tris[k++] = static_cast<std::uint32_t>(i);
    }
  }
  tree.stats_.degenerate = triangles.size() - count;
  if (count == 0) {
    tree.stats_.build_ms = timer.elapsed_ms();
    return tree;  // empty tree: every ray misses
  }

  int max_depth = options.max_depth;
  if (max_depth <= 0) max_depth = static_cast<int>(8.0 + 1.3 * std::log2(static_cast<double>(count)));
  max_depth = std::clamp(max_depth, 1, 60);

  const std::size_t mask_below =
      static_cast<std::size_t>(std::clamp(options.effective_mask_below(), 0, static_cast<int>(kMaxMaskRefs)));
  const auto exact_below = static_cast<std::size_t>(std::max(options.exact_below, 1));
  const std::size_t binned_root_above =
      std::min(exact_below, static_cast<std::size_t>(std::max(options.binned_root_above, 1)));
  const std::size_t threads = build_threads();
  BuildContext ctx{options,      tri_box,    positions, triangles, max_depth, kBins, exact_below,
                   binned_root_above, sah_scale_for(root),
                   options.clip, mask_below, build_isa(options) == Isa::Avx512, build_isa(options) >= Isa::Avx2,
                   std::max(options.leaf_box_saving, 0.0f), threads > 1 ? count / 4 : SIZE_MAX, threads};
  const glm::vec3 eye = options.footprint_eye;
  if (options.footprint_pixels > 0.0f && options.pixel_slope > 0.0f && options.footprint_max_refs > 0 &&
      std::isfinite(options.pixel_slope) && std::isfinite(eye.x + eye.y + eye.z)) {
    ctx.pixel_slope = options.pixel_slope;
    ctx.footprint_grow = std::min(options.footprint_pixels, kMaxFootprintPixels) * kFootprintSteps;
    ctx.footprint_max_refs = static_cast<std::size_t>(options.footprint_max_refs);
    ctx.eye = eye;
  }
  ctx.work.store(1, std::memory_order_relaxed);  // the root
  std::unique_ptr<TopNode> top = TopBuilder(ctx).build(std::move(tris), root, 0);

  const std::uint64_t node_total = 1 + top->nodes_below;
  if (node_total >= KdNode::kMaxNodes) {
    throw Error(fmt::format("kd-tree: more than 2^{} nodes (the 8-byte node format's limit)",
                            std::countr_zero(KdNode::kMaxNodes)));
  }
  if (top->refs >= (1u << 30)) {
    throw Error("kd-tree: more than 2^30 triangle references (the 8-byte node format's limit)");
  }
  tree.nodes_ = RawArray<KdNode>(node_total);  // the placer writes every node and reference once
  tree.prim_refs_ = RawArray<std::uint32_t>(top->refs);
  tree.leaf_records_ = RawArray<TriRecord>(top->refs);  // the placer writes the boxes, the copy below the rest
  // Leaf boxes are widened by 2^-18 of the scene's largest coordinate (~32 float ulps there):
  // the float triangle test accepts hits a rounding error outside a triangle, and such a hit
  // must not fall outside the box of the leaf that holds it.
  const glm::vec3 mag = glm::max(glm::abs(root.lo), glm::abs(root.hi));
  const float box_pad = std::max({mag.x, mag.y, mag.z}) * 0x1p-18f;
  Placer{tree.nodes_.data(), tree.prim_refs_.data(), tree.leaf_records_.data(), box_pad}.place(*top, 0, 1, 0);
  double cost_area = 0.0;
  add_stats(*top, root, 0, options, ctx.sah_scale, tree.stats_, cost_area);
  const float root_area = scaled_area(root, ctx.sah_scale);
  tree.stats_.sah_cost = root_area > 0.0f ? cost_area / static_cast<double>(root_area) : 0.0;
  top.reset();

  tri_box = RawArray<Aabb>();  // the build's last use: a smaller peak for what follows
  if (options.mark_denser) {
    // Tasks over the top 6 levels where the tree is large enough to pay for them.
    const int parallel_depth = tree.nodes_.size() >= (std::size_t{1} << 16) && threads > 1 ? 6 : 0;
    mark_denser(tree.nodes_.data(), tree.prim_refs_.data(), tri_area.data(), 0, root, parallel_depth);
    tri_area = RawArray<float>();
  }
  // Large arrays are written with streaming stores: their lines are not read first (spd-rings'
  // 116 MB at 2 threads: this loop 8.9 -> 6.1 ms). At 32 MiB an array is far past the L2 the
  // walks run from (trace_experiments.md, session 37), so a normal store's cached copy would
  // mostly be gone by the time the tracer reads it; a small tree's (a moving mesh's, rebuilt
  // every frame) is stored normally and stays cached.
  const bool stream = tree.leaf_records_.size() * sizeof(TriRecord) >= (std::size_t{32} << 20);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, tree.prim_refs_.size(), 4096), [&](const auto& range) {
    for (std::size_t i = range.begin(); i != range.end(); ++i) {
      const std::uint32_t r = tree.prim_refs_[i];
      if (r == kLeafBoxRef) continue;  // the placer wrote the boxes
      if (!stream) {
        tree.leaf_records_[i] = records[r];
        continue;
      }
      const float* from = reinterpret_cast<const float*>(&records[r]);
      float* to = reinterpret_cast<float*>(&tree.leaf_records_[i]);
      _mm_stream_ps(to, _mm_load_ps(from));
      _mm_stream_ps(to + 4, _mm_load_ps(from + 4));
      _mm_stream_ps(to + 8, _mm_load_ps(from + 8));
    }
    if (stream) _mm_sfence();
  });

  tree.stats_.nodes = tree.nodes_.size();
  tree.stats_.prim_refs = tree.prim_refs_.size() - tree.stats_.leaf_boxes;
  tree.stats_.bytes = tree.nodes_.size() * sizeof(KdNode) + tree.prim_refs_.size() * sizeof(std::uint32_t) +
                      tree.leaf_records_.size() * sizeof(TriRecord);
  const std::uint64_t full = tree.stats_.leaves - tree.stats_.empty_leaves;
  tree.stats_.mean_tris_per_leaf = full > 0 ? static_cast<double>(tree.stats_.prim_refs) / static_cast<double>(full) : 0.0;

  // Enlarge the traversal bounds by a few ulps of the largest coordinate so that rays grazing
  // the outermost triangles are not clipped away by rounding in the slab test.
  const float pad = std::max({mag.x, mag.y, mag.z}) * 4.0f * std::numeric_limits<float>::epsilon();
  tree.bounds_.lo = root.lo - glm::vec3(pad);
  tree.bounds_.hi = root.hi + glm::vec3(pad);
  tree.stats_.build_ms = timer.elapsed_ms();
  return tree;
}

}  // namespace rtc
