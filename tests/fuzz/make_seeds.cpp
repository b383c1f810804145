// Writes the binary seeds of the fuzz corpus (tests/fuzz/make_corpus.py calls it): every
// protocol message type (as a stream and as type byte + payload), scenes as wire bytes, and
// tile pixels in every wire format and compression. Usage: fuzz_make_seeds CORPUS_DIR SCENE...
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "common/base/error.h"
#include "common/image/image.h"
#include "common/image/pixel_format.h"
#include "common/scene/load.h"
#include "common/scene/serialize.h"
#include "protocol/message.h"

namespace {

namespace fs = std::filesystem;
namespace proto = rtc::protocol;

void write(const fs::path& path, const std::vector<std::uint8_t>& bytes) {
  fs::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw rtc::Error(path.string() + ": cannot write");
}

std::vector<proto::Message> sample_messages() {
  proto::Digest digest{};
  for (std::size_t i = 0; i < digest.size(); ++i) digest[i] = static_cast<std::uint8_t>(i * 7 + 1);
  proto::TileResult result{3, 2, 5, 32, 64, 32, 32, 0, 0, 0, 4096, 1234, 1024, 2048, 16, {1, 2, 3, 4, 5, 6, 7, 8}};
  proto::TileMarks marks{3, 5, true, {1, 2, 40, 41, 900}, {7, 8, 9}};
  proto::MarkGrid grid;
  grid.lo[0] = -1.5;
  grid.hi[0] = 2.5;
  grid.lo[1] = 0;
  grid.hi[1] = 4;
  grid.lo[2] = -3;
  grid.hi[2] = 3;
  grid.dims[0] = 16;
  grid.dims[1] = 16;
  grid.dims[2] = 24;
  return {
      proto::Challenge{digest, true, "rtc 0.1.0 (clang, fuzz)"},
      proto::Hello{proto::kVersion, 16, 8, "avx2", "rtc 0.1.0", "worker-a"},
      proto::Auth{digest},
      proto::Welcome{7, 1000, 18},
      proto::SceneOffer{digest, 123456, "office_mover"},
      proto::SceneRequest{digest, true},
      proto::SceneChunk{digest, 1 << 20, {9, 8, 7, 6, 5, 4, 3, 2, 1}},
      proto::SceneReady{digest, 42},
      proto::FrameSettings{3, 2, 0, 1, 0},
      proto::TileAssign{3, 2, 5, 32, 64, 32, 32},
      result,
      proto::Heartbeat{11, 123456789},
      proto::HeartbeatAck{11, 123456789},
      proto::ErrorMessage{proto::ErrorCode::AuthFailed, "authentication failed"},
      proto::Goodbye{"master shutting down"},
      proto::ProbeRequest{4096},
      proto::ProbeData{std::vector<std::uint8_t>(64, 0xab)},
      proto::FrameEnd{3},
      grid,
      marks,
  };
}

}  // namespace

int main(int argc, char** argv) try {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s CORPUS_DIR [SCENE...]\n", argv[0]);
    return 2;
  }
  const fs::path corpus(argv[1]);
  int n = 0;
  std::vector<std::uint8_t> stream;
  for (const proto::Message& m : sample_messages()) {
    const std::vector<std::uint8_t> bytes = proto::encode(m);
    const std::string name = proto::type_name(static_cast<std::uint16_t>(proto::type_of(m)));
    write(corpus / "protocol" / ("stream-" + name), bytes);
    // type byte + payload: the second reading of protocol_fuzz.cpp
    std::vector<std::uint8_t> typed{static_cast<std::uint8_t>(proto::type_of(m))};
    typed.insert(typed.end(), bytes.begin() + proto::kHeaderSize, bytes.end());
    write(corpus / "protocol" / ("payload-" + name), typed);
    stream.insert(stream.end(), bytes.begin(), bytes.end());
    n += 2;
  }
  write(corpus / "protocol" / "stream-all", stream);
  ++n;

  for (int i = 2; i < argc; ++i) {
    const rtc::Scene scene = rtc::load_scene(argv[i]);
    write(corpus / "scene_bytes" / fs::path(argv[i]).filename(), rtc::serialize_scene(scene));
    ++n;
  }

  // A 4x3 tile with depth and normals, in every format and compression (rgba8 has no channels).
  rtc::Image tile(4, 3, true, true);
  for (std::size_t i = 0; i < tile.rgba.size(); ++i) tile.rgba[i] = static_cast<float>(i % 17) / 16.0f;
  for (std::size_t i = 0; i < tile.depth.size(); ++i) tile.depth[i] = 1.0f + static_cast<float>(i);
  for (std::size_t i = 0; i < tile.normal.size(); ++i) tile.normal[i] = (i % 3 == 1) ? 1.0f : 0.0f;
  for (std::uint8_t f = 1; f <= 3; ++f) {
    for (std::uint8_t c = 0; c < 3; ++c) {
      const auto format = *rtc::wire_format_from_byte(f);
      const auto compression = *rtc::compression_from_byte(c);
      const std::uint8_t channels = format == rtc::WireFormat::Rgba8 ? 0 : rtc::kChannelDepth | rtc::kChannelNormal;
      std::vector<std::uint8_t> pixels;
      const auto raw = static_cast<std::uint32_t>(rtc::encode_tile_pixels(tile, format, compression, channels, pixels));
      // tile_pixels_fuzz.cpp's header: width - 1, height - 1, format, compression, channels, raw size
      std::vector<std::uint8_t> seed{3, 2, f, c, channels, static_cast<std::uint8_t>(raw), static_cast<std::uint8_t>(raw >> 8),
                                     static_cast<std::uint8_t>(raw >> 16), static_cast<std::uint8_t>(raw >> 24)};
      seed.insert(seed.end(), pixels.begin(), pixels.end());
      write(corpus / "tile_pixels" / (std::string(rtc::wire_format_name(format)) + "-" +
                                      std::string(rtc::compression_name(compression))),
            seed);
      ++n;
    }
  }
  std::printf("fuzz_make_seeds: wrote %d seeds under %s\n", n, corpus.c_str());
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "fuzz_make_seeds: %s\n", e.what());
  return 1;
}
