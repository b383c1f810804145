// Stress-test support: the float brute-force oracle and the all-ISA agreement check.
#include "tests/stress/stress_support.h"
#include "tests/support/hit_compare.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numbers>
#include <optional>
#include <random>

#include <fmt/format.h>
#include <tbb/parallel_for.h>

namespace rtc::stress {

void Soup::add(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  const auto base = static_cast<unsigned>(positions.size());
  positions.insert(positions.end(), {a, b, c});
  triangles.emplace_back(base, base + 1, base + 2);
}

void Soup::append(const Soup& other) {
  const auto base = static_cast<unsigned>(positions.size());
  positions.insert(positions.end(), other.positions.begin(), other.positions.end());
  for (const glm::uvec3& t : other.triangles) triangles.push_back(t + glm::uvec3(base));
}

Aabb bounds_of(const Soup& soup) {
  Aabb b;
  for (const glm::uvec3& t : soup.triangles) {
    for (int k = 0; k < 3; ++k) b.extend(soup.positions[t[k]]);
  }
  return b;
}

WaldResult wald_test(const TriAccel& acc, const RayQuery& ray) {
  // kd_traverse.h intersect_triangle, lane by lane: same operations, same order, same types.
  static constexpr int kNext[5] = {1, 2, 0, 1, 2};
  const int k = static_cast<int>(acc.k);
  const int u = kNext[k], v = kNext[k + 1];
  const float ok = ray.org[k], ou = ray.org[u], ov = ray.org[v];
  const float dk = ray.dir[k], du = ray.dir[u], dv = ray.dir[v];
  const float num = ((acc.n_d - ok) - acc.n_u * ou) - acc.n_v * ov;
  const float den = (dk + acc.n_u * du) + acc.n_v * dv;
  WaldResult r;
  r.t = num / den;
  const float hu = ou + r.t * du;
  const float hv = ov + r.t * dv;
  r.beta = (acc.b_nu * hu + acc.b_nv * hv) + acc.b_d;
  r.gamma = (acc.c_nu * hu + acc.c_nv * hv) + acc.c_d;
  r.inside = r.beta >= 0.0f && r.gamma >= 0.0f && r.beta + r.gamma <= 1.0f;
  return r;
}

BruteForce::BruteForce(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles)
    : records_(triangles.size()),
      positions_(positions.begin(), positions.end()),
      triangles_(triangles.begin(), triangles.end()) {
  tbb::parallel_for(std::size_t{0}, triangles.size(), [&](std::size_t i) {
    const glm::uvec3 t = triangles[i];
    records_[i] = make_tri_accel(positions[t.x], positions[t.y], positions[t.z]);
    records_[i].id = static_cast<std::uint32_t>(i);
  });
}

namespace {

// (t ascending, id descending): the order in which the tracer prefers hits.
bool better(float t, std::uint32_t id, const RayHit& than) {
  return than.prim == kNoHit || t < than.t || (t == than.t && id > than.prim);
}

void closest_range(const std::vector<TriAccel>& records, std::size_t begin, std::size_t end, const RayQuery& ray,
                   RayHit& best) {
  for (std::size_t i = begin; i < end; ++i) {
    const TriAccel& acc = records[i];
    if (acc.k > 2) continue;  // degenerate: never in a leaf, never hits
    const WaldResult w = wald_test(acc, ray);
    if (!(w.t > ray.t_min) || !(w.t < ray.t_max) || !w.inside) continue;
    if (better(w.t, acc.id, best)) best = RayHit{w.t, w.beta, w.gamma, acc.id};
  }
}

bool occluded_range(const std::vector<TriAccel>& records, std::size_t begin, std::size_t end, const RayQuery& ray) {
  for (std::size_t i = begin; i < end; ++i) {
    const TriAccel& acc = records[i];
    if (acc.k > 2) continue;
    const WaldResult w = wald_test(acc, ray);
    if (w.t > ray.t_min && w.t < ray.t_max && w.inside) return true;
  }
  return false;
}

}  // namespace

std::vector<BruteForce::Accepted> BruteForce::accepted(const RayQuery& ray) const {
  std::vector<Accepted> out;
  for (const TriAccel& acc : records_) {
    if (acc.k > 2) continue;
    const WaldResult w = wald_test(acc, ray);
    if (!(w.t > ray.t_min) || !(w.t < ray.t_max) || !w.inside) continue;
    const float alpha = (1.0f - w.beta) - w.gamma;
    const bool at_edge = std::min({w.beta, w.gamma, alpha}) <= 0x1p-20f;
    // Moller-Trumbore in double on the float vertices; its weights are trusted only where the
    // ray is not nearly parallel to the plane (det well above double's rounding of it), so a
    // real hit on a grazed triangle is never taken for an exact miss.
    const glm::uvec3 t = triangles_[acc.id];
    const glm::dvec3 a(positions_[t.x]), b(positions_[t.y]), c(positions_[t.z]);
    double min_bary = 0.0, det = 0.0;
    (void)test::ray_triangle_t(ray, positions_[t.x], positions_[t.y], positions_[t.z], &min_bary, &det);
    const bool exact_miss = std::fabs(det) > 1e-10 * glm::length(b - a) * glm::length(c - a) *
                                                 glm::length(glm::dvec3(ray.dir)) &&
                            min_bary < -1e-6;
    out.push_back(Accepted{RayHit{w.t, w.beta, w.gamma, acc.id}, at_edge || exact_miss});
  }
  std::sort(out.begin(), out.end(), [](const Accepted& a, const Accepted& b) {
    return a.hit.t < b.hit.t || (a.hit.t == b.hit.t && a.hit.prim > b.hit.prim);
  });
  return out;
}

RayHit BruteForce::closest(const RayQuery& ray) const {
  RayHit best;
  closest_range(records_, 0, records_.size(), ray, best);
  if (best.prim == kNoHit) best = RayHit{ray.t_max, 0.0f, 0.0f, kNoHit};
  return best;
}

bool BruteForce::occluded(const RayQuery& ray) const { return occluded_range(records_, 0, records_.size(), ray); }

void BruteForce::closest(std::span<const RayQuery> rays, std::span<RayHit> out) const {
  constexpr std::size_t kChunk = 1 << 14;  // 768 KiB of records: stays in L2 for all rays
  const std::size_t chunks = (records_.size() + kChunk - 1) / kChunk;
  std::vector<RayHit> partial(chunks * rays.size());
  // Each chunk keeps its best per ray; the (t, -id) minimum is associative, so combining the
  // chunks in any order gives the sequential answer.
  tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
    const std::size_t end = std::min(records_.size(), (c + 1) * kChunk);
    for (std::size_t r = 0; r < rays.size(); ++r) closest_range(records_, c * kChunk, end, rays[r], partial[c * rays.size() + r]);
  });
  for (std::size_t r = 0; r < rays.size(); ++r) {
    RayHit best;
    for (std::size_t c = 0; c < chunks; ++c) {
      const RayHit& h = partial[c * rays.size() + r];
      if (h.prim != kNoHit && better(h.t, h.prim, best)) best = h;
    }
    if (best.prim == kNoHit) best = RayHit{rays[r].t_max, 0.0f, 0.0f, kNoHit};
    out[r] = best;
  }
}

void BruteForce::occluded(std::span<const RayQuery> rays, std::span<std::uint8_t> out) const {
  // Chunks of records small enough to stay in cache while every ray passes over them.
  constexpr std::size_t kChunk = 1 << 14;
  const std::size_t chunks = (records_.size() + kChunk - 1) / kChunk;
  std::vector<std::uint8_t> partial(chunks * rays.size(), 0);
  tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
    const std::size_t end = std::min(records_.size(), (c + 1) * kChunk);
    for (std::size_t r = 0; r < rays.size(); ++r) {
      partial[c * rays.size() + r] = occluded_range(records_, c * kChunk, end, rays[r]) ? 1 : 0;
    }
  });
  for (std::size_t r = 0; r < rays.size(); ++r) {
    std::uint8_t any = 0;
    for (std::size_t c = 0; c < chunks; ++c) any |= partial[c * rays.size() + r];
    out[r] = any;
  }
}

std::vector<Isa> available_isas() {
  std::vector<Isa> out;
  for (const Isa isa : compiled_isas()) {
    if (cpu_supports(isa)) out.push_back(isa);
  }
  return out;
}

std::string describe(const RayHit& hit) {
  if (hit.prim == kNoHit) return fmt::format("miss (t {:a})", hit.t);
  return fmt::format("triangle {} t {:a} ({}) beta {:a} gamma {:a}", hit.prim, hit.t, hit.t, hit.beta, hit.gamma);
}

std::string Agreement::summary() const {
  return fmt::format("{} rays, {} hit, {} mismatches, {} differences explained by edge rounding", rays, hits,
                     mismatches, edge_rounding);
}

Agreement expect_agrees_with_brute_force(const KdTree& tree, const BruteForce& oracle, std::span<const RayQuery> rays,
                                         const std::string& what, EdgeRounding edges) {
  Agreement a;
  a.rays = rays.size();
  std::vector<RayHit> want(rays.size()), got(rays.size());
  std::vector<std::uint8_t> want_occ(rays.size()), got_occ(rays.size());
  oracle.closest(rays, want);
  oracle.occluded(rays, want_occ);
  for (const RayHit& h : want) a.hits += h.prim != kNoHit;
  int reported = 0;
  std::vector<std::optional<std::vector<BruteForce::Accepted>>> accepted(rays.size());  // for the rays that differ
  for (const Isa isa : available_isas()) {
    const TraceKernels& k = trace_kernels(isa);
    for (const bool packets : {true, false}) {
      k.intersect(tree, rays.data(), got.data(), rays.size(), packets);
      k.occluded(tree, rays.data(), got_occ.data(), rays.size(), packets);
      for (std::size_t i = 0; i < rays.size(); ++i) {
        const bool same_hit = std::memcmp(&got[i], &want[i], sizeof(RayHit)) == 0;
        const bool same_occ = got_occ[i] == want_occ[i];
        if (same_hit && same_occ) continue;
        if (edges == EdgeRounding::Explained && want[i].prim != kNoHit) {
          if (!accepted[i]) accepted[i] = oracle.accepted(rays[i]);
          // The kd-tree's hit must be one the float test gives (the same bits: t, weights, id)
          // and agree with its own occlusion answer; every hit the brute force has before it
          // (all of them where the kd-tree has none), and for occlusion all of them where the
          // kd-tree reports none, must be an artefact.
          const bool got_hit = got[i].prim != kNoHit;
          bool explained = !(got_occ[i] != 0 && want_occ[i] == 0) && got_hit == (got_occ[i] != 0);
          if (got_hit) {
            explained = explained && std::any_of(accepted[i]->begin(), accepted[i]->end(), [&](const auto& h) {
              return std::memcmp(&h.hit, &got[i], sizeof(RayHit)) == 0;
            });
          }
          for (const BruteForce::Accepted& h : *accepted[i]) {
            if (!explained) break;
            const bool before_closest =
                !got_hit || h.hit.t < got[i].t || (h.hit.t == got[i].t && h.hit.prim > got[i].prim);
            if (!before_closest) break;
            if (!h.artefact) explained = false;
          }
          if (explained) {
            ++a.edge_rounding;
            continue;
          }
        }
        ++a.mismatches;
        if (reported++ < 6) {
          ADD_FAILURE() << what << ": ray " << i << " (" << isa_name(isa) << ", "
                        << (packets ? fmt::format("{}-wide packets", k.packet_width) : std::string("single rays"))
                        << ") " << test::describe_ray(rays[i]) << "\n  kd-tree: " << describe(got[i]) << ", occluded "
                        << int{got_occ[i]} << "\n  brute force: " << describe(want[i]) << ", occluded "
                        << int{want_occ[i]};
        }
      }
    }
  }
  return a;
}

std::uint64_t check_hit_sanity(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles,
                               std::span<const RayQuery> rays, std::span<const RayHit> hits, const std::string& what) {
  std::uint64_t bad = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const RayHit& h = hits[i];
    const RayQuery& q = rays[i];
    std::string why;
    if (h.prim == kNoHit) {
      if (std::memcmp(&h.t, &q.t_max, sizeof(float)) != 0) why = "a miss must keep t = t_max";
    } else if (h.prim >= triangles.size()) {
      why = "triangle id out of range";
    } else if (!std::isfinite(h.t) || !std::isfinite(h.beta) || !std::isfinite(h.gamma)) {
      why = "NaN or infinite hit data";
    } else if (!(h.t > q.t_min && h.t < q.t_max)) {
      why = "t outside (t_min, t_max)";
    } else if (!(h.beta >= 0.0f && h.gamma >= 0.0f && h.beta + h.gamma <= 1.0f)) {
      why = "barycentrics outside the triangle";
    } else {
      // Independent check in double: distance to the plane of the triangle that was hit.
      const glm::uvec3 t = triangles[h.prim];
      const glm::dvec3 a(positions[t.x]), b(positions[t.y]), c(positions[t.z]);
      const glm::dvec3 n = glm::normalize(glm::cross(b - a, c - a));
      const glm::dvec3 d(q.dir), o(q.org);
      const double cos_angle = std::fabs(glm::dot(n, d)) / glm::length(d);
      if (cos_angle >= 1e-3) {
        const double exact = glm::dot(n, a - o) / glm::dot(n, d);
        // Float's error in t is a few ulps of the coordinates involved, divided by cos.
        const double scale = std::max({glm::length(o), glm::length(a), glm::length(b), glm::length(c)}) / glm::length(d);
        if (std::fabs(exact - h.t) > 1e-4 * (std::fabs(exact) + scale)) {
          why = fmt::format("t differs from the double-precision distance {}", exact);
        }
      }
    }
    if (why.empty()) continue;
    if (bad++ < 6) ADD_FAILURE() << what << ": ray " << i << " " << test::describe_ray(q) << ": " << describe(h) << ": " << why;
  }
  return bad;
}

std::vector<RayQuery> random_rays(std::uint32_t seed, std::size_t count, const Aabb& box) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const glm::vec3 lo = box.lo - 0.5f * box.extent(), size = 2.0f * box.extent();
  std::vector<RayQuery> rays(count);
  for (RayQuery& r : rays) {
    r.org = lo + glm::vec3(u(rng), u(rng), u(rng)) * size;
    const float z = 2.0f * u(rng) - 1.0f, phi = 2.0f * std::numbers::pi_v<float> * u(rng);
    const float s = std::sqrt(std::max(0.0f, 1.0f - z * z));
    r.dir = glm::vec3(s * std::cos(phi), s * std::sin(phi), z);
  }
  return rays;
}

std::vector<RayQuery> rays_at_triangles(std::uint32_t seed, std::size_t count, const Soup& soup, const Aabb& box) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::uniform_int_distribution<std::size_t> pick(0, soup.triangles.size() - 1);
  std::vector<RayQuery> rays(count);
  for (RayQuery& r : rays) {
    r.org = box.lo + glm::vec3(u(rng), u(rng), u(rng)) * box.extent();
    const glm::uvec3 t = soup.triangles[pick(rng)];
    float b = u(rng), c = u(rng);
    if (b + c > 1.0f) {
      b = 1.0f - b;
      c = 1.0f - c;
    }
    const glm::vec3 target = soup.positions[t.x] * (1.0f - b - c) + soup.positions[t.y] * b + soup.positions[t.z] * c;
    r.dir = target - r.org;
    if (r.dir == glm::vec3(0.0f)) r.dir = glm::vec3(0.0f, 0.0f, 1.0f);
  }
  return rays;
}

}  // namespace rtc::stress
