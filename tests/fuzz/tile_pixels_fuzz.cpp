// Fuzz target: tile pixels from a worker (common/image/pixel_format.h, decode_tile_pixels),
// what the master decodes from every TileResult: every wire format, compression and channel
// set. The first 9 bytes pick the tile (width, height up to 64, format, compression, channels,
// raw size); the rest are the pixel bytes. Whatever decodes must encode and decode to the same
// bytes again.
#include <cstring>
#include <span>
#include <string>
#include <vector>

#include "common/image/image.h"
#include "common/image/pixel_format.h"
#include "tests/fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using rtc::fuzz::check;
  if (size < 9) return 0;
  const int width = 1 + data[0] % 64;
  const int height = 1 + data[1] % 64;
  const auto format = rtc::wire_format_from_byte(data[2] % 4);      // 0: not a format
  const auto compression = rtc::compression_from_byte(data[3] % 4);  // 3: not a compression
  const std::uint8_t channels = data[4] % 8;                          // bit 2: not a channel
  std::uint32_t raw_size = 0;
  std::memcpy(&raw_size, data + 5, 4);
  if (!format || !compression) return 0;  // the master checks these bytes before decoding
  const std::span<const std::uint8_t> bytes(data + 9, size - 9);
  rtc::Image tile;
  const std::string error =
      rtc::decode_tile_pixels(bytes, raw_size, width, height, *format, *compression, channels, tile);
  if (!error.empty()) return 0;
  check(tile.width == width && tile.height == height, "decoded tile has the wrong size");
  std::vector<std::uint8_t> encoded;
  const std::size_t raw = rtc::encode_tile_pixels(tile, *format, *compression, channels, encoded);
  rtc::Image again;
  const std::string error2 =
      rtc::decode_tile_pixels(encoded, static_cast<std::uint32_t>(raw), width, height, *format, *compression, channels, again);
  check(error2.empty(), "a decoded tile does not decode once encoded: " + error2);
  std::vector<std::uint8_t> encoded2;
  (void)rtc::encode_tile_pixels(again, *format, *compression, channels, encoded2);
  check(encoded2 == encoded, "encode(decode(encode(tile))) differs from encode(tile)");
  return 0;
}
