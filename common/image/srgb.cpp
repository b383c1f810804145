// 8-bit conversions: exact sRGB <-> 8-bit from precomputed tables (see gen_srgb_tables.py), and
// the linear 8-bit alpha of PNG files and rgba8 tiles.
#include "common/image/image.h"

#include <array>
#include <bit>
#include <cstddef>

namespace rtc {
namespace {
#include "common/image/srgb_tables.inc"

// Floats at or below 2^-13 all give code 0 (the first threshold is about 1.5e-4).
constexpr std::uint32_t kLowBits = std::bit_cast<std::uint32_t>(0x1p-13f);
constexpr std::uint32_t kOneBits = std::bit_cast<std::uint32_t>(1.0f);
static_assert(kEncodeThresholds[0] > 0x1p-13f);

// Buckets of 2^16 consecutive floats in (2^-13, 1): the top 7 mantissa bits, 128 per octave.
// Each holds the code of its first float, so at most a step or two is left to take.
constexpr int kBucketShift = 16;
constexpr std::size_t kBucketCount = (kOneBits - kLowBits) >> kBucketShift;

constexpr std::uint8_t code_by_search(float linear) {
  std::size_t code = 0;
  while (code < kEncodeThresholds.size() && linear >= kEncodeThresholds[code]) ++code;
  return static_cast<std::uint8_t>(code);
}

constexpr std::array<std::uint8_t, kBucketCount> make_bucket_codes() {
  std::array<std::uint8_t, kBucketCount> codes{};
  for (std::size_t i = 0; i < kBucketCount; ++i) {
    const auto first_bits = static_cast<std::uint32_t>(kLowBits + (i << kBucketShift));
    codes[i] = code_by_search(std::bit_cast<float>(first_bits));
  }
  return codes;
}

constexpr std::array<std::uint8_t, kBucketCount> kBucketCodes = make_bucket_codes();

}  // namespace

std::uint8_t linear_to_srgb8(float linear) {
  // Each threshold is the first float whose exact sRGB value rounds up to the next code, so
  // the code is the number of thresholds at or below `linear`. The comparisons are exact, so
  // every machine gives the same code.
  if (!(linear > 0x1p-13f)) return 0;  // also NaN and negatives
  if (linear >= 1.0f) return 255;
  const std::uint32_t bits = std::bit_cast<std::uint32_t>(linear);
  std::size_t code = kBucketCodes[(bits - kLowBits) >> kBucketShift];
  while (code < kEncodeThresholds.size() && linear >= kEncodeThresholds[code]) ++code;
  return static_cast<std::uint8_t>(code);
}

float srgb8_to_linear(std::uint8_t v) { return kDecode[v]; }

std::uint8_t linear_to_unorm8(float value) {
  if (!(value > 0.0f)) return 0;  // also NaN
  if (value >= 1.0f) return 255;
  return static_cast<std::uint8_t>(value * 255.0f + 0.5f);
}

}  // namespace rtc
