// Image in memory: construction, pixel access, tile blits and the content hash.
#include "common/image/image.h"

#include <algorithm>
#include <bit>
#include <cstddef>
#include <limits>
#include <string_view>

#include <fmt/format.h>

#include "common/base/error.h"

namespace rtc {
namespace {

std::size_t pixel_count(int width, int height) {
  return static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
}

std::string describe_rect(int x0, int y0, int width, int height) {
  return fmt::format("{}x{} at ({}, {})", width, height, x0, y0);
}

// Tiles come from peers, so a mismatch is bad input (rtc::Error), not a broken invariant.
void check_shape(const Image& image, std::string_view what) {
  const std::size_t pixels = pixel_count(std::max(image.width, 0), std::max(image.height, 0));
  const bool ok = image.width >= 0 && image.height >= 0 && image.rgba.size() == 4 * pixels &&
                  (image.depth.empty() || image.depth.size() == pixels) &&
                  (image.normal.empty() || image.normal.size() == 3 * pixels);
  if (!ok) {
    throw Error(fmt::format("{}: {}x{} image has {} RGBA, {} depth and {} normal floats", what,
                            image.width, image.height, image.rgba.size(), image.depth.size(),
                            image.normal.size()));
  }
}

class Fnv1a64 {
 public:
  void add_u32(std::uint32_t value) {
    // Fixed little-endian byte order so big-endian machines give the same hash.
    for (int i = 0; i < 4; ++i) {
      hash_ ^= (value >> (8 * i)) & 0xffu;
      hash_ *= kPrime;
    }
  }
  void add_floats(const std::vector<float>& values) {
    for (const float v : values) add_u32(std::bit_cast<std::uint32_t>(v));
  }
  [[nodiscard]] std::uint64_t value() const { return hash_; }

 private:
  static constexpr std::uint64_t kPrime = 0x100000001b3ull;
  std::uint64_t hash_ = 0xcbf29ce484222325ull;
};

}  // namespace

Image::Image(int w, int h, bool with_depth, bool with_normal) { reset(w, h, with_depth, with_normal); }

void Image::reset(int w, int h, bool with_depth, bool with_normal) {
  RTC_CHECK(w >= 0 && h >= 0, "image size must not be negative");
  width = w;
  height = h;
  const std::size_t pixels = pixel_count(w, h);
  // assign() keeps the vectors' memory when it is large enough.
  rgba.assign(4 * pixels, 0.0f);
  if (with_depth) {
    depth.assign(pixels, std::numeric_limits<float>::infinity());
  } else {
    depth.clear();
  }
  if (with_normal) {
    normal.assign(3 * pixels, 0.0f);
  } else {
    normal.clear();
  }
}

bool Image::has_shape(int w, int h, bool with_depth, bool with_normal) const {
  const std::size_t pixels = pixel_count(std::max(w, 0), std::max(h, 0));
  return width == w && height == h && rgba.size() == 4 * pixels && depth.size() == (with_depth ? pixels : 0) &&
         normal.size() == (with_normal ? 3 * pixels : 0);
}

float* Image::pixel(int x, int y) {
  RTC_DCHECK(x >= 0 && x < width && y >= 0 && y < height, "pixel outside the image");
  return rgba.data() + 4 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                            static_cast<std::size_t>(x));
}

const float* Image::pixel(int x, int y) const {
  RTC_DCHECK(x >= 0 && x < width && y >= 0 && y < height, "pixel outside the image");
  return rgba.data() + 4 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                            static_cast<std::size_t>(x));
}

void Image::blit(const Image& tile, int x0, int y0) {
  check_shape(*this, "blit target");
  check_shape(tile, "blit tile");
  // 64-bit sums: x0 + tile.width must not overflow for hostile coordinates.
  const bool fits = x0 >= 0 && y0 >= 0 &&
                    static_cast<std::int64_t>(x0) + tile.width <= width &&
                    static_cast<std::int64_t>(y0) + tile.height <= height;
  if (!fits) {
    throw Error(fmt::format("blit: tile {} does not fit in the {}x{} image",
                            describe_rect(x0, y0, tile.width, tile.height), width, height));
  }
  const bool copy_depth = has_depth() && tile.has_depth();
  const bool copy_normal = has_normal() && tile.has_normal();
  const auto tile_width = static_cast<std::size_t>(tile.width);
  for (int ty = 0; ty < tile.height; ++ty) {
    const std::size_t src = static_cast<std::size_t>(ty) * tile_width;
    const std::size_t dst = static_cast<std::size_t>(y0 + ty) * static_cast<std::size_t>(width) +
                            static_cast<std::size_t>(x0);
    std::copy_n(tile.rgba.begin() + static_cast<std::ptrdiff_t>(4 * src), 4 * tile_width,
                rgba.begin() + static_cast<std::ptrdiff_t>(4 * dst));
    if (copy_depth) {
      std::copy_n(tile.depth.begin() + static_cast<std::ptrdiff_t>(src), tile_width,
                  depth.begin() + static_cast<std::ptrdiff_t>(dst));
    }
    if (copy_normal) {
      std::copy_n(tile.normal.begin() + static_cast<std::ptrdiff_t>(3 * src), 3 * tile_width,
                  normal.begin() + static_cast<std::ptrdiff_t>(3 * dst));
    }
  }
}

std::string image_hash(const Image& image) {
  Fnv1a64 fnv;
  fnv.add_u32(static_cast<std::uint32_t>(image.width));
  fnv.add_u32(static_cast<std::uint32_t>(image.height));
  // The channel sizes go in too, so a frame with depth never hashes like one without.
  fnv.add_u32(static_cast<std::uint32_t>(image.rgba.size()));
  fnv.add_u32(static_cast<std::uint32_t>(image.depth.size()));
  fnv.add_u32(static_cast<std::uint32_t>(image.normal.size()));
  fnv.add_floats(image.rgba);
  fnv.add_floats(image.depth);
  fnv.add_floats(image.normal);
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out(16, '0');
  const std::uint64_t value = fnv.value();
  for (std::size_t i = 0; i < 16; ++i) out[i] = kHex[(value >> (60 - 4 * i)) & 0xfu];
  return out;
}

}  // namespace rtc
