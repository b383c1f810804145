// NFF loader and tessellation: cone forms, spheres, view/lights/fill, patches, polygon
// triangulation (fan and ear clipping) and the errors.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "common/scene/mesh_file.h"
#include "common/scene/tessellate.h"
#include "test_files.h"

namespace rtc {
namespace {

using test::error_of;
using test::TempDir;

double triangle_area(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  return 0.5 *
         glm::length(glm::cross(glm::dvec3(b) - glm::dvec3(a), glm::dvec3(c) - glm::dvec3(a)));
}

double mesh_area(const Mesh& mesh) {
  double area = 0.0;
  for (const glm::uvec3& t : mesh.triangles) {
    area += triangle_area(mesh.positions[t.x], mesh.positions[t.y], mesh.positions[t.z]);
  }
  return area;
}

glm::dvec3 geometric_normal(const Mesh& mesh, const glm::uvec3& t) {
  const glm::dvec3 a(mesh.positions[t.x]), b(mesh.positions[t.y]), c(mesh.positions[t.z]);
  return glm::cross(b - a, c - a);
}

TEST(NffLoader, OneLineAndThreeLineConesGiveTheSameMesh) {
  TempDir dir;
  const Mesh one = load_nff(dir.write("one.nff", "c 0 0 0 1 0 0 2 0.5\n")).mesh;
  const Mesh three = load_nff(dir.write("three.nff", "c\n0 0 0 1\n0 0 2 0.5\n")).mesh;
  EXPECT_EQ(one.triangles.size(), 32u);
  EXPECT_EQ(one.positions, three.positions);
  EXPECT_EQ(one.triangles, three.triangles);
  EXPECT_EQ(one.normals, three.normals);
}

TEST(NffLoader, ConesAreOpenAndWindOutward) {
  TempDir dir;
  const Mesh cone = load_nff(dir.write("c.nff", "c 1 2 3 1 1 2 5 0.25\n")).mesh;
  ASSERT_EQ(cone.triangles.size(), 32u);
  for (const glm::uvec3& t : cone.triangles) {
    const glm::dvec3 centroid = (glm::dvec3(cone.positions[t.x]) + glm::dvec3(cone.positions[t.y]) +
                                 glm::dvec3(cone.positions[t.z])) /
                                3.0;
    const glm::dvec3 outward(centroid.x - 1.0, centroid.y - 2.0, 0.0);
    EXPECT_GT(glm::dot(geometric_normal(cone, t), outward), 0.0);
    EXPECT_GT(glm::dot(glm::dvec3(cone.normals[t.x]), outward), 0.0);
  }
  // A true cone (apex radius 0) keeps its numbering; half its triangles collapse at the apex.
  const Mesh pointed = load_nff(dir.write("p.nff", "c 0 0 0 1 0 0 1 0\n")).mesh;
  EXPECT_EQ(pointed.triangles.size() + pointed.dropped_degenerate, 32u);
  EXPECT_EQ(pointed.dropped_degenerate, 16u);
}

TEST(NffLoader, SphereIsACubeSphereOf192Triangles) {
  TempDir dir;
  const Mesh sphere = load_nff(dir.write("s.nff", "s 1 2 3 0.5\n")).mesh;
  EXPECT_EQ(sphere.triangles.size(), 192u);
  EXPECT_EQ(sphere.positions.size(), 98u);
  for (std::size_t i = 0; i < sphere.positions.size(); ++i) {
    EXPECT_NEAR(glm::length(sphere.positions[i] - glm::vec3(1, 2, 3)), 0.5, 1e-6);
    EXPECT_NEAR(glm::length(sphere.normals[i]), 1.0, 1e-6);
  }
  for (const glm::uvec3& t : sphere.triangles) {
    const glm::dvec3 out = glm::dvec3(sphere.positions[t.x]) - glm::dvec3(1, 2, 3);
    EXPECT_GT(glm::dot(geometric_normal(sphere, t), out), 0.0) << "counter-clockwise from outside";
  }
}

TEST(NffLoader, TessellationIsAParameter) {
  TempDir dir;
  const auto nff = dir.write("t.nff", "s 0 0 0 1\nc 0 0 0 1 0 0 1 1\n");
  const Mesh fine = load_nff(nff).mesh;
  EXPECT_EQ(fine.triangles.size(), 192u + 32u);
  const Mesh coarse = load_nff(nff, Tessellation{2, 8}).mesh;
  EXPECT_EQ(coarse.triangles.size(), 48u + 16u);
  MeshLoadOptions options;
  options.tessellation.sphere_quads = 8;
  EXPECT_EQ(load_mesh_file(nff, options).mesh.triangles.size(), 768u + 32u);
  EXPECT_NE(error_of([&] {
              (void)load_nff(nff, Tessellation{0, 16});
            }).find("sphere_quads"),
            std::string::npos);
}

TEST(NffLoader, ReadsViewBackgroundLightsAndFill) {
  TempDir dir;
  const auto nff =
      dir.write("scene.nff",
                "# SPD-like header\n"
                "v\nfrom 1 2 3\nat 0 0 0\nup 0 0 1\nangle 45\nhither 0.01\nresolution 320 240\n"
                "b 0.1 0.2 0.3\n"
                "l 1 1 1\n"
                "l 2 2 2 0.5 0.25 1\n"
                "l 3 3 3\n"
                "f 1 0.5 0.25 0.8 0.4 20 0.1 1.5\n"
                "p 3\n0 0 0\n1 0 0\n0 1 0\n"
                "f 1 1 1 1 0 100000 0 1\n"
                "p 3 0 0 0 0 1 0 1 0 0\n"
                "f 1 0.5 0.25 0.8 0.4 20 0.1 1.5\n"
                "s 0 0 0 1\n");
  const MeshFile file = load_nff(nff);
  ASSERT_TRUE(file.camera.has_value());
  EXPECT_EQ(file.camera->eye, glm::vec3(1, 2, 3));
  EXPECT_EQ(file.camera->up, glm::vec3(0, 0, 1));
  EXPECT_EQ(file.camera->vfov_deg, 45.0f);
  EXPECT_EQ(file.resolution, glm::ivec2(320, 240));
  EXPECT_EQ(file.background, glm::vec3(0.1f, 0.2f, 0.3f));
  ASSERT_EQ(file.lights.size(), 3u);
  const float spd = std::sqrt(3.0f) / 6.0f;  // sqrt(n) / (2n), n = 3
  EXPECT_EQ(file.lights[0].color, glm::vec3(spd));
  EXPECT_EQ(file.lights[1].color, glm::vec3(0.5f, 0.25f, 1.0f));
  EXPECT_EQ(file.lights[2].position, glm::vec3(3, 3, 3));
  EXPECT_EQ(file.lights[2].color, glm::vec3(spd));
  ASSERT_EQ(file.materials.size(), 3u) << "default + two distinct f lines";
  const Mesh& mesh = file.mesh;
  ASSERT_EQ(mesh.triangles.size(), 2u + 192u);
  const Material& shiny = file.materials[mesh.material_ids[0]];
  EXPECT_EQ(shiny.diffuse, 0.8f * glm::vec3(1, 0.5f, 0.25f));
  EXPECT_EQ(shiny.specular, glm::vec3(0.4f));
  EXPECT_EQ(shiny.shininess, 20.0f);
  EXPECT_TRUE(shiny.reflective);
  EXPECT_FLOAT_EQ(shiny.opacity, 0.9f);
  const Material& matte = file.materials[mesh.material_ids[1]];
  EXPECT_FALSE(matte.reflective);
  EXPECT_EQ(matte.shininess, 100000.0f);
  EXPECT_EQ(mesh.material_ids[2], mesh.material_ids[0]) << "identical f lines share a material";
}

TEST(NffLoader, PatchesKeepTheirNormals) {
  TempDir dir;
  const Mesh mesh =
      load_nff(dir.write("pp.nff",
                         "pp 3\n0 0 0 0 0 1\n1 0 0 0 1 1\n0 1 0 0 0 3\np 3\n0 0 1\n1 0 1\n0 1 1\n"))
          .mesh;
  ASSERT_EQ(mesh.triangles.size(), 2u);
  ASSERT_EQ(mesh.normals.size(), 6u);
  EXPECT_EQ(mesh.normals[0], glm::vec3(0, 0, 1));
  EXPECT_NEAR(glm::length(mesh.normals[1]), 1.0f, 1e-6f);
  EXPECT_EQ(mesh.normals[3], glm::vec3(0.0f)) << "polygon vertices carry no normal";
}

TEST(NffLoader, ConcavePolygonIsEarClippedWithItsArea) {
  // A comb with 4 slots cut from the top, 19 vertices, counter-clockwise seen from +z.
  std::vector<glm::vec3> comb{{0, 0, 0}, {8, 0, 0}, {8, 3, 0}};
  for (int tooth = 3; tooth >= 0; --tooth) {
    const float x = 2.0f * tooth;
    comb.push_back({x + 1.5f, 3, 0});
    comb.push_back({x + 1.5f, 1, 0});
    comb.push_back({x + 0.5f, 1, 0});
    if (tooth > 0) comb.push_back({x + 0.5f, 3, 0});
  }
  comb.push_back({0, 3, 0});
  std::string text = "p " + std::to_string(comb.size()) + "\n";
  for (const glm::vec3& p : comb) {
    text += std::to_string(p.x) + " " + std::to_string(p.y) + " " + std::to_string(p.z) + "\n";
  }
  TempDir dir;
  const Mesh mesh = load_nff(dir.write("comb.nff", text)).mesh;
  ASSERT_EQ(mesh.triangles.size(), comb.size() - 2);
  double shoelace = 0.0;
  for (std::size_t i = 0; i < comb.size(); ++i) {
    const glm::vec3& a = comb[i];
    const glm::vec3& b = comb[(i + 1) % comb.size()];
    shoelace += 0.5 * (double(a.x) * b.y - double(b.x) * a.y);
  }
  EXPECT_NEAR(mesh_area(mesh), shoelace, 1e-9 * shoelace);
  for (const glm::uvec3& t : mesh.triangles) {
    EXPECT_GT(geometric_normal(mesh, t).z, 0.0) << "winding kept (one-sided, CCW)";
  }
}

TEST(NffLoader, ASecondViewBlockReplacesTheFirstWithAWarning) {
  TempDir dir;
  const test::CapturedLog log;
  const MeshFile file = load_nff(dir.write("two.nff",
                                           "v\nfrom 1 2 3\nat 0 0 0\nup 0 0 1\nangle 45\n"
                                           "s 0 0 0 1\n"
                                           "v\nfrom 4 5 6\nat 0 0 0\nup 0 1 0\nangle 30\n"));
  ASSERT_TRUE(file.camera.has_value());
  EXPECT_EQ(file.camera->eye, glm::vec3(4, 5, 6));
  EXPECT_EQ(file.camera->vfov_deg, 30.0f);
  EXPECT_EQ(log.count("two.nff:7: a second view block replaces the one at line 1"), 1u);
  const test::CapturedLog one;
  (void)load_nff(dir.write("one.nff", "v\nfrom 1 2 3\nat 0 0 0\nup 0 0 1\nangle 45\ns 0 0 0 1\n"));
  EXPECT_EQ(one.count("view block"), 0u);
  // Within a block each key comes once: a second "from" is a mistake, not a replacement.
  EXPECT_EQ(error_of([&] {
              (void)load_nff(dir.write("twice.nff", "v\nfrom 1 2 3\nat 0 0 0\nfrom 4 5 6\nup 0 0 1\nangle 45\n"));
            }),
            (dir.path() / "twice.nff").string() + ":4: view block gives \"from\" twice");
}

TEST(NffLoader, BadInputNamesTheLine) {
  TempDir dir;
  EXPECT_NE(error_of([&] {
              (void)load_nff(dir.write("u.nff", "s 0 0 0 1\nq 1 2 3\n"));
            }).find("u.nff:2: unknown NFF statement \"q\""),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              (void)load_nff(dir.write("t.nff", "p 4\n0 0 0\n1 0 0\n1 1 0\n"));
            }).find("t.nff:4: unexpected end of file"),
            std::string::npos);
  // A vertex line cut short is named, not the next statement read as its last number.
  EXPECT_EQ(error_of([&] { (void)load_nff(dir.write("c.nff", "p 3\n0 0 0\n1 0\n0 1 0\np 3\n")); }),
            (dir.path() / "c.nff").string() + ":3: line ends early, expected polygon vertex");
  EXPECT_EQ(error_of([&] { (void)load_nff(dir.write("pp.nff", "pp 3\n0 0 0 0 0 1\n1 0 0 0 0\n0 1 0 0 0 1\n")); }),
            (dir.path() / "pp.nff").string() + ":3: line ends early, expected patch normal");
  EXPECT_NE(error_of([&] {
              (void)load_nff(dir.write("n.nff", "s 0 nan 0 1\n"));
            }).find("n.nff:1: bad sphere centre"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              (void)load_nff(dir.write("r.nff", "s 0 0 0 -1\n"));
            }).find("radius must be positive"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              (void)load_nff(dir.write("k.nff", "p 2\n0 0 0\n1 0 0\n"));
            }).find("at least 3"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              (void)load_nff(dir.write("h.nff", "p 99999999999\n0 0 0\n"));
            }).find("truncated"),
            std::string::npos);
  EXPECT_NE(error_of([&] { (void)load_nff(dir.write("e.nff", "b 0 0 0\n")); }).find("no triangles"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              (void)load_nff(dir.write("v.nff", "v\nfrom 0 0 1\nat 0 0 0\nangle 45\ns 0 0 0 1\n"));
            }).find("without \"up\""),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              (void)load_nff(dir.write("f.nff", "f 1 1 1 1 0\ns 0 0 0 1\n"));
            }).find("f.nff:1: line ends early"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              (void)load_nff(dir.write("z.nff", std::string("\x1f\x8b\x08\0", 4)));
            }).find("decompress"),
            std::string::npos);
}

TEST(NffLoader, NegativeFillValuesAreClampedAndOverflowIsRejected) {
  TempDir dir;
  const test::CapturedLog log;
  const MeshFile file = load_nff(dir.write("neg.nff",
                                           "f 1 1 1 1 0.5 -10 0 0\ns 0 0 0 1\n"
                                           "f 1 -1 1 1 -0.5 20 0 0\ns 3 0 0 1\n"
                                           "f 1 -1 1 1 -0.5 20 0 0\ns 6 0 0 1\n"));
  ASSERT_EQ(file.materials.size(), 3u);  // default + two distinct f lines
  EXPECT_EQ(file.materials[1].shininess, 0.0f);
  EXPECT_TRUE(file.materials[1].reflective);
  EXPECT_EQ(file.materials[2].diffuse, glm::vec3(1, 0, 1));
  EXPECT_EQ(file.materials[2].specular, glm::vec3(0.0f));
  EXPECT_FALSE(file.materials[2].reflective) << "a clamped Ks is no mirror";
  EXPECT_EQ(log.count("neg.nff:1: negative fill Shine -10 clamped to 0"), 1u);
  EXPECT_EQ(log.count("neg.nff:3: negative fill Kd * colour (1, -1, 1) clamped to 0"), 1u);
  EXPECT_EQ(log.count("neg.nff:3: negative fill Ks (-0.5, -0.5, -0.5) clamped to 0"), 1u);
  EXPECT_EQ(log.count("negative"), 3u) << "a repeated f line shares the material and the warning";
  // Kd * colour overflows to infinity although both are finite.
  const std::string message = error_of([&] {
    (void)load_nff(dir.write("big.nff", "s 0 0 0 1\nf 1e30 1 1 1e30 0 10 0 0\ns 0 0 0 1\n"));
  });
  EXPECT_NE(message.find("big.nff:2: fill Kd * colour (inf, 1e+30, 1e+30) is not finite"),
            std::string::npos)
      << message;
}

TEST(NffLoader, TransmittanceOutsideZeroToOneIsClampedWithAWarning) {
  TempDir dir;
  const test::CapturedLog log;
  const MeshFile file = load_nff(dir.write("t.nff", "f 1 1 1 1 0 10 1.5 1\ns 0 0 0 1\nf 1 1 1 1 0 10 0.25 1\ns 3 0 0 1\n"));
  ASSERT_EQ(file.materials.size(), 3u);
  EXPECT_EQ(file.materials[1].opacity, 0.0f) << "T 1.5 taken as 1";
  EXPECT_EQ(file.materials[2].opacity, 0.75f);
  EXPECT_EQ(log.count("t.nff:1: fill T 1.5 is outside [0, 1]: taken as 1"), 1u);
  EXPECT_EQ(log.count("outside"), 1u);
}

TEST(NffLoader, NegativeBackgroundAndLightColoursAreClamped) {
  TempDir dir;
  const test::CapturedLog log;
  const MeshFile file = load_nff(dir.write("dark.nff", "b 0.5 -0.25 0\nl 1 2 3 -1 1 1\ns 0 0 0 1\n"));
  ASSERT_TRUE(file.background.has_value());
  EXPECT_EQ(*file.background, glm::vec3(0.5f, 0.0f, 0.0f));
  ASSERT_EQ(file.lights.size(), 1u);
  EXPECT_EQ(file.lights[0].color, glm::vec3(0.0f, 1.0f, 1.0f));
  EXPECT_EQ(log.count("dark.nff:1: negative background colour (0.5, -0.25, 0) clamped to 0"), 1u);
  EXPECT_EQ(log.count("dark.nff:2: negative light colour (-1, 1, 1) clamped to 0"), 1u);
}

TEST(NffLoader, SpheresAndConesBeyondTheFloatRangeAreRejected) {
  TempDir dir;
  const std::string sphere =
      error_of([&] { (void)load_nff(dir.write("s.nff", "s 0 0 0 1\ns 0 -3e38 0 1e38\n")); });
  EXPECT_NE(sphere.find("s.nff:2: sphere centre (0, -3e+38, 0) with radius 1e+38 reaches beyond "
                        "the float range"),
            std::string::npos)
      << sphere;
  const std::string cone =
      error_of([&] { (void)load_nff(dir.write("c.nff", "c\n0 0 0 1\n2.9e38 0 0 2e37\n")); });
  EXPECT_NE(cone.find("c.nff:3: cone apex (2.9e+38, 0, 0) with radius 2e+37 reaches beyond"),
            std::string::npos)
      << cone;
  // A cone spanning most of the range is fine, normals included (its unscaled normal is not).
  const Mesh wide = load_nff(dir.write("w.nff", "c -2.9e38 0 0 1e30 2.9e38 0 0 1e30\n")).mesh;
  ASSERT_EQ(wide.triangles.size(), 32u);
  for (const glm::vec3& n : wide.normals) {
    EXPECT_TRUE(std::isfinite(n.x) && std::isfinite(n.y) && std::isfinite(n.z));
    EXPECT_NEAR(glm::length(n), 1.0f, 1e-6f);
  }
}

// --- tessellation -----------------------------------------------------------------------

TEST(Tessellation, ConvexPolygonIsAFanFromVertexZero) {
  const std::vector<glm::vec3> hexagon{{2, 0, 0},  {1, 1.7f, 0},   {-1, 1.7f, 0},
                                       {-2, 0, 0}, {-1, -1.7f, 0}, {1, -1.7f, 0}};
  EXPECT_TRUE(is_convex_polygon(hexagon));
  const std::vector<glm::uvec3> tris = triangulate_polygon(hexagon);
  ASSERT_EQ(tris.size(), 4u);
  for (std::uint32_t k = 0; k < 4; ++k) EXPECT_EQ(tris[k], glm::uvec3(0, k + 1, k + 2));
}

TEST(Tessellation, EarClippingCoversConcavePolygonsInAnyPlane) {
  // Star polygons with 5..40 points in three planes and both windings.
  for (int points = 5; points <= 40; points += 7) {
    for (int plane = 0; plane < 3; ++plane) {
      for (const bool clockwise : {false, true}) {
        std::vector<glm::vec3> star;
        double shoelace = 0.0;
        std::vector<glm::dvec2> flat;
        for (int i = 0; i < 2 * points; ++i) {
          const double angle = (clockwise ? -1.0 : 1.0) * std::numbers::pi * i / points;
          const double radius = i % 2 == 0 ? 2.0 : 0.7;
          flat.emplace_back(radius * std::cos(angle), radius * std::sin(angle));
        }
        for (std::size_t i = 0; i < flat.size(); ++i) {
          const glm::dvec2& a = flat[i];
          const glm::dvec2& b = flat[(i + 1) % flat.size()];
          shoelace += 0.5 * (a.x * b.y - b.x * a.y);
          glm::vec3 p(0.0f);
          p[(plane + 1) % 3] = static_cast<float>(a.x);
          p[(plane + 2) % 3] = static_cast<float>(a.y);
          p[plane] = 3.0f;
          star.push_back(p);
        }
        EXPECT_FALSE(is_convex_polygon(star));
        const std::vector<glm::uvec3> tris = triangulate_polygon(star);
        ASSERT_EQ(tris.size(), star.size() - 2);
        double area = 0.0;
        for (const glm::uvec3& t : tris) {
          const glm::dvec3 n =
              glm::cross(glm::dvec3(star[t.y] - star[t.x]), glm::dvec3(star[t.z] - star[t.x]));
          EXPECT_GT(n[plane] * shoelace, 0.0) << "every triangle keeps the polygon's winding";
          area += 0.5 * glm::length(n);
        }
        EXPECT_NEAR(area, std::abs(shoelace), 1e-5 * std::abs(shoelace))
            << points << " points, plane " << plane << (clockwise ? ", clockwise" : "");
      }
    }
  }
}

TEST(Tessellation, DegeneratePolygonsStillGiveSizeMinusTwoTriangles) {
  const std::vector<glm::vec3> line{{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}, {4, 0, 0}};
  EXPECT_EQ(triangulate_polygon(line).size(), 3u);
  // Self-intersecting bow tie.
  const std::vector<glm::vec3> bow{{0, 0, 0}, {2, 2, 0}, {2, 0, 0}, {0, 2, 0}, {-1, 1, 0}};
  EXPECT_EQ(triangulate_polygon(bow).size(), 3u);
  EXPECT_TRUE(triangulate_polygon(std::vector<glm::vec3>{{0, 0, 0}, {1, 0, 0}}).empty());
}

TEST(Tessellation, CubeSphereCountsForEveryLevel) {
  for (int quads = 1; quads <= 6; ++quads) {
    const SphereTemplate sphere = make_cube_sphere(quads);
    EXPECT_EQ(sphere.triangles.size(), static_cast<std::size_t>(12 * quads * quads));
    EXPECT_EQ(sphere.points.size(), static_cast<std::size_t>(6 * quads * quads + 2));
  }
}

}  // namespace
}  // namespace rtc
