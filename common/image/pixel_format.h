// Tile pixels on the wire: RGBA as sRGB 8-bit, half or float, optional depth and normal
// channels, optionally compressed with lz4 or zstd. The bytes are written out in
// protocol/protocol.md ("Tile pixels"). Knows pixels, not rays or sockets.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/image/image.h"

namespace rtc {

enum class WireFormat : std::uint8_t {
  Rgba8 = 1,  ///< 4 B/px: RGB linear_to_srgb8, A the same rounding write_image uses for PNG
  Half = 2,   ///< 8 B/px: RGBA as IEEE half (Imath::half, round to nearest even)
  Float = 3,  ///< 16 B/px: RGBA as the float bits
};
enum class Compression : std::uint8_t { None = 0, Lz4 = 1, Zstd = 2 };

/// The shipped default (rtc-master --compress), chosen from the time/error sweep
/// (tests/bench/results/sweep): lz4 cuts rgba8 tiles ~3x for ~1-2 ms of codec time per 512x512
/// frame and no error, so it is on the Pareto front on every shared scene; zstd saves a few
/// more bytes (~4.5x) for more CPU, worth it on links slower than ~100 Mbit/s.
inline constexpr Compression kDefaultCompression = Compression::Lz4;

/// Optional channels after RGBA (bit flags): depth is always float32 (as in EXR files), the
/// normal in the wire format's type (half or float). Not allowed with Rgba8.
inline constexpr std::uint8_t kChannelDepth = 1;
inline constexpr std::uint8_t kChannelNormal = 2;

/// "rgba8", "half", "float" / "none", "lz4", "zstd".
[[nodiscard]] std::string_view wire_format_name(WireFormat f);
[[nodiscard]] std::string_view compression_name(Compression c);
/// Parses those names; std::nullopt for anything else.
[[nodiscard]] std::optional<WireFormat> parse_wire_format(std::string_view s);
[[nodiscard]] std::optional<Compression> parse_compression(std::string_view s);
/// Validates raw enum bytes from a peer.
[[nodiscard]] std::optional<WireFormat> wire_format_from_byte(std::uint8_t b);
[[nodiscard]] std::optional<Compression> compression_from_byte(std::uint8_t b);

/// Bytes of a w x h tile before compression.
[[nodiscard]] std::size_t raw_tile_bytes(int width, int height, WireFormat format, std::uint8_t channels);

/// Upper bound on what encode_tile_pixels appends for `raw_bytes` raw bytes under any
/// compression (compressed data can be a little larger than its input).
[[nodiscard]] std::size_t max_encoded_tile_bytes(std::size_t raw_bytes);

/// Encodes `tile` (RGBA, plus depth/normal when `channels` asks; the tile must have them) and
/// appends the (compressed) bytes to `out`; returns the raw (uncompressed) size. Deterministic.
/// Thread-safe. Caller bugs (missing channel, channels with Rgba8) are RTC_CHECKs.
std::size_t encode_tile_pixels(const Image& tile, WireFormat format, Compression compression,
                               std::uint8_t channels, std::vector<std::uint8_t>& out);

/// Decodes bytes from a peer into `out` (resized to width x height, with depth/normal per
/// `channels`). Returns "" on success, else the reason ("lz4 data corrupt", "raw size 4096,
/// expected 4100 for 32x32 rgba8", ...). Never throws, never reads or writes out of bounds,
/// never allocates more than raw_tile_bytes() for the stated size (a hostile raw_size is
/// rejected before decompressing). rgba8 decodes RGB with srgb8_to_linear and A as v / 255.
[[nodiscard]] std::string decode_tile_pixels(std::span<const std::uint8_t> bytes, std::uint32_t raw_size,
                                             int width, int height, WireFormat format, Compression compression,
                                             std::uint8_t channels, Image& out);

}  // namespace rtc
