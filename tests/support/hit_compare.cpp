// Ray-by-ray comparison of two tracers' hits.
#include "tests/support/hit_compare.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include <fmt/format.h>

namespace rtc::test {

double ray_triangle_t(const RayQuery& ray, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c,
                      double* min_bary, double* det_out) {
  const glm::dvec3 o(ray.org), d(ray.dir), A(a), B(b), C(c);
  const glm::dvec3 e1 = B - A, e2 = C - A;
  const glm::dvec3 p = glm::cross(d, e2);
  const double det = glm::dot(e1, p);
  if (det_out != nullptr) *det_out = det;
  if (det == 0.0) return std::numeric_limits<double>::quiet_NaN();
  const double inv = 1.0 / det;
  const glm::dvec3 s = o - A;
  const double u = glm::dot(s, p) * inv;
  const glm::dvec3 q = glm::cross(s, e1);
  const double v = glm::dot(d, q) * inv;
  if (min_bary != nullptr) *min_bary = std::min({u, v, 1.0 - u - v});
  return glm::dot(e2, q) * inv;
}

std::string describe_ray(const RayQuery& r) {
  return fmt::format("org=({:a}, {:a}, {:a}) dir=({:a}, {:a}, {:a}) t=[{:a}, {:a}]", r.org.x, r.org.y, r.org.z,
                     r.dir.x, r.dir.y, r.dir.z, r.t_min, r.t_max);
}

namespace {
bool share_vertex(const glm::uvec3& s, const glm::uvec3& t, std::span<const glm::vec3> pos) {
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (s[i] == t[j] || pos[s[i]] == pos[t[j]]) return true;
    }
  }
  return false;
}
bool coplanar(const glm::uvec3& s, const glm::uvec3& t, std::span<const glm::vec3> pos) {
  const glm::dvec3 a(pos[s.x]), b(pos[s.y]), c(pos[s.z]);
  const glm::dvec3 n = glm::normalize(glm::cross(b - a, c - a));
  const double size = std::max({glm::length(b - a), glm::length(c - a), 1e-30});
  for (int k = 0; k < 3; ++k) {
    if (std::fabs(glm::dot(n, glm::dvec3(pos[t[k]]) - a)) > 1e-6 * size) return false;
  }
  return true;
}
}  // namespace

HitComparison compare_hits(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles,
                           std::span<const RayQuery> rays, std::span<const RayHit> ours,
                           std::span<const RayHit> theirs, double rel_tol, double edge_eps, double abs_tol) {
  HitComparison c;
  c.rays = rays.size();
  auto note = [&c](std::size_t i) {
    if (c.examples.size() < 8) c.examples.push_back(i);
  };
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const bool h0 = ours[i].prim != kNoHit, h1 = theirs[i].prim != kNoHit;
    if (!h0 && !h1) {
      ++c.both_miss;
      continue;
    }
    if (h0 != h1) {
      ++c.hit_miss_disagree;
      // Explained only where the ray passes the hit triangle within edge_eps of its boundary
      // (in barycentric weight) on either side, or runs parallel to its plane (det 0: no weights;
      // a ray in the plane grazes it): a hit well inside or a miss well outside the triangle is
      // a real disagreement.
      const glm::uvec3 t = triangles[h0 ? ours[i].prim : theirs[i].prim];
      double b = 0;
      (void)ray_triangle_t(rays[i], positions[t.x], positions[t.y], positions[t.z], &b);
      if (std::fabs(b) <= edge_eps) {
        ++c.hit_miss_on_edge;
      } else {
        note(i);
      }
      continue;
    }
    ++c.both_hit;
    const double t0 = ours[i].t, t1 = theirs[i].t;
    const double rel = std::fabs(t0 - t1) / std::max(std::fabs(t1), 1e-30);
    const bool t_close = std::fabs(t0 - t1) <= rel_tol * std::fabs(t1) + abs_tol;
    if (ours[i].prim == theirs[i].prim) {
      ++c.same_prim;
      c.max_rel_t_same_prim = std::max(c.max_rel_t_same_prim, rel);
      if (!t_close) {
        // Both hit the same triangle, yet the distances differ: fine only when ours is the
        // exact one (double precision) and theirs carries the error.
        const glm::uvec3 t = triangles[ours[i].prim];
        const double exact = ray_triangle_t(rays[i], positions[t.x], positions[t.y], positions[t.z]);
        if (std::fabs(t0 - exact) <= 1e-6 * std::fabs(exact) + abs_tol) {
          ++c.same_prim_theirs_off;
          continue;
        }
        ++c.same_prim_t_bad;
        note(i);
      }
      continue;
    }
    // Different triangles: a tie only if both really are hit at the same distance, at a
    // shared vertex or along edges of both.
    const glm::uvec3 ta = triangles[ours[i].prim], tb = triangles[theirs[i].prim];
    double ba = 0, bb = 0;
    const double xa = ray_triangle_t(rays[i], positions[ta.x], positions[ta.y], positions[ta.z], &ba);
    const double xb = ray_triangle_t(rays[i], positions[tb.x], positions[tb.y], positions[tb.z], &bb);
    const double scale = std::max({std::fabs(xa), std::fabs(xb), 1e-30});
    const bool same_t = std::fabs(xa - xb) <= rel_tol * scale + abs_tol && t_close;
    const bool both_hit = ba >= -edge_eps && bb >= -edge_eps;
    const bool on_edges = (ba <= edge_eps && bb <= edge_eps) || share_vertex(ta, tb, positions);
    // A verified tie: both triangles really are hit (double precision) at the same distance,
    // at a shared edge or vertex, or because they are coplanar and overlap there, or because
    // two surfaces cross within the tolerance of the ray (interpenetrating objects).
    if (same_t && both_hit) {
      ++c.ties;
      if (coplanar(ta, tb, positions)) {
        ++c.coplanar_ties;
      } else if (!on_edges) {
        ++c.crossing_ties;
      }
      continue;
    }
    // The nearer of the two hits sits on an edge of its triangle: a silhouette graze.
    const double near_bary = xa <= xb ? ba : bb;
    if (!same_t && std::fabs(near_bary) <= edge_eps) {
      ++c.edge_grazes;
      continue;
    }
    ++c.bad_ties;
    note(i);
  }
  return c;
}

std::string HitComparison::summary() const {
  return fmt::format(
      "{} rays: {} both hit, {} both miss, {} hit/miss disagree ({:.4f}% agree, {} of them on edges), {} same triangle "
      "(max rel dt {:.2e}, {} over tolerance, {} where only theirs is off the exact t), {} verified ties ({} at edges/vertices = "
      "{:.4f}%, {} coplanar overlaps, {} crossing surfaces), {} edge grazes, {} unexplained",
      rays, both_hit, both_miss, hit_miss_disagree, 100.0 * hit_miss_agreement(), hit_miss_on_edge, same_prim,
      max_rel_t_same_prim, same_prim_t_bad, same_prim_theirs_off, ties, ties - coplanar_ties - crossing_ties,
      100.0 * tie_fraction(), coplanar_ties, crossing_ties, edge_grazes, bad_ties);
}

std::vector<RayQuery> pixel_centre_rays(const CameraRays& camera) {
  std::vector<RayQuery> rays;
  rays.reserve(static_cast<std::size_t>(camera.width()) * static_cast<std::size_t>(camera.height()));
  for (int y = 0; y < camera.height(); ++y) {
    for (int x = 0; x < camera.width(); ++x) {
      const Ray r = camera.ray(x, y);
      rays.push_back(RayQuery{r.origin, 0.0f, r.dir, std::numeric_limits<float>::infinity()});
    }
  }
  return rays;
}

}  // namespace rtc::test
