// Packet kd-tree traversal and Wald's projection triangle test, written once over the packet
// width N (N = 1 is the scalar reference). Included only by kernel sources compiled per ISA.
//
// Every lane does exactly what a single ray would do: the same leaves in the same order
// (per-ray [near, far] segments, a lane leaves the packet's path as soon as its segment is
// empty or it has found its hit), and the same float operations in the same order. Closest
// hits break ties in t by the higher triangle id, so the result does not depend on the order
// in which the triangles of a leaf are tested. Together this makes packets and single rays
// give the same bits.
#pragma once

#include <cstdint>

#include "common/accel/kd_tree.h"
#include "common/accel/trace.h"
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
  if constexpr (kOcclusion) {
    active &= (t > ray.t_min) & (t < ray.t_max);
  } else {
    const vint<N> id(prim);
    // Ties in t (coplanar overlapping triangles, shared edges) go to the higher triangle id:
    // any fixed rule makes the result independent of test order; this one agrees with
    // Embree's choice on the shared scenes far more often than the lower id does.
    active &= (t > ray.t_min) & ((t < hit.t) | ((t == hit.t) & (id > hit.prim) & (t < ray.t_max)));
  }
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

/// Traverses the tree with the active lanes, which must share the sign of every direction
/// component (the caller falls back to N = 1 otherwise). Directions with a zero component give
/// infinite reciprocals; a split plane through such a ray's origin gives t = NaN, and then the
/// lane visits both children with its whole segment (min/max keep the segment on NaN).
template <int N, bool kOcclusion>
void traverse_coherent(const KdTree& tree, const RayPacket<N>& ray, vbool<N> active,
                       HitPacket<N>& hit, vbool<N>& occluded) {
  const KdNode* nodes = tree.nodes().data();
  const std::uint32_t* refs = tree.prim_refs().data();
  const TriAccel* accel = tree.tri_accel().data();
  const Aabb& box = tree.bounds();

  int lead = 0;
  while (!active.lane(lead)) ++lead;
  int sign[3];
  PacketVec3<N> inv_dir;
  inv_dir[0] = vfloat<N>(1.0f) / ray.dir[0];
  inv_dir[1] = vfloat<N>(1.0f) / ray.dir[1];
  inv_dir[2] = vfloat<N>(1.0f) / ray.dir[2];

  vfloat<N> near = ray.t_min, far = ray.t_max;
  for (int axis = 0; axis < 3; ++axis) {
    sign[axis] = sign_bit(ray.dir[axis]).lane(lead) ? 1 : 0;
    const float entry = sign[axis] ? box.hi[axis] : box.lo[axis];
    const float exit = sign[axis] ? box.lo[axis] : box.hi[axis];
    const vfloat<N> t_entry = (vfloat<N>(entry) - ray.org[axis]) * inv_dir[axis];
    const vfloat<N> t_exit = (vfloat<N>(exit) - ray.org[axis]) * inv_dir[axis];
    near = max(t_entry, near);  // NaN (origin on the face, parallel ray) keeps near
    far = min(t_exit, far);
  }
  active &= near <= far;
  if (none(active)) return;

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
  vbool<N> done(false);
  std::uint32_t index = 0;

  for (;;) {
    const KdNode node = nodes[index];
    if (!node.is_leaf()) {
      const int axis = node.axis();
      const vfloat<N> t_split = (vfloat<N>(node.split) - ray.org[axis]) * inv_dir[axis];
      const std::uint32_t near_child = node.left() + static_cast<std::uint32_t>(sign[axis]);
      const std::uint32_t far_child = node.left() + static_cast<std::uint32_t>(sign[axis] ^ 1);
      const vfloat<N> near_end = min(t_split, far);     // NaN: far
      const vfloat<N> far_start = max(t_split, near);   // NaN: near
      const vbool<N> go_near = active & (near <= near_end);
      const vbool<N> go_far = active & (far_start <= far);
      // One decision per node for the whole packet.
      if (none(go_far)) {
        index = near_child;
        far = near_end;
        active = go_near;
      } else if (none(go_near)) {
        index = far_child;
        near = far_start;
        active = go_far;
      } else {
        Entry& e = stack[depth++];
        far_start.store(e.near);
        far.store(e.far);
        e.mask = bits(go_far);
        e.node = far_child;
        index = near_child;
        far = near_end;
        active = go_near;
      }
      continue;
    }

    const std::uint32_t* leaf_refs = refs + node.prim_offset();
    for (std::uint32_t i = 0; i < node.count; ++i) {
      const TriAccel& acc = accel[leaf_refs[i]];
      intersect_triangle<N, kOcclusion>(acc, static_cast<std::int32_t>(acc.id), ray, active, hit, occluded);
      if constexpr (kOcclusion) {
        // A shadow ray stops at its first hit: occluded lanes test nothing more.
        active &= !occluded;
        if (none(active)) break;
      }
    }
    // A lane is finished once it is occluded, or its closest hit lies strictly inside this
    // leaf's segment: every later leaf starts beyond it. A hit exactly on the far boundary
    // goes on into the next leaf, where a triangle at the same t may win the tie (higher id):
    // that keeps the answer independent of where the tree put its planes. Empty leaves count.
    if constexpr (kOcclusion) {
      done |= occluded;
    } else {
      done |= active & (hit.t < far);
    }

    for (;;) {
      if (depth == 0) return;
      const Entry& e = stack[--depth];
      const unsigned lanes = e.mask & ~bits(done);
      if (lanes != 0) {
        active = vbool<N>::from_bits(lanes);
        index = e.node;
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
  void set(int i, const RayQuery& q) {
    for (int a = 0; a < 3; ++a) {
      org[a][i] = q.org[a];
      dir[a][i] = q.dir[a];
    }
    t_min[i] = q.t_min;
    t_max[i] = q.t_max;
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

/// Lane i of a packet as a one-ray packet.
template <int N>
inline RayPacket<1> lane_ray(const RayPacket<N>& p, int i) {
  RayPacket<1> r;
  r.org = PacketVec3<1>{p.org[0].lane(i), p.org[1].lane(i), p.org[2].lane(i)};
  r.dir = PacketVec3<1>{p.dir[0].lane(i), p.dir[1].lane(i), p.dir[2].lane(i)};
  r.t_min = p.t_min.lane(i);
  r.t_max = p.t_max.lane(i);
  return r;
}

/// One lane of a packet traced alone (N = 1), its result written back into the packet.
template <int N, bool kOcclusion>
inline void trace_lane(const KdTree& tree, const RayPacket<N>& ray, int i, HitPacket<N>& hit, vbool<N>& occluded) {
  const RayPacket<1> r = lane_ray(ray, i);
  HitPacket<1> h{0.0f, 0.0f, 0.0f, -1};  // occlusion queries leave `hit` alone
  if constexpr (!kOcclusion) h = HitPacket<1>{hit.t.lane(i), hit.beta.lane(i), hit.gamma.lane(i), hit.prim.lane(i)};
  vbool<1> occ(occluded.lane(i));
  traverse_coherent<1, kOcclusion>(tree, r, vbool<1>(true), h, occ);
  if constexpr (kOcclusion) {
    if (occ.m) occluded |= vbool<N>::from_bits(1u << i);
  } else {
    hit.t.set_lane(i, h.t.v);
    hit.beta.set_lane(i, h.beta.v);
    hit.gamma.set_lane(i, h.gamma.v);
    hit.prim.set_lane(i, h.prim.v);
  }
}

/// Closest hit (kOcclusion = false) or any hit (true) for the active lanes. The traversal
/// needs one direction sign per axis, so a packet whose active lanes point into different
/// octants (reflections off curved surfaces, shadow rays from scattered hits) is regrouped:
/// each octant's lanes traverse as one masked packet, and an octant with a single lane goes
/// alone through the N = 1 kernel. Lanes never interact, so the bits are the same either way.
template <int N, bool kOcclusion>
void trace_packet(const KdTree& tree, const RayPacket<N>& ray, vbool<N> active, HitPacket<N>& hit,
                  vbool<N>& occluded) {
  if (tree.empty() || none(active)) return;
  if constexpr (N == 1) {
    traverse_coherent<N, kOcclusion>(tree, ray, active, hit, occluded);
  } else {
    const unsigned sx = bits(sign_bit(ray.dir[0]));
    const unsigned sy = bits(sign_bit(ray.dir[1]));
    const unsigned sz = bits(sign_bit(ray.dir[2]));
    unsigned left = bits(active);
    while (left != 0) {  // once for a coherent packet
      const int first = __builtin_ctz(left);
      // Lanes in the same octant as the first remaining one.
      const unsigned mx = ((sx >> first) & 1u) ? sx : ~sx;
      const unsigned my = ((sy >> first) & 1u) ? sy : ~sy;
      const unsigned mz = ((sz >> first) & 1u) ? sz : ~sz;
      const unsigned group = left & mx & my & mz;
      left &= ~group;
      if ((group & (group - 1)) == 0) {
        trace_lane<N, kOcclusion>(tree, ray, first, hit, occluded);
      } else {
        traverse_coherent<N, kOcclusion>(tree, ray, vbool<N>::from_bits(group), hit, occluded);
      }
    }
  }
}

/// Closest hits; hit must come in with t = t_max and prim = -1 for the active lanes.
template <int N>
inline void intersect(const KdTree& tree, const RayPacket<N>& ray, vbool<N> active, HitPacket<N>& hit) {
  vbool<N> unused(false);
  trace_packet<N, false>(tree, ray, active, hit, unused);
}

/// Occlusion (shadow) queries: stops at the first hit of each lane.
template <int N>
inline vbool<N> occluded(const KdTree& tree, const RayPacket<N>& ray, vbool<N> active) {
  vbool<N> occ(false);
  HitPacket<N> unused;  // not read by occlusion queries
  trace_packet<N, true>(tree, ray, active, unused, occ);
  return occ;
}

}  // namespace rtc::RTC_ISA_NS
RTC_ISA_END
