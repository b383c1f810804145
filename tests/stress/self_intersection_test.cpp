// Self-intersection at every scale: shadow and mirror rays leaving the surfaces of one scene
// scaled from 1e-4 to 1e6 and moved up to 1e6 from the origin. No false self-occlusion
// (acne), no light leaking through thin geometry, no mirror ray hitting its own surface.
//
// The oracle is exact geometry in double precision, free of the tracer's arithmetic: the
// primary hit point P is put exactly on the hit triangle's plane, and the segment from P to
// the light (or the mirror ray from P) is tested against every other triangle. A secondary
// ray legitimately starts up to `step` (offset_ray_origin: 2^-16 of the largest vertex
// coordinate) away from P, so answers that would change when the ray moves by a few steps
// (an occluder's edge, the light or the origin within `delta` of the ray) are "boundary" and
// either answer is accepted; every other answer must be exactly the geometric one.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>

#include "common/accel/trace.h"
#include "common/math/ray_offset.h"
#include "common/render/renderer.h"
#include "common/render/shading.h"
#include "common/scene/mesh_builder.h"
#include "common/scene/tessellate.h"
#include "tests/stress/stress_support.h"
#include "tests/support/hit_compare.h"

namespace rtc::stress {
namespace {

Mesh quads_mesh(const std::string& name, const std::vector<std::array<glm::vec3, 4>>& quads, std::uint32_t material) {
  Mesh m;
  m.name = name;
  for (const auto& q : quads) {
    const auto b = static_cast<unsigned>(m.positions.size());
    m.positions.insert(m.positions.end(), q.begin(), q.end());
    m.triangles.emplace_back(b, b + 1, b + 2);
    m.triangles.emplace_back(b, b + 2, b + 3);
  }
  m.material_ids.assign(m.triangles.size(), material);
  for (std::uint32_t i = 0; i < m.triangles.size(); ++i) m.source_index.push_back(i);
  return m;
}

// The six faces of an axis-aligned box (lo, hi), as quads.
std::vector<std::array<glm::vec3, 4>> box_quads(const glm::vec3& lo, const glm::vec3& hi) {
  auto p = [&](int i) { return glm::vec3(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z); };
  return {{p(0), p(1), p(3), p(2)}, {p(4), p(6), p(7), p(5)}, {p(0), p(4), p(5), p(1)},
          {p(2), p(3), p(7), p(6)}, {p(0), p(2), p(6), p(4)}, {p(1), p(5), p(7), p(3)}};
}

// At unit scale: an 8 x 8 floor of 16 x 16 quads (many shared edges), a box on it, a wall
// 0.02 thick, a plate 0.004 thick floating 0.3 above the floor, a smooth cube-sphere resting
// on the floor, one high light and one grazing light (long shadows across the floor). The
// floor and the sphere are mirrors.
Scene unit_scene() {
  Scene s;
  s.name = "stress-self-intersection";
  Material diffuse;
  diffuse.diffuse = glm::vec3(0.7f, 0.6f, 0.5f);
  Material mirror;
  mirror.diffuse = glm::vec3(0.4f);
  mirror.reflective = true;
  mirror.specular = glm::vec3(0.5f);
  s.materials = {diffuse, mirror};
  std::vector<std::array<glm::vec3, 4>> floor;
  const int n = 16;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const float x0 = -4.0f + 0.5f * static_cast<float>(i), z0 = -4.0f + 0.5f * static_cast<float>(j);
      floor.push_back({glm::vec3(x0, 0, z0), glm::vec3(x0, 0, z0 + 0.5f), glm::vec3(x0 + 0.5f, 0, z0 + 0.5f),
                       glm::vec3(x0 + 0.5f, 0, z0)});
    }
  }
  s.meshes.push_back(quads_mesh("floor", floor, 1));
  s.meshes.push_back(quads_mesh("box", box_quads({-2.5f, 0.0f, -1.0f}, {-1.5f, 1.0f, 0.0f}), 0));
  s.meshes.push_back(quads_mesh("wall", box_quads({0.0f, 0.0f, -2.5f}, {0.02f, 1.5f, -0.5f}), 0));
  s.meshes.push_back(quads_mesh("plate", box_quads({0.8f, 0.3f, 0.5f}, {2.3f, 0.304f, 2.0f}), 0));
  MeshBuilder ball("ball", "stress");
  ball.set_material(1);
  append_sphere(ball, make_cube_sphere(6), glm::dvec3(-1.0, 0.7, 2.0), 0.7);
  s.meshes.push_back(ball.finish());
  s.lights = {PointLight{glm::vec3(1.5f, 5.0f, 1.0f), glm::vec3(0.8f)},
              PointLight{glm::vec3(6.0f, 0.6f, -1.0f), glm::vec3(0.5f)}};
  s.camera.eye = glm::vec3(4.0f, 3.5f, 6.0f);
  s.camera.look_at = glm::vec3(-0.3f, 0.3f, 0.0f);
  s.camera.up = glm::vec3(0, 1, 0);
  s.camera.vfov_deg = 50.0f;
  s.width = 96;
  s.height = 72;
  return s;
}

// Every length times `scale`, then moved by `offset`; computed in double, rounded once.
Scene transformed(const Scene& unit, double scale, const glm::dvec3& offset) {
  Scene s = unit;
  auto P = [&](const glm::vec3& p) { return glm::vec3(glm::dvec3(p) * scale + offset); };
  for (Mesh& m : s.meshes) {
    for (glm::vec3& p : m.positions) p = P(p);
  }
  for (PointLight& l : s.lights) l.position = P(l.position);
  s.camera.eye = P(s.camera.eye);
  s.camera.look_at = P(s.camera.look_at);
  return s;
}

// The exact geometry of one secondary ray against every triangle but its own.
struct Exact {
  bool robust = false;   // something is hit with a margin of delta (edges, both ends)
  bool lenient = false;  // something is hit allowing delta the other way
  double robust_t = std::numeric_limits<double>::infinity();  // nearest robust hit (world units)
};

// `segment`: the ray ends at the light (parameter 1); otherwise it is infinite.
Exact exact_hits(const FrameGeometry& g, std::uint32_t own, const glm::dvec3& p, const glm::dvec3& dir, bool segment,
                 double delta) {
  Exact e;
  const double len = glm::length(dir);
  const glm::dvec3 d = dir / len;
  for (std::uint32_t i = 0; i < g.triangles.size(); ++i) {
    if (i == own) continue;  // a flat triangle cannot shadow or reflect into a ray leaving it
    const glm::uvec3 t = g.triangles[i];
    const glm::dvec3 a(g.positions[t.x]), b(g.positions[t.y]), c(g.positions[t.z]);
    const glm::dvec3 n = glm::cross(b - a, c - a);
    // Nor can a triangle in the same plane as P (the floor's other quads): the ray leaves the
    // plane at P, so it meets that plane nowhere else.
    const glm::dvec3 un0 = glm::normalize(n);
    if (std::fabs(glm::dot(un0, a - p)) <= 1e-9 * glm::length(a) && std::fabs(glm::dot(un0, b - p)) <= 1e-9 * glm::length(b) &&
        std::fabs(glm::dot(un0, c - p)) <= 1e-9 * glm::length(c)) {
      continue;
    }
    const double den = glm::dot(n, d);
    if (den == 0.0) continue;
    const double dist = glm::dot(n, a - p) / den;  // along the unit direction
    if (!std::isfinite(dist)) continue;
    const glm::dvec3 x = p + dist * d;
    const glm::dvec3 un = glm::normalize(n);
    double margin = std::numeric_limits<double>::infinity();  // distance inside the edges
    const glm::dvec3 v[3] = {a, b, c};
    for (int k = 0; k < 3; ++k) {
      const glm::dvec3 edge = v[(k + 1) % 3] - v[k];
      const glm::dvec3 inward = glm::normalize(glm::cross(un, edge));
      margin = std::min(margin, glm::dot(x - v[k], inward));
    }
    const double end = segment ? len - dist : std::numeric_limits<double>::infinity();
    if (margin >= delta && dist >= delta && end >= delta) {
      e.robust = true;
      e.robust_t = std::min(e.robust_t, dist);
    }
    if (margin > -delta && dist > -delta && end > -delta) e.lenient = true;
  }
  return e;
}

bool share_vertex(const glm::uvec3& a, const glm::uvec3& b) {
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (a[i] == b[j]) return true;
    }
  }
  return false;
}

struct Tally {
  std::uint64_t shadow_rays = 0, shadow_boundary = 0, acne = 0, leaks = 0, self_shadow = 0, coplanar_shadow = 0;
  std::uint64_t tiny_t_occluders = 0;  // occluder on own/adjacent triangle within 1e-3 of the segment
  std::uint64_t mirror_rays = 0, mirror_boundary = 0, mirror_self = 0, mirror_phantom = 0, mirror_escape = 0,
                mirror_skipped = 0;
  std::vector<std::uint8_t> classes;  // per pixel and light: 0 miss/no ray, 1 lit, 2 shadowed
};

Tally measure(const Scene& scene, const std::string& what) {
  const auto fs = build_frame_state(scene, 0, scene.settings, KdBuildOptions{});
  const FrameGeometry& g = *fs->geometry;
  const TraceKernels& k = trace_kernels();
  const int w = scene.width;
  const std::vector<RayQuery> primary = test::pixel_centre_rays(fs->camera_rays);
  std::vector<RayHit> hits(primary.size());
  k.intersect(g.single_tree(), primary.data(), hits.data(), primary.size(), true);

  // The largest coordinate in the scene bounds the offset step of any secondary ray.
  float magnitude = 0.0f;
  for (const glm::vec3& p : g.positions) magnitude = std::max({magnitude, std::fabs(p.x), std::fabs(p.y), std::fabs(p.z)});
  const Aabb box = g.single_tree().bounds();
  const double size = glm::length(glm::dvec3(box.extent()));
  const double delta = 4.0 * static_cast<double>(magnitude) / 65536.0 + 1e-6 * size;

  Tally tally;
  tally.classes.assign(primary.size() * scene.lights.size(), 0);
  int reported = 0;
  auto report = [&](const std::string& kind, const RayQuery& q, std::size_t pixel) {
    if (reported++ < 5) {
      ADD_FAILURE() << what << ": " << kind << " at pixel (" << pixel % static_cast<std::size_t>(w) << ", "
                    << pixel / static_cast<std::size_t>(w) << "), secondary ray " << test::describe_ray(q);
    }
  };
  for (std::size_t i = 0; i < primary.size(); ++i) {
    const RayHit& hit = hits[i];
    if (hit.prim == kNoHit) continue;
    const RayQuery& q = primary[i];
    const SurfaceSample s = surface_at(*fs, q.dir, hit.prim, hit.beta, hit.gamma);
    const glm::uvec3 own = g.triangles[hit.prim];
    const glm::dvec3 a(g.positions[own.x]), b(g.positions[own.y]), c(g.positions[own.z]);
    const glm::dvec3 n = glm::cross(b - a, c - a);
    const glm::dvec3 o(q.org), d(q.dir);
    const glm::dvec3 p = o + d * (glm::dot(n, a - o) / glm::dot(n, d));  // exactly on the plane

    for (std::size_t l = 0; l < scene.lights.size(); ++l) {
      const std::optional<ShadowRay> sr = shadow_ray(s, fs->lights[l]);
      if (!sr) continue;
      ++tally.shadow_rays;
      std::uint8_t occ = 0;
      k.occluded(g.single_tree(), &sr->ray, &occ, 1, false);
      tally.classes[i * scene.lights.size() + l] = occ ? 2 : 1;
      RayHit blocker;
      k.intersect(g.single_tree(), &sr->ray, &blocker, 1, false);
      if (blocker.prim != kNoHit) {
        const glm::uvec3 other = g.triangles[blocker.prim];
        if (blocker.prim == hit.prim) {
          ++tally.self_shadow;
          report("shadow ray hits its own triangle", sr->ray, i);
        } else if (share_vertex(own, other)) {
          // A coplanar neighbour can never shadow a point lifted off the common plane.
          const glm::dvec3 m = glm::cross(glm::dvec3(g.positions[other.y]) - glm::dvec3(g.positions[other.x]),
                                          glm::dvec3(g.positions[other.z]) - glm::dvec3(g.positions[other.x]));
          const bool coplanar = glm::length(glm::cross(glm::normalize(m), glm::normalize(n))) < 1e-6 &&
                                std::fabs(glm::dot(glm::normalize(n), glm::dvec3(g.positions[other.x]) - a)) <= 1e-6 * size;
          if (coplanar) {
            ++tally.coplanar_shadow;
            report("shadow ray hits a coplanar neighbour", sr->ray, i);
          }
          if (blocker.t < 1e-3f) ++tally.tiny_t_occluders;
        }
      }
      const Exact e = exact_hits(g, hit.prim, p, glm::dvec3(fs->lights[l].position) - p, true, delta);
      if (e.robust != e.lenient) {
        ++tally.shadow_boundary;
      } else if (occ && !e.lenient) {
        ++tally.acne;
        report("false occlusion (acne)", sr->ray, i);
      } else if (!occ && e.robust) {
        ++tally.leaks;
        report("light leak", sr->ray, i);
      }
    }

    // The mirror ray as the renderer makes it, for every surface (not only mirrors).
    glm::vec3 r = s.dir - s.normal * (2.0f * glm::dot(s.dir, s.normal));
    if (!(glm::dot(r, s.geometric) > 0.0f)) r = s.dir - s.geometric * (2.0f * glm::dot(s.dir, s.geometric));
    const RayQuery mq{s.point, 0.0f, r, std::numeric_limits<float>::infinity()};
    ++tally.mirror_rays;
    RayHit mh;
    k.intersect(g.single_tree(), &mq, &mh, 1, false);
    const Exact e = exact_hits(g, hit.prim, p, glm::dvec3(r), false, delta);
    if (mh.prim == hit.prim) {
      ++tally.mirror_self;
      report("mirror ray hits its own triangle", mq, i);
    } else if (e.robust != e.lenient) {
      ++tally.mirror_boundary;
    } else if (mh.prim != kNoHit && !e.lenient) {
      ++tally.mirror_phantom;
      report("mirror ray hits where nothing is", mq, i);
    } else if (mh.prim == kNoHit && e.robust) {
      ++tally.mirror_escape;
      report("mirror ray escapes through geometry", mq, i);
    } else if (mh.prim != kNoHit) {
      // The surface hit must not lie beyond the nearest certain one.
      const glm::uvec3 t = g.triangles[mh.prim];
      const double dist = static_cast<double>(refined_distance(mq.org, mq.dir, g.positions[t.x], g.positions[t.y],
                                                               g.positions[t.z], mh.t)) * glm::length(glm::dvec3(r));
      if (dist > e.robust_t + 2.0 * delta) {
        ++tally.mirror_skipped;
        report("mirror ray skips a nearer surface", mq, i);
      }
    }
  }
  return tally;
}

TEST(StressSelfIntersection, NoAcneNoLeaksAtAnyScaleOrDistance) {
  const Scene unit = unit_scene();
  const Tally reference = measure(unit, "unit scale");
  struct Case {
    double scale;
    glm::dvec3 offset;
  };
  const Case cases[] = {{1.0, {0, 0, 0}},       {1e-4, {0, 0, 0}},        {1e-2, {0, 0, 0}},
                        {1e2, {0, 0, 0}},       {1e4, {0, 0, 0}},         {1e6, {0, 0, 0}},
                        {1.0, {1e3, 0, 0}},     {1e-1, {-50, 30, 70}},    {1e3, {1e6, 1e6, 0}},
                        {1e4, {-1e6, 0, 1e6}},  {1e6, {1e6, -1e6, 1e6}},  {1e-4, {0.1, 0, -0.05}}};
  for (const Case& c : cases) {
    const std::string what = "scale " + std::to_string(c.scale) + " offset (" + std::to_string(c.offset.x) + ", " +
                             std::to_string(c.offset.y) + ", " + std::to_string(c.offset.z) + ")";
    const Tally t = measure(transformed(unit, c.scale, c.offset), what);
    std::uint64_t differ = 0, compared = 0;
    for (std::size_t i = 0; i < t.classes.size(); ++i) {
      if (t.classes[i] == 0 || reference.classes[i] == 0) continue;
      ++compared;
      differ += t.classes[i] != reference.classes[i];
    }
    const double pct = [](std::uint64_t a, std::uint64_t b) { return b ? 100.0 * static_cast<double>(a) / static_cast<double>(b) : 0.0; }(differ, compared);
    std::printf(
        "%s: shadow rays %llu (boundary %llu), acne %llu, leaks %llu, own-triangle %llu, coplanar-neighbour %llu, "
        "tiny-t neighbour occluders %llu; mirror rays %llu (boundary %llu), own %llu, phantom %llu, escape %llu, "
        "skipped %llu; lit/shadowed differs from unit scale for %.3f%% of %llu pixel-lights\n",
        what.c_str(), static_cast<unsigned long long>(t.shadow_rays), static_cast<unsigned long long>(t.shadow_boundary),
        static_cast<unsigned long long>(t.acne), static_cast<unsigned long long>(t.leaks),
        static_cast<unsigned long long>(t.self_shadow), static_cast<unsigned long long>(t.coplanar_shadow),
        static_cast<unsigned long long>(t.tiny_t_occluders), static_cast<unsigned long long>(t.mirror_rays),
        static_cast<unsigned long long>(t.mirror_boundary), static_cast<unsigned long long>(t.mirror_self),
        static_cast<unsigned long long>(t.mirror_phantom), static_cast<unsigned long long>(t.mirror_escape),
        static_cast<unsigned long long>(t.mirror_skipped), pct, static_cast<unsigned long long>(compared));
    EXPECT_EQ(t.acne + t.leaks + t.self_shadow + t.coplanar_shadow, 0u) << what;
    EXPECT_EQ(t.mirror_self + t.mirror_phantom + t.mirror_escape + t.mirror_skipped, 0u) << what;
    // Boundary answers may go either way, so they must not be the bulk. With the scene 1e3
    // times its size away from the origin, delta is 6% of a floor quad and a third of the
    // shadow rays pass that close to some edge (measured: 32% shadow, 28% mirror; 0.1% at the
    // origin); the other two thirds are still checked exactly.
    EXPECT_LT(t.shadow_boundary, t.shadow_rays / 2) << what;
    EXPECT_LT(t.mirror_boundary, t.mirror_rays / 2) << what;
    // Rays shifted by rounding cross shadow edges in a few pixels; acne would flip whole areas.
    EXPECT_LT(pct, 1.0) << what << ": lit/shadowed differs from the unit-scale scene";
  }
}

}  // namespace
}  // namespace rtc::stress
