// OBJ/MTL, PLY and glTF loaders on small generated files: what they read and every way they
// reject bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <string>

#include "common/base/error.h"
#include "common/scene/file_bytes.h"
#include "common/scene/mesh_file.h"
#include "test_files.h"

namespace rtc {
namespace {

using test::error_of;
using test::TempDir;

// --- OBJ --------------------------------------------------------------------------------

TEST(ObjLoader, ReadsTrianglesNormalsAndMaterials) {
  TempDir dir;
  dir.write("m.mtl",
            "# two materials\n"
            "newmtl red\nKd 0.8 0.1 0.1\nKs 0.5 0.5 0.5\nNs 100\nKe 0 0 0.25\nd 0.75\nillum 3\n"
            "newmtl grey\nKd 0.5\nillum 2\n");
  const auto obj = dir.write("m.obj",
                             "mtllib m.mtl\n"
                             "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                             "vn 0 0 2\n"
                             "usemtl red\n"
                             "f 1//1 2//1 3//1\n"
                             "usemtl grey\n"
                             "f 1 3 4\n");
  const MeshFile file = load_obj(obj);
  const Mesh& mesh = file.mesh;
  ASSERT_EQ(mesh.triangles.size(), 2u);
  EXPECT_EQ(mesh.source_index, (std::vector<std::uint32_t>{0, 1}));
  // Vertices 1 and 3 appear with and without a normal: two mesh vertices each.
  EXPECT_EQ(mesh.positions.size(), 6u);
  ASSERT_EQ(mesh.normals.size(), mesh.positions.size());
  EXPECT_EQ(mesh.normals[mesh.triangles[0].x], glm::vec3(0, 0, 1)) << "normals are normalised";
  EXPECT_EQ(mesh.normals[mesh.triangles[1].x], glm::vec3(0.0f)) << "no normal: zero";
  ASSERT_EQ(file.materials.size(), 3u);  // default + red + grey
  const Material& red = file.materials[mesh.material_ids[0]];
  EXPECT_EQ(red.name, "red");
  EXPECT_EQ(red.diffuse, glm::vec3(0.8f, 0.1f, 0.1f));
  EXPECT_EQ(red.specular, glm::vec3(0.5f));
  EXPECT_EQ(red.shininess, 100.0f);
  EXPECT_EQ(red.emission, glm::vec3(0, 0, 0.25f));
  EXPECT_EQ(red.opacity, 0.75f);
  EXPECT_TRUE(red.reflective);
  const Material& grey = file.materials[mesh.material_ids[1]];
  EXPECT_EQ(grey.name, "grey");
  EXPECT_EQ(grey.diffuse, glm::vec3(0.5f));
  EXPECT_FALSE(grey.reflective);
}

TEST(ObjLoader, NegativeShininessAndColoursAreClampedWithOneWarningEach) {
  TempDir dir;
  dir.write("neg.mtl",
            "newmtl dark\nNs -5\nKd -0.5 0.25 0.5\nKs 0.5 -1 0.5\nKe -2\n"
            "newmtl fine\nNs 10\nKd 0.5\n");
  const auto obj = dir.write("neg.obj",
                             "mtllib neg.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl dark\nf 1 2 3\n");
  const test::CapturedLog log;
  const MeshFile file = load_obj(obj);
  const Material& dark = file.materials.at(file.mesh.material_ids[0]);
  EXPECT_EQ(dark.shininess, 0.0f);
  EXPECT_EQ(dark.diffuse, glm::vec3(0.0f, 0.25f, 0.5f));
  EXPECT_EQ(dark.specular, glm::vec3(0.5f, 0.0f, 0.5f));
  EXPECT_EQ(dark.emission, glm::vec3(0.0f));
  EXPECT_EQ(log.count("neg.mtl:2: negative Ns -5 clamped to 0"), 1u);
  EXPECT_EQ(log.count("neg.mtl:3: negative Kd (-0.5, 0.25, 0.5) clamped to 0"), 1u);
  EXPECT_EQ(log.count("neg.mtl:4: negative Ks"), 1u);
  EXPECT_EQ(log.count("neg.mtl:5: negative Ke (-2, -2, -2)"), 1u);
  EXPECT_EQ(log.count("negative"), 4u) << "nothing for the fine material";
  // Non-finite values never get that far: the number parser rejects them with their line.
  dir.write("inf.mtl", "newmtl x\nNs 1e999\n");
  const auto inf = dir.write("inf.obj", "mtllib inf.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  EXPECT_NE(error_of([&] { (void)load_obj(inf); }).find("inf.mtl:2: bad Ns value"),
            std::string::npos);
}

TEST(ObjLoader, OpacityOutsideZeroToOneIsClampedWithAWarning) {
  TempDir dir;
  dir.write("see.mtl", "newmtl cloud\nd 7\nnewmtl glass\nTr -0.5\nnewmtl fine\nd 0.25\nTr 2\n");
  const auto obj = dir.write("see.obj",
                             "mtllib see.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                             "usemtl cloud\nf 1 2 3\nusemtl glass\nf 1 2 3\nusemtl fine\nf 1 2 3\n");
  const test::CapturedLog log;
  const MeshFile file = load_obj(obj);
  ASSERT_EQ(file.mesh.material_ids.size(), 3u);
  EXPECT_EQ(file.materials.at(file.mesh.material_ids[0]).opacity, 1.0f);
  EXPECT_EQ(file.materials.at(file.mesh.material_ids[1]).opacity, 1.0f) << "Tr -0.5 taken as 0";
  EXPECT_EQ(file.materials.at(file.mesh.material_ids[2]).opacity, 0.25f) << "d comes before Tr";
  EXPECT_EQ(log.count("see.mtl:2: d 7 is outside [0, 1]: taken as 1"), 1u);
  EXPECT_EQ(log.count("see.mtl:4: Tr -0.5 is outside [0, 1]: taken as 0"), 1u);
  EXPECT_EQ(log.count("see.mtl:7: Tr 2 is outside [0, 1]: taken as 1"), 1u);
  EXPECT_EQ(log.count("outside [0, 1]"), 3u);
}

TEST(ObjLoader, FanTriangulatesPolygonsFromVertexZero) {
  TempDir dir;
  const auto obj = dir.write("poly.obj",
                             "v 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\n"
                             "f 1 2 3 4 5\n"
                             "f 1 2 3\n");
  const Mesh mesh = load_obj(obj).mesh;
  ASSERT_EQ(mesh.triangles.size(), 4u);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(mesh.positions[mesh.triangles[k].x], glm::vec3(0, 0, 0)) << "fan from vertex 0";
  }
  EXPECT_EQ(mesh.source_index, (std::vector<std::uint32_t>{0, 1, 2, 3}));
}

TEST(ObjLoader, AcceptsNegativeIndicesAndTextureCoordinates) {
  TempDir dir;
  const auto obj = dir.write("neg.obj",
                             "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                             "f -3/-3 -2/-2 -1/-1\n");
  const Mesh mesh = load_obj(obj).mesh;
  ASSERT_EQ(mesh.triangles.size(), 1u);
  EXPECT_EQ(mesh.positions[mesh.triangles[0].y], glm::vec3(1, 0, 0));
}

TEST(ObjLoader, MissingMtlWarnsAndUsesTheDefaultMaterial) {
  TempDir dir;
  const auto obj = dir.write(
      "nomtl.obj", "mtllib absent.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl shiny\nf 1 2 3\n");
  const MeshFile file = load_obj(obj);
  ASSERT_EQ(file.mesh.material_ids.size(), 1u);
  EXPECT_EQ(file.materials.at(file.mesh.material_ids[0]), Material{});
}

TEST(ObjLoader, GeometryItCannotDrawAndUnknownStatementsAreWarnedOnceEach) {
  TempDir dir;
  const auto obj = dir.write("mixed.obj",
                             "g body\nusemap wood\nv 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\nl 2 3\np 1\n"
                             "frobnicate 1 2\nf 1 2 3\nfrobnicate 3\ncstype bspline\ndeg 3\ncurv 0 1 1 2 3\nparm u 0 1\n"
                             "end\n");
  const test::CapturedLog log;
  const MeshFile file = load_obj(obj);
  EXPECT_EQ(file.mesh.triangles.size(), 1u);
  EXPECT_EQ(log.count("warning: " + obj.string() + ":6: OBJ statement \"l\" skipped, here and below: rtc draws faces"),
            1u);
  EXPECT_EQ(log.count("mixed.obj:8: OBJ statement \"p\" skipped"), 1u);
  EXPECT_EQ(log.count("warning: " + obj.string() + ":9: unknown OBJ statement \"frobnicate\" skipped"), 1u);
  EXPECT_EQ(log.count("mixed.obj:12: OBJ statement \"cstype\" skipped with the other free-form statements"), 1u);
  EXPECT_EQ(log.count("warning: "), 4u) << "once per keyword, once for the free-form family; nothing for g or usemap";
}

TEST(ObjLoader, UnknownStatementsAreSaidTenTimesAtMost) {
  TempDir dir;
  std::string text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  for (int i = 0; i < 25; ++i) text += "junk" + std::to_string(i) + " 1\n";
  const auto obj = dir.write("junk.obj", text);
  const test::CapturedLog log;
  EXPECT_EQ(load_obj(obj).mesh.triangles.size(), 1u);
  EXPECT_EQ(log.count("unknown OBJ statement"), 10u);
  EXPECT_EQ(log.count("junk.obj:14: unknown OBJ statement \"junk9\" skipped, here and below; further unknown statements "
                      "are skipped unsaid (is this an OBJ file?)"),
            1u);
}

TEST(ObjLoader, ANulByteIsNoObjText) {
  TempDir dir;
  const auto obj = dir.write("binary.obj", std::string("v 0 0 0\nv 1 0 0\nv 0\0 1 0\n", 25));
  const test::CapturedLog log;
  EXPECT_EQ(error_of([&] { (void)load_obj(obj); }),
            obj.string() + ":3: a NUL byte at offset 19: not an OBJ text file (a binary file with an .obj name?)");
  EXPECT_EQ(log.count("warning: "), 0u);
}

TEST(ObjLoader, IndexOutOfRangeNamesFileAndLine) {
  TempDir dir;
  const auto obj = dir.write("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n# comment\nf 1 2 4\n");
  const std::string message = error_of([&] { (void)load_obj(obj); });
  EXPECT_NE(message.find("bad.obj:5:"), std::string::npos) << message;
  EXPECT_NE(message.find("out of range"), std::string::npos) << message;
  const auto zero = dir.write("zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
  EXPECT_NE(error_of([&] { (void)load_obj(zero); }).find("zero.obj:4:"), std::string::npos);
  const auto normal =
      dir.write("vn.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//2 2//1 3//1\n");
  EXPECT_NE(error_of([&] { (void)load_obj(normal); }).find("normal index 2"), std::string::npos);
}

TEST(ObjLoader, NonFiniteCoordinateIsRejected) {
  TempDir dir;
  for (const char* value : {"nan", "inf", "-inf", "1e999", "abc"}) {
    const auto obj =
        dir.write("nan.obj", std::string("v 0 0 0\nv ") + value + " 0 0\nv 0 1 0\nf 1 2 3\n");
    const std::string message = error_of([&] { (void)load_obj(obj); });
    EXPECT_NE(message.find("nan.obj:2:"), std::string::npos) << value << ": " << message;
    EXPECT_NE(message.find("vertex x"), std::string::npos) << value << ": " << message;
  }
}

TEST(ObjLoader, MeshWithoutTrianglesIsRejected) {
  TempDir dir;
  const auto obj = dir.write("empty.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
  EXPECT_NE(error_of([&] { (void)load_obj(obj); }).find("no triangles"), std::string::npos);
  const auto nothing = dir.write("nothing.obj", "");
  EXPECT_NE(error_of([&] { (void)load_obj(nothing); }).find("no triangles"), std::string::npos);
}

TEST(ObjLoader, ShortFaceAndGarbageAreRejectedWithTheirLine) {
  TempDir dir;
  const auto two = dir.write("two.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n");
  EXPECT_NE(error_of([&] { (void)load_obj(two); }).find("two.obj:3: face with 2 vertices"),
            std::string::npos);
  const auto letters = dir.write("letters.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 x 3\n");
  EXPECT_NE(error_of([&] { (void)load_obj(letters); }).find("letters.obj:4: bad face vertex"),
            std::string::npos);
  const auto truncated = dir.write("cut.obj", "v 0 0 0\nv 1 0");
  EXPECT_NE(error_of([&] { (void)load_obj(truncated); }).find("cut.obj:2:"), std::string::npos);
  std::string noise;
  for (int i = 0; i < 4096; ++i) noise += static_cast<char>((i * 7919 + 13) % 256);
  const auto binary = dir.write("noise.obj", noise);
  (void)error_of([&] { (void)load_obj(binary); });  // an rtc::Error, not a crash
}

TEST(ObjLoader, DropsDegenerateTrianglesAndKeepsSourceIndices) {
  TempDir dir;
  const auto obj = dir.write("degenerate.obj",
                             "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\n"
                             "f 1 2 3\n"
                             "f 1 2 2\n"  // repeated index
                             "f 1 2 4\n"  // collinear: zero area
                             "f 3 2 1\n");
  const Mesh mesh = load_obj(obj).mesh;
  EXPECT_EQ(mesh.dropped_degenerate, 2u);
  EXPECT_EQ(mesh.source_index, (std::vector<std::uint32_t>{0, 3}));
  EXPECT_EQ(mesh.material_ids.size(), 2u);
  const auto all = dir.write("all.obj", "v 0 0 0\nv 1 0 0\nf 1 2 2\n");
  EXPECT_NE(error_of([&] { (void)load_obj(all); }).find("all 1 triangles are degenerate"),
            std::string::npos);
}

TEST(MeshFile, MissingFileAndUnknownFormatAreRejected) {
  TempDir dir;
  EXPECT_NE(error_of([&] { (void)load_mesh_file(dir.path() / "absent.obj"); }).find("not found"),
            std::string::npos);
  const auto stl = dir.write("x.stl", "solid x\n");
  EXPECT_NE(error_of([&] { (void)load_mesh_file(stl); }).find("unknown mesh format"),
            std::string::npos);
  const auto gz = dir.write("x.nff.gz", "\x1f\x8b");
  EXPECT_NE(error_of([&] { (void)load_mesh_file(gz); }).find("decompress"), std::string::npos);
  EXPECT_NE(error_of([&] { (void)load_obj(dir.path()); }).find("cannot"), std::string::npos);
}

TEST(MeshFile, ALinkLoopIsNamedAsOneNotAsMissing) {
  TempDir dir;
  std::filesystem::create_symlink("b.obj", dir.path() / "a.obj");
  std::filesystem::create_symlink("a.obj", dir.path() / "b.obj");
  const std::string message = error_of([&] { (void)load_mesh_file(dir.path() / "a.obj"); });
  EXPECT_NE(message.find("a.obj: Too many levels of symbolic links"), std::string::npos) << message;
  EXPECT_EQ(message.find("not found"), std::string::npos) << message;
  EXPECT_EQ(missing_file_reason((dir.path() / "absent.obj").string()), "file not found");
  EXPECT_EQ(missing_file_reason((dir.path() / "absent" / "x.obj").string()), "file not found");
  EXPECT_EQ(missing_file_reason(dir.path().string()), "");
}

TEST(MeshFile, DevicesAreNotRead) {
  // /dev/zero never ends: read, it would fill the memory (found by fuzzing, tests/fuzz).
  const std::string message = error_of([&] { (void)FileBytes("/dev/zero"); });
  EXPECT_NE(message.find("/dev/zero"), std::string::npos) << message;
  EXPECT_NE(message.find("not a regular file"), std::string::npos) << message;
}

TEST(MeshFile, NamesWithANulByteAreNotOpened) {
  // open() would stop at the NUL and read the shorter name, a file that exists here.
  TempDir dir;
  const auto real = dir.write("real.bin", "bytes");
  const std::string message = error_of([&] { (void)FileBytes(real.string() + std::string("\0.obj", 5)); });
  EXPECT_NE(message.find("real.bin\\0.obj: file name contains a NUL byte"), std::string::npos) << message;
}

TEST(ObjLoader, MaterialLibraryErrorsNameTheObjLine) {
  TempDir dir;
  std::filesystem::create_directories(dir.path() / "lib.mtl");  // a folder named like a library
  const auto obj = dir.write("m.obj", "v 0 0 0\nv 1 0 0\nmtllib lib.mtl\nv 0 1 0\nf 1 2 3\n");
  const std::string message = error_of([&] { (void)load_obj(obj); });
  EXPECT_NE(message.find("m.obj:3: material library: "), std::string::npos) << message;
  EXPECT_NE(message.find("lib.mtl"), std::string::npos) << message;
  const auto nul = dir.write("nul.obj", std::string("mtllib \0x.mtl\nv 0 0 0\n", 22));
  // (Refused as a whole file: OBJ is text.)
  EXPECT_EQ(error_of([&] { (void)load_obj(nul); }),
            nul.string() + ":1: a NUL byte at offset 7: not an OBJ text file (a binary file with an .obj name?)");
}

// --- PLY --------------------------------------------------------------------------------

struct PlyData {
  std::vector<glm::vec3> points{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  std::vector<std::vector<int>> faces{{0, 1, 2, 3}, {0, 2, 1}};
};

std::string ply_header(const std::string& format, const PlyData& data,
                       const std::string& index_type) {
  return "ply\nformat " + format + " 1.0\ncomment test\nelement vertex " +
         std::to_string(data.points.size()) +
         "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
         std::to_string(data.faces.size()) + "\nproperty list uchar " + index_type +
         " vertex_indices\nend_header\n";
}

std::string ascii_ply(const PlyData& data) {
  std::string out = ply_header("ascii", data, "int");
  for (const glm::vec3& p : data.points) {
    out += std::to_string(p.x) + " " + std::to_string(p.y) + " " + std::to_string(p.z) + "\n";
  }
  for (const auto& f : data.faces) {
    out += std::to_string(f.size());
    for (int i : f) {
      out += ' ';
      out += std::to_string(i);
    }
    out += "\n";
  }
  return out;
}

std::string binary_ply(const PlyData& data, bool big_endian = false) {
  std::string out =
      ply_header(big_endian ? "binary_big_endian" : "binary_little_endian", data, "int");
  auto put = [&](auto value) {
    std::string bytes;
    test::append_le(bytes, value);
    if (big_endian) bytes = std::string(bytes.rbegin(), bytes.rend());
    out += bytes;
  };
  for (const glm::vec3& p : data.points) {
    put(p.x);
    put(p.y);
    put(p.z);
  }
  for (const auto& f : data.faces) {
    out += static_cast<char>(f.size());
    for (int i : f) put(static_cast<std::int32_t>(i));
  }
  return out;
}

TEST(PlyLoader, AsciiLittleAndBigEndianGiveTheSameMesh) {
  TempDir dir;
  const PlyData data;
  const Mesh ascii = load_ply(dir.write("a.ply", ascii_ply(data))).mesh;
  const Mesh little = load_ply(dir.write("le.ply", binary_ply(data))).mesh;
  const Mesh big = load_ply(dir.write("be.ply", binary_ply(data, true))).mesh;
  for (const Mesh* m : {&ascii, &little, &big}) {
    EXPECT_EQ(m->positions, data.points);
    ASSERT_EQ(m->triangles.size(), 3u) << "quad fanned into 2, plus 1";
    EXPECT_EQ(m->triangles[0], glm::uvec3(0, 1, 2));
    EXPECT_EQ(m->triangles[1], glm::uvec3(0, 2, 3));
    EXPECT_EQ(m->triangles[2], glm::uvec3(0, 2, 1));
    EXPECT_EQ(m->source_index, (std::vector<std::uint32_t>{0, 1, 2}));
  }
}

TEST(PlyLoader, AcceptsHeaderLineWithoutKeywordAndNormals) {
  TempDir dir;
  const auto ply =
      dir.write("wuson_like.ply",
                "ply\nformat ascii 1.0\nCreated by Blender3D 247 - www.blender.org, source file: \n"
                "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                "property float nx\nproperty float ny\nproperty float nz\nproperty float "
                "s\nproperty float t\n"
                "element face 1\nproperty list uchar uint vertex_indices\nend_header\n"
                "0 0 0 0 0 1 0 0\n1 0 0 0 0 1 1 0\n0 1 0 0 0 1 0 1\n3 0 1 2\n");
  const Mesh mesh = load_ply(ply).mesh;
  ASSERT_EQ(mesh.triangles.size(), 1u);
  ASSERT_EQ(mesh.normals.size(), 3u);
  EXPECT_EQ(mesh.normals[1], glm::vec3(0, 0, 1));
}

TEST(PlyLoader, TruncatedBinaryFileIsRejected) {
  TempDir dir;
  const std::string full = binary_ply(PlyData{});
  for (const std::size_t cut : {full.size() - 1, full.size() - 10, full.size() - 40}) {
    const auto ply = dir.write("cut.ply", full.substr(0, cut));
    const std::string message = error_of([&] { (void)load_ply(ply); });
    EXPECT_NE(message.find("cut.ply"), std::string::npos) << message;
    EXPECT_NE(message.find("truncated"), std::string::npos) << message;
  }
  const auto header_only = dir.write("header.ply", "ply\nformat ascii 1.0\nelement vertex 3\n");
  EXPECT_NE(error_of([&] { (void)load_ply(header_only); }).find("end_header"), std::string::npos);
}

TEST(PlyLoader, HugeElementCountIsRejectedBeforeAllocating) {
  TempDir dir;
  const auto ply = dir.write("huge.ply",
                             "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\n"
                             "property float x\nproperty float y\nproperty float z\n"
                             "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                             "0123456789");
  const std::string message = error_of([&] { (void)load_ply(ply); });
  EXPECT_NE(message.find("declares 4000000000 items"), std::string::npos) << message;
}

TEST(PlyLoader, ElementWithoutPropertiesCannotDeclareAbsurdCounts) {
  TempDir dir;
  // No properties: each item takes no bytes, so the count is bounded by the file size.
  const std::string binary = binary_ply(PlyData{});
  std::string huge = binary;
  huge.insert(huge.find("element face"), "element junk 9223372036854775807\n");
  const std::string message = error_of([&] { (void)load_ply(dir.write("junk.ply", huge)); });
  EXPECT_NE(message.find("junk.ply:8: element junk has no properties but declares "
                         "9223372036854775807 items, more than the file's"),
            std::string::npos)
      << message;
  std::string few = binary;
  few.insert(few.find("element face"), "element junk 3\n");
  EXPECT_EQ(load_ply(dir.write("few.ply", few)).mesh.triangles.size(), 3u);
}

TEST(PlyLoader, AsciiElementCountIsBoundedByTheDataLines) {
  TempDir dir;
  const std::string ascii = ascii_ply(PlyData{});  // 4 vertex and 2 face lines
  std::string junk = ascii;
  junk.insert(junk.find("end_header"), "element junk 7\n");
  const std::string message = error_of([&] { (void)load_ply(dir.write("junk.ply", junk)); });
  EXPECT_NE(message.find("junk.ply:10: element junk declares 7 items but the data has only 6 "
                         "lines"),
            std::string::npos)
      << message;
  std::string many = ascii;
  many.replace(many.find("element vertex 4"), 16, "element vertex 4000000000");
  EXPECT_NE(error_of([&] { (void)load_ply(dir.write("many.ply", many)); })
                .find("element vertex declares 4000000000 items but the data has only 6 lines"),
            std::string::npos);
  std::string fits = ascii;
  fits.insert(fits.find("end_header"), "element junk 6\n");
  EXPECT_EQ(load_ply(dir.write("fits.ply", fits)).mesh.triangles.size(), 3u);
}

TEST(PlyLoader, DoublesBeyondTheFloatRangeAreRejected) {
  TempDir dir;
  const auto write = [&](const std::string& name, double big, bool normal) {
    std::string out = "ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
                      "property double x\nproperty double y\nproperty double z\n";
    if (normal) out += "property double nx\nproperty double ny\nproperty double nz\n";
    out += "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    const double points[3][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    for (int v = 0; v < 3; ++v) {
      for (int a = 0; a < 3; ++a) {
        test::append_le(out, v == 1 && a == 2 && !normal ? big : points[v][a]);
      }
      if (normal) {
        for (int a = 0; a < 3; ++a) test::append_le(out, v == 2 && a == 0 ? big : 1.0);
      }
    }
    out += static_cast<char>(3);
    for (const std::int32_t i : {0, 1, 2}) test::append_le(out, i);
    return dir.write(name, out);
  };
  const std::string coordinate = error_of([&] { (void)load_ply(write("c.ply", 1e300, false)); });
  EXPECT_NE(coordinate.find("c.ply: vertex 1: coordinate (1, 0, 1e+300) is out of float range"),
            std::string::npos)
      << coordinate;
  const std::string normal = error_of([&] { (void)load_ply(write("n.ply", -4e38, true)); });
  EXPECT_NE(normal.find("n.ply: vertex 2: normal (-4e+38, 1, 1) is out of float range"),
            std::string::npos)
      << normal;
  // Just inside the float range is fine.
  EXPECT_EQ(load_ply(write("ok.ply", 3e38, false)).mesh.positions[1].z, 3e38f);
}

TEST(PlyLoader, IndexOutOfRangeIsRejected) {
  TempDir dir;
  PlyData data;
  data.faces = {{0, 1, 2}, {0, 2, 4}};
  const std::string binary =
      error_of([&] { (void)load_ply(dir.write("b.ply", binary_ply(data))); });
  EXPECT_NE(binary.find("b.ply: face 1: vertex index 4 out of range (4 vertices)"),
            std::string::npos)
      << binary;
  const std::string ascii = error_of([&] { (void)load_ply(dir.write("a.ply", ascii_ply(data))); });
  // Header 10 lines, 4 vertex lines, the second face on line 16.
  EXPECT_NE(ascii.find("a.ply:16: face 1: vertex index 4 out of range"), std::string::npos)
      << ascii;
  data.faces = {{0, 1, -1}};
  const std::string negative =
      error_of([&] { (void)load_ply(dir.write("n.ply", binary_ply(data))); });
  EXPECT_NE(negative.find("vertex index -1 out of range"), std::string::npos) << negative;
}

TEST(PlyLoader, NonFiniteCoordinateIsRejected) {
  TempDir dir;
  PlyData data;
  data.points[2].y = std::numeric_limits<float>::quiet_NaN();
  const std::string message =
      error_of([&] { (void)load_ply(dir.write("nan.ply", binary_ply(data))); });
  EXPECT_NE(message.find("vertex 2: non-finite coordinate"), std::string::npos) << message;
  data.points[2].y = std::numeric_limits<float>::infinity();
  EXPECT_NE(
      error_of([&] { (void)load_ply(dir.write("inf.ply", binary_ply(data))); }).find("non-finite"),
      std::string::npos);
  std::string ascii = ascii_ply(PlyData{});
  ascii[ascii.find("end_header\n") + 11] = 'n';  // "0.000000" -> "n.000000"
  EXPECT_NE(error_of([&] {
              (void)load_ply(dir.write("t.ply", ascii));
            }).find("t.ply:11: vertex 0: bad number"),
            std::string::npos);
}

TEST(PlyLoader, EmptyMeshAndBadHeadersAreRejected) {
  TempDir dir;
  PlyData data;
  data.faces.clear();
  EXPECT_NE(
      error_of([&] { (void)load_ply(dir.write("e.ply", binary_ply(data))); }).find("no triangles"),
      std::string::npos);
  EXPECT_NE(
      error_of([&] { (void)load_ply(dir.write("x.ply", "solid x\n")); }).find("not a PLY file"),
      std::string::npos);
  EXPECT_NE(
      error_of([&] {
        (void)load_ply(dir.write("f.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n"));
      }).find("unknown PLY format"),
      std::string::npos);
  EXPECT_NE(error_of([&] {
              (void)load_ply(dir.write("p.ply",
                                       "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\n"
                                       "property float y\nproperty float z\nend_header\n"));
            }).find("no \"element face\""),
            std::string::npos);
  EXPECT_NE(
      error_of([&] {
        (void)load_ply(dir.write(
            "q.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n"));
      }).find("q.ply:4: unknown property type"),
      std::string::npos);
}

TEST(PlyLoader, DropsDegenerateFaces) {
  TempDir dir;
  PlyData data;
  data.points.push_back({2, 0, 0});
  data.faces = {{0, 1, 2}, {0, 1, 4}, {0, 0, 1}, {2, 1, 0}};
  const Mesh mesh = load_ply(dir.write("d.ply", binary_ply(data))).mesh;
  EXPECT_EQ(mesh.dropped_degenerate, 2u);
  EXPECT_EQ(mesh.source_index, (std::vector<std::uint32_t>{0, 3}));
}

TEST(PlyLoader, SkipsOtherElementsAndProperties) {
  TempDir dir;
  const auto ply =
      dir.write("extra.ply",
                "ply\nformat ascii 1.0\nelement material 1\nproperty uchar red\n"
                "property list uchar float weights\n"
                "element vertex 3\nproperty double z\nproperty float y\nproperty short x\n"
                "element face 1\nproperty uchar flags\nproperty list ushort uint vertex_index\n"
                "end_header\n7 2 0.5 0.5\n0 0 0\n0 0 1\n0 1 0\n9 3 0 1 2\n");
  const Mesh mesh = load_ply(ply).mesh;
  EXPECT_EQ(mesh.positions[1], glm::vec3(1, 0, 0));
  EXPECT_EQ(mesh.positions[2], glm::vec3(0, 1, 0));
  EXPECT_EQ(mesh.triangles.size(), 1u);
}

TEST(ObjLoader, NormalsOfAnyFiniteLengthKeepTheirDirection) {
  // Squared lengths beyond the float range or below its normal numbers.
  TempDir dir;
  const Mesh mesh = load_obj(dir.write("n.obj",
                                       "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
                                       "vn 1e20 0 0\nvn 0 1e-25 0\nvn 3e38 0 3e38\n"
                                       "f 1//1 2//2 3//3\n"))
                        .mesh;
  ASSERT_EQ(mesh.triangles.size(), 1u);
  EXPECT_EQ(mesh.normals[mesh.triangles[0].x], glm::vec3(1, 0, 0));
  EXPECT_EQ(mesh.normals[mesh.triangles[0].y], glm::vec3(0, 1, 0));
  const glm::vec3 diagonal = mesh.normals[mesh.triangles[0].z];
  EXPECT_FLOAT_EQ(diagonal.x, 0.70710678f);
  EXPECT_EQ(diagonal.y, 0.0f);
  EXPECT_FLOAT_EQ(diagonal.z, 0.70710678f);
}

// --- glTF -------------------------------------------------------------------------------

TEST(GltfLoader, BakesNodeTransformsAndInstances) {
  TempDir dir;
  const MeshFile file = load_gltf(dir.write("two.gltf", test::small_gltf()));
  const Mesh& mesh = file.mesh;
  EXPECT_EQ(mesh.triangles.size() + mesh.dropped_degenerate, 4u);
  ASSERT_EQ(mesh.triangles.size(), 2u);
  EXPECT_EQ(mesh.source_index, (std::vector<std::uint32_t>{0, 2}));
  EXPECT_EQ(mesh.positions[mesh.triangles[0].y], glm::vec3(11, 0, 0));
  EXPECT_EQ(mesh.positions[mesh.triangles[1].z], glm::vec3(0, 2, 5));
  EXPECT_EQ(file.materials.at(mesh.material_ids[0]).diffuse, glm::vec3(0.2f, 0.4f, 0.6f));
}

TEST(GltfLoader, TexturesAreNotReadAndThatIsSaid) {
  TempDir dir;
  std::string gltf = test::small_gltf();
  const std::string factor = R"("baseColorFactor": [0.2, 0.4, 0.6, 1.0])";
  ASSERT_NE(gltf.find(factor), std::string::npos);
  gltf.replace(gltf.find(factor), factor.size(), factor + R"(, "baseColorTexture": {"index": 0})");
  const std::string materials = R"("materials": [)";
  gltf.replace(gltf.find(materials), materials.size(),
               R"("images": [{"uri": "absent.png"}], "textures": [{"source": 0}], "materials": [)");
  const test::CapturedLog log;
  const MeshFile file = load_gltf(dir.write("tex.gltf", gltf));  // the missing image is no error
  EXPECT_EQ(file.materials.at(file.mesh.material_ids[0]).diffuse, glm::vec3(0.2f, 0.4f, 0.6f));
  EXPECT_EQ(log.count("tex.gltf: 1 of 1 materials have a base colour texture; rtc draws their colour factors only"), 1u);
  const test::CapturedLog quiet;
  (void)load_gltf(dir.write("plain.gltf", test::small_gltf()));
  EXPECT_EQ(quiet.count("texture"), 0u);
}

TEST(GltfLoader, AlphaOutsideZeroToOneIsClampedWithAWarning) {
  TempDir dir;
  std::string gltf = test::small_gltf();
  const std::string factor = R"("baseColorFactor": [0.2, 0.4, 0.6, 1.0])";
  ASSERT_NE(gltf.find(factor), std::string::npos);
  gltf.replace(gltf.find(factor), factor.size(), R"("baseColorFactor": [0.2, 0.4, 0.6, -3])");
  const test::CapturedLog log;
  const MeshFile file = load_gltf(dir.write("alpha.gltf", gltf));
  EXPECT_EQ(file.materials.at(file.mesh.material_ids[0]).opacity, 0.0f);
  EXPECT_EQ(log.count("alpha.gltf: material \"default\" baseColorFactor alpha -3 is outside [0, 1]: taken as 0"), 1u);
}

TEST(GltfLoader, RotationsAreUnitQuaternions) {
  TempDir dir;
  std::string gltf = test::small_gltf();
  const std::string node = R"({"mesh": 0, "translation": [10, 0, 0]})";
  ASSERT_NE(gltf.find(node), std::string::npos);
  // 90 degrees about z, written with length sqrt(2): taken as the unit quaternion (a plain
  // mat4_cast would also scale and skew), with a warning.
  gltf.replace(gltf.find(node), node.size(), R"({"mesh": 0, "translation": [10, 0, 0], "rotation": [0, 0, 1, 1]})");
  const test::CapturedLog log;
  const Mesh mesh = load_gltf(dir.write("turn.gltf", gltf)).mesh;
  ASSERT_EQ(mesh.triangles.size(), 2u);
  const glm::vec3 p = mesh.positions[mesh.triangles[0].y];  // (1, 0, 0) before the node's transform
  EXPECT_NEAR(p.x, 10.0f, 1e-6f);
  EXPECT_NEAR(p.y, 1.0f, 1e-6f);
  EXPECT_NEAR(p.z, 0.0f, 1e-6f);
  EXPECT_EQ(log.count("turn.gltf: node 0: rotation (0, 0, 1, 1) is not a unit quaternion (length 1.41421); normalised"), 1u);
  gltf.replace(gltf.find("[0, 0, 1, 1]"), 12, "[0, 0, 0, 0]");
  const std::string message = error_of([&] { (void)load_gltf(dir.write("zero.gltf", gltf)); });
  EXPECT_NE(message.find("zero.gltf: glTF: node 0: rotation must be a non-zero, finite quaternion"), std::string::npos)
      << message;
}

TEST(GltfLoader, PositionsBeyondTheFloatRangeAreRejected) {
  TempDir dir;
  std::string gltf = test::small_gltf();
  const std::string matrix = "[2,0,0,0, 0,2,0,0, 0,0,2,0, 0,0,5,1]";
  // Scale and translation are floats, but together they put vertex 1 at x = 6e38.
  gltf.replace(gltf.find(matrix), matrix.size(),
               "[3e38,0,0,0, 0,3e38,0,0, 0,0,3e38,0, 3e38,0,0,1]");
  const std::string message = error_of([&] { (void)load_gltf(dir.write("far.gltf", gltf)); });
  EXPECT_NE(message.find("far.gltf: glTF: mesh"), std::string::npos) << message;
  EXPECT_NE(message.find("outside the float range"), std::string::npos) << message;
}

// An accessor reaching past its buffer view: Debian's Assimp read past the buffer here (a heap
// overflow found by fuzz_gltf, tests/fuzz/regressions/gltf); every range is checked now.
TEST(GltfLoader, AccessorBeyondItsBufferViewIsRejected) {
  TempDir dir;
  std::string gltf = test::small_gltf();
  const std::string count = R"("count": 3, "type": "VEC3")";
  gltf.replace(gltf.find(count), count.size(), R"("count": 30, "type": "VEC3")");
  std::string message = error_of([&] { (void)load_gltf(dir.write("long.gltf", gltf)); });
  EXPECT_NE(message.find("long.gltf: glTF: mesh"), std::string::npos) << message;
  EXPECT_NE(message.find("30 elements from byte 0 exceed buffer view 0 of 36 bytes"), std::string::npos) << message;

  gltf = test::small_gltf();
  const std::string view = R"({"buffer": 0, "byteOffset": 36, "byteLength": 12})";
  gltf.replace(gltf.find(view), view.size(), R"({"buffer": 0, "byteOffset": 40, "byteLength": 12})");
  message = error_of([&] { (void)load_gltf(dir.write("view.gltf", gltf)); });
  EXPECT_NE(message.find("buffer view 1 (bytes 40 + 12) exceeds its buffer of 48 bytes"), std::string::npos) << message;
}

TEST(GltfLoader, NodesMustFormATree) {
  TempDir dir;
  std::string gltf = test::small_gltf();
  const std::string nodes = R"({"mesh": 0, "translation": [10, 0, 0]})";
  // Node 0 lists node 1 as its child, but node 1 is also a root of the scene.
  gltf.replace(gltf.find(nodes), nodes.size(), R"({"mesh": 0, "translation": [10, 0, 0], "children": [1]})");
  const std::string message = error_of([&] { (void)load_gltf(dir.write("dag.gltf", gltf)); });
  EXPECT_NE(message.find("dag.gltf: glTF: node 1 is a scene root and another node's child"), std::string::npos)
      << message;
  // A node that lists itself: said as such (it was "has more than one parent").
  gltf = test::small_gltf();
  gltf.replace(gltf.find(nodes), nodes.size(), R"({"mesh": 0, "translation": [10, 0, 0], "children": [0]})");
  const std::string self = error_of([&] { (void)load_gltf(dir.write("self.gltf", gltf)); });
  EXPECT_NE(self.find("self.gltf: glTF: node 0 is its own child"), std::string::npos) << self;
}

TEST(GltfLoader, StripsAndFansFollowTheSpecification) {
  TempDir dir;
  // Four vertices of a unit square, no indices: a strip gives (0 1 2) (1 3 2), a fan (1 2 0) (2 3 0).
  std::string buffer;
  for (const float v : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f, 1.f, 1.f, 0.f}) test::append_le(buffer, v);
  for (const int mode : {5, 6}) {
    const std::string gltf =
        R"({"asset": {"version": "2.0"}, "nodes": [{"mesh": 0}],
      "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": )" +
        std::to_string(mode) + R"(}]}],
      "buffers": [{"byteLength": 48, "uri": "data:application/octet-stream;base64,)" +
        test::base64(buffer) + R"("}],
      "bufferViews": [{"buffer": 0, "byteLength": 48}],
      "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                     "min": [0, 0, 0], "max": [1, 1, 0]}]})";
    const Mesh mesh = load_gltf(dir.write("square.gltf", gltf)).mesh;
    ASSERT_EQ(mesh.triangles.size(), 2u) << "mode " << mode;
    const auto at = [&](std::size_t t, int k) { return mesh.positions[mesh.triangles[t][k]]; };
    if (mode == 5) {
      EXPECT_EQ(at(1, 0), glm::vec3(1, 0, 0));
      EXPECT_EQ(at(1, 1), glm::vec3(1, 1, 0));
      EXPECT_EQ(at(1, 2), glm::vec3(0, 1, 0));
    } else {
      EXPECT_EQ(at(0, 2), glm::vec3(0, 0, 0));
      EXPECT_EQ(at(1, 0), glm::vec3(0, 1, 0));
      EXPECT_EQ(at(1, 1), glm::vec3(1, 1, 0));
    }
  }
}

// glTF 2.0, section 3.2: a major version other than 2, or a minVersion above 2.0, must not be
// loaded (TinyGLTF took both); 2.1 is a 2.x asset and loads.
TEST(GltfLoader, VersionIsChecked) {
  TempDir dir;
  const auto with_asset = [](const std::string& asset) {
    std::string gltf = test::small_gltf();
    const std::string old = R"("asset": {"version": "2.0"})";
    gltf.replace(gltf.find(old), old.size(), "\"asset\": " + asset);
    return gltf;
  };
  // The error with the temporary folder taken off the file's name.
  const auto error = [&](const std::string& name, const std::string& asset) {
    const std::string message = error_of([&] { (void)load_gltf(dir.write(name, with_asset(asset))); });
    return message.substr(message.rfind('/') + 1);
  };
  EXPECT_EQ(load_gltf(dir.write("v21.gltf", with_asset(R"({"version": "2.1"})"))).mesh.triangles.size(), 2u);
  EXPECT_EQ(load_gltf(dir.write("min20.gltf", with_asset(R"({"version": "2.1", "minVersion": "2.0"})")))
                .mesh.triangles.size(),
            2u);
  EXPECT_EQ(error("v3.gltf", R"({"version": "3.0"})"),
            "v3.gltf: glTF: version 3.0 is not supported (rtc reads glTF 2.x)");
  EXPECT_EQ(error("v1.gltf", R"({"version": "1.0"})"),
            "v1.gltf: glTF: version 1.0 is not supported (rtc reads glTF 2.x)");
  EXPECT_EQ(error("two.gltf", R"({"version": "two"})"),
            "two.gltf: glTF: asset.version 'two' is not of the form <major>.<minor>");
  EXPECT_EQ(error("min21.gltf", R"({"version": "2.1", "minVersion": "2.1"})"),
            "min21.gltf: glTF: asset.minVersion 2.1 is above 2.0, the version rtc reads");
}

// A buffer URI naming a folder is named as one (TinyGLTF's own message was "File not found").
TEST(GltfLoader, BufferUriNamingAFolderIsNamed) {
  TempDir dir;
  (void)dir.write("sub/keep", "x");
  std::string gltf = test::small_gltf();
  const std::string uri = R"("uri": "data:)";
  gltf.replace(gltf.find(uri), gltf.find('"', gltf.find(uri) + uri.size()) + 1 - gltf.find(uri), R"("uri": "sub")");
  const std::string message = error_of([&] { (void)load_gltf(dir.write("folder.gltf", gltf)); });
  EXPECT_NE(message.find("folder.gltf: glTF: "), std::string::npos) << message;
  EXPECT_NE(message.find("sub: cannot read the file (a directory?)"), std::string::npos) << message;
}

TEST(GltfLoader, GarbageIsRejected) {
  TempDir dir;
  EXPECT_NE(error_of([&] {
              (void)load_gltf(dir.write("bad.glb", "glTF\x02\0\0\0garbage"));
            }).find("bad.glb"),
            std::string::npos);
  EXPECT_NE(
      error_of([&] { (void)load_gltf(dir.write("bad.gltf", "{\"asset\": 3}")); }).find("bad.gltf"),
      std::string::npos);
}

}  // namespace
}  // namespace rtc
