// Per-ISA tile rendering: packets of 2x2 primary rays, packet shadow rays per light, mirror
// reflections recursing as packets, Whitted/Phong shading (Wald et al. 2001, section 3). Mirror
// bounces that scatter are regrouped across the tile's packets (render_tile_bounces).
//
// Shading runs lane by lane in scalar float code (common/render/shading.h and the few lines
// below), the same code at every packet width, so a pixel is the same bits whether its rays
// travelled in a packet or alone.
//
// Work a frame does not need is skipped (issue 7): the kernels are templates over the features
// they handle, and each frame gets the instantiation that covers its own (FrameState::features;
// a view with no lights and no mirrors runs a pure ray-cast kernel); tiles and packets whose
// primary rays all miss the geometry's bounds (FrameState::cull) get the background without
// entering the kd-tree. Neither changes a bit of any pixel.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "common/accel/kd_traverse.h"
#include "common/accel/trace.h"
#include "common/image/image.h"
#include "common/math/det_math.h"
#include "common/math/det_math_lanes.h"
#include "common/render/frame_state.h"
#include "common/render/render_kernels.h"
#include "common/render/shading.h"
#include "common/render/temporal.h"
#include "common/render/trace_ticks.h"

RTC_ISA_BEGIN
namespace rtc::RTC_ISA_NS {
namespace {

inline float max3(const glm::vec3& a) { return std::max(a.x, std::max(a.y, a.z)); }

/// Per-lane results of tracing a packet one bounce deeper.
template <int N>
struct Lanes {
  glm::vec3 weight[N];  // throughput carried by each lane
  glm::vec3 color[N];   // radiance accumulated, already weighted
};

/// The packet taken into a tree's space (FrameGeometry::spaces): the same t along every ray.
/// Multiplies and adds in a fixed order (no FMA: -ffp-contract=off), so every packet width
/// gives the same bits.
template <int N>
RayPacket<N> to_space(const RayPacket<N>& p, const TreeSpace& s) {
  RayPacket<N> q;
  for (int r = 0; r < 3; ++r) {
    q.org[r] = ((vfloat<N>(s.m[0][r]) * p.org[0] + vfloat<N>(s.m[1][r]) * p.org[1]) +
                vfloat<N>(s.m[2][r]) * p.org[2]) +
               vfloat<N>(s.t[r]);
    q.dir[r] = (vfloat<N>(s.m[0][r]) * p.dir[0] + vfloat<N>(s.m[1][r]) * p.dir[1]) + vfloat<N>(s.m[2][r]) * p.dir[2];
  }
  q.t_min = p.t_min;
  q.t_max = p.t_max;
  return q;
}

/// Closest hits of the lanes in `lanes_mask`, from rtc's kd-trees or the external tracer.
template <int N>
void closest_hits(const FrameState& fs, const RayLanes<N>& rays, unsigned lanes_mask, RayHit (&out)[N]) {
  RTC_TRACE_TICK_SCOPE(fs.tracer != nullptr, static_cast<unsigned>(std::popcount(lanes_mask)), N);
  if (fs.tracer != nullptr) {
    RayQuery q[N];
    RayHit h[N];
    int n = 0;
    for (int i = 0; i < N; ++i) {
      if ((lanes_mask >> i) & 1u) q[n++] = rays.query(i);
    }
    fs.tracer->intersect(fs.tracer->context, q, h, static_cast<std::size_t>(n));
    n = 0;
    for (int i = 0; i < N; ++i) {
      if ((lanes_mask >> i) & 1u) out[i] = h[n++];
    }
    return;
  }
  const RayPacket<N> p = rays.packet();
  HitPacket<N> hit{p.t_max, vfloat<N>(0.0f), vfloat<N>(0.0f), vint<N>(-1)};
  // The static meshes' tree first (most hits are there), then each moving mesh's: every tree
  // starts from the hits found so far, which end its lanes' segments, and replaces one only
  // with a nearer triangle or one at the same t with a higher id, so the result is the bits of
  // one tree over all triangles (kd_traverse.h, intersect).
  const vbool<N> active = vbool<N>::from_bits(lanes_mask);
  const FrameGeometry& g = *fs.geometry;
  for (std::size_t k = 0; k < g.trees.size(); ++k) {
    const TreeSpace* space = g.space(k);
    intersect<N>(*g.trees[k], space == nullptr ? p : to_space(p, *space), active, hit);
  }
  float t[N], beta[N], gamma[N];
  std::int32_t prim[N];
  hit.t.store(t);
  hit.beta.store(beta);
  hit.gamma.store(gamma);
  hit.prim.store(prim);
  for (int i = 0; i < N; ++i) out[i] = RayHit{t[i], beta[i], gamma[i], static_cast<std::uint32_t>(prim[i])};
}

/// Occlusion of the lanes in `lanes_mask`, as a lane bit mask. `by_static` (optional) gets the
/// lanes blocked by meshes that never move (FrameGeometry::first_tree_static). `order` picks
/// the end each ray's walk starts from (the same answer either way) and learns the time taken.
template <int N>
unsigned occluded_lanes(const FrameState& fs, const RayLanes<N>& rays, unsigned lanes_mask, ShadowOrderChooser& order,
                        unsigned* by_static = nullptr) {
  if (by_static != nullptr) *by_static = 0;
  RTC_TRACE_TICK_SCOPE(fs.tracer != nullptr, static_cast<unsigned>(std::popcount(lanes_mask)), N);
  if (fs.tracer != nullptr) {
    RayQuery q[N];
    std::uint8_t occ[N];
    int n = 0;
    for (int i = 0; i < N; ++i) {
      if ((lanes_mask >> i) & 1u) q[n++] = rays.query(i);
    }
    fs.tracer->occluded(fs.tracer->context, q, occ, static_cast<std::size_t>(n));
    unsigned out = 0;
    n = 0;
    for (int i = 0; i < N; ++i) {
      if (((lanes_mask >> i) & 1u) && occ[n++] != 0) out |= 1u << i;
    }
    return out;
  }
  // Any tree's hit occludes: a lane leaves the query once one tree has blocked it.
  const RayPacket<N> p = rays.packet();
  unsigned blocked = 0;
  const FrameGeometry& g = *fs.geometry;
  const ShadowWalk walk = order.next();
  for (std::size_t k = 0; k < g.trees.size(); ++k) {
    const unsigned open = lanes_mask & ~blocked;
    if (open == 0) break;
    const TreeSpace* space = g.space(k);
    blocked |= bits(occluded<N>(*g.trees[k], space == nullptr ? p : to_space(p, *space), vbool<N>::from_bits(open),
                                walk));
    if (by_static != nullptr && g.first_tree_static && k == 0) *by_static = blocked;
  }
  order.done(static_cast<unsigned>(std::popcount(lanes_mask)));
  return blocked;
}

/// First-hit data the image keeps besides colour (sample 0 only).
struct Aov {
  float depth = std::numeric_limits<float>::infinity();
  glm::vec3 normal{0.0f};
};

/// What a kernel instantiation may have to do: one compiled without a bit never does that work,
/// not even the test for it. kAll is the general kernel, which tests for everything as it goes.
enum KernelFeature : unsigned {
  kShadows = 1u,      // lights: shadow rays and the diffuse terms
  kReflections = 2u,  // mirror rays
  kHighlights = 4u,   // Phong highlights (only with kShadows)
  kAovs = 8u,         // depth and normal of the first hit
  kAll = 15u,
};

/// The features a frame needs of its kernel (FrameFeatures, found once per frame).
unsigned kernel_features(const FrameFeatures& f, bool aovs) {
  unsigned need = 0;
  if (f.lights) need |= kShadows;
  if (f.reflections) need |= kReflections;
  if (f.lights && f.highlights) need |= kHighlights;
  if (aovs) need |= kAovs;
  return need;
}

/// Least and greatest of `v` over the lanes of `m` (+inf and -inf when none), exact for finite
/// lanes.
template <int N>
void lane_range(vfloat<N> v, vbool<N> m, float& lo, float& hi) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  lo = reduce_min(select(m, v, vfloat<N>(kInf)));
  hi = reduce_max(select(m, v, vfloat<N>(-kInf)));
}

/// The box of the points (x[0], x[1], x[2]) over the lanes of `m`; false when a coordinate of
/// one of them is not finite.
template <int N>
inline bool lane_box(const vfloat<N> (&x)[3], vbool<N> m, glm::vec3& lo, glm::vec3& hi) {
  vbool<N> finite = m;
  for (int a = 0; a < 3; ++a) {
    lane_range<N>(x[a], m, lo[a], hi[a]);
    finite &= (x[a] - x[a]) == vfloat<N>(0.0f);  // false for infinities and NaN
  }
  return bits(finite) == bits(m);
}

/// The rays of `lanes` one by one, ends t_end[lane], for the recorder's per-ray entries.
template <int N>
struct RayList {
  RayList(const RayLanes<N>& rays, unsigned lanes, const float* ends) {
    for (int i = 0; i < N; ++i) {
      if (!((lanes >> i) & 1u)) continue;
      const RayQuery q = rays.query(i);
      org[n] = q.org;
      dir[n] = q.dir;
      t_end[n++] = ends[i];
    }
  }
  glm::vec3 org[N], dir[N];
  float t_end[N];
  int n = 0;
};

/// Temporal coherence: the voxels the rays of `active` crossed up to their hits, all the way
/// on a miss (`hit` null: every lane missed). The group's boxes are reduced here with the
/// packet's SIMD width; the recorder takes the rays one by one only when they need it.
template <int N>
void mark_paths(MarkRecorder& marks, const RayLanes<N>& rays, unsigned active, const RayHit* hit) {
  alignas(64) float t_end[N];
  for (int i = 0; i < N; ++i) t_end[i] = hit == nullptr || hit[i].prim == kNoHit ? rays.t_max[i] : hit[i].t;
  const vbool<N> m = vbool<N>::from_bits(active);
  vfloat<N> org[3], dir[3];
  for (int a = 0; a < 3; ++a) {
    org[a] = vfloat<N>::load(rays.org[a]);
    dir[a] = vfloat<N>::load(rays.dir[a]);
  }
  const vfloat<N> t = vfloat<N>::load(t_end);
  glm::vec3 o_lo, o_hi, d_lo, d_hi;
  float t_lo, t_hi;
  lane_range<N>(t, m, t_lo, t_hi);
  const bool t_ok = bits(m & (t == t)) == active;  // no NaN (+inf is a miss)
  if (active != 0 && t_ok && lane_box<N>(org, m, o_lo, o_hi) && lane_box<N>(dir, m, d_lo, d_hi) &&
      marks.path_box(o_lo, o_hi, d_lo, d_hi, std::max(t_hi, 0.0f))) {
    return;
  }
  RayList<N> list(rays, active, t_end);
  marks.path(list.n, list.org, list.dir, list.t_end);
}

/// Temporal coherence: the shadow segments of `lanes`, from their origins to t_max (the light).
template <int N>
void mark_shadows(MarkRecorder& marks, const RayLanes<N>& rays, unsigned lanes) {
  const vbool<N> m = vbool<N>::from_bits(lanes);
  vfloat<N> a[3], b[3];
  const vfloat<N> t = vfloat<N>::load(rays.t_max);
  for (int k = 0; k < 3; ++k) {
    a[k] = vfloat<N>::load(rays.org[k]);
    b[k] = a[k] + vfloat<N>::load(rays.dir[k]) * t;  // as org + dir * t_end, lane by lane
  }
  glm::vec3 a_lo, a_hi, b_lo, b_hi;
  if (lane_box<N>(a, m, a_lo, a_hi) && lane_box<N>(b, m, b_lo, b_hi) && marks.shadow_box(a_lo, a_hi, b_lo, b_hi)) {
    return;
  }
  RayList<N> list(rays, lanes, rays.t_max);
  marks.shadow(list.n, list.org, list.dir, list.t_end);
}

/// An order of n items by a key of at most 40 bits, ties by position: sorted as 64-bit words
/// with the position in the low 24 bits, or as (key, position) pairs from 2^24 items on.
class KeySort {
 public:
  template <class Key>
  void sort(std::size_t n, Key&& key) {
    packed_ = n < kPositions;
    if (packed_) {
      words_.resize(n);
      for (std::size_t j = 0; j < n; ++j) words_[j] = key(j) << 24 | j;
      std::sort(words_.begin(), words_.end());
    } else {
      pairs_.resize(n);
      for (std::size_t j = 0; j < n; ++j) pairs_[j] = {key(j), j};
      std::sort(pairs_.begin(), pairs_.end());
    }
  }
  /// The position of the k-th item in the order.
  [[nodiscard]] std::size_t at(std::size_t k) const {
    return packed_ ? static_cast<std::size_t>(words_[k] & (kPositions - 1)) : pairs_[k].second;
  }

 private:
  static constexpr std::size_t kPositions = std::size_t{1} << 24;
  std::vector<std::uint64_t> words_;
  std::vector<std::pair<std::uint64_t, std::size_t>> pairs_;
  bool packed_ = true;
};

/// Mirror bounces as render_tile_bounces traces them. A packet whose bounces fill at least half
/// its lanes and head into at most two direction octants traces them at once, as one packet
/// (they left neighbouring pixels' hits and mostly stay together). Other bounces (few, or
/// scattered in direction) wait in a queue for the bounces of the tile's other packets, and are
/// traced later in full packets of similar rays (sort_bounces). Either way a lane's colour at each depth ("term":
/// 0 + weight * local, as trace_radiance leaves it) is kept in a chain per primary sample, and
/// the sample's colour is summed from the deepest term back, term + colour below, as the
/// recursion without a queue adds a bounce's colour to its parent's: the same operations in
/// the same order, so the same bits.
struct Bounce {
  glm::vec3 org{0.0f}, dir{0.0f}, weight{0.0f};
  std::uint32_t parent = 0;  // the term of the hit it leaves
  int depth = 0;             // its own depth (its parent's + 1)
};

struct Bounces {
  struct Term {
    glm::vec3 color{0.0f};
    std::int32_t child = -1;  // the term of the bounce below, if any
  };
  std::vector<Term> terms;
  std::vector<Bounce> queue;          // waiting to be traced
  std::vector<Bounce> batch;          // the queue taken in sorted order
  KeySort order;                      // sort_bounces' scratch
  std::vector<std::uint32_t> path;    // color()'s scratch
  static constexpr std::uint32_t kNone = ~std::uint32_t{0};

  std::uint32_t add() {
    terms.push_back(Term{});
    return static_cast<std::uint32_t>(terms.size() - 1);
  }
  /// A new term for the bounce leaving term `parent`.
  std::uint32_t add_child(std::uint32_t parent) {
    const std::uint32_t t = add();
    terms[parent].child = static_cast<std::int32_t>(t);
    return t;
  }
  /// The sample's colour from its primary term: the deepest term, then each term above plus the
  /// colour below it.
  [[nodiscard]] glm::vec3 color(std::uint32_t root) {
    if (terms[root].child < 0) return terms[root].color;
    path.clear();
    for (std::int32_t t = static_cast<std::int32_t>(root); t >= 0; t = terms[static_cast<std::size_t>(t)].child) {
      path.push_back(static_cast<std::uint32_t>(t));
    }
    glm::vec3 c = terms[path.back()].color;
    for (std::size_t k = path.size() - 1; k-- > 0;) c = terms[path[k]].color + c;
    return c;
  }
};

/// Shadow-ray walk orders of a tile: one chooser per light for the primary hits' shadow rays and
/// one for the mirror bounces' (points of another kind, often another preference), each
/// learning from and adding to the renderer's shared tally for it (TileKernelOptions).
struct ShadowOrders {
  std::vector<ShadowOrderChooser> per_light;  // [2 * light + (depth > 0)]
  ShadowOrders(std::size_t lights, const TileKernelOptions& options) {
    per_light.reserve(2 * lights);
    for (std::size_t k = 0; k < 2 * lights; ++k) {
      per_light.emplace_back(options.shadow_order, k < options.shadow_tally_count ? &options.shadow_tally[k] : nullptr);
    }
  }
  ShadowOrders(const ShadowOrders&) = delete;
  ShadowOrders& operator=(const ShadowOrders&) = delete;
  ~ShadowOrders() {
    for (ShadowOrderChooser& c : per_light) c.flush();
  }
  ShadowOrderChooser& at(std::size_t light, int depth) { return per_light[2 * light + (depth > 0 ? 1 : 0)]; }
};

/// A packet's hits as its shading needs them: their surfaces and the light gathered so far.
/// trace_radiance runs its steps in turn; render_tile_bounces runs each step over all the
/// packets of a batch, so that the shadow rays of many packets can be regrouped between them.
template <int N, unsigned F>
struct HitShading {
  SurfaceSample surf[N];
  glm::vec3 local[N];
  unsigned hit_lanes = 0;

  /// The surfaces of the active lanes' hits, their ambient and emitted light, and the depth and
  /// normal channels; a lane that missed gets the background in its colour.
  void surfaces(const FrameState& fs, const RayLanes<N>& rays, unsigned active, const RayHit (&hit)[N],
                Lanes<N>& lanes, Aov* aov) {
    for (int i = 0; i < N; ++i) {
      if (!((active >> i) & 1u)) continue;
      if (hit[i].prim == kNoHit) {
        lanes.color[i] = lanes.color[i] + lanes.weight[i] * fs.background;
        continue;
      }
      hit_lanes |= 1u << i;
      const RayQuery q = rays.query(i);
      surf[i] = surface_at(fs, q.dir, hit[i].prim, hit[i].beta, hit[i].gamma);
      const Material& m = *surf[i].material;
      local[i] = fs.ambient * m.diffuse + m.emission;
      if constexpr ((F & kAovs) != 0) {
        if (aov != nullptr) {
          // The depth channel gets the distance recomputed in double (exact for grazing rays too).
          const FrameGeometry& g = *fs.geometry;
          const glm::uvec3 tri = g.triangles[hit[i].prim];
          aov[i].depth = refined_distance(q.org, q.dir, g.positions[tri.x], g.positions[tri.y], g.positions[tri.z],
                                          hit[i].t);
          aov[i].normal = surf[i].normal;
        }
      }
    }
  }

  /// The hits' shadow rays towards `light` in `shadow` and their unit directions in `to_light`;
  /// returns the lanes that have one.
  unsigned shadow_rays(const PointLight& light, RayLanes<N>& shadow, glm::vec3 (&to_light)[N]) const {
    unsigned want = 0;
    for (int i = 0; i < N; ++i) {
      if (!((hit_lanes >> i) & 1u)) continue;
      glm::vec3 d;
      if (!shadow_ray_parts(surf[i], light, d, to_light[i])) continue;
      want |= 1u << i;
      shadow.set(i, surf[i].point, 0.0f, d, 1.0f);  // shadow_ray's ray
    }
    return want;
  }

  /// Adds `light` to the lanes of `lit` (their shadow rays unblocked).
  void add_light(const PointLight& light, unsigned lit, const glm::vec3 (&to_light)[N]) {
    if constexpr ((F & kHighlights) == 0) {
      for (int i = 0; i < N; ++i) {
        if (!((lit >> i) & 1u)) continue;
        const SurfaceSample& s = surf[i];
        const float n_dot_l = glm::dot(s.normal, to_light[i]);
        local[i] = local[i] + light.color * (s.material->diffuse * n_dot_l);
      }
    } else {
      // Diffuse per lane; the highlights' powers of all lit lanes in one batch
      // (det_powf_lanes: det_powf's bits, eight lanes side by side), then added per lane.
      glm::vec3 contrib[N]{};  // read only where `lit`; zeroed for GCC's -Wmaybe-uninitialized
      float base[N], power[N], highlight[N];
      int slot[N]{};
      unsigned shiny = 0;
      std::size_t powers = 0;
      for (int i = 0; i < N; ++i) {
        if (!((lit >> i) & 1u)) continue;
        const SurfaceSample& s = surf[i];
        const Material& m = *s.material;
        const float n_dot_l = glm::dot(s.normal, to_light[i]);
        contrib[i] = m.diffuse * n_dot_l;
        if (max3(m.specular) > 0.0f) {
          const glm::vec3 r = s.normal * (2.0f * n_dot_l) - to_light[i];
          const float r_dot_v = glm::dot(r, s.view);
          if (r_dot_v > 0.0f) {
            shiny |= 1u << i;
            base[powers] = r_dot_v;
            power[powers] = m.shininess;
            slot[i] = static_cast<int>(powers++);
          }
        }
      }
      if (shiny != 0) det_powf_lanes(base, power, highlight, powers);
      for (int i = 0; i < N; ++i) {
        if (!((lit >> i) & 1u)) continue;
        if ((shiny >> i) & 1u) contrib[i] = contrib[i] + surf[i].material->specular * highlight[slot[i]];
        local[i] = local[i] + light.color * contrib[i];
      }
    }
  }
};

// Every instantiation does, for every lane, the same operations in the same order as the
// general one (F = kAll) does for a frame with those features: what F leaves out is only work
// whose result the frame never uses (a light loop over no lights, a mirror test no material
// passes, a surface nothing reads), so the pixels are the same bits.
//
// `bounces` (optional, with `terms`: each lane's term there, or Bounces::kNone): mirror bounces
// are traced at once or queued there (Bounces). Returns the lanes with a bounce queued, here or
// further down: each has a term now (made where it had none), and its colour is its term's so
// far (what the queued bounce brings is linked to the term, not added), which the caller stores
// in the term. Without `bounces`, 0.
template <int N, unsigned F>
unsigned trace_radiance(const FrameState& fs, const RayLanes<N>& rays, unsigned active, int depth, Lanes<N>& lanes,
                        Aov* aov, TileRayCounts& counts, MarkRecorder* marks, ShadowOrders& orders,
                        std::uint32_t* terms = nullptr, Bounces* bounces = nullptr);

/// The last step of a packet's shading: each hit's light, weighted, into its lane's colour, and
/// its mirror bounce traced (trace_radiance's recursion; with `bounces`, traced at once or
/// queued, as trace_radiance says). Returns trace_radiance's pending lanes.
template <int N, unsigned F>
unsigned finish_hits(const FrameState& fs, const HitShading<N, F>& sh, int depth, Lanes<N>& lanes,
                     TileRayCounts& counts, MarkRecorder* marks, ShadowOrders& orders, std::uint32_t* terms,
                     Bounces* bounces) {
  const unsigned hit_lanes = sh.hit_lanes;
  if constexpr ((F & kReflections) == 0) {
    for (int i = 0; i < N; ++i) {
      if ((hit_lanes >> i) & 1u) lanes.color[i] = lanes.color[i] + lanes.weight[i] * sh.local[i];
    }
    return 0;
  } else {
    // Mirror reflections, as one packet per bounce, cut off by depth and by ray weight.
    RayLanes<N> refl;
    Lanes<N> next;
    unsigned bounce = 0;
    for (int i = 0; i < N; ++i) {
      if (!((hit_lanes >> i) & 1u)) continue;
      lanes.color[i] = lanes.color[i] + lanes.weight[i] * sh.local[i];
      const SurfaceSample& s = sh.surf[i];
      const Material& m = *s.material;
      if (!m.reflective || depth >= fs.settings.max_depth) continue;
      const glm::vec3 w = lanes.weight[i] * m.specular;
      if (!(max3(w) >= fs.settings.min_weight) || !(max3(w) > 0.0f)) continue;
      const glm::vec3 d = s.dir;
      glm::vec3 r = d - s.normal * (2.0f * glm::dot(d, s.normal));
      // An interpolated normal can send the mirror ray below the surface; use the true one then.
      if (!(glm::dot(r, s.geometric) > 0.0f)) r = d - s.geometric * (2.0f * glm::dot(d, s.geometric));
      bounce |= 1u << i;
      next.weight[i] = w;
      next.color[i] = glm::vec3(0.0f);
      refl.set(i, s.point, 0.0f, r, std::numeric_limits<float>::infinity());
    }
    if (bounce == 0) return 0;
    if (bounces != nullptr) {
      const unsigned sx = bits(sign_bit(vfloat<N>::load(refl.dir[0])));
      const unsigned sy = bits(sign_bit(vfloat<N>::load(refl.dir[1])));
      const unsigned sz = bits(sign_bit(vfloat<N>::load(refl.dir[2])));
      int octants = 0;
      for (unsigned left = bounce; left != 0; ++octants) {
        left &= ~octant_group(left, sx, sy, sz, __builtin_ctz(left));
      }
      if (octants > 2 || 2 * std::popcount(bounce) < N) {
        for (int i = 0; i < N; ++i) {
          if (!((bounce >> i) & 1u)) continue;
          if (terms[i] == Bounces::kNone) terms[i] = bounces->add();
          const RayQuery q = refl.query(i);
          bounces->queue.push_back(Bounce{q.org, q.dir, next.weight[i], terms[i], depth + 1});
        }
        counts.reflection_regrouped += static_cast<std::uint64_t>(std::popcount(bounce));
        return bounce;
      }
      // Traced at once. A lane whose bounces all came back adds their colour as the recursion
      // does; one with a bounce queued further down links its child's term instead.
      std::uint32_t child[N];
      std::fill(child, child + N, Bounces::kNone);
      const unsigned pending =
          trace_radiance<N, F>(fs, refl, bounce, depth + 1, next, nullptr, counts, marks, orders, child, bounces);
      for (int i = 0; i < N; ++i) {
        if (!((bounce >> i) & 1u)) continue;
        if ((pending >> i) & 1u) {
          if (terms[i] == Bounces::kNone) terms[i] = bounces->add();
          bounces->terms[terms[i]].child = static_cast<std::int32_t>(child[i]);
          bounces->terms[child[i]].color = next.color[i];
        } else {
          lanes.color[i] = lanes.color[i] + next.color[i];
        }
      }
      return pending;
    }
    trace_radiance<N, F>(fs, refl, bounce, depth + 1, next, nullptr, counts, marks, orders);
    for (int i = 0; i < N; ++i) {
      if ((bounce >> i) & 1u) lanes.color[i] = lanes.color[i] + next.color[i];
    }
    return 0;
  }
}

template <int N, unsigned F>
unsigned trace_radiance(const FrameState& fs, const RayLanes<N>& rays, unsigned active, int depth, Lanes<N>& lanes,
                        Aov* aov, TileRayCounts& counts, MarkRecorder* marks, ShadowOrders& orders,
                        std::uint32_t* terms, Bounces* bounces) {
  (depth == 0 ? counts.primary : counts.reflection) += static_cast<std::uint64_t>(std::popcount(active));
  RayHit hit[N];
  if constexpr (kTraceTicks) trace_tick_next(depth == 0 ? TraceCall::Primary : TraceCall::Mirror);
  closest_hits<N>(fs, rays, active, hit);
  if (marks != nullptr) mark_paths<N>(*marks, rays, active, hit);

  if constexpr ((F & (kShadows | kReflections)) == 0) {
    // Ray casting: a hit's colour is its material's ambient and emitted light, so the surface
    // itself is needed only for the normal channel.
    for (int i = 0; i < N; ++i) {
      if (!((active >> i) & 1u)) continue;
      if (hit[i].prim == kNoHit) {
        lanes.color[i] = lanes.color[i] + lanes.weight[i] * fs.background;
        continue;
      }
      const Material& m = fs.materials[fs.geometry->material_ids[hit[i].prim]];
      const glm::vec3 local = fs.ambient * m.diffuse + m.emission;
      if constexpr ((F & kAovs) != 0) {
        if (aov != nullptr) {
          const RayQuery q = rays.query(i);
          const FrameGeometry& g = *fs.geometry;
          const glm::uvec3 tri = g.triangles[hit[i].prim];
          aov[i].depth = refined_distance(q.org, q.dir, g.positions[tri.x], g.positions[tri.y], g.positions[tri.z],
                                          hit[i].t);
          aov[i].normal = shading_normal_at(fs, q.dir, hit[i].prim, hit[i].beta, hit[i].gamma);
        }
      }
      lanes.color[i] = lanes.color[i] + lanes.weight[i] * local;
    }
    return 0;
  } else {
    HitShading<N, F> sh;
    sh.surfaces(fs, rays, active, hit, lanes, aov);
    if (sh.hit_lanes == 0) return 0;

    if constexpr ((F & kShadows) != 0) {
      if (marks != nullptr && !fs.lights.empty()) marks->shaded();
      // One packet of shadow rays per light (Wald et al. 2001, section 3).
      for (std::size_t light_index = 0; light_index < fs.lights.size(); ++light_index) {
        const PointLight& light = fs.lights[light_index];
        RayLanes<N> shadow;
        glm::vec3 to_light[N]{};  // read only where `want`; zeroed for GCC's -Wmaybe-uninitialized
        const unsigned want = sh.shadow_rays(light, shadow, to_light);
        if (want == 0) continue;
        counts.shadow += static_cast<std::uint64_t>(std::popcount(want));
        unsigned by_static = 0;
        if constexpr (kTraceTicks) trace_tick_next(TraceCall::Shadow, light_index);
        const unsigned blocked = occluded_lanes<N>(fs, shadow, want, orders.at(light_index, depth),
                                                   marks != nullptr ? &by_static : nullptr);
        if (marks != nullptr) {
          // Temporal coherence: a shadow ray blocked by a mesh that never moves stays blocked
          // whatever moves, so it needs no marks (in an interior most of them; on the office
          // benchmark it halves the tiles retraced). The others may change along their whole way.
          const unsigned open = want & ~by_static;
          if (open != 0) mark_shadows<N>(*marks, shadow, open);
        }
        sh.add_light(light, want & ~blocked, to_light);
      }
    }
    return finish_hits<N, F>(fs, sh, depth, lanes, counts, marks, orders, terms, bounces);
  }
}

/// Fills a tile none of whose primary rays can hit anything with what a miss gives each pixel
/// (background colour, depth +inf, normal 0), the colour computed once with the operations
/// render_tile_impl and trace_radiance apply to a missing lane.
void fill_missed_tile(const FrameState& fs, int w, int h, int spp, Image& out, TileRayCounts& counts) {
  glm::vec3 sum(0.0f);
  for (int s = 0; s < spp; ++s) {
    glm::vec3 color(0.0f);
    color = color + glm::vec3(1.0f) * fs.background;
    sum = sum + color;
  }
  const float inv_spp = 1.0f / static_cast<float>(spp);
  const glm::vec3 c = spp == 1 ? sum : sum * inv_spp;
  const bool aovs = !out.depth.empty();
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      float* p = out.pixel(x, y);
      p[0] = c.x;
      p[1] = c.y;
      p[2] = c.z;
      p[3] = 1.0f;
      if (aovs) {
        const std::size_t idx = static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x);
        out.depth[idx] = std::numeric_limits<float>::infinity();
        out.normal[3 * idx + 0] = 0.0f;
        out.normal[3 * idx + 1] = 0.0f;
        out.normal[3 * idx + 2] = 0.0f;
      }
    }
  }
  const auto rays = static_cast<std::uint64_t>(w) * static_cast<std::uint64_t>(h) * static_cast<std::uint64_t>(spp);
  counts.primary += rays;
  counts.primary_skipped += rays;
}

/// A 10-bit cell index of x in [lo, lo + 1024 / scale); NaN and values outside clamp to the ends.
inline std::uint64_t bounce_cell(float x, float lo, float scale) {
  const float f = (x - lo) * scale;
  if (!(f > 0.0f)) return 0;
  return f < 1023.0f ? static_cast<std::uint64_t>(f) : 1023u;
}

/// x's low 10 bits spread to every third bit (a Morton code's part for one axis).
inline std::uint64_t spread_bits3(std::uint64_t x) {
  x &= 0x3FF;
  x = (x | (x << 16)) & 0x030000FFu;
  x = (x | (x << 8)) & 0x0300F00Fu;
  x = (x | (x << 4)) & 0x030C30C3u;
  x = (x | (x << 2)) & 0x09249249u;
  return x;
}

/// A direction's octant (3 bits) and the 30-bit Morton code of a point in the box [lo, lo +
/// 1024 / scale), as one key.
inline std::uint64_t octant_morton(const glm::vec3& dir, const glm::vec3& p, const glm::vec3& lo,
                                   const glm::vec3& scale) {
  const std::uint64_t octant = (std::signbit(dir.x) ? 1u : 0u) | (std::signbit(dir.y) ? 2u : 0u) |
                               (std::signbit(dir.z) ? 4u : 0u);
  return octant << 30 | spread_bits3(bounce_cell(p.x, lo.x, scale.x)) |
         spread_bits3(bounce_cell(p.y, lo.y, scale.y)) << 1 | spread_bits3(bounce_cell(p.z, lo.z, scale.z)) << 2;
}

/// 1024 / extent per axis of the box [lo, hi] (0 where it is empty or not finite).
inline glm::vec3 cell_scale(const glm::vec3& lo, const glm::vec3& hi) {
  glm::vec3 scale(0.0f);
  for (int a = 0; a < 3; ++a) {
    const float extent = hi[a] - lo[a];
    if (extent > 0.0f && std::isfinite(extent)) scale[a] = 1024.0f / extent;
  }
  return scale;
}

/// Moves the queue into `batch` sorted so that a packet gets rays of one depth and direction
/// octant whose origins lie close together: by depth, octant, the Morton code of the origin in
/// the queue's box (10 bits per axis), then queue position. Depths are at most 64
/// (RenderSettings::max_depth).
void sort_bounces(Bounces& b) {
  std::vector<Bounce>& queue = b.queue;
  glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
  for (const Bounce& x : queue) {
    lo = glm::min(lo, x.org);
    hi = glm::max(hi, x.org);
  }
  const glm::vec3 scale = cell_scale(lo, hi);
  b.order.sort(queue.size(), [&](std::size_t k) {
    const Bounce& x = queue[k];
    return static_cast<std::uint64_t>(std::min(x.depth, 127)) << 33 | octant_morton(x.dir, x.org, lo, scale);
  });
  b.batch.resize(queue.size());
  for (std::size_t k = 0; k < queue.size(); ++k) b.batch[k] = queue[b.order.at(k)];
  queue.clear();
}

/// The pixels of the packet whose block starts at (bx, by) of a w x h tile: lane i's is (px[i],
/// py[i]); returns the lanes inside the tile.
template <int N>
unsigned packet_pixels(int bx, int by, int w, int h, int (&px)[N], int (&py)[N]) {
  constexpr int kBlockW = packet_block_width(N);
  unsigned valid = 0;
  for (int i = 0; i < N; ++i) {
    px[i] = bx + i % kBlockW;
    py[i] = by + i / kBlockW;
    if (px[i] < w && py[i] < h) valid |= 1u << i;
  }
  return valid;
}

/// The camera rays of the `valid` lanes' pixels (tile pixel + (x0, y0)) at sample offset (sx, sy).
template <int N>
void camera_packet(const FrameState& fs, int x0, int y0, const int (&px)[N], const int (&py)[N], unsigned valid,
                   double sx, double sy, RayLanes<N>& primary) {
  for (int i = 0; i < N; ++i) {
    if (!((valid >> i) & 1u)) continue;
    const Ray r = fs.camera_rays.ray(x0 + px[i], y0 + py[i], sx, sy);
    primary.set(i, r.origin, 0.0f, r.dir, std::numeric_limits<float>::infinity());
  }
}

/// What trace_radiance does for primary lanes that miss, without the kd-tree (a packet that
/// provably sees nothing).
template <int N>
void miss_packet(const FrameState& fs, unsigned valid, Lanes<N>& lanes, TileRayCounts& counts) {
  for (int i = 0; i < N; ++i) {
    if ((valid >> i) & 1u) lanes.color[i] = lanes.color[i] + lanes.weight[i] * fs.background;
  }
  counts.primary += static_cast<std::uint64_t>(std::popcount(valid));
  counts.primary_skipped += static_cast<std::uint64_t>(std::popcount(valid));
}

/// A packet of a sorted batch of bounces (trace_batch) while its shadow rays are out.
template <int N, unsigned F>
struct BatchPacket {
  RayLanes<N> rays;
  Lanes<N> lanes;
  std::uint32_t term[N];
  unsigned active = 0;
  int depth = 0;
  HitShading<N, F> sh;
  RayLanes<N> shadow;  // the present light's shadow rays
  glm::vec3 to_light[N];
  unsigned want = 0, blocked = 0;
};

/// One light's shadow rays of a batch, as (packet, lane) with their sort keys.
struct BatchShadows {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> at;  // (packet, lane)
  KeySort order;                                             // of `at`
};

/// Traces bounces.batch (sorted by sort_bounces) in packets of up to N bounces of one depth. Each
/// step of their shading runs over all the packets in turn (HitShading), and between them each
/// light's shadow rays of all the packets are sorted by direction octant and the Morton code of
/// their origin, and traced in full packets: a packet of scattered bounces has scattered hits,
/// whose shadow rays would otherwise fill a few lanes of a packet each. Every ray gets the same
/// answer in any packet, and each hit is shaded by the same operations in the same order (the
/// lights in turn), so the pixels are the same bits.
template <int N, unsigned F>
void trace_batch(const FrameState& fs, Bounces& bounces, std::vector<BatchPacket<N, F>>& packets,
                 BatchShadows& shadows, TileRayCounts& counts, ShadowOrders& orders) {
  const std::vector<Bounce>& batch = bounces.batch;
  packets.clear();
  for (std::size_t k = 0; k < batch.size();) {
    BatchPacket<N, F>& p = packets.emplace_back();
    p.depth = batch[k].depth;
    std::fill(p.term, p.term + N, Bounces::kNone);
    int n = 0;
    for (; n < N && k < batch.size() && batch[k].depth == p.depth; ++n, ++k) {
      const Bounce& b = batch[k];
      p.rays.set(n, b.org, 0.0f, b.dir, std::numeric_limits<float>::infinity());
      p.lanes.weight[n] = b.weight;
      p.lanes.color[n] = glm::vec3(0.0f);
      p.term[n] = bounces.add_child(b.parent);
      p.active |= 1u << n;
    }
    counts.reflection += static_cast<std::uint64_t>(n);
    RayHit hit[N];
    if constexpr (kTraceTicks) trace_tick_next(TraceCall::Mirror);
    closest_hits<N>(fs, p.rays, p.active, hit);
    p.sh.surfaces(fs, p.rays, p.active, hit, p.lanes, nullptr);
  }
  if constexpr ((F & kShadows) != 0) {
    for (std::size_t light_index = 0; light_index < fs.lights.size(); ++light_index) {
      const PointLight& light = fs.lights[light_index];
      shadows.at.clear();
      glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
      for (std::size_t q = 0; q < packets.size(); ++q) {
        BatchPacket<N, F>& p = packets[q];
        p.want = p.sh.hit_lanes != 0 ? p.sh.shadow_rays(light, p.shadow, p.to_light) : 0u;
        p.blocked = 0;
        for (unsigned m = p.want; m != 0; m &= m - 1) {
          const int i = __builtin_ctz(m);
          shadows.at.emplace_back(static_cast<std::uint32_t>(q), static_cast<std::uint32_t>(i));
          lo = glm::min(lo, p.sh.surf[i].point);
          hi = glm::max(hi, p.sh.surf[i].point);
        }
      }
      const std::size_t rays = shadows.at.size();
      if (rays == 0) continue;
      counts.shadow += static_cast<std::uint64_t>(rays);
      const glm::vec3 scale = cell_scale(lo, hi);
      const auto key = [&](std::size_t j) {
        const auto [q, i] = shadows.at[j];
        const RayLanes<N>& r = packets[q].shadow;
        return octant_morton(glm::vec3(r.dir[0][i], r.dir[1][i], r.dir[2][i]), packets[q].sh.surf[i].point, lo, scale);
      };
      shadows.order.sort(rays, key);
      ShadowOrderChooser& chooser = orders.at(light_index, 1);
      for (std::size_t j = 0; j < rays; j += N) {
        const int n = static_cast<int>(std::min<std::size_t>(N, rays - j));
        RayLanes<N> group;
        for (int l = 0; l < n; ++l) {
          const auto [q, i] = shadows.at[shadows.order.at(j + static_cast<std::size_t>(l))];
          const RayLanes<N>& r = packets[q].shadow;
          group.set(l, glm::vec3(r.org[0][i], r.org[1][i], r.org[2][i]), r.t_min[i],
                    glm::vec3(r.dir[0][i], r.dir[1][i], r.dir[2][i]), r.t_max[i]);
        }
        const unsigned all = (1u << n) - 1u;  // n <= N <= 16
        if constexpr (kTraceTicks) trace_tick_next(TraceCall::Shadow, light_index);
        const unsigned blocked = occluded_lanes<N>(fs, group, all, chooser);
        for (int l = 0; l < n; ++l) {
          if (!((blocked >> l) & 1u)) continue;
          const auto [q, i] = shadows.at[shadows.order.at(j + static_cast<std::size_t>(l))];
          packets[q].blocked |= 1u << i;
        }
      }
      for (BatchPacket<N, F>& p : packets) {
        if (p.want != 0) p.sh.add_light(light, p.want & ~p.blocked, p.to_light);
      }
    }
  }
  for (BatchPacket<N, F>& p : packets) {
    if (p.sh.hit_lanes != 0) {
      finish_hits<N, F>(fs, p.sh, p.depth, p.lanes, counts, nullptr, orders, p.term, &bounces);
    }
    for (int j = 0; j < N; ++j) {
      if ((p.active >> j) & 1u) bounces.terms[p.term[j]].color = p.lanes.color[j];
    }
  }
}

// render_tile_impl for kernels with mirrors and no temporal marks: each sample's primary packets
// with their bounces (Bounces: a packet's bounces traced at once where they fill half of it in
// one direction octant), then the bounces left queued, in sorted full packets, until none is
// left. A pixel's sample whose bounces all came back is done at once; one with a bounce queued
// gets its colour from its chain of terms once the queue is empty. Samples are summed in order,
// and every colour by the recursion's operations, so the same bits.
template <int N, unsigned F>
void render_tile_bounces(const FrameState& fs, int x0, int y0, int w, int h, Image& out, TileRayCounts& counts,
                         const FrustumCull* cull, const TileKernelOptions& options) {
  static_assert((F & kReflections) != 0, "for kernels with mirrors");
  constexpr int kBlockW = packet_block_width(N);
  constexpr int kBlockH = N / kBlockW;
  const int spp = std::max(1, fs.settings.spp);
  const bool aovs = !out.depth.empty();
  const std::size_t pixels = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
  ShadowOrders orders(fs.lights.size(), options);
  // Kept per thread from tile to tile (nothing in a tile's tracing runs another tile on this
  // thread), but for a very large tile's, which are freed after it.
  constexpr std::size_t kKeepPixels = std::size_t{256} * 256;
  struct Scratch {
    std::vector<glm::vec3> sum;  // spp > 1: the samples' colours so far
    std::vector<std::pair<std::uint32_t, std::uint32_t>> waiting;  // (pixel, term) with a bounce queued
    Bounces bounces;
    std::vector<BatchPacket<N, F>> packets;
    BatchShadows shadows;
  };
  thread_local Scratch scratch;
  std::vector<glm::vec3>& sum = scratch.sum;
  auto& waiting = scratch.waiting;
  Bounces& bounces = scratch.bounces;
  if (spp > 1) sum.assign(pixels, glm::vec3(0.0f));
  // Pixel idx (row-major in the tile) gets colour c, alpha 1.
  const auto write = [&](std::size_t idx, const glm::vec3& c) {
    float* p = out.pixel(static_cast<int>(idx % static_cast<std::size_t>(w)),
                         static_cast<int>(idx / static_cast<std::size_t>(w)));
    p[0] = c.x;
    p[1] = c.y;
    p[2] = c.z;
    p[3] = 1.0f;
  };
  // A sample's colour: written out (one sample: the sum 0 + colour), or added to the pixel's sum.
  const auto done = [&](std::size_t idx, const glm::vec3& color) {
    if (spp > 1) {
      sum[idx] = sum[idx] + color;
    } else {
      write(idx, glm::vec3(0.0f) + color);
    }
  };
  for (int s = 0; s < spp; ++s) {
    double sx, sy;
    sample_offset(s, sx, sy);
    bounces.terms.clear();
    bounces.queue.clear();
    waiting.clear();
    for (int by = 0; by < h; by += kBlockH) {
      for (int bx = 0; bx < w; bx += kBlockW) {
        int px[N], py[N];
        const unsigned valid = packet_pixels<N>(bx, by, w, h, px, py);
        const bool skip =
            cull != nullptr && cull->misses(x0 + bx, y0 + by, x0 + bx + kBlockW, y0 + by + kBlockH);
        Lanes<N> lanes;
        std::uint32_t term[N];
        std::fill(term, term + N, Bounces::kNone);
        for (int i = 0; i < N; ++i) {
          lanes.weight[i] = glm::vec3(1.0f);
          lanes.color[i] = glm::vec3(0.0f);
        }
        unsigned pending = 0;
        Aov aov[N];
        if (!skip) {
          RayLanes<N> primary;
          camera_packet<N>(fs, x0, y0, px, py, valid, sx, sy, primary);
          Aov* first = nullptr;
          if constexpr ((F & kAovs) != 0) first = s == 0 ? aov : nullptr;
          pending = trace_radiance<N, F>(fs, primary, valid, 0, lanes, first, counts, nullptr, orders, term, &bounces);
        } else {
          miss_packet<N>(fs, valid, lanes, counts);
        }
        for (int i = 0; i < N; ++i) {
          if (!((valid >> i) & 1u)) continue;
          const std::size_t idx =
              static_cast<std::size_t>(py[i]) * static_cast<std::size_t>(w) + static_cast<std::size_t>(px[i]);
          if (s == 0 && aovs) {
            out.depth[idx] = aov[i].depth;
            out.normal[3 * idx + 0] = aov[i].normal.x;
            out.normal[3 * idx + 1] = aov[i].normal.y;
            out.normal[3 * idx + 2] = aov[i].normal.z;
          }
          if ((pending >> i) & 1u) {
            bounces.terms[term[i]].color = lanes.color[i];
            waiting.emplace_back(static_cast<std::uint32_t>(idx), term[i]);
          } else {
            done(idx, lanes.color[i]);
          }
        }
      }
    }
    while (!bounces.queue.empty()) {
      sort_bounces(bounces);  // into bounces.batch; what these bounces queue goes to bounces.queue
      trace_batch<N, F>(fs, bounces, scratch.packets, scratch.shadows, counts, orders);
    }
    for (const auto& [idx, t] : waiting) done(idx, bounces.color(t));
  }
  if (spp > 1) {
    const float inv_spp = 1.0f / static_cast<float>(spp);
    for (std::size_t idx = 0; idx < pixels; ++idx) write(idx, sum[idx] * inv_spp);
  }
  if (pixels > kKeepPixels) scratch = Scratch{};
}

// Packets of 2x2 pixels (N = 4), 4x2 (N = 8), 4x4 (N = 16); single pixels when N = 1. `cull`
// (optional) says which tiles and packets see nothing of the geometry: their rays are not
// traced (but still marked for temporal coherence: a mesh may move into that space later).
template <int N, unsigned F>
void render_tile_impl(const FrameState& fs, int x0, int y0, int w, int h, Image& out, TileRayCounts& counts,
                      MarkRecorder* marks, const FrustumCull* cull, const TileKernelOptions& options) {
  constexpr int kBlockW = packet_block_width(N);
  constexpr int kBlockH = N / kBlockW;
  const int spp = std::max(1, fs.settings.spp);
  const bool aovs = !out.depth.empty();
  const bool tile_misses = cull != nullptr && cull->misses(x0, y0, x0 + w, y0 + h);
  if (tile_misses && marks == nullptr) {
    fill_missed_tile(fs, w, h, spp, out, counts);
    return;
  }
  if constexpr ((F & kReflections) != 0) {
    if (marks == nullptr) {
      render_tile_bounces<N, F>(fs, x0, y0, w, h, out, counts, cull, options);
      return;
    }
  }
  ShadowOrders orders(fs.lights.size(), options);
  for (int by = 0; by < h; by += kBlockH) {
    for (int bx = 0; bx < w; bx += kBlockW) {
      int px[N], py[N];
      const unsigned valid = packet_pixels<N>(bx, by, w, h, px, py);
      const bool skip = tile_misses || (cull != nullptr && cull->misses(x0 + bx, y0 + by, x0 + bx + kBlockW,
                                                                         y0 + by + kBlockH));
      glm::vec3 sum[N];
      for (glm::vec3& v : sum) v = glm::vec3(0.0f);
      Aov aov[N];
      for (int s = 0; s < spp; ++s) {
        double sx, sy;
        sample_offset(s, sx, sy);
        Lanes<N> lanes;
        for (int i = 0; i < N; ++i) {
          lanes.weight[i] = glm::vec3(1.0f);
          lanes.color[i] = glm::vec3(0.0f);
        }
        RayLanes<N> primary;
        if (!skip || marks != nullptr) camera_packet<N>(fs, x0, y0, px, py, valid, sx, sy, primary);
        if (!skip) {
          Aov* first = nullptr;
          if constexpr ((F & kAovs) != 0) first = s == 0 ? aov : nullptr;
          trace_radiance<N, F>(fs, primary, valid, 0, lanes, first, counts, marks, orders);
        } else {
          if (marks != nullptr) mark_paths<N>(*marks, primary, valid, nullptr);
          miss_packet<N>(fs, valid, lanes, counts);
        }
        for (int i = 0; i < N; ++i) sum[i] = sum[i] + lanes.color[i];
      }
      const float inv_spp = 1.0f / static_cast<float>(spp);
      for (int i = 0; i < N; ++i) {
        if (!((valid >> i) & 1u)) continue;
        float* p = out.pixel(px[i], py[i]);
        const glm::vec3 c = spp == 1 ? sum[i] : sum[i] * inv_spp;
        p[0] = c.x;
        p[1] = c.y;
        p[2] = c.z;
        p[3] = 1.0f;
        if (aovs) {
          const std::size_t idx = static_cast<std::size_t>(py[i]) * static_cast<std::size_t>(w) +
                                  static_cast<std::size_t>(px[i]);
          out.depth[idx] = aov[i].depth;
          out.normal[3 * idx + 0] = aov[i].normal.x;
          out.normal[3 * idx + 1] = aov[i].normal.y;
          out.normal[3 * idx + 2] = aov[i].normal.z;
        }
      }
    }
  }
}

using TileFn = void (*)(const FrameState&, int, int, int, int, Image&, TileRayCounts&, MarkRecorder*,
                        const FrustumCull*, const TileKernelOptions&);

// The instantiations compiled; a frame gets the one with the fewest features that covers its own.
// Each costs compile time (this file is compiled once per ISA; all twelve distinct masks took
// ~2.3x the time of the general kernel alone), so these five are the ones scenes need:
// - the ray-cast kernel (no lights, no mirrors), with and without depth and normal channels:
//   0.61-0.63 of the general one's time without them, 0.90-0.93 with them;
// - lights without mirrors, with and without the channels: ten of the sixteen shared views (all
//   but the interiors, balls-s3, gears, teapot and the small mountain) have lights and no
//   mirror; this kernel never tests a hit for reflection, at 0.99-1.01 of the general kernel's
//   time (tests/bench/results/specialise.md): the test was cheap. The five take 18.4-19.9 s of
//   CPU to compile for the three ISAs, against 15.3-16.3 s for three (kernel_compile_time.sh);
// - the general kernel, which tests for everything as it goes.
// Left out: no lights with mirrors (the general kernel's light loop then runs over no lights and
// traces no shadow ray anyway), and no highlights alone (a per-material test either way).
constexpr unsigned kCompiled[] = {0u, kAovs, kShadows | kHighlights, kShadows | kHighlights | kAovs, kAll};

template <int N, std::size_t... I>
constexpr std::array<TileFn, sizeof...(I)> tile_kernels(std::index_sequence<I...>) {
  return {&render_tile_impl<N, kCompiled[I]>...};
}

/// Index into kCompiled of the instantiation with the fewest features that covers `need`.
std::size_t compiled_for(unsigned need) {
  std::size_t best = std::size(kCompiled);
  for (std::size_t k = 0; k < std::size(kCompiled); ++k) {
    if ((need & ~kCompiled[k]) == 0 &&
        (best == std::size(kCompiled) || std::popcount(kCompiled[k]) < std::popcount(kCompiled[best]))) {
      best = k;
    }
  }
  return best;  // kAll is there, so one is found
}

unsigned need_of(const FrameState& fs, const TileKernelOptions& options, bool aovs) {
  return options.specialise ? kernel_features(fs.features, aovs) : kAll;
}

void render_tile_entry(const FrameState& fs, int x0, int y0, int w, int h, const TileKernelOptions& options,
                       Image& out, TileRayCounts& counts, MarkRecorder* marks) {
  static constexpr auto kPacket = tile_kernels<RTC_ISA_WIDTH>(std::make_index_sequence<std::size(kCompiled)>{});
  static constexpr auto kSingle = tile_kernels<1>(std::make_index_sequence<std::size(kCompiled)>{});
  if (marks != nullptr && marks->grid_empty() && fs.lights.empty()) marks = nullptr;  // nothing to record
  const std::size_t k = compiled_for(need_of(fs, options, !out.depth.empty()));
  const FrustumCull* cull = options.skip_empty && fs.cull.active() ? &fs.cull : nullptr;
  (options.packets ? kPacket[k] : kSingle[k])(fs, x0, y0, w, h, out, counts, marks, cull, options);
}

const char* kernel_name_entry(const FrameState& fs, const TileKernelOptions& options, bool aovs) {
  const unsigned f = kCompiled[compiled_for(need_of(fs, options, aovs))];
  if (f == kAll) return "general";
  if ((f & (kShadows | kReflections)) == 0) return (f & kAovs) != 0 ? "ray-cast+aovs" : "ray-cast";
  if ((f & kReflections) == 0) return (f & kAovs) != 0 ? "no-mirror+aovs" : "no-mirror";
  return "specialised";
}

}  // namespace

const RenderKernels& render_kernels_for_isa() {
  static const RenderKernels kernels{Isa::RTC_ISA_ENUM, &render_tile_entry, &kernel_name_entry, &det_powf_lanes};
  return kernels;
}

}  // namespace rtc::RTC_ISA_NS
RTC_ISA_END
