// Helpers for the scene tests: a temporary folder for generated files, error and warning
// capture and the location of the shared scene pack.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cstring>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <unistd.h>

#include <spdlog/sinks/ringbuffer_sink.h>
#include <spdlog/spdlog.h>

#include "common/base/error.h"
#include "common/scene/scene.h"

namespace rtc::test {

/// A fresh folder under the system temp directory, removed with its contents on destruction.
class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    path_ = std::filesystem::temp_directory_path() /
            ("rtc_scene_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  /// Writes `bytes` to `name` inside the folder (sub-folders are created) and returns its path.
  std::filesystem::path write(const std::string& name, std::string_view bytes) const {
    const std::filesystem::path file = path_ / name;
    std::filesystem::create_directories(file.parent_path());
    std::ofstream out(file, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return file;
  }
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

/// The message of the rtc::Error that `f` throws; "" (and a test failure) when it throws
/// nothing. Any other exception type fails the test too.
template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const rtc::Error& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected rtc::Error, got another exception: " << e.what();
    return e.what();
  }
  ADD_FAILURE() << "expected rtc::Error, nothing was thrown";
  return "";
}

/// Collects what the default logger logs while it lives (the last 256 messages).
class CapturedLog {
 public:
  CapturedLog() : sink_(std::make_shared<spdlog::sinks::ringbuffer_sink_mt>(256)) {
    sink_->set_pattern("%l: %v");
    spdlog::default_logger()->sinks().push_back(sink_);
  }
  ~CapturedLog() {
    auto& sinks = spdlog::default_logger()->sinks();
    sinks.erase(std::remove(sinks.begin(), sinks.end(), sink_), sinks.end());
  }
  CapturedLog(const CapturedLog&) = delete;
  CapturedLog& operator=(const CapturedLog&) = delete;

  /// The messages, one per element, as "level: message".
  [[nodiscard]] std::vector<std::string> lines() const { return sink_->last_formatted(); }
  /// How many messages contain `text`.
  [[nodiscard]] std::size_t count(std::string_view text) const {
    std::size_t n = 0;
    for (const std::string& line : lines()) n += line.find(text) != std::string::npos ? 1 : 0;
    return n;
  }

 private:
  std::shared_ptr<spdlog::sinks::ringbuffer_sink_mt> sink_;
};

/// The scene pack folder (RTC_SHARED_SCENES), or "" when it is absent.
/// A scene with one material and one mesh holding one triangle, placed at the origin.
inline Scene one_triangle_scene() {
  Scene scene;
  scene.materials.emplace_back();
  Mesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  mesh.triangles = {{0, 1, 2}};
  mesh.material_ids = {0};
  mesh.source_index = {0};
  scene.meshes.push_back(mesh);
  return scene;
}

inline std::filesystem::path scene_pack() {
  const std::filesystem::path pack = RTC_SHARED_SCENES;
  std::error_code ec;
  return std::filesystem::is_directory(pack, ec) ? pack : std::filesystem::path();
}

/// Little-endian bytes of a trivially copyable value, appended to `out`.
template <typename T>
void append_le(std::string& out, T value) {
  static_assert(std::endian::native == std::endian::little, "tests assume a little-endian host");
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  out.append(bytes, sizeof(T));
}

inline std::string base64(const std::string& bytes) {
  static const char* const kTable =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  std::size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const auto n = (std::uint32_t(std::uint8_t(bytes[i])) << 16) |
                   (std::uint32_t(std::uint8_t(bytes[i + 1])) << 8) | std::uint8_t(bytes[i + 2]);
    for (int k = 3; k >= 0; --k) out += kTable[(n >> (6 * k)) & 63];
  }
  if (i < bytes.size()) {
    std::uint32_t n = std::uint32_t(std::uint8_t(bytes[i])) << 16;
    if (i + 1 < bytes.size()) n |= std::uint32_t(std::uint8_t(bytes[i + 1])) << 8;
    out += kTable[(n >> 18) & 63];
    out += kTable[(n >> 12) & 63];
    out += i + 1 < bytes.size() ? kTable[(n >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

/// One triangle plus one degenerate (repeated index), instanced by two nodes.
inline std::string small_gltf() {
  std::string buffer;
  for (const float v : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) append_le(buffer, v);
  for (const std::uint16_t i : {0, 1, 2, 0, 1, 1}) append_le(buffer, i);
  return R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1]}],
  "nodes": [{"mesh": 0, "translation": [10, 0, 0]},
            {"mesh": 0, "matrix": [2,0,0,0, 0,2,0,0, 0,0,2,0, 0,0,5,1]}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
  "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.4, 0.6, 1.0]}}],
  "buffers": [{"byteLength": 48, "uri": "data:application/octet-stream;base64,)" +
         base64(buffer) + R"("}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                  {"buffer": 0, "byteOffset": 36, "byteLength": 12}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                 "min": [0, 0, 0], "max": [1, 1, 0]},
                {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}]})";
}

}  // namespace rtc::test

/// Skips the current test with a message when the shared scene pack is not there.
#define RTC_REQUIRE_SCENE_PACK()                                                       \
  do {                                                                                 \
    if (::rtc::test::scene_pack().empty()) {                                           \
      GTEST_SKIP() << "scene pack not found at " << RTC_SHARED_SCENES << "; skipping"; \
    }                                                                                  \
  } while (0)
