// Tile pixels on the wire: the documented bytes of each format, exact round trips (float bits,
// half after rounding, rgba8 PNG-identical), lossless lz4 / zstd, and hostile input rejected
// with a reason instead of a crash.
#include "common/image/pixel_format.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <fmt/format.h>

namespace rtc {
namespace {

using Bytes = std::vector<std::uint8_t>;

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
constexpr std::uint8_t kBoth = kChannelDepth | kChannelNormal;
constexpr WireFormat kFormats[] = {WireFormat::Rgba8, WireFormat::Half, WireFormat::Float};
constexpr Compression kCompressions[] = {Compression::None, Compression::Lz4, Compression::Zstd};

std::uint32_t bits(float v) { return std::bit_cast<std::uint32_t>(v); }

std::string hex(float v) { return fmt::format("{:a} (0x{:08x})", v, bits(v)); }

bool has_substr(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

Bytes encode(const Image& tile, WireFormat format, Compression compression, std::uint8_t channels) {
  Bytes out;
  const std::size_t raw = encode_tile_pixels(tile, format, compression, channels, out);
  EXPECT_EQ(raw, raw_tile_bytes(tile.width, tile.height, format, channels));
  return out;
}

/// decode_tile_pixels with the raw size the tile should have; fails the test on a rejection.
Image decode(const Bytes& bytes, int width, int height, WireFormat format, Compression compression,
             std::uint8_t channels) {
  Image out;
  const auto raw = static_cast<std::uint32_t>(raw_tile_bytes(width, height, format, channels));
  const std::string problem =
      decode_tile_pixels(bytes, raw, width, height, format, compression, channels, out);
  EXPECT_EQ(problem, "");
  return out;
}

/// The 2x1 tile of the byte-level vectors: (0, 0.5, 1, 1) and (0.25, 2, -1, 0.5), depth 1.5
/// and +inf, normals (0, 0, 1) and (0, -1, 0).
Image two_pixels() {
  Image tile(2, 1, true, true);
  tile.rgba = {0.0f, 0.5f, 1.0f, 1.0f, 0.25f, 2.0f, -1.0f, 0.5f};
  tile.depth = {1.5f, kInf};
  tile.normal = {0.0f, 0.0f, 1.0f, 0.0f, -1.0f, 0.0f};
  return tile;
}

/// A rendered-looking tile: smooth shading, a background corner, an edge, a little noise.
Image realistic_tile(int width, int height, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> noise(-0.002f, 0.002f);
  Image tile(width, height, true, true);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const auto i = static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                     static_cast<std::size_t>(x);
      float* p = tile.pixel(x, y);
      const bool background = x + y < width / 4;
      const float shade =
          background ? 0.0f : 0.2f + 0.6f * static_cast<float>(x) / static_cast<float>(width);
      p[0] = background ? 0.0f : shade + noise(rng);
      p[1] = background ? 0.0f : 0.8f * shade + noise(rng);
      p[2] = background ? 0.0f : (x > width / 2 ? 0.9f : 0.3f) * shade;
      p[3] = 1.0f;
      tile.depth[i] = background
                          ? kInf
                          : 10.0f + 0.01f * static_cast<float>(y) + 0.003f * static_cast<float>(x);
      if (!background) {
        const float nx = static_cast<float>(x - width / 2) / static_cast<float>(width);
        const float nz = std::sqrt(1.0f - nx * nx);
        tile.normal[3 * i + 0] = nx;
        tile.normal[3 * i + 1] = 0.0f;
        tile.normal[3 * i + 2] = nz;
      }
    }
  }
  return tile;
}

// ---- names and sizes -----------------------------------------------------------------------

TEST(PixelFormat, NamesParseBackAndBytesAreValidated) {
  for (const WireFormat f : kFormats) EXPECT_EQ(parse_wire_format(wire_format_name(f)), f);
  for (const Compression c : kCompressions) EXPECT_EQ(parse_compression(compression_name(c)), c);
  EXPECT_EQ(wire_format_name(WireFormat::Rgba8), "rgba8");
  EXPECT_EQ(compression_name(Compression::Zstd), "zstd");
  EXPECT_EQ(parse_wire_format("RGBA8"), std::nullopt);
  EXPECT_EQ(parse_compression("gzip"), std::nullopt);
  EXPECT_EQ(wire_format_from_byte(0), std::nullopt);
  EXPECT_EQ(wire_format_from_byte(2), WireFormat::Half);
  EXPECT_EQ(wire_format_from_byte(4), std::nullopt);
  EXPECT_EQ(compression_from_byte(0), Compression::None);
  EXPECT_EQ(compression_from_byte(2), Compression::Zstd);
  EXPECT_EQ(compression_from_byte(3), std::nullopt);
  EXPECT_EQ(compression_from_byte(255), std::nullopt);
}

TEST(PixelFormat, RawTileBytesCountsEveryChannel) {
  EXPECT_EQ(raw_tile_bytes(2, 1, WireFormat::Rgba8, 0), 8u);
  EXPECT_EQ(raw_tile_bytes(2, 1, WireFormat::Half, 0), 16u);
  EXPECT_EQ(raw_tile_bytes(2, 1, WireFormat::Float, 0), 32u);
  EXPECT_EQ(raw_tile_bytes(2, 1, WireFormat::Half, kChannelDepth), 24u);
  EXPECT_EQ(raw_tile_bytes(2, 1, WireFormat::Half, kBoth), 2u * (8 + 4 + 6));
  EXPECT_EQ(raw_tile_bytes(2, 1, WireFormat::Float, kBoth), 2u * (16 + 4 + 12));
  EXPECT_EQ(raw_tile_bytes(64, 64, WireFormat::Float, kChannelNormal), 64u * 64 * 28);
  EXPECT_EQ(raw_tile_bytes(2, 1, WireFormat::Rgba8, kChannelDepth), 0u) << "not a tile";
  EXPECT_EQ(raw_tile_bytes(2, 1, WireFormat::Half, 4), 0u) << "unknown channel bit";
  EXPECT_EQ(raw_tile_bytes(-1, 1, WireFormat::Half, 0), 0u);
}

// ---- byte-level vectors --------------------------------------------------------------------

TEST(PixelFormat, Rgba8BytesAreSrgbCodesAndLinearAlpha) {
  // sRGB(0.5) = 0.7354 -> 187.5 -> 188; sRGB(0.25) = 0.5371 -> 136.96 -> 137; alpha 0.5 ->
  // 0.5 * 255 + 0.5 = 128 truncated; 2 clamps to 255 and -1 to 0.
  Image tile = two_pixels();
  const Bytes expected = {0x00, 0xbc, 0xff, 0xff, 0x89, 0xff, 0x00, 0x80};
  EXPECT_EQ(encode(tile, WireFormat::Rgba8, Compression::None, 0), expected);
}

TEST(PixelFormat, HalfBytesAreRgbaThenFloatDepthThenHalfNormals) {
  const Bytes expected = {
      0x00, 0x00, 0x00, 0x38, 0x00, 0x3c, 0x00, 0x3c,  // 0, 0.5, 1, 1
      0x00, 0x34, 0x00, 0x40, 0x00, 0xbc, 0x00, 0x38,  // 0.25, 2, -1, 0.5
      0x00, 0x00, 0xc0, 0x3f, 0x00, 0x00, 0x80, 0x7f,  // depth 1.5, +inf (f32)
      0x00, 0x00, 0x00, 0x00, 0x00, 0x3c,              // normal (0, 0, 1)
      0x00, 0x00, 0x00, 0xbc, 0x00, 0x00,              // normal (0, -1, 0)
  };
  EXPECT_EQ(encode(two_pixels(), WireFormat::Half, Compression::None, kBoth), expected);
  const Bytes depth_only(expected.begin(), expected.begin() + 24);
  EXPECT_EQ(encode(two_pixels(), WireFormat::Half, Compression::None, kChannelDepth), depth_only);
  Bytes normal_only(expected.begin(), expected.begin() + 16);
  normal_only.insert(normal_only.end(), expected.begin() + 24, expected.end());
  EXPECT_EQ(encode(two_pixels(), WireFormat::Half, Compression::None, kChannelNormal), normal_only);
}

TEST(PixelFormat, FloatBytesAreTheFloatBits) {
  const Bytes expected = {
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x3f,                          // 0, 0.5
      0x00, 0x00, 0x80, 0x3f, 0x00, 0x00, 0x80, 0x3f,                          // 1, 1
      0x00, 0x00, 0x80, 0x3e, 0x00, 0x00, 0x00, 0x40,                          // 0.25, 2
      0x00, 0x00, 0x80, 0xbf, 0x00, 0x00, 0x00, 0x3f,                          // -1, 0.5
      0x00, 0x00, 0xc0, 0x3f, 0x00, 0x00, 0x80, 0x7f,                          // depth 1.5, +inf
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x80, 0x3f,  // (0, 0, 1)
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x80, 0xbf, 0x00, 0x00, 0x00, 0x00,  // (0, -1, 0)
  };
  EXPECT_EQ(encode(two_pixels(), WireFormat::Float, Compression::None, kBoth), expected);
}

TEST(PixelFormat, EncodeAppendsToWhatIsAlreadyThere) {
  Bytes out = {1, 2, 3};
  const std::size_t raw =
      encode_tile_pixels(two_pixels(), WireFormat::Rgba8, Compression::None, 0, out);
  EXPECT_EQ(raw, 8u);
  ASSERT_EQ(out.size(), 11u);
  EXPECT_EQ(out[0], 1);
  EXPECT_EQ(out[3], 0x00);
  EXPECT_EQ(out[10], 0x80);
}

// ---- exact round trips ---------------------------------------------------------------------

/// Values that catch sign, rounding and special cases.
std::vector<float> special_values() {
  std::vector<float> v = {0.0f,     -0.0f,    1.0f,       -1.0f,   0.5f,         2.0f,  65504.0f,
                          65519.0f, 65520.0f, 1e9f,       -1e9f,   kInf,         -kInf, kNan,
                          1e-5f,    6e-8f,    1e-40f,     -1e-40f, 0.1f,         0.3f,  1.0f / 3.0f,
                          0.99999f, 1.00001f, 0.0031308f, 1e-4f,   3.0517578e-5f};
  v.push_back(std::bit_cast<float>(0x7fc12345u));  // NaN with a payload
  v.push_back(std::bit_cast<float>(0xff800001u));  // signalling-pattern NaN, negative
  for (int i = -100; i <= 1100; ++i) v.push_back(static_cast<float>(i) / 1000.0f);
  for (int code = 0; code < 256; ++code) {
    v.push_back(srgb8_to_linear(static_cast<std::uint8_t>(code)));
    v.push_back(static_cast<float>(code) / 255.0f);
  }
  return v;
}

/// A tile whose RGBA, depth and normal floats are `values` (cycled).
Image tile_of(const std::vector<float>& values) {
  const int width = 37;
  const int height = static_cast<int>((values.size() + 4 * width - 1) / (4 * width));
  Image tile(width, height, true, true);
  for (std::size_t i = 0; i < tile.rgba.size(); ++i) tile.rgba[i] = values[i % values.size()];
  for (std::size_t i = 0; i < tile.depth.size(); ++i) {
    tile.depth[i] = values[(7 * i + 3) % values.size()];
  }
  for (std::size_t i = 0; i < tile.normal.size(); ++i) {
    tile.normal[i] = values[(5 * i + 1) % values.size()];
  }
  return tile;
}

TEST(PixelFormat, FloatRoundTripKeepsEveryBit) {
  const Image tile = tile_of(special_values());
  for (const Compression c : kCompressions) {
    const Image back = decode(encode(tile, WireFormat::Float, c, kBoth), tile.width, tile.height,
                              WireFormat::Float, c, kBoth);
    EXPECT_EQ(image_hash(back), image_hash(tile)) << compression_name(c);
  }
}

TEST(PixelFormat, HalfRoundsToNearestEvenAndDecodesExactly) {
  struct Case {
    float in;
    std::uint16_t half_bits;
  };
  const Case cases[] = {
      {1.0f + 0x1p-11f, 0x3c00},             // halfway between 1 and 1 + 2^-10: to even (1)
      {1.0f + 3 * 0x1p-11f, 0x3c02},         // halfway between 0x3c01 and 0x3c02: to even
      {1.0f + 0x1p-11f + 0x1p-20f, 0x3c01},  // just above halfway: up
      {65504.0f, 0x7bff},                    // largest half
      {65519.0f, 0x7bff},                    // below halfway to 65536: down
      {65520.0f, 0x7c00},                    // halfway, to even: infinity
      {0x1p-25f, 0x0000},                    // halfway between 0 and the smallest subnormal: to 0
      {0x1.8p-25f, 0x0001},                  // above halfway: the smallest subnormal
      {-0.0f, 0x8000},
      {-kInf, 0xfc00},
  };
  for (const Case& c : cases) {
    Image tile(1, 1);
    tile.rgba = {c.in, 0.0f, 0.0f, 1.0f};
    const Bytes bytes = encode(tile, WireFormat::Half, Compression::None, 0);
    ASSERT_EQ(bytes.size(), 8u);
    EXPECT_EQ(bytes[0] | bytes[1] << 8, c.half_bits) << hex(c.in);
  }
  Image nan_tile(1, 1);
  nan_tile.rgba = {kNan, 0.0f, 0.0f, 1.0f};
  EXPECT_TRUE(std::isnan(decode(encode(nan_tile, WireFormat::Half, Compression::None, 0), 1, 1,
                                WireFormat::Half, Compression::None, 0)
                             .rgba[0]));

  // Every half decodes to the float of the same value: decoding then encoding gives the bits back.
  Image all(256, 256);
  Bytes raw(8 * 256 * 256);
  for (std::uint32_t h = 0; h < 65536; ++h) {
    for (int c = 0; c < 4; ++c) {
      raw[8 * h + 2 * c] = static_cast<std::uint8_t>(h);
      raw[8 * h + 2 * c + 1] = static_cast<std::uint8_t>(h >> 8);
    }
  }
  const Image decoded = decode(raw, 256, 256, WireFormat::Half, Compression::None, 0);
  EXPECT_EQ(decoded.rgba[4 * 0x3c00], 1.0f);
  EXPECT_EQ(decoded.rgba[4 * 0x0001], 0x1p-24f);
  EXPECT_EQ(decoded.rgba[4 * 0xfbff], -65504.0f);
  EXPECT_EQ(encode(decoded, WireFormat::Half, Compression::None, 0), raw);
}

TEST(PixelFormat, HalfRoundTripIsTheHalfRoundingOfEachValue) {
  const Image tile = tile_of(special_values());
  // Rounding to half twice changes nothing: the reference is encode(decode(encode(tile))).
  for (const Compression c : kCompressions) {
    const Bytes bytes = encode(tile, WireFormat::Half, c, kBoth);
    const Image back = decode(bytes, tile.width, tile.height, WireFormat::Half, c, kBoth);
    EXPECT_EQ(encode(back, WireFormat::Half, c, kBoth), bytes) << compression_name(c);
    for (std::size_t i = 0; i < tile.rgba.size(); ++i) {
      const float v = tile.rgba[i];
      if (std::isnan(v)) {
        ASSERT_TRUE(std::isnan(back.rgba[i])) << i;
      } else if (std::abs(v) <= 65504.0f) {
        // Within half's range: the nearest half, so within half an ulp (2^-11 relative, or
        // 2^-25 absolute among the subnormals).
        ASSERT_LE(std::abs(back.rgba[i] - v), std::max(std::abs(v) * 0x1p-11f, 0x1p-25f)) << hex(v);
      }
    }
    for (std::size_t i = 0; i < tile.depth.size(); ++i) {
      ASSERT_EQ(bits(back.depth[i]), bits(tile.depth[i])) << "depth is f32 in every format";
    }
  }
}

TEST(PixelFormat, Rgba8RoundTripGivesTheSamePngCodes) {
  const std::vector<float> values = special_values();
  Image tile(static_cast<int>(values.size()), 1);
  for (std::size_t i = 0; i < values.size(); ++i) {
    for (int c = 0; c < 4; ++c) {
      tile.rgba[4 * i + static_cast<std::size_t>(c)] =
          values[(i + static_cast<std::size_t>(c)) % values.size()];
    }
  }
  for (const Compression c : kCompressions) {
    const Image back =
        decode(encode(tile, WireFormat::Rgba8, c, 0), tile.width, 1, WireFormat::Rgba8, c, 0);
    for (std::size_t i = 0; i < tile.rgba.size(); ++i) {
      if (i % 4 == 3) {
        ASSERT_EQ(linear_to_unorm8(back.rgba[i]), linear_to_unorm8(tile.rgba[i]))
            << hex(tile.rgba[i]);
        ASSERT_EQ(back.rgba[i], static_cast<float>(linear_to_unorm8(tile.rgba[i])) / 255.0f);
      } else {
        ASSERT_EQ(linear_to_srgb8(back.rgba[i]), linear_to_srgb8(tile.rgba[i]))
            << hex(tile.rgba[i]);
        ASSERT_EQ(back.rgba[i], srgb8_to_linear(linear_to_srgb8(tile.rgba[i])));
      }
    }
  }
  for (int code = 0; code < 256; ++code) {
    EXPECT_EQ(linear_to_unorm8(static_cast<float>(code) / 255.0f), code);
  }
  EXPECT_EQ(linear_to_unorm8(kNan), 0);
  EXPECT_EQ(linear_to_unorm8(-0.5f), 0);
  EXPECT_EQ(linear_to_unorm8(kInf), 255);
  EXPECT_EQ(linear_to_unorm8(0.5f), 128);
  EXPECT_EQ(linear_to_unorm8(0.5f / 255.0f), 1) << "0.5 rounds up";
}

TEST(PixelFormat, Rgba8DecodedTileWritesTheSamePngFile) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / fmt::format("rtc_pixel_format_test_{}", ::getpid());
  std::filesystem::create_directories(dir);
  const std::vector<float> values = special_values();
  Image tile(41, static_cast<int>(values.size() / 41));
  for (std::size_t i = 0; i < tile.rgba.size(); ++i) tile.rgba[i] = values[(3 * i) % values.size()];
  const Image back = decode(encode(tile, WireFormat::Rgba8, Compression::Lz4, 0), tile.width,
                            tile.height, WireFormat::Rgba8, Compression::Lz4, 0);
  write_image(dir / "original.png", tile);
  write_image(dir / "decoded.png", back);
  const auto read = [](const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  const std::string original = read(dir / "original.png");
  EXPECT_FALSE(original.empty());
  EXPECT_TRUE(original == read(dir / "decoded.png")) << "PNG files differ";
  std::filesystem::remove_all(dir);
}

TEST(PixelFormat, CompressionIsLosslessOnARealisticTile) {
  const Image tile = realistic_tile(64, 64, 5);
  for (const WireFormat f : kFormats) {
    const std::uint8_t channels = f == WireFormat::Rgba8 ? 0 : kBoth;
    const Bytes plain = encode(tile, f, Compression::None, channels);
    const std::string reference = image_hash(decode(plain, 64, 64, f, Compression::None, channels));
    for (const Compression c : {Compression::Lz4, Compression::Zstd}) {
      SCOPED_TRACE(fmt::format("{} {}", wire_format_name(f), compression_name(c)));
      const Bytes packed = encode(tile, f, c, channels);
      EXPECT_LT(packed.size(), plain.size());
      EXPECT_EQ(encode(tile, f, c, channels), packed) << "deterministic";
      EXPECT_EQ(image_hash(decode(packed, 64, 64, f, c, channels)), reference);
    }
  }
}

TEST(PixelFormat, DecodingReusesAndReshapesTheOutputImage) {
  Image out = realistic_tile(8, 8, 1);
  const Image tile = two_pixels();
  const Bytes bytes = encode(tile, WireFormat::Float, Compression::None, 0);
  ASSERT_EQ(decode_tile_pixels(bytes, 32, 2, 1, WireFormat::Float, Compression::None, 0, out), "");
  EXPECT_EQ(out.width, 2);
  EXPECT_EQ(out.height, 1);
  EXPECT_EQ(out.rgba, tile.rgba);
  EXPECT_FALSE(out.has_depth());
  EXPECT_FALSE(out.has_normal());
}

// ---- rejections ----------------------------------------------------------------------------

struct Rejection {
  std::string reason;
  Image out;
};

Rejection reject(const Bytes& bytes, std::uint32_t raw_size, int width, int height,
                 WireFormat format, Compression compression, std::uint8_t channels) {
  Rejection r;
  r.out = two_pixels();
  r.reason =
      decode_tile_pixels(bytes, raw_size, width, height, format, compression, channels, r.out);
  EXPECT_NE(r.reason, "") << "accepted";
  EXPECT_EQ(image_hash(r.out), image_hash(two_pixels()))
      << "a rejected tile must leave `out` as it was";
  return r;
}

TEST(PixelFormat, RejectsSizesAndChannelsNoTileHas) {
  const Bytes bytes(8);
  const auto F = WireFormat::Float;
  const auto N = Compression::None;
  EXPECT_TRUE(
      has_substr(reject(bytes, 8, 0, 1, F, N, 0).reason, "tile size 0x1 outside [1, 32768]"));
  EXPECT_TRUE(has_substr(reject(bytes, 8, 1, -4, F, N, 0).reason, "tile size 1x-4"));
  EXPECT_TRUE(has_substr(reject(bytes, 8, 32769, 1, F, N, 0).reason, "tile size 32769x1"));
  EXPECT_TRUE(has_substr(reject(bytes, 8, 1, 32769, F, N, 0).reason, "outside [1, 32768]"));
  EXPECT_TRUE(
      has_substr(reject(bytes, 0, 32768, 32768, WireFormat::Rgba8, N, 0).reason,
                 "32768x32768 rgba8 tile is 4294967296 raw bytes, over the limit of 67108864"));
  EXPECT_TRUE(has_substr(reject(bytes, 0, 2048, 2049, F, N, 0).reason, "over the limit"));
  EXPECT_TRUE(
      has_substr(reject(bytes, 0, 2048, 2048, F, N, kChannelDepth).reason, "over the limit"));
  EXPECT_TRUE(has_substr(reject(bytes, 8, 2, 1, WireFormat::Rgba8, N, kChannelDepth).reason,
                         "depth and normal channels need half or float, not rgba8"));
  EXPECT_TRUE(
      has_substr(reject(bytes, 8, 2, 1, WireFormat::Rgba8, N, kChannelNormal).reason, "not rgba8"));
  EXPECT_TRUE(has_substr(reject(bytes, 8, 2, 1, F, N, 4).reason, "unknown channel bits 0x04"));
  EXPECT_TRUE(has_substr(reject(bytes, 8, 2, 1, F, N, 0x80).reason, "unknown channel bits 0x80"));
  EXPECT_TRUE(has_substr(reject(bytes, 8, 2, 1, static_cast<WireFormat>(9), N, 0).reason,
                         "unknown wire format 9"));
  EXPECT_TRUE(
      has_substr(reject(bytes, 8, 2, 1, WireFormat::Rgba8, static_cast<Compression>(3), 0).reason,
                 "unknown compression 3"));
  // The largest tile within the limit is fine.
  Image out;
  const Bytes big(std::size_t{64} << 20);
  EXPECT_EQ(decode_tile_pixels(big, 64u << 20, 2048, 2048, F, N, 0, out), "");
  EXPECT_EQ(out.rgba.size(), std::size_t{4} * 2048 * 2048);
}

TEST(PixelFormat, RejectsARawSizeOtherThanTheTileHas) {
  const Bytes bytes = encode(two_pixels(), WireFormat::Half, Compression::None, kBoth);
  EXPECT_TRUE(has_substr(reject(bytes, 35, 2, 1, WireFormat::Half, Compression::None, kBoth).reason,
                         "raw size 35, expected 36 for 2x1 half+depth+normal"));
  EXPECT_TRUE(has_substr(
      reject(bytes, 0xffffffffu, 2, 1, WireFormat::Half, Compression::Zstd, kBoth).reason,
      "raw size 4294967295, expected 36"));
  EXPECT_TRUE(
      has_substr(reject(bytes, 36, 2, 1, WireFormat::Half, Compression::None, kChannelDepth).reason,
                 "raw size 36, expected 24 for 2x1 half+depth"));
}

TEST(PixelFormat, RejectsUncompressedBytesOfTheWrongLength) {
  Bytes bytes = encode(two_pixels(), WireFormat::Float, Compression::None, 0);
  bytes.push_back(0);
  EXPECT_TRUE(has_substr(reject(bytes, 32, 2, 1, WireFormat::Float, Compression::None, 0).reason,
                         "uncompressed size 33, expected 32"));
  bytes.resize(31);
  EXPECT_TRUE(has_substr(reject(bytes, 32, 2, 1, WireFormat::Float, Compression::None, 0).reason,
                         "uncompressed size 31, expected 32"));
}

TEST(PixelFormat, RejectsCorruptCompressedData) {
  const Bytes garbage = {0xff, 0xff, 0xff, 0xff, 0x12, 0x34, 0x56, 0x78, 0x9a};
  const auto F = WireFormat::Float;
  EXPECT_TRUE(
      has_substr(reject(garbage, 32, 2, 1, F, Compression::Lz4, 0).reason, "lz4 data corrupt"));
  EXPECT_TRUE(
      has_substr(reject(garbage, 32, 2, 1, F, Compression::Zstd, 0).reason, "zstd data corrupt"));
  EXPECT_TRUE(has_substr(reject({}, 32, 2, 1, F, Compression::Lz4, 0).reason, "lz4 data empty"));
  EXPECT_TRUE(has_substr(reject({}, 32, 2, 1, F, Compression::Zstd, 0).reason, "zstd data empty"));
  // Plain bytes are not a compressed stream.
  const Bytes plain = encode(realistic_tile(4, 4, 2), F, Compression::None, 0);
  EXPECT_NE(reject(plain, 256, 4, 4, F, Compression::Zstd, 0).reason, "");
}

TEST(PixelFormat, RejectsDataThatDecompressesToAnotherSize) {
  // A 2x1 tile's data (32 raw bytes) declared as 3x1 (48) and the other way round.
  const Image small = two_pixels();
  Image large(3, 1);
  const auto F = WireFormat::Float;
  for (const Compression c : {Compression::Lz4, Compression::Zstd}) {
    SCOPED_TRACE(compression_name(c));
    const std::string name(compression_name(c));
    EXPECT_TRUE(has_substr(reject(encode(small, F, c, 0), 48, 3, 1, F, c, 0).reason,
                           name + " data decompresses to 32 bytes, expected 48"));
    const std::string longer = reject(encode(large, F, c, 0), 32, 2, 1, F, c, 0).reason;
    EXPECT_TRUE(has_substr(longer, name + " data")) << longer;
  }
}

// Flipped, overwritten and cut bytes of compressed tiles: a reason or a tile of the stated
// size, never a crash or an out-of-bounds access (run under ASan in the asan preset).
TEST(PixelFormat, RandomCorruptionOfCompressedTilesNeverCrashes) {
  const std::uint32_t seed = 424242;
  SCOPED_TRACE(fmt::format("seed {}", seed));
  std::mt19937 rng(seed);
  const Image tile = realistic_tile(16, 16, 3);
  for (const WireFormat f : kFormats) {
    const std::uint8_t channels = f == WireFormat::Rgba8 ? 0 : kBoth;
    const auto raw = static_cast<std::uint32_t>(raw_tile_bytes(16, 16, f, channels));
    for (const Compression c : {Compression::Lz4, Compression::Zstd}) {
      const Bytes good = encode(tile, f, c, channels);
      int accepted = 0;
      for (int iteration = 0; iteration < 1500; ++iteration) {
        Bytes bytes = good;
        const int edits = 1 + static_cast<int>(rng() % 3);
        for (int e = 0; e < edits && !bytes.empty(); ++e) {
          const std::size_t at = rng() % bytes.size();
          switch (rng() % 3) {
            case 0:
              bytes[at] = static_cast<std::uint8_t>(rng());
              break;
            case 1:
              bytes[at] ^= static_cast<std::uint8_t>(1u << (rng() % 8));
              break;
            default:
              bytes.resize(at);
              break;
          }
        }
        Image out;
        const std::string reason = decode_tile_pixels(bytes, raw, 16, 16, f, c, channels, out);
        if (reason.empty()) {
          ++accepted;
          ASSERT_EQ(out.rgba.size(), 4u * 16 * 16) << "iteration " << iteration;
          ASSERT_EQ(out.depth.size(), channels != 0 ? 256u : 0u);
        }
      }
      RecordProperty(fmt::format("accepted_{}_{}", wire_format_name(f), compression_name(c)),
                     accepted);
    }
  }
}

}  // namespace
}  // namespace rtc
