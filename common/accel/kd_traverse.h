// Packet kd-tree traversal with Wald's projection triangle test or Woop's watertight one,
// written once over the packet width N (N = 1 is the scalar reference). Included only by
// kernel sources compiled per ISA. The test is a template parameter of the traversal, chosen
// once per query from KdTree::watertight().
//
// Every lane does exactly what a single ray would do: the same leaves in the same order
// (per-ray [near, far] segments, a lane leaves the packet's path as soon as its segment is
// empty or it has found its hit), and the same float operations in the same order. Closest
// hits break ties in t by the higher triangle id, so the result does not depend on the order
// in which the triangles of a leaf are tested. Together this makes packets and single rays
// give the same bits.
#pragma once

#include <bit>
#include <cstdint>
#include <type_traits>
#include <utility>

#include "common/accel/kd_tree.h"
#include "common/accel/shadow_order.h"
#include "common/accel/trace.h"
#include "common/accel/walk_stats.h"
#include "common/simd/simd.h"

RTC_ISA_BEGIN
namespace rtc::RTC_ISA_NS {

/// Rays of a packet, structure of arrays. Directions need not be normalised.
template <int N>
struct RayPacket {
  PacketVec3<N> org, dir;
  vfloat<N> t_min, t_max;
};

/// Closest hits: t, barycentric weights (beta, gamma) of vertices 1 and 2, triangle id
/// (-1 for a miss; then t stays t_max).
template <int N>
struct HitPacket {
  vfloat<N> t, beta, gamma;
  vint<N> prim;
};

inline constexpr int kNextAxis[5] = {1, 2, 0, 1, 2};

/// How far (relative) past a closest hit a stacked subtree's segment may start and still be
/// visited: 2^-16 (1.5e-5) covers the float test's t error except for rays within ~1e-5 rad
/// of a triangle's plane.
inline constexpr float kPopSlack = 0x1p-16f;

/// The farthest a segment may start and still hold a hit that can replace one at `t_hit`:
/// t_hit plus kPopSlack of its magnitude.
template <int N>
inline vfloat<N> hit_reach(const vfloat<N>& t_hit) {
  return t_hit + max(t_hit, -t_hit) * vfloat<N>(kPopSlack);
}

/// Lanes whose distance t a test may report: any t in (t_min, t_max) for occlusion; for the
/// closest hit, t in (t_min, hit.t), or t == hit.t with a higher triangle id. Ties in t
/// (coplanar overlapping triangles, shared edges) go to the higher id: any fixed rule makes the
/// result independent of test order; this one agrees with Embree's choice on the shared scenes
/// far more often than the lower id does. Both triangle tests use it.
template <int N, bool kOcclusion>
inline vbool<N> accepted_t(const vfloat<N>& t, std::int32_t prim, const RayPacket<N>& ray, const HitPacket<N>& hit) {
  if constexpr (kOcclusion) {
    return (t > ray.t_min) & (t < ray.t_max);
  } else {
    const vint<N> id(prim);
    return (t > ray.t_min) & ((t < hit.t) | ((t == hit.t) & (id > hit.prim) & (t < ray.t_max)));
  }
}

/// Wald's test (2001, section 2.2) against one triangle for the active lanes. kOcclusion:
/// any hit in (t_min, t_max) sets `occluded`; otherwise closer hits replace `hit`.
template <int N, bool kOcclusion>
inline void intersect_triangle(const TriAccel& acc, std::int32_t prim, const RayPacket<N>& ray,
                               vbool<N> active, HitPacket<N>& hit, vbool<N>& occluded) {
  const int k = static_cast<int>(acc.k);
  const int u = kNextAxis[k], v = kNextAxis[k + 1];
  const vfloat<N>& ok = ray.org[k];
  const vfloat<N>& ou = ray.org[u];
  const vfloat<N>& ov = ray.org[v];
  const vfloat<N>& dk = ray.dir[k];
  const vfloat<N>& du = ray.dir[u];
  const vfloat<N>& dv = ray.dir[v];
  const vfloat<N> n_u(acc.n_u), n_v(acc.n_v);
  // A ray parallel to the plane gives den = 0 and t = +-inf or NaN: every comparison below
  // is false for NaN and t < t_max fails for inf, so such lanes never hit.
  const vfloat<N> num = ((vfloat<N>(acc.n_d) - ok) - n_u * ou) - n_v * ov;
  const vfloat<N> den = (dk + n_u * du) + n_v * dv;
  const vfloat<N> t = num / den;
  active &= accepted_t<N, kOcclusion>(t, prim, ray, hit);
  if (none(active)) return;
  const vfloat<N> hu = ou + t * du;
  const vfloat<N> hv = ov + t * dv;
  const vfloat<N> beta = (vfloat<N>(acc.b_nu) * hu + vfloat<N>(acc.b_nv) * hv) + vfloat<N>(acc.b_d);
  const vfloat<N> gamma = (vfloat<N>(acc.c_nu) * hu + vfloat<N>(acc.c_nv) * hv) + vfloat<N>(acc.c_d);
  active &= (beta >= vfloat<N>(0.0f)) & (gamma >= vfloat<N>(0.0f)) & (beta + gamma <= vfloat<N>(1.0f));
  if (none(active)) return;
  if constexpr (kOcclusion) {
    occluded |= active;
  } else {
    hit.t = select(active, t, hit.t);
    hit.beta = select(active, beta, hit.beta);
    hit.gamma = select(active, gamma, hit.gamma);
    hit.prim = select(active, vint<N>(prim), hit.prim);
  }
}

/// Wald's test as the traversal's triangle test: needs nothing per packet.
template <int N>
struct WaldTest {
  static constexpr bool kConservative = false;  ///< leaves visited as computed (see traverse_coherent)
  WaldTest(const RayPacket<N>& /*ray*/, vbool<N> /*active*/) {}
  template <bool kOcclusion>
  void intersect(const TriRecord& rec, const RayPacket<N>& ray, vbool<N> active, HitPacket<N>& hit,
                 vbool<N>& occluded) const {
    intersect_triangle<N, kOcclusion>(rec.wald, static_cast<std::int32_t>(rec.wald.id), ray, active, hit, occluded);
  }
};

/// A single ray (N = 1) against a leaf with Wald's test, W triangles at a time: one triangle
/// per SIMD lane. Each lane does the scalar test's float operations in the same order, so the
/// same t, beta and gamma bits. The lanes' hits are then reduced by the closest-hit order
/// (smaller t, then the higher id), which is the result of testing the triangles one by one in
/// any order (accepted_t). A leaf with fewer than W triangles repeats its last one in the
/// spare lanes: the same candidate twice changes nothing.
///
/// records: the 48-byte TriAccel records, 16-byte aligned, each three 16-byte rows
/// (n_u n_v n_d k | b_nu b_nv b_d id | c_nu c_nv c_d pad), transposed by loads and shuffles.
template <int W>
struct LeafLanes;

template <>
struct LeafLanes<4> {
  /// Row `row` of the four records as four vectors: word w of record j in lane j of out[w].
  static void rows(const TriRecord* const* at, int row, vfloat<4>* out) {
    __m128 r0 = _mm_load_ps(reinterpret_cast<const float*>(at[0]) + 4 * row);
    __m128 r1 = _mm_load_ps(reinterpret_cast<const float*>(at[1]) + 4 * row);
    __m128 r2 = _mm_load_ps(reinterpret_cast<const float*>(at[2]) + 4 * row);
    __m128 r3 = _mm_load_ps(reinterpret_cast<const float*>(at[3]) + 4 * row);
    _MM_TRANSPOSE4_PS(r0, r1, r2, r3);
    out[0] = vfloat<4>(r0);
    out[1] = vfloat<4>(r1);
    out[2] = vfloat<4>(r2);
    out[3] = vfloat<4>(r3);
  }
  static vint<4> as_int(vfloat<4> x) { return vint<4>(_mm_castps_si128(x.v)); }
};

#if RTC_ISA_WIDTH >= 8
template <>
struct LeafLanes<8> {
  /// Records 0-3 in the low 128-bit halves, 4-7 in the high ones; the in-half 4x4 transpose
  /// (the body of _MM_TRANSPOSE4_PS on 256-bit registers) then gives lane j record j.
  static void rows(const TriRecord* const* at, int row, vfloat<8>* out) {
    __m256 r[4];
    for (int j = 0; j < 4; ++j) {
      r[j] = _mm256_insertf128_ps(
          _mm256_castps128_ps256(_mm_load_ps(reinterpret_cast<const float*>(at[j]) + 4 * row)),
          _mm_load_ps(reinterpret_cast<const float*>(at[j + 4]) + 4 * row), 1);
    }
    const __m256 t0 = _mm256_unpacklo_ps(r[0], r[1]);
    const __m256 t1 = _mm256_unpacklo_ps(r[2], r[3]);
    const __m256 t2 = _mm256_unpackhi_ps(r[0], r[1]);
    const __m256 t3 = _mm256_unpackhi_ps(r[2], r[3]);
    out[0] = vfloat<8>(_mm256_shuffle_ps(t0, t1, _MM_SHUFFLE(1, 0, 1, 0)));
    out[1] = vfloat<8>(_mm256_shuffle_ps(t0, t1, _MM_SHUFFLE(3, 2, 3, 2)));
    out[2] = vfloat<8>(_mm256_shuffle_ps(t2, t3, _MM_SHUFFLE(1, 0, 1, 0)));
    out[3] = vfloat<8>(_mm256_shuffle_ps(t2, t3, _MM_SHUFFLE(3, 2, 3, 2)));
  }
  static vint<8> as_int(vfloat<8> x) { return vint<8>(_mm256_castps_si256(x.v)); }
};
#endif

/// Tests triangles [first, first + W) of a leaf of `count` (indices past the end repeat the
/// last triangle). Returns true when an occlusion query is done (a hit).
template <int W, bool kOcclusion>
inline bool intersect_lanes(const TriRecord* leaf, std::uint32_t first, std::uint32_t count,
                            const RayPacket<1>& ray, HitPacket<1>& hit) {
  const TriRecord* at[W];
  for (int j = 0; j < W; ++j) {
    const std::uint32_t i = first + static_cast<std::uint32_t>(j);
    at[j] = leaf + (i < count ? i : count - 1);
  }
  vfloat<W> f[12];
  LeafLanes<W>::rows(at, 0, f);
  LeafLanes<W>::rows(at, 1, f + 4);
  LeafLanes<W>::rows(at, 2, f + 8);
  const vfloat<W>& n_u = f[0];
  const vfloat<W>& n_v = f[1];
  const vfloat<W>& n_d = f[2];
  const vint<W> k = LeafLanes<W>::as_int(f[3]);
  const vint<W> id = LeafLanes<W>::as_int(f[7]);
  // The ray's components by each lane's projection axis k (u = k + 1, v = k + 2, mod 3).
  const vbool<W> k0 = k == vint<W>(0), k1 = k == vint<W>(1);
  const auto by_axis = [&](const PacketVec3<1>& c, int shift) {
    const vfloat<W> x(c[0].v), y(c[1].v), z(c[2].v);
    if (shift == 0) return select(k0, x, select(k1, y, z));
    if (shift == 1) return select(k0, y, select(k1, z, x));
    return select(k0, z, select(k1, x, y));
  };
  const vfloat<W> ok = by_axis(ray.org, 0), ou = by_axis(ray.org, 1), ov = by_axis(ray.org, 2);
  const vfloat<W> dk = by_axis(ray.dir, 0), du = by_axis(ray.dir, 1), dv = by_axis(ray.dir, 2);
  // intersect_triangle's operations, in its order.
  const vfloat<W> num = ((n_d - ok) - n_u * ou) - n_v * ov;
  const vfloat<W> den = (dk + n_u * du) + n_v * dv;
  const vfloat<W> t = num / den;
  const vfloat<W> t_min(ray.t_min.v), t_max(ray.t_max.v);
  vbool<W> active = t > t_min;
  if constexpr (kOcclusion) {
    active &= t < t_max;
  } else {
    const vfloat<W> hit_t(hit.t.v);
    active &= (t < hit_t) | ((t == hit_t) & (id > vint<W>(hit.prim.v)) & (t < t_max));
  }
  if (none(active)) return false;
  const vfloat<W> hu = ou + t * du;
  const vfloat<W> hv = ov + t * dv;
  const vfloat<W> beta = (f[4] * hu + f[5] * hv) + f[6];
  const vfloat<W> gamma = (f[8] * hu + f[9] * hv) + f[10];
  active &= (beta >= vfloat<W>(0.0f)) & (gamma >= vfloat<W>(0.0f)) & (beta + gamma <= vfloat<W>(1.0f));
  unsigned lanes = bits(active);
  if (lanes == 0) return false;
  if constexpr (kOcclusion) {
    return true;
  } else {
    alignas(32) float ts[W], bs[W], gs[W];
    alignas(32) std::int32_t ids[W];
    t.store(ts);
    beta.store(bs);
    gamma.store(gs);
    id.store(ids);
    int best = __builtin_ctz(lanes);
    for (lanes &= lanes - 1; lanes != 0; lanes &= lanes - 1) {
      const int j = __builtin_ctz(lanes);
      if (ts[j] < ts[best] || (ts[j] == ts[best] && ids[j] > ids[best])) best = j;
    }
    hit.t = vfloat<1>(ts[best]);
    hit.beta = vfloat<1>(bs[best]);
    hit.gamma = vfloat<1>(gs[best]);
    hit.prim = vint<1>(ids[best]);
    return false;
  }
}

/// Triangles [0, count) of a leaf, W at a time; true when an occlusion query found a hit.
template <int W, bool kOcclusion>
inline bool intersect_leaf_lanes(const TriRecord* leaf, std::uint32_t count, const RayPacket<1>& ray,
                                 HitPacket<1>& hit) {
  for (std::uint32_t first = 0; first < count; first += W) {
    if (intersect_lanes<W, kOcclusion>(leaf, first, count, ray, hit)) return true;
  }
  return false;
}

/// A single ray against a whole leaf with Wald's test (see LeafLanes). kOcclusion: stops at
/// the first hit and sets `occluded`.
template <bool kOcclusion>
inline void intersect_leaf_single(const TriRecord* leaf, std::uint32_t count, const RayPacket<1>& ray,
                                  HitPacket<1>& hit, vbool<1>& occluded) {
  if (count == 1) {
    intersect_triangle<1, kOcclusion>(leaf[0].wald, static_cast<std::int32_t>(leaf[0].wald.id), ray, vbool<1>(true),
                                      hit, occluded);
    return;
  }
#if RTC_ISA_WIDTH >= 8
  const bool found = count > 4 ? intersect_leaf_lanes<8, kOcclusion>(leaf, count, ray, hit)
                               : intersect_leaf_lanes<4, kOcclusion>(leaf, count, ray, hit);
#else
  const bool found = intersect_leaf_lanes<4, kOcclusion>(leaf, count, ray, hit);
#endif
  if (found) occluded = vbool<1>(true);
}

/// |x| (clears the sign bit, also of -0).
template <int N>
inline vfloat<N> abs_value(vfloat<N> x) {
  return select(sign_bit(x), -x, x);
}

/// Coordinate k (0, 1, 2) of (x, y, z).
inline float coord(float x, float y, float z, int k) { return k == 0 ? x : k == 1 ? y : z; }

/// Component k of v per lane, k given as the masks k == 0 and k == 1.
template <int N>
inline vfloat<N> pick(vbool<N> is0, vbool<N> is1, const PacketVec3<N>& v) {
  return select(is0, v[0], select(is1, v[1], v[2]));
}

/// Woop, Benthin and Wald's watertight test (2013, JCGT 2(1), section 3 and the appendix's
/// code). Per packet: kz = the axis of the largest |dir|, kx and ky the next ones (swapped
/// when dir[kz] < 0 to keep the winding), and the shear Sx = dir[kx]/dir[kz],
/// Sy = dir[ky]/dir[kz], Sz = 1/dir[kz], all per lane. Per triangle: the vertices relative to
/// the origin are sheared so the ray becomes +z from (0, 0), the 2D edge functions U, V, W
/// (recomputed in double for a lane where one is exactly 0, so that an edge shared by two
/// triangles gives opposite signs in both), a hit when they share a sign and det = U + V + W
/// is not 0. Lanes whose axes differ use per-lane selects; when every active lane has the same
/// axes (all coherent packets) the axes are plain indices. Both give the same bits per lane.
template <int N>
struct WatertightTest {
  static constexpr bool kConservative = true;  ///< a hit needs every leaf the ray touches
  vfloat<N> sx, sy, sz;
  vbool<N> kx0, kx1, ky0, ky1, kz0, kz1;  // per lane: kx == 0, kx == 1, ...
  int kx = -1, ky = -1, kz = -1;          // the same for every active lane, else -1
  PacketVec3<N> org;                      // with kz >= 0: the origin permuted to (kx, ky, kz)

  WatertightTest(const RayPacket<N>& ray, vbool<N> active) {
    const vfloat<N> ax = abs_value(ray.dir[0]), ay = abs_value(ray.dir[1]), az = abs_value(ray.dir[2]);
    // The paper's max_dim: ties go to the later axis.
    const vbool<N> x_gt_y = ax > ay;
    kz0 = x_gt_y & (ax > az);
    kz1 = (!x_gt_y) & (ay > az);
    const vbool<N> kz2 = !(kz0 | kz1);
    const vfloat<N> d_z = pick(kz0, kz1, ray.dir);
    const vbool<N> neg = d_z < vfloat<N>(0.0f);
    const vbool<N> pos = !neg;
    kx0 = (kz2 & pos) | (kz1 & neg);
    kx1 = (kz0 & pos) | (kz2 & neg);
    ky0 = (kz1 & pos) | (kz2 & neg);
    ky1 = (kz2 & pos) | (kz0 & neg);
    sx = pick(kx0, kx1, ray.dir) / d_z;
    sy = pick(ky0, ky1, ray.dir) / d_z;
    sz = vfloat<N>(1.0f) / d_z;

    const unsigned lanes = bits(active);
    const auto uniform = [lanes](vbool<N> m) {
      const unsigned b = bits(m) & lanes;
      return b == 0 || b == lanes;
    };
    if (lanes != 0 && uniform(kz0) && uniform(kz1) && uniform(neg)) {
      const int lead = __builtin_ctz(lanes);
      kz = kz0.lane(lead) ? 0 : kz1.lane(lead) ? 1 : 2;
      kx = kNextAxis[kz];
      ky = kNextAxis[kz + 1];
      if (neg.lane(lead)) std::swap(kx, ky);
      org[0] = ray.org[kx];
      org[1] = ray.org[ky];
      org[2] = ray.org[kz];
    }
  }

  template <bool kOcclusion>
  void intersect(const TriRecord& rec, const RayPacket<N>& ray, vbool<N> active, HitPacket<N>& hit,
                 vbool<N>& occluded) const {
    const TriVerts& tri = rec.watertight;
    const std::int32_t prim = static_cast<std::int32_t>(tri.id);
    // The vertices relative to the ray origin, permuted to (kx, ky, kz): the same
    // subtractions either way, so the same bits per lane.
    vfloat<N> a_x, a_y, a_z, b_x, b_y, b_z, c_x, c_y, c_z;
    if (kz >= 0) {
      a_x = vfloat<N>(coord(tri.ax, tri.ay, tri.az, kx)) - org[0];
      a_y = vfloat<N>(coord(tri.ax, tri.ay, tri.az, ky)) - org[1];
      a_z = vfloat<N>(coord(tri.ax, tri.ay, tri.az, kz)) - org[2];
      b_x = vfloat<N>(coord(tri.bx, tri.by, tri.bz, kx)) - org[0];
      b_y = vfloat<N>(coord(tri.bx, tri.by, tri.bz, ky)) - org[1];
      b_z = vfloat<N>(coord(tri.bx, tri.by, tri.bz, kz)) - org[2];
      c_x = vfloat<N>(coord(tri.cx, tri.cy, tri.cz, kx)) - org[0];
      c_y = vfloat<N>(coord(tri.cx, tri.cy, tri.cz, ky)) - org[1];
      c_z = vfloat<N>(coord(tri.cx, tri.cy, tri.cz, kz)) - org[2];
    } else {
      PacketVec3<N> a, b, c;
      for (int axis = 0; axis < 3; ++axis) {
        a[axis] = vfloat<N>(coord(tri.ax, tri.ay, tri.az, axis)) - ray.org[axis];
        b[axis] = vfloat<N>(coord(tri.bx, tri.by, tri.bz, axis)) - ray.org[axis];
        c[axis] = vfloat<N>(coord(tri.cx, tri.cy, tri.cz, axis)) - ray.org[axis];
      }
      a_x = pick(kx0, kx1, a), a_y = pick(ky0, ky1, a), a_z = pick(kz0, kz1, a);
      b_x = pick(kx0, kx1, b), b_y = pick(ky0, ky1, b), b_z = pick(kz0, kz1, b);
      c_x = pick(kx0, kx1, c), c_y = pick(ky0, ky1, c), c_z = pick(kz0, kz1, c);
    }
    const vfloat<N> ax = a_x - sx * a_z, ay = a_y - sy * a_z;
    const vfloat<N> bx = b_x - sx * b_z, by = b_y - sy * b_z;
    const vfloat<N> cx = c_x - sx * c_z, cy = c_y - sy * c_z;
    vfloat<N> u = cx * by - cy * bx;
    vfloat<N> v = ax * cy - ay * cx;
    vfloat<N> w = bx * ay - by * ax;
    const vfloat<N> zero(0.0f);
    // An edge function of exactly 0 may be a rounded sign: the paper recomputes all three in
    // double (products of floats are exact there), one lane at a time as it is rare.
    const unsigned redo = bits(active & ((u == zero) | (v == zero) | (w == zero)));
    if (redo != 0) {
      for (int i = 0; i < N; ++i) {
        if (((redo >> i) & 1u) == 0) continue;
        const double dax = ax.lane(i), day = ay.lane(i), dbx = bx.lane(i), dby = by.lane(i);
        const double dcx = cx.lane(i), dcy = cy.lane(i);
        u.set_lane(i, static_cast<float>(dcx * dby - dcy * dbx));
        v.set_lane(i, static_cast<float>(dax * dcy - day * dcx));
        w.set_lane(i, static_cast<float>(dbx * day - dby * dax));
      }
    }
    // Both windings hit; NaN (a zero direction) fails both.
    active &= ((u >= zero) & (v >= zero) & (w >= zero)) | ((u <= zero) & (v <= zero) & (w <= zero));
    if (none(active)) return;
    const vfloat<N> det = (u + v) + w;
    active &= !(det == zero);
    if (none(active)) return;
    const vfloat<N> t_scaled = (u * (sz * a_z) + v * (sz * b_z)) + w * (sz * c_z);
    const vfloat<N> inv_det = vfloat<N>(1.0f) / det;
    // The paper compares T with t_min * det and t_hit * det to skip the division for misses;
    // in a packet the division is one instruction for all lanes, and comparing the t that is
    // stored keeps the tie rule exact (equal t goes to the higher id) and the result
    // independent of the order in which triangles are tested, as in Wald's test.
    const vfloat<N> t = t_scaled * inv_det;
    active &= accepted_t<N, kOcclusion>(t, prim, ray, hit);
    if (none(active)) return;
    if constexpr (kOcclusion) {
      occluded |= active;
    } else {
      // U, V, W are the weights of vertices 0, 1, 2 (U is the edge function of edge b-c).
      hit.t = select(active, t, hit.t);
      hit.beta = select(active, v * inv_det, hit.beta);
      hit.gamma = select(active, w * inv_det, hit.gamma);
      hit.prim = select(active, vint<N>(prim), hit.prim);
    }
  }
};

/// Lane i of a packet as a one-ray packet. Always inlined, as clip_to_box is.
template <int N>
[[gnu::always_inline]] inline RayPacket<1> lane_ray(const RayPacket<N>& p, int i) {
  RayPacket<1> r;
  r.org = PacketVec3<1>{p.org[0].lane(i), p.org[1].lane(i), p.org[2].lane(i)};
  r.dir = PacketVec3<1>{p.dir[0].lane(i), p.dir[1].lane(i), p.dir[2].lane(i)};
  r.t_min = p.t_min.lane(i);
  r.t_max = p.t_max.lane(i);
  return r;
}

/// Lane i of a packet as a one-ray query: `fn(ray, hit, occluded)` runs on copies of the
/// lane's ray and results, and what it finds is written back into the packet.
template <int N, bool kOcclusion, class Fn>
inline void on_lane(const RayPacket<N>& ray, int i, HitPacket<N>& hit, vbool<N>& occluded, Fn&& fn) {
  const RayPacket<1> r = lane_ray(ray, i);
  HitPacket<1> h{0.0f, 0.0f, 0.0f, -1};  // occlusion queries leave `hit` alone
  if constexpr (!kOcclusion) h = HitPacket<1>{hit.t.lane(i), hit.beta.lane(i), hit.gamma.lane(i), hit.prim.lane(i)};
  vbool<1> occ(occluded.lane(i));
  fn(r, h, occ);
  if constexpr (kOcclusion) {
    if (occ.m) occluded |= vbool<N>::from_bits(1u << i);
  } else if (h.prim.v != hit.prim.lane(i)) {  // a new hit is always another triangle
    hit.t.set_lane(i, h.t.v);
    hit.beta.set_lane(i, h.beta.v);
    hit.gamma.set_lane(i, h.gamma.v);
    hit.prim.set_lane(i, h.prim.v);
  }
}

/// A leaf's triangles tested side by side for one ray (intersect_leaf_single), where
/// that applies: always for a single ray with Wald's test, and for a packet with Wald's test
/// that reaches the leaf with one live lane (a divergent packet's lanes part ways lower in the
/// tree), whose ray alone then beats testing the triangles one by one for the whole packet.
/// Two or more lanes each alone measured slower (trace_experiments.md). Returns false where
/// it does not apply: the caller tests the triangles one by one.
template <int N, bool kOcclusion, template <int> class Test>
inline bool intersect_leaf_by_lanes(const TriRecord* leaf, std::uint32_t count, const RayPacket<N>& ray,
                                    vbool<N> active, HitPacket<N>& hit, vbool<N>& occluded) {
  if constexpr (!std::is_same_v<Test<N>, WaldTest<N>>) {
    return false;
  } else if constexpr (N == 1) {
    // A single ray's segment is never empty here (a child is entered only with a non-empty
    // one), so the whole leaf is tested.
    if (count != 0) intersect_leaf_single<kOcclusion>(leaf, count, ray, hit, occluded);
    return true;
  } else {
    const unsigned live = bits(active);
    if (count < 2 || live == 0 || (live & (live - 1)) != 0) return false;
    on_lane<N, kOcclusion>(ray, __builtin_ctz(live), hit, occluded,
                           [&](const RayPacket<1>& r, HitPacket<1>& h, vbool<1>& occ) {
                             intersect_leaf_single<kOcclusion>(leaf, count, r, h, occ);
                           });
    return true;
  }
}

/// Asks at once for every cache line that a leaf's slots span (its LeafBox where `boxed`, then
/// its `count` records) but the first, which the walk loads right away. A packet tests a leaf's
/// records one by one, and each test ends in branches on its lanes (`none(active)`) whose
/// mispredictions throw away the loads the core had begun for the records after it, so without
/// this a leaf's lines came in one after another. 16-wide primary rays 1.05-1.12x on the large
/// scenes where rtc trailed Embree (spd-balls 1.12, spd-mount-s10 1.11, spd-balls-s3 1.08,
/// spd-tree 1.05), shadow rays 0.98-1.06x (median 1.02), the same hits
/// (tests/bench/results/leaf_prefetch.md). Single rays load a leaf's records together anyway
/// (intersect_leaf_single).
inline void prefetch_leaf(const TriRecord* leaf, std::uint32_t count, bool boxed) {
  constexpr std::uintptr_t kLine = 64;
  const std::uintptr_t first = reinterpret_cast<std::uintptr_t>(leaf - (boxed ? 1 : 0)) & ~(kLine - 1);
  const std::uintptr_t last = (reinterpret_cast<std::uintptr_t>(leaf + count) - 1) & ~(kLine - 1);
  for (std::uintptr_t line = first + kLine; line <= last; line += kLine) {
    __builtin_prefetch(reinterpret_cast<const void*>(line));
  }
}

/// Narrows each lane's [near, far] to the part of its ray inside the box [lo, hi] (the slab
/// test), for rays that run towards -a where bit a of `sign_bits` is set. A slab distance of
/// NaN (an origin on a face, a ray parallel to it) leaves the interval as it is.
/// Always inlined: GCC 12 kept it out of line in most walks, and a call there (at every boxed
/// leaf) makes every vector register the walk holds caller-saved; inlined, 16-wide primary rays
/// 1.00-1.06x (median 1.04) and frames 1.01-1.05x on the six large views, the same hits
/// (tests/bench/results/inline_clip_zen5.md).
template <int N>
[[gnu::always_inline]] inline void clip_to_box(const glm::vec3& lo, const glm::vec3& hi, std::uint32_t sign_bits,
                                               const RayPacket<N>& ray, const PacketVec3<N>& inv_dir, vfloat<N>& near,
                                               vfloat<N>& far) {
  for (int axis = 0; axis < 3; ++axis) {
    const bool negative = (sign_bits >> axis) & 1u;
    const vfloat<N> t_entry = (vfloat<N>(negative ? hi[axis] : lo[axis]) - ray.org[axis]) * inv_dir[axis];
    const vfloat<N> t_exit = (vfloat<N>(negative ? lo[axis] : hi[axis]) - ray.org[axis]) * inv_dir[axis];
    near = max(t_entry, near);  // NaN keeps near
    far = min(t_exit, far);
  }
}

/// Traverses the tree with the active lanes, which must share the sign of every direction
/// component (the caller falls back to N = 1 otherwise). Directions with a zero component give
/// infinite reciprocals; a split plane through such a ray's origin gives t = NaN, and then the
/// lane visits both children with its whole segment (min/max keep the segment on NaN).
/// Test is WaldTest or WatertightTest, matching the tree's records. kWalk (occlusion only):
/// where both children are entered, the one nearer along the rays first (Near), the farther one
/// (Far), or the denser one (Dense, KdNode::denser; the far one where some lane's segment
/// starts at its origin, so in the near child: a surface rarely shadows itself); the children
/// and their segments are the same, so the same leaves are visited until every lane has a hit,
/// and the answer is the same (ShadowOrder). Packets (N > 1) never enter a child its parent marks as
/// an empty leaf (KdNode::child_empty): it holds nothing to test.
template <int N, bool kOcclusion, template <int> class Test, ShadowWalk kWalk = ShadowWalk::Near>
void traverse_coherent(const KdTree& tree, const RayPacket<N>& ray, vbool<N> active,
                       HitPacket<N>& hit_io, vbool<N>& occluded) {
  static_assert(kOcclusion || kWalk == ShadowWalk::Near, "closest hits are found near to far");
  // Closest-hit packets work on a local copy of the hits, written back when the walk ends, so
  // GCC holds them in registers through the walk (the pop's test reads their t at every entry).
  // 16-wide primary rays 1.01-1.04x (median 1.03) on the six large views, the same hits
  // (tests/bench/results/walk_local_hit_whole_zen5.md, whose single-ray walks, with the copy
  // too, read 0.96-1.02x: single rays, whose leaf tests take a lane's hit as a scalar anyway,
  // and occlusion walks, which leave `hit_io` alone, use it directly).
  [[maybe_unused]] HitPacket<N> local_hit;
  HitPacket<N>& hit = kOcclusion || N == 1 ? hit_io : (local_hit = hit_io);
  const KdNode* nodes = tree.nodes().data();
  const TriRecord* records = tree.leaf_records().data();
  const Aabb& box = tree.bounds();

  int lead = 0;
  while (!active.lane(lead)) ++lead;
  // Bit a set: the rays run towards -a. Kept in a register, not an array: the child index
  // follows from it at every inner node, and an array lookup would put a load on that chain.
  std::uint32_t sign_bits = 0;
  PacketVec3<N> inv_dir;
  inv_dir[0] = vfloat<N>(1.0f) / ray.dir[0];
  inv_dir[1] = vfloat<N>(1.0f) / ray.dir[1];
  inv_dir[2] = vfloat<N>(1.0f) / ray.dir[2];

  vfloat<N> near = ray.t_min, far = ray.t_max;
  if constexpr (!kOcclusion) {
    // A lane may come in with a hit from another tree (Renderer's static and moving trees are
    // traced in turn): nothing here beyond that hit's reach can replace it, so the segment ends
    // there, by the rule that skips a stacked subtree below. The ray's t_max stays as it is,
    // since accepted_t's tie rule needs t < t_max: a triangle at exactly the hit's t with a
    // higher id still wins, as it would in one tree over both sets. A lane without a hit
    // (prim -1, t = t_max) keeps its segment.
    far = select(hit.prim > vint<N>(-1), min(far, hit_reach(hit.t)), far);
  }
  for (int axis = 0; axis < 3; ++axis) {
    sign_bits |= static_cast<std::uint32_t>(sign_bit(ray.dir[axis]).lane(lead)) << axis;
  }
  clip_to_box(box.lo, box.hi, sign_bits, ray, inv_dir, near, far);
  // A watertight test finds a hit on a shared edge or vertex only in a leaf that holds one of
  // the triangles there, and a triangle that merely touches a split plane at a vertex is
  // referenced on one side only. A ray through such a vertex crosses three planes at nearly
  // the same t, which rounding may order so that it skips the leaves holding the triangles
  // (72 of 414720 rays aimed at a cube-sphere's vertices and edges missed). So with
  // kConservative a segment counts as non-empty while near <= far * (1 + 2^-20): a slab t
  // (b - o) * (1 / d) is within 3 ulps of exact (relative), so a leaf the exact ray touches is
  // never skipped. The segments themselves stay exact, so leaves are still visited in order
  // and the early exit (hit.t < far) is unchanged.
  const auto reach = [](vfloat<N> t_far) {
    if constexpr (Test<N>::kConservative) {
      return t_far * vfloat<N>(1.0f + 0x1p-20f);
    } else {
      return t_far;
    }
  };
  active &= near <= reach(far);
  if (none(active)) return;
  const Test<N> test(ray, active);
  WalkCounter<kWalkStats> stats(N > 1, kOcclusion);  // counts nothing unless built with RTC_WALK_STATS
  if constexpr (kWalkStats) {
    stats.start(static_cast<std::uint32_t>(std::popcount(bits(active))));
    stats.read(nodes, sizeof(KdNode));  // the root
  }

  // Plain arrays, not vfloat members: a stack of 64 vector entries would otherwise be
  // zero-initialised on every call, which measured as a large share of a primary ray's cost.
  struct Entry {
    alignas(16) float near[N];
    alignas(16) float far[N];
    unsigned mask;
    std::uint32_t node;
  };
  Entry stack[64];
  int depth = 0;
  [[maybe_unused]] vbool<N> done(false);
  std::uint32_t index = 0;

  // Single rays (N = 1) look a step ahead: an inner node's children are loaded, and their
  // planes' distances computed, before its decision, so that the chain node -> distance ->
  // decision -> child's load -> distance, which every step waited on (and a mispredicted
  // decision with it), is one load and one distance shorter; the same operations on the same
  // values, so the same bits. Single rays 1.03-1.09x over nine views. Occlusion packets load
  // the children ahead but compute the chosen one's distances after the decision (shadow
  // packets 1.01-1.03x on five of six views, radiance-cabin 0.996); closest-hit packets load
  // each node after its parent's decision: the forms that looked ahead measured 0.87-1.02x
  // there (trace_experiments.md, session 35).
  // N = 1: the origin and reciprocals by axis, index 3 (a leaf's low bits) reading zeros: a
  // leaf's value is never used, so a child's is computed without a branch on its kind. (A
  // leaf's second word, its count, reads as a normal float thanks to KdNode::kLeafTag: as a
  // denormal it cost a microcode assist per operation on some CPUs.)
  [[maybe_unused]] float org4[4] = {}, inv4[4] = {};
  if constexpr (N == 1) {
    for (int a = 0; a < 3; ++a) {
      org4[a] = ray.org[a].v;
      inv4[a] = inv_dir[a].v;
    }
  }
  const auto plane_t = [&](const KdNode& n) {
    if constexpr (N == 1) {
      const int a = static_cast<int>(n.bits & 3u);
      return vfloat<N>((n.split - org4[a]) * inv4[a]);
    } else {
      const int a = n.axis();
      return (vfloat<N>(n.split) - ray.org[a]) * inv_dir[a];
    }
  };
  constexpr bool kLoadAhead = N == 1 || kOcclusion;
  [[maybe_unused]] KdNode ahead = nodes[index];         // kLoadAhead: the node visited next
  // N = 1: its plane's distances. Packets compute a node's only once they know it is inner: a
  // leaf's axis bits read 3, past the three components of the origin (a one-leaf tree's root).
  [[maybe_unused]] vfloat<N> ahead_t;
  if constexpr (N == 1) ahead_t = plane_t(ahead);
  for (;;) {
    KdNode node;
    vfloat<N> t_split;
    if constexpr (N == 1) {
      node = ahead;
      t_split = ahead_t;
    } else if constexpr (kLoadAhead) {
      node = ahead;
    } else {
      node = nodes[index];
      if constexpr (kWalkStats) stats.read(&nodes[index], sizeof(KdNode));
    }
    if (!node.is_leaf()) {
      stats.inner();
      if constexpr (kWalkStats && kLoadAhead) stats.read(&nodes[node.left()], 2 * sizeof(KdNode));  // both children
      const int axis = node.axis();
      if constexpr (N > 1) t_split = plane_t(node);
      const std::uint32_t sign = (sign_bits >> axis) & 1u;
      const std::uint32_t near_child = node.left() + sign;
      const std::uint32_t far_child = node.left() + (sign ^ 1u);
      [[maybe_unused]] KdNode child0, child1;
      [[maybe_unused]] float t0 = 0.0f, t1 = 0.0f;
      if constexpr (kLoadAhead) {
        child0 = nodes[node.left()];
        child1 = nodes[node.left() + 1];
      }
      if constexpr (N == 1) {
        t0 = plane_t(child0).v;
        t1 = plane_t(child1).v;
      }
      // Child c (0 or 1), node `child` (= node.left() + c, passed as computed above: deriving it
      // here changed the closest-hit packets' compiled walk), is visited next.
      const auto enter = [&](std::uint32_t child, std::uint32_t c) {
        index = child;
        if constexpr (kLoadAhead) ahead = c != 0 ? child1 : child0;
        if constexpr (N == 1) ahead_t = vfloat<N>(c != 0 ? t1 : t0);
      };
      const vfloat<N> near_end = min(t_split, far);     // NaN: far
      const vfloat<N> far_start = max(t_split, near);   // NaN: near
      const vbool<N> go_near = active & (near <= reach(near_end));
      const vbool<N> go_far = active & (far_start <= reach(far));
      // One decision per node for the whole packet. Where both children are entered, the far
      // one is stacked (or, by kWalk, the near one). A child that is an empty leaf holds
      // nothing to test: it is passed by, not entered (its lanes would only pop the stack
      // there), so the same triangles are tested in the same order.
      // (Packets only: a single ray's empty-leaf visit is a few scalar instructions and mostly
      // loads the line its sibling needs next, and testing the marks at every node measured
      // 0.96-0.97x on single shadow rays.)
      const bool near_empty = N > 1 && node.child_empty(sign);
      const bool far_empty = N > 1 && node.child_empty(sign ^ 1u);
      if (none(go_far)) {
        if (near_empty) goto pop;
        enter(near_child, sign);
        far = near_end;
        active = go_near;
      } else if (none(go_near) || near_empty) {
        if (far_empty) goto pop;
        enter(far_child, sign ^ 1u);
        near = far_start;
        active = go_far;
      } else if (far_empty) {
        enter(near_child, sign);
        far = near_end;
        active = go_near;
      } else if (kWalk == ShadowWalk::Far ||
                 (kWalk == ShadowWalk::Dense &&
                  (node.denser() != sign || any(go_near & (near <= ray.t_min))))) {
        stats.push();
        Entry& e = stack[depth++];
        near.store(e.near);
        near_end.store(e.far);
        e.mask = bits(go_near);
        e.node = near_child;
        enter(far_child, sign ^ 1u);
        near = far_start;
        active = go_far;
      } else {
        stats.push();
        Entry& e = stack[depth++];
        far_start.store(e.near);
        far.store(e.far);
        e.mask = bits(go_far);
        e.node = far_child;
        enter(near_child, sign);
        far = near_end;
        active = go_near;
      }
      continue;
    } else {
      const TriRecord* leaf = records + node.prim_offset();
      const std::uint32_t count = node.tri_count();
      stats.leaf(count);
      if constexpr (N > 1) prefetch_leaf(leaf, count, node.has_box());
      if constexpr (kWalkStats) {
        // Packets ask for all of the leaf's slots at once; a single ray reads its box first (its
        // records below, where the box lets it through).
        const std::uint32_t box_slots = node.has_box() ? 1u : 0u;
        stats.read(leaf - box_slots, (box_slots + (N > 1 ? count : 0u)) * sizeof(TriRecord));
      }
      if (node.has_box()) {
        // The leaf's LeafBox: a lane whose ray misses it cannot hit the leaf's triangles
        // there. The whole ray [t_min, t_max] is tested, not the segment in this leaf: the box
        // lies in the cell (but for its widening), so that culls as much, and a hit the float
        // test accepts a rounding error outside a triangle, even outside this cell, is still
        // found here wherever it lies in the widened box. The same slab test as the tree's box
        // above (NaN keeps the interval), with the conservative reach, so a lane is dropped
        // only when it surely misses.
        const LeafBox& b = leaf[-1].box;
        vfloat<N> enter = ray.t_min, leave = ray.t_max;
        clip_to_box(glm::vec3(b.lo_x, b.lo_y, b.lo_z), glm::vec3(b.hi_x, b.hi_y, b.hi_z), sign_bits, ray, inv_dir, enter,
                    leave);
        const vbool<N> inside = active & (enter <= leave * vfloat<N>(1.0f + 0x1p-20f));
        if constexpr (kWalkStats) {
          stats.box(static_cast<std::uint32_t>(std::popcount(bits(active))),
                    static_cast<std::uint32_t>(std::popcount(bits(inside))));
        }
        if (none(inside)) goto pop;
        active = inside;
      }
      if constexpr (kWalkStats && N == 1) stats.read(leaf, count * sizeof(TriRecord));
      if (intersect_leaf_by_lanes<N, kOcclusion, Test>(leaf, count, ray, active, hit, occluded)) {
        stats.tests(count, 1);  // one live lane, the leaf's triangles side by side
      } else {
        if constexpr (kOcclusion) {
          for (std::uint32_t i = 0; i < count; ++i) {
            if constexpr (kWalkStats) stats.tests(1, static_cast<std::uint32_t>(std::popcount(bits(active))));
            test.template intersect<kOcclusion>(leaf[i], ray, active, hit, occluded);
            // A shadow ray stops at its first hit: occluded lanes test nothing more.
            active &= !occluded;
            if (none(active)) break;
          }
        } else {
          // The leaf's tests update a local copy of the hits, which GCC 12 holds in registers
          // through the leaf; on `hit` itself it loaded the hits' t and ids from memory again
          // at every triangle (clang 14 held them in registers either way). The same hits; the
          // occlusion walks compile to the same code. 16-wide primary rays median 1.00x over
          // the six large views, spd-tree 1.07x, within this VM's noise elsewhere
          // (tests/bench/results/local_hit_zen5.md; trace_experiments.md, session 55).
          // For packets `hit` is already the walk's local copy, so this copies one local into
          // another; testing on `hit` there instead measured no gain (primary rays median 1.00x,
          // pop_reach_hoist_zen5.md; trace_experiments.md, session 56), and single rays with the
          // watertight test still need this copy.
          HitPacket<N> local = hit;
          for (std::uint32_t i = 0; i < count; ++i) {
            if constexpr (kWalkStats) stats.tests(1, static_cast<std::uint32_t>(std::popcount(bits(active))));
            test.template intersect<kOcclusion>(leaf[i], ray, active, local, occluded);
          }
          hit = local;
        }
      }
      // An occluded lane is finished. A closest-hit lane skips a stacked subtree only when its
      // hit lies before the subtree's segment, with a slack (decided per entry when it is
      // popped, so a ray lying in a split plane, whose NaN split gives both children the whole
      // segment, still visits the second child). A hit exactly on a leaf's far plane thus goes
      // on into the next leaf, where a triangle at the same t may win the tie (higher id). The
      // slack covers the float test's own error: it accepts points a rounding error outside a
      // triangle (at an edge or shared vertex; t off by ~1e-6 relative for rays grazing the
      // plane), so outside the leaves that reference it, and a nearer triangle's leaf may start
      // just after the hit already found. With it the answer is the brute-force loop's,
      // whatever the tree's planes (tests/stress: fans, grazing rays, rays in split planes).
      if constexpr (kOcclusion) {
        done |= occluded;
      }
    }

  pop:
    for (;;) {
      if (depth == 0) {
        if constexpr (!kOcclusion && N > 1) hit_io = hit;
        return;
      }
      const Entry& e = stack[--depth];
      unsigned lanes;
      if constexpr (kOcclusion) {
        lanes = e.mask & ~bits(done);
      } else {
        lanes = e.mask & bits(vfloat<N>::load(e.near) <= hit_reach(hit.t));
      }
      if (lanes != 0) {
        active = vbool<N>::from_bits(lanes);
        index = e.node;
        if constexpr (kLoadAhead) ahead = nodes[index];
        if constexpr (N == 1) ahead_t = plane_t(ahead);
        near = vfloat<N>::load(e.near);
        far = vfloat<N>::load(e.far);
        break;
      }
    }
  }
}

/// Rays assembled lane by lane in plain arrays, then loaded into a packet in one go.
template <int N>
struct RayLanes {
  float org[3][N] = {};
  float dir[3][N] = {};
  float t_min[N] = {};
  float t_max[N] = {};
  void set(int i, const RayQuery& q) { set(i, q.org, q.t_min, q.dir, q.t_max); }
  /// Lane i from the ray's parts, each stored as a float (callers pass the parts rather than a
  /// RayQuery they just built: copying that went through vector moves of fields stored one by
  /// one, which stalls store forwarding).
  void set(int i, const glm::vec3& o, float t0, const glm::vec3& d, float t1) {
    for (int a = 0; a < 3; ++a) {
      org[a][i] = o[a];
      dir[a][i] = d[a];
    }
    t_min[i] = t0;
    t_max[i] = t1;
  }
  [[nodiscard]] RayQuery query(int i) const {
    return RayQuery{{org[0][i], org[1][i], org[2][i]}, t_min[i], {dir[0][i], dir[1][i], dir[2][i]}, t_max[i]};
  }
  [[nodiscard]] RayPacket<N> packet() const {
    RayPacket<N> p;
    for (int a = 0; a < 3; ++a) {
      p.org[a] = vfloat<N>::load(org[a]);
      p.dir[a] = vfloat<N>::load(dir[a]);
    }
    p.t_min = vfloat<N>::load(t_min);
    p.t_max = vfloat<N>::load(t_max);
    return p;
  }
};

/// One lane of a packet traced alone (N = 1), its result written back into the packet.
template <int N, bool kOcclusion, template <int> class Test, ShadowWalk kWalk = ShadowWalk::Near>
inline void trace_lane(const KdTree& tree, const RayPacket<N>& ray, int i, HitPacket<N>& hit, vbool<N>& occluded) {
  on_lane<N, kOcclusion>(ray, i, hit, occluded, [&](const RayPacket<1>& r, HitPacket<1>& h, vbool<1>& occ) {
    traverse_coherent<1, kOcclusion, Test, kWalk>(tree, r, vbool<1>(true), h, occ);
  });
}

/// The lanes of `lanes` whose rays point into the same octant as lane `first`'s: bit i of `sx`,
/// `sy`, `sz` is set where lane i runs towards -x, -y, -z.
inline unsigned octant_group(unsigned lanes, unsigned sx, unsigned sy, unsigned sz, int first) {
  const unsigned mx = ((sx >> first) & 1u) ? sx : ~sx;
  const unsigned my = ((sy >> first) & 1u) ? sy : ~sy;
  const unsigned mz = ((sz >> first) & 1u) ? sz : ~sz;
  return lanes & mx & my & mz;
}

/// Closest hit (kOcclusion = false) or any hit (true) for the active lanes. The traversal
/// needs one direction sign per axis, so a packet whose active lanes point into different
/// octants (reflections off curved surfaces, shadow rays from scattered hits) is regrouped:
/// each octant's lanes traverse as one masked packet, and an octant with a single lane goes
/// alone through the N = 1 kernel. Lanes never interact, so the bits are the same either way.
template <int N, bool kOcclusion, template <int> class Test, ShadowWalk kWalk = ShadowWalk::Near>
void trace_packet(const KdTree& tree, const RayPacket<N>& ray, vbool<N> active, HitPacket<N>& hit,
                  vbool<N>& occluded) {
  if (tree.empty() || none(active)) return;
  if constexpr (N == 1) {
    traverse_coherent<N, kOcclusion, Test, kWalk>(tree, ray, active, hit, occluded);
  } else {
    const unsigned sx = bits(sign_bit(ray.dir[0]));
    const unsigned sy = bits(sign_bit(ray.dir[1]));
    const unsigned sz = bits(sign_bit(ray.dir[2]));
    unsigned left = bits(active);
    while (left != 0) {  // once for a coherent packet
      const int first = __builtin_ctz(left);
      const unsigned group = octant_group(left, sx, sy, sz, first);  // the first remaining lane's
      left &= ~group;
      if ((group & (group - 1)) == 0) {
        trace_lane<N, kOcclusion, Test, kWalk>(tree, ray, first, hit, occluded);
      } else {
        traverse_coherent<N, kOcclusion, Test, kWalk>(tree, ray, vbool<N>::from_bits(group), hit, occluded);
      }
    }
  }
}

/// Closest hits; hit must come in with t = t_max and prim = -1 for the active lanes, or with a
/// hit found for the same ray in another tree (ids of one numbering, KdTree::build's `ids`):
/// then a triangle replaces it only when closer, or at the same t with a higher id, so trees
/// traced in turn give the bits of one tree over all their triangles. The triangle test
/// follows the tree's records (KdTree::watertight()).
template <int N>
inline void intersect(const KdTree& tree, const RayPacket<N>& ray, vbool<N> active, HitPacket<N>& hit) {
  vbool<N> unused(false);
  if (tree.watertight()) {
    trace_packet<N, false, WatertightTest>(tree, ray, active, hit, unused);
  } else {
    trace_packet<N, false, WaldTest>(tree, ray, active, hit, unused);
  }
}

/// trace_packet for occlusion in the order `walk`.
template <int N, template <int> class Test>
inline void occluded_walk(const KdTree& tree, const RayPacket<N>& ray, vbool<N> active, ShadowWalk walk,
                          HitPacket<N>& unused, vbool<N>& occ) {
  switch (walk) {
    case ShadowWalk::Far:
      trace_packet<N, true, Test, ShadowWalk::Far>(tree, ray, active, unused, occ);
      return;
    case ShadowWalk::Dense:
      trace_packet<N, true, Test, ShadowWalk::Dense>(tree, ray, active, unused, occ);
      return;
    case ShadowWalk::Near:
      break;
  }
  trace_packet<N, true, Test, ShadowWalk::Near>(tree, ray, active, unused, occ);
}

/// Occlusion (shadow) queries: stops at the first hit of each lane. `walk`: the order each
/// ray's leaves are visited in (the same answer, ShadowOrder).
template <int N>
inline vbool<N> occluded(const KdTree& tree, const RayPacket<N>& ray, vbool<N> active,
                         ShadowWalk walk = ShadowWalk::Near) {
  vbool<N> occ(false);
  HitPacket<N> unused;  // not read by occlusion queries
  if (tree.watertight()) {
    occluded_walk<N, WatertightTest>(tree, ray, active, walk, unused, occ);
  } else {
    occluded_walk<N, WaldTest>(tree, ray, active, walk, unused, occ);
  }
  return occ;
}

/// occluded() in the order `chooser` picks, telling it the time taken.
template <int N>
inline vbool<N> occluded(const KdTree& tree, const RayPacket<N>& ray, vbool<N> active, ShadowOrderChooser& chooser) {
  const vbool<N> occ = occluded<N>(tree, ray, active, chooser.next());
  chooser.done(static_cast<unsigned>(std::popcount(bits(active))));
  return occ;
}

}  // namespace rtc::RTC_ISA_NS
RTC_ISA_END
