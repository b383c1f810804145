// Tile pixels on the wire: the raw layout (RGBA, then depth, then normals) in rgba8, half or
// float, and its lz4 / zstd compression. rgba8 uses exactly the conversions of write_image's
// PNG path, so a PNG written from a decoded tile equals one written from the float tile.
#include "common/image/pixel_format.h"

#include <climits>
#include <cstring>
#include <limits>
#include <memory>
#include <new>

#include <Imath/half.h>
#include <fmt/format.h>
#include <lz4.h>
#include <zstd.h>

#include "common/base/error.h"

namespace rtc {
namespace {

// A peer's tile: each side at most this many pixels, and at most kMaxRawTileBytes before
// compression (what decode_tile_pixels allocates for a hostile size).
constexpr int kMaxTileSide = 32768;
constexpr std::size_t kMaxRawTileBytes = std::size_t{64} << 20;
constexpr std::uint8_t kKnownChannels = kChannelDepth | kChannelNormal;
constexpr int kZstdLevel = 1;

/// Bytes of one RGBA pixel, or 0 for a value outside the enum.
std::size_t rgba_bytes(WireFormat format) {
  switch (format) {
    case WireFormat::Rgba8:
      return 4;
    case WireFormat::Half:
      return 8;
    case WireFormat::Float:
      return 16;
  }
  return 0;
}

/// Bytes of one normal component (the wire format's type).
std::size_t normal_component_bytes(WireFormat format) { return format == WireFormat::Half ? 2 : 4; }

/// "32x32 half+depth+normal", for messages.
std::string describe(int width, int height, WireFormat format, std::uint8_t channels) {
  std::string text = fmt::format("{}x{} {}", width, height, wire_format_name(format));
  if ((channels & kChannelDepth) != 0) text += "+depth";
  if ((channels & kChannelNormal) != 0) text += "+normal";
  return text;
}

void put_halves(const float* src, std::size_t count, std::uint8_t* dst) {
  for (std::size_t i = 0; i < count; ++i) {
    const std::uint16_t bits = Imath::half(src[i]).bits();  // round to nearest even
    std::memcpy(dst + 2 * i, &bits, 2);
  }
}

void get_halves(const std::uint8_t* src, std::size_t count, float* dst) {
  for (std::size_t i = 0; i < count; ++i) {
    std::uint16_t bits = 0;
    std::memcpy(&bits, src + 2 * i, 2);
    Imath::half h;
    h.setBits(bits);
    dst[i] = static_cast<float>(h);  // exact: every half is a float
  }
}

/// The raw layout of `tile` into `dst` (raw_tile_bytes of it).
void write_raw(const Image& tile, WireFormat format, std::uint8_t channels, std::uint8_t* dst) {
  const std::size_t pixels =
      static_cast<std::size_t>(tile.width) * static_cast<std::size_t>(tile.height);
  const float* rgba = tile.rgba.data();
  switch (format) {
    case WireFormat::Rgba8:
      for (std::size_t i = 0; i < 4 * pixels; i += 4) {
        dst[i + 0] = linear_to_srgb8(rgba[i + 0]);
        dst[i + 1] = linear_to_srgb8(rgba[i + 1]);
        dst[i + 2] = linear_to_srgb8(rgba[i + 2]);
        dst[i + 3] = linear_to_unorm8(rgba[i + 3]);
      }
      break;
    case WireFormat::Half:
      put_halves(rgba, 4 * pixels, dst);
      break;
    case WireFormat::Float:
      std::memcpy(dst, rgba, 16 * pixels);
      break;
  }
  dst += rgba_bytes(format) * pixels;
  if ((channels & kChannelDepth) != 0) {
    std::memcpy(dst, tile.depth.data(), 4 * pixels);
    dst += 4 * pixels;
  }
  if ((channels & kChannelNormal) != 0) {
    if (format == WireFormat::Half) {
      put_halves(tile.normal.data(), 3 * pixels, dst);
    } else {
      std::memcpy(dst, tile.normal.data(), 12 * pixels);
    }
  }
}

/// The inverse of write_raw; `out` already has its size and channels.
void read_raw(const std::uint8_t* src, WireFormat format, std::uint8_t channels, Image& out) {
  const std::size_t pixels =
      static_cast<std::size_t>(out.width) * static_cast<std::size_t>(out.height);
  float* rgba = out.rgba.data();
  switch (format) {
    case WireFormat::Rgba8:
      for (std::size_t i = 0; i < 4 * pixels; i += 4) {
        rgba[i + 0] = srgb8_to_linear(src[i + 0]);
        rgba[i + 1] = srgb8_to_linear(src[i + 1]);
        rgba[i + 2] = srgb8_to_linear(src[i + 2]);
        rgba[i + 3] = static_cast<float>(src[i + 3]) / 255.0f;
      }
      break;
    case WireFormat::Half:
      get_halves(src, 4 * pixels, rgba);
      break;
    case WireFormat::Float:
      std::memcpy(rgba, src, 16 * pixels);
      break;
  }
  src += rgba_bytes(format) * pixels;
  if ((channels & kChannelDepth) != 0) {
    std::memcpy(out.depth.data(), src, 4 * pixels);
    src += 4 * pixels;
  }
  if ((channels & kChannelNormal) != 0) {
    if (format == WireFormat::Half) {
      get_halves(src, 3 * pixels, out.normal.data());
    } else {
      std::memcpy(out.normal.data(), src, 12 * pixels);
    }
  }
}

// One zstd context per thread: creating one per tile costs more than compressing a small tile.
struct ZstdContexts {
  std::unique_ptr<ZSTD_CCtx, decltype(&ZSTD_freeCCtx)> compress{ZSTD_createCCtx(), &ZSTD_freeCCtx};
  std::unique_ptr<ZSTD_DCtx, decltype(&ZSTD_freeDCtx)> decompress{ZSTD_createDCtx(),
                                                                  &ZSTD_freeDCtx};
};

ZstdContexts& zstd_contexts() {
  thread_local ZstdContexts contexts;
  return contexts;
}

/// `bytes` of this thread's scratch memory for a tile's raw pixels, kept between tiles: a fresh
/// buffer a tile cost its zero fill and page faults (lz4 2048x2048 float frames in 1024-pixel
/// tiles: the master's network thread took 707 ms a frame with fresh buffers and its other fresh
/// copies, 2026-12-02). Holds the largest tile's raw bytes this thread has handled, as the
/// thread's tile image and pixel buffer already do (a worker's render threads; 32 MiB each for
/// 1024x1024 float tiles with depth and normals).
std::span<std::uint8_t> raw_scratch(std::size_t bytes) {
  thread_local std::vector<std::uint8_t> scratch;
  if (scratch.size() < bytes) {
    std::vector<std::uint8_t>().swap(scratch);  // never the old and the new at once
    scratch.resize(bytes);
  }
  return {scratch.data(), bytes};
}

/// Appends the compressed `raw` to `out`.
void compress_into(std::span<const std::uint8_t> raw, Compression compression,
                   std::vector<std::uint8_t>& out) {
  const std::size_t start = out.size();
  if (compression == Compression::Lz4) {
    RTC_CHECK(raw.size() <= static_cast<std::size_t>(LZ4_MAX_INPUT_SIZE), "tile too large for lz4");
    const int bound = LZ4_compressBound(static_cast<int>(raw.size()));
    out.resize(start + static_cast<std::size_t>(bound));
    const int n = LZ4_compress_default(reinterpret_cast<const char*>(raw.data()),
                                       reinterpret_cast<char*>(out.data() + start),
                                       static_cast<int>(raw.size()), bound);
    RTC_CHECK(n > 0, "LZ4_compress_default failed");
    out.resize(start + static_cast<std::size_t>(n));
    return;
  }
  const std::size_t bound = ZSTD_compressBound(raw.size());
  out.resize(start + bound);
  ZSTD_CCtx* context = zstd_contexts().compress.get();
  const std::size_t n = context != nullptr ? ZSTD_compressCCtx(context, out.data() + start, bound,
                                                               raw.data(), raw.size(), kZstdLevel)
                                           : ZSTD_compress(out.data() + start, bound, raw.data(),
                                                           raw.size(), kZstdLevel);
  RTC_CHECK(!ZSTD_isError(n), "ZSTD_compress failed");
  out.resize(start + n);
}

/// Decompresses `bytes` into `raw` (already raw_size long); "" or the reason.
std::string decompress_into(std::span<const std::uint8_t> bytes, Compression compression,
                            std::span<std::uint8_t> raw) {
  if (bytes.empty()) return fmt::format("{} data empty", compression_name(compression));
  if (compression == Compression::Lz4) {
    if (bytes.size() > static_cast<std::size_t>(INT_MAX)) return "lz4 data too long";
    const int n = LZ4_decompress_safe(reinterpret_cast<const char*>(bytes.data()),
                                      reinterpret_cast<char*>(raw.data()),
                                      static_cast<int>(bytes.size()), static_cast<int>(raw.size()));
    if (n < 0) return "lz4 data corrupt";
    if (static_cast<std::size_t>(n) != raw.size()) {
      return fmt::format("lz4 data decompresses to {} bytes, expected {}", n, raw.size());
    }
    return {};
  }
  ZSTD_DCtx* context = zstd_contexts().decompress.get();
  const std::size_t n =
      context != nullptr
          ? ZSTD_decompressDCtx(context, raw.data(), raw.size(), bytes.data(), bytes.size())
          : ZSTD_decompress(raw.data(), raw.size(), bytes.data(), bytes.size());
  if (ZSTD_isError(n)) return fmt::format("zstd data corrupt ({})", ZSTD_getErrorName(n));
  if (n != raw.size()) {
    return fmt::format("zstd data decompresses to {} bytes, expected {}", n, raw.size());
  }
  return {};
}

}  // namespace

std::string_view wire_format_name(WireFormat f) {
  switch (f) {
    case WireFormat::Rgba8:
      return "rgba8";
    case WireFormat::Half:
      return "half";
    case WireFormat::Float:
      return "float";
  }
  return "unknown";
}

std::string_view compression_name(Compression c) {
  switch (c) {
    case Compression::None:
      return "none";
    case Compression::Lz4:
      return "lz4";
    case Compression::Zstd:
      return "zstd";
  }
  return "unknown";
}

std::optional<WireFormat> parse_wire_format(std::string_view s) {
  for (const WireFormat f : {WireFormat::Rgba8, WireFormat::Half, WireFormat::Float}) {
    if (s == wire_format_name(f)) return f;
  }
  return std::nullopt;
}

std::optional<Compression> parse_compression(std::string_view s) {
  for (const Compression c : {Compression::None, Compression::Lz4, Compression::Zstd}) {
    if (s == compression_name(c)) return c;
  }
  return std::nullopt;
}

std::optional<WireFormat> wire_format_from_byte(std::uint8_t b) {
  if (b < static_cast<std::uint8_t>(WireFormat::Rgba8) ||
      b > static_cast<std::uint8_t>(WireFormat::Float)) {
    return std::nullopt;
  }
  return static_cast<WireFormat>(b);
}

std::optional<Compression> compression_from_byte(std::uint8_t b) {
  if (b > static_cast<std::uint8_t>(Compression::Zstd)) return std::nullopt;
  return static_cast<Compression>(b);
}

// 0 for arguments no tile has (negative size, unknown format or channel bits, channels with
// rgba8); SIZE_MAX when the size does not fit size_t.
std::size_t raw_tile_bytes(int width, int height, WireFormat format, std::uint8_t channels) {
  const std::size_t rgba = rgba_bytes(format);
  if (width < 0 || height < 0 || rgba == 0 || (channels & ~kKnownChannels) != 0 ||
      (format == WireFormat::Rgba8 && channels != 0)) {
    return 0;
  }
  std::size_t per_pixel = rgba;
  if ((channels & kChannelDepth) != 0) per_pixel += 4;
  if ((channels & kChannelNormal) != 0) per_pixel += 3 * normal_component_bytes(format);
  const std::size_t pixels = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  if (pixels > std::numeric_limits<std::size_t>::max() / per_pixel) {
    return std::numeric_limits<std::size_t>::max();
  }
  return pixels * per_pixel;
}

// The raw (uncompressed) tile, all little-endian, pixels row-major from the top-left:
//   RGBA of every pixel, interleaved R G B A:
//     rgba8: 4 x u8 (RGB linear_to_srgb8, A linear_to_unorm8),
//     half:  4 x IEEE binary16 (Imath::half, round to nearest even),
//     float: 4 x IEEE binary32 (the bits as they are);
//   with kChannelDepth: width * height f32 depth (the bits; +inf for background);
//   with kChannelNormal: width * height normals x, y, z, as half in the half format, else f32.
// Compression none sends these bytes; lz4 sends one LZ4_compress_default block (no frame);
// zstd one ZSTD_compress frame at level 1. The receiver is told the raw size separately.
std::size_t max_encoded_tile_bytes(std::size_t raw_bytes) {
  // LZ4_COMPRESSBOUND and ZSTD_COMPRESSBOUND are both below raw + raw / 255 + 1024.
  return raw_bytes + raw_bytes / 255 + 1024;
}

std::size_t encode_tile_pixels(const Image& tile, WireFormat format, Compression compression,
                               std::uint8_t channels, std::vector<std::uint8_t>& out) {
  RTC_CHECK(rgba_bytes(format) != 0, "encode_tile_pixels: unknown wire format");
  RTC_CHECK((channels & ~kKnownChannels) == 0, "encode_tile_pixels: unknown channel bits");
  RTC_CHECK(format != WireFormat::Rgba8 || channels == 0,
            "encode_tile_pixels: depth and normal need half or float");
  RTC_CHECK(compression == Compression::None || compression == Compression::Lz4 ||
                compression == Compression::Zstd,
            "encode_tile_pixels: unknown compression");
  RTC_CHECK(tile.width >= 0 && tile.height >= 0, "encode_tile_pixels: negative tile size");
  const std::size_t pixels =
      static_cast<std::size_t>(tile.width) * static_cast<std::size_t>(tile.height);
  RTC_CHECK(tile.rgba.size() == 4 * pixels,
            "encode_tile_pixels: RGBA does not match the tile size");
  RTC_CHECK((channels & kChannelDepth) == 0 || tile.depth.size() == pixels,
            "encode_tile_pixels: tile has no depth");
  RTC_CHECK((channels & kChannelNormal) == 0 || tile.normal.size() == 3 * pixels,
            "encode_tile_pixels: tile has no normals");

  const std::size_t raw_size = raw_tile_bytes(tile.width, tile.height, format, channels);
  if (compression == Compression::None) {
    const std::size_t start = out.size();
    out.resize(start + raw_size);
    write_raw(tile, format, channels, out.data() + start);
    return raw_size;
  }
  const std::span<std::uint8_t> raw = raw_scratch(raw_size);
  write_raw(tile, format, channels, raw.data());
  compress_into(raw, compression, out);
  return raw_size;
}

std::string decode_tile_pixels(std::span<const std::uint8_t> bytes, std::uint32_t raw_size,
                               int width, int height, WireFormat format, Compression compression,
                               std::uint8_t channels, Image& out) {
  if (width <= 0 || height <= 0 || width > kMaxTileSide || height > kMaxTileSide) {
    return fmt::format("tile size {}x{} outside [1, {}]", width, height, kMaxTileSide);
  }
  if (rgba_bytes(format) == 0) {
    return fmt::format("unknown wire format {}", static_cast<int>(format));
  }
  if ((channels & ~kKnownChannels) != 0) {
    return fmt::format("unknown channel bits 0x{:02x}", channels);
  }
  if (format == WireFormat::Rgba8 && channels != 0) {
    return "depth and normal channels need half or float, not rgba8";
  }
  if (compression != Compression::None && compression != Compression::Lz4 &&
      compression != Compression::Zstd) {
    return fmt::format("unknown compression {}", static_cast<int>(compression));
  }
  const std::size_t expected = raw_tile_bytes(width, height, format, channels);
  if (expected > kMaxRawTileBytes) {
    return fmt::format("{} tile is {} raw bytes, over the limit of {}",
                       describe(width, height, format, channels), expected, kMaxRawTileBytes);
  }
  if (raw_size != expected) {
    return fmt::format("raw size {}, expected {} for {}", raw_size, expected,
                       describe(width, height, format, channels));
  }
  if (compression == Compression::None && bytes.size() != raw_size) {
    return fmt::format("uncompressed size {}, expected {}", bytes.size(), raw_size);
  }

  // `out` is only touched once the bytes are known to be good (or memory runs out).
  try {
    const std::uint8_t* src = bytes.data();
    if (compression != Compression::None) {
      const std::span<std::uint8_t> raw = raw_scratch(raw_size);
      const std::string problem = decompress_into(bytes, compression, raw);
      if (!problem.empty()) return problem;
      src = raw.data();
    }
    const std::size_t pixels = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
    out.rgba.resize(4 * pixels);
    if ((channels & kChannelDepth) != 0) {
      out.depth.resize(pixels);
    } else {
      out.depth.clear();
    }
    if ((channels & kChannelNormal) != 0) {
      out.normal.resize(3 * pixels);
    } else {
      out.normal.clear();
    }
    out.width = width;
    out.height = height;
    read_raw(src, format, channels, out);
  } catch (const std::bad_alloc&) {
    return fmt::format("out of memory for a {} tile", describe(width, height, format, channels));
  }
  return {};
}

}  // namespace rtc
