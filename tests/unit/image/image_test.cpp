// Unit tests for rtc_image: file round trips, sRGB, frame names, blits and content hashes.
#include "common/image/image.h"

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <csignal>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "common/base/error.h"

namespace rtc {
namespace {

namespace fs = std::filesystem;

constexpr float kInf = std::numeric_limits<float>::infinity();

std::string hex(float value) {
  char text[64];
  std::snprintf(text, sizeof text, "%a", static_cast<double>(value));
  return text;
}

// sRGB encode in double: an independent reference, trusted to about 1e-12.
double srgb_encode_reference(double linear) {
  return linear <= 0.0031308 ? 12.92 * linear : 1.055 * std::pow(linear, 1.0 / 2.4) - 0.055;
}

double srgb_decode_reference(double encoded) {
  return encoded <= 0.04045 ? encoded / 12.92 : std::pow((encoded + 0.055) / 1.055, 2.4);
}

float float_from_bits(std::uint32_t bits) { return std::bit_cast<float>(bits); }

// A test image whose every channel differs per pixel, with values exact in half.
Image make_test_image(int width, int height, bool with_depth, bool with_normal) {
  Image image(width, height, with_depth, with_normal);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const auto i = static_cast<std::size_t>(y * width + x);
      float* p = image.pixel(x, y);
      p[0] = static_cast<float>(x) / 8.0f;
      p[1] = static_cast<float>(y) / 16.0f;
      p[2] = 0.5f + static_cast<float>(x + y) / 1024.0f;
      p[3] = (x + y) % 2 == 0 ? 1.0f : 0.25f;
      if (with_depth) image.depth[i] = x == 0 ? kInf : 1000.0f + static_cast<float>(i) * 0.125f;
      if (with_normal) {
        image.normal[3 * i + 0] = x == 0 ? 0.0f : 0.5f;
        image.normal[3 * i + 1] = x == 0 ? 0.0f : -0.75f;
        image.normal[3 * i + 2] = x == 0 ? 0.0f : static_cast<float>(y) / 32.0f;
      }
    }
  }
  return image;
}

std::set<std::string> names_in(const fs::path& folder) {
  std::set<std::string> names;
  for (const auto& entry : fs::directory_iterator(folder)) {
    names.insert(entry.path().filename().string());
  }
  return names;
}

// Each test writes into its own fresh folder, removed afterwards.
class ImageFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / fmt::format("rtc_image_test_{}_{}_{}", ::getpid(),
                                                   info->test_suite_name(), info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ignored;
    fs::remove_all(dir_, ignored);
  }
  fs::path dir_;
};

// ---- EXR -------------------------------------------------------------------------------------

using ExrFile = ImageFileTest;

TEST_F(ExrFile, HalfRoundTripKeepsValuesDepthAndNormals) {
  const Image image = make_test_image(13, 7, true, true);
  const fs::path path = dir_ / "frame.exr";
  write_image(path, image);

  const Image back = read_image(path);
  ASSERT_EQ(back.width, 13);
  ASSERT_EQ(back.height, 7);
  ASSERT_TRUE(back.has_depth());
  ASSERT_TRUE(back.has_normal());
  EXPECT_EQ(back.rgba, image.rgba);
  EXPECT_EQ(back.depth, image.depth);
  EXPECT_EQ(back.normal, image.normal);
  EXPECT_EQ(image_hash(back), image_hash(image));
}

TEST_F(ExrFile, HalfFileNamesAndTypesItsChannels) {
  const fs::path path = dir_ / "frame.exr";
  write_image(path, make_test_image(4, 3, true, true));

  const ImageFileInfo info = read_image_info(path);
  EXPECT_EQ(info.width, 4);
  EXPECT_EQ(info.height, 3);
  ASSERT_EQ(info.channel_names.size(), 8u);
  ASSERT_EQ(info.channel_types.size(), 8u);
  const std::set<std::string> names(info.channel_names.begin(), info.channel_names.end());
  EXPECT_EQ(names, (std::set<std::string>{"R", "G", "B", "A", "Z", "N.X", "N.Y", "N.Z"}));
  for (std::size_t c = 0; c < info.channel_names.size(); ++c) {
    const std::string expected = info.channel_names[c] == "Z" ? "float" : "half";
    EXPECT_EQ(info.channel_types[c], expected) << "channel " << info.channel_names[c];
  }
}

TEST_F(ExrFile, HalfRoundsToTheNearestHalf) {
  Image image(1, 1);
  image.rgba = {0.1f, 1.0f / 3.0f, 65504.0f, 1.0f};
  const fs::path path = dir_ / "half.exr";
  write_image(path, image);

  const Image back = read_image(path);
  // The halves nearest 0.1 and 1/3; 65504 is the largest finite half.
  EXPECT_EQ(back.rgba[0], 0.0999755859375f) << hex(back.rgba[0]);
  EXPECT_EQ(back.rgba[1], 0.333251953125f) << hex(back.rgba[1]);
  EXPECT_EQ(back.rgba[2], 65504.0f);
  EXPECT_EQ(back.rgba[3], 1.0f);
}

TEST_F(ExrFile, FloatRoundTripIsBitExact) {
  constexpr std::uint32_t kSeed = 20240611;
  SCOPED_TRACE(fmt::format("seed {}", kSeed));
  std::mt19937 rng(kSeed);
  std::uniform_real_distribution<float> value(-4.0f, 4.0f);
  Image image(17, 9, true, true);
  for (float& v : image.rgba) v = value(rng);
  for (float& v : image.depth) v = std::abs(value(rng)) * 1000.0f;
  for (float& v : image.normal) v = value(rng) / 4.0f;
  image.rgba[0] = -0.0f;
  image.rgba[1] = 1e-40f;  // subnormal
  image.depth[0] = kInf;

  const fs::path path = dir_ / "float.exr";
  ImageWriteOptions options;
  options.exr_type = ExrPixelType::Float;
  write_image(path, image, options);

  const ImageFileInfo info = read_image_info(path);
  for (const std::string& type : info.channel_types) EXPECT_EQ(type, "float");
  const Image back = read_image(path);
  EXPECT_EQ(image_hash(back), image_hash(image));
  EXPECT_TRUE(std::signbit(back.rgba[0]));
  EXPECT_EQ(back.rgba[1], 1e-40f);
  EXPECT_EQ(back.depth[0], kInf);
}

TEST_F(ExrFile, OptionsLeaveOutDepthAndNormals) {
  const fs::path path = dir_ / "rgba_only.exr";
  ImageWriteOptions options;
  options.write_depth = false;
  options.write_normal = false;
  write_image(path, make_test_image(5, 4, true, true), options);

  const ImageFileInfo info = read_image_info(path);
  const std::set<std::string> names(info.channel_names.begin(), info.channel_names.end());
  EXPECT_EQ(names, (std::set<std::string>{"R", "G", "B", "A"}));
  const Image back = read_image(path);
  EXPECT_FALSE(back.has_depth());
  EXPECT_FALSE(back.has_normal());
  EXPECT_EQ(back.rgba, make_test_image(5, 4, false, false).rgba);
}

TEST_F(ExrFile, ImageWithoutDepthWritesNoZ) {
  const fs::path path = dir_ / "no_depth.exr";
  write_image(path, make_test_image(3, 3, false, true));
  const ImageFileInfo info = read_image_info(path);
  const std::set<std::string> names(info.channel_names.begin(), info.channel_names.end());
  EXPECT_EQ(names, (std::set<std::string>{"R", "G", "B", "A", "N.X", "N.Y", "N.Z"}));
  const Image back = read_image(path);
  EXPECT_FALSE(back.has_depth());
  EXPECT_TRUE(back.has_normal());
}

TEST(ExrCompressionNames, ParseWhatTheyName) {
  const std::vector<ExrCompression> all = {ExrCompression::None,  ExrCompression::Rle,  ExrCompression::Zips,
                                           ExrCompression::Zip,   ExrCompression::Piz,  ExrCompression::Pxr24,
                                           ExrCompression::B44,   ExrCompression::B44a, ExrCompression::Dwaa,
                                           ExrCompression::Dwab};
  std::set<std::string> names;
  for (const ExrCompression c : all) {
    const std::string name(exr_compression_name(c));
    names.insert(name);
    EXPECT_EQ(parse_exr_compression(name), c) << name;
    EXPECT_NE(exr_compression_names().find(name), std::string::npos) << name;
  }
  EXPECT_EQ(names.size(), all.size());
  EXPECT_EQ(exr_compression_names(), "none, rle, zips, zip, piz, pxr24, b44, b44a, dwaa or dwab");
  for (const char* bad : {"", "ZIP", "zip ", "gzip", "dwa"}) EXPECT_EQ(parse_exr_compression(bad), std::nullopt) << bad;
  EXPECT_FALSE(exr_compression_lossy(ExrCompression::Piz, ExrPixelType::Half, true));
  EXPECT_TRUE(exr_compression_lossy(ExrCompression::Dwaa, ExrPixelType::Float, false));
  EXPECT_FALSE(exr_compression_lossy(ExrCompression::B44, ExrPixelType::Float, true));
  EXPECT_TRUE(exr_compression_lossy(ExrCompression::B44, ExrPixelType::Half, false));
  // PXR24 rounds float channels only: Z is float, so without it a half file keeps its values.
  EXPECT_TRUE(exr_compression_lossy(ExrCompression::Pxr24, ExrPixelType::Half, true));
  EXPECT_FALSE(exr_compression_lossy(ExrCompression::Pxr24, ExrPixelType::Half, false));
  EXPECT_TRUE(exr_compression_lossy(ExrCompression::Pxr24, ExrPixelType::Float, false));
  EXPECT_EQ(ImageWriteOptions{}.exr_compression, ExrCompression::Zip);
}

// Every compression, through OpenImageIO and back, on a frame taller than the rows write_image
// hands over at once (64) and than any compression's block (DWAB: 256 rows), in float and half:
// the header names it, and each channel comes back as the compression promises against the same
// file written with zip. Lossless ones (on random values): every bit. PXR24: half channels
// exact, float ones (Z always) within 24-bit rounding. B44/B44A: float channels exact, half ones
// close. DWAA/DWAB: A, Z, N.X and N.Z exact, R, G, B and N.Y (taken for luminance) close. The
// lossy ones get a smooth frame.
TEST_F(ExrFile, EveryCompressionKeepsWhatItPromises) {
  constexpr std::uint32_t kSeed = 20261204;
  SCOPED_TRACE(fmt::format("seed {}", kSeed));
  std::mt19937 rng(kSeed);
  std::uniform_real_distribution<float> noise(-4.0f, 4.0f);
  const int width = 67, height = 300;
  Image random(width, height, true, true);
  for (float& v : random.rgba) v = noise(rng);
  for (float& v : random.depth) v = std::abs(noise(rng)) * 1000.0f;
  for (float& v : random.normal) v = noise(rng) / 4.0f;
  random.depth[0] = kInf;
  Image smooth(width, height, true, true);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const auto i = static_cast<std::size_t>(y * width + x);
      float* p = smooth.pixel(x, y);
      p[0] = 0.25f + 0.5f * static_cast<float>(x) / width;
      p[1] = 0.25f + 0.5f * static_cast<float>(y) / height;
      p[2] = 0.5f + 0.001f * static_cast<float>((x * 7 + y * 3) % 11);
      p[3] = (x + y) % 3 == 0 ? 1.0f : 0.75f;
      smooth.depth[i] = 10.0f + static_cast<float>(x + y) / 64.0f + 1e-3f * static_cast<float>(i % 7);
      smooth.normal[3 * i + 0] = 0.001f * static_cast<float>(x % 13);
      smooth.normal[3 * i + 1] = 0.6f + 0.001f * static_cast<float>(y % 5);
      smooth.normal[3 * i + 2] = 0.8f;
    }
  }
  // How a group of channels may come back: bit for bit, within pxr24's rounding, or close.
  enum class Kept { Exact, Rounded24, Close };
  const auto check = [](const std::vector<float>& got, const std::vector<float>& want, Kept kept, const char* what) {
    ASSERT_EQ(got.size(), want.size()) << what;
    float worst = 0.0f;
    std::size_t differ = 0;
    for (std::size_t i = 0; i < got.size(); ++i) {
      if (std::bit_cast<std::uint32_t>(got[i]) == std::bit_cast<std::uint32_t>(want[i])) continue;
      ++differ;
      worst = std::max(worst, std::isinf(want[i]) ? kInf : std::abs(got[i] - want[i]) / std::max(1.0f, std::abs(want[i])));
    }
    switch (kept) {
      case Kept::Exact: EXPECT_EQ(differ, 0u) << what << ": worst difference " << worst; break;
      case Kept::Rounded24: EXPECT_LE(worst, 1.0f / 32768.0f) << what; break;
      case Kept::Close: EXPECT_LT(worst, 0.02f) << what; break;
    }
  };
  for (const char* name : {"none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab"}) {
    SCOPED_TRACE(name);
    const ExrCompression compression = *parse_exr_compression(name);
    const bool lossless = compression <= ExrCompression::Piz;
    const Image& image = lossless ? random : smooth;
    for (const ExrPixelType type : {ExrPixelType::Float, ExrPixelType::Half}) {
      const bool is_float = type == ExrPixelType::Float;
      SCOPED_TRACE(is_float ? "float" : "half");
      ImageWriteOptions options;
      options.exr_type = type;
      const fs::path zip_path = dir_ / fmt::format("ref_{}.exr", is_float ? "float" : "half");
      write_image(zip_path, image, options);
      const Image ref = read_image(zip_path);
      options.exr_compression = compression;
      const fs::path path = dir_ / fmt::format("{}_{}.exr", name, is_float ? "float" : "half");
      write_image(path, image, options);
      const ImageFileInfo info = read_image_info(path);
      EXPECT_NE(std::find(info.metadata.begin(), info.metadata.end(), std::pair<std::string, std::string>("compression", name)),
                info.metadata.end());
      EXPECT_EQ(info.channel_names.size(), 8u);
      const Image back = read_image(path);
      ASSERT_TRUE(back.has_shape(width, height, true, true));
      if (lossless && is_float) {
        EXPECT_EQ(image_hash(back), image_hash(image));
      }
      // What the mains warn about: a lossy choice changes these frames, another changes nothing.
      EXPECT_EQ(exr_compression_lossy(compression, type, true), image_hash(back) != image_hash(ref));
      // And without Z (the frame's depth), which PXR24 would round.
      ImageWriteOptions no_depth = options;
      no_depth.write_depth = false;
      no_depth.exr_compression = ExrCompression::Zip;
      const fs::path ref_path = dir_ / fmt::format("ref_nz_{}.exr", is_float ? "float" : "half");
      write_image(ref_path, image, no_depth);
      no_depth.exr_compression = compression;
      const fs::path nz_path = dir_ / fmt::format("{}_nz_{}.exr", name, is_float ? "float" : "half");
      write_image(nz_path, image, no_depth);
      EXPECT_EQ(exr_compression_lossy(compression, type, false),
                image_hash(read_image(nz_path)) != image_hash(read_image(ref_path)));
      // RGB and A apart: DWA treats them differently.
      std::vector<float> rgb, rgb_ref, alpha, alpha_ref;
      for (std::size_t i = 0; i < back.rgba.size(); ++i) {
        ((i % 4 == 3) ? alpha : rgb).push_back(back.rgba[i]);
        ((i % 4 == 3) ? alpha_ref : rgb_ref).push_back(ref.rgba[i]);
      }
      Kept colour = Kept::Exact, normal = Kept::Exact, depth = Kept::Exact, alpha_kept = Kept::Exact;
      switch (compression) {
        case ExrCompression::Pxr24:
          depth = Kept::Rounded24;
          if (is_float) colour = normal = alpha_kept = Kept::Rounded24;
          break;
        case ExrCompression::B44:
        case ExrCompression::B44a:
          if (!is_float) colour = normal = alpha_kept = Kept::Close;
          break;
        case ExrCompression::Dwaa:
        case ExrCompression::Dwab:
          colour = Kept::Close;
          break;
        default:
          break;
      }
      check(rgb, rgb_ref, colour, "R G B");
      check(alpha, alpha_ref, alpha_kept, "A");
      check(back.depth, ref.depth, depth, "Z");
      // One normal component at a time: DWA takes a channel named Y (N.Y) for luminance.
      for (int axis = 0; axis < 3; ++axis) {
        std::vector<float> component, component_ref;
        for (std::size_t i = static_cast<std::size_t>(axis); i < back.normal.size(); i += 3) {
          component.push_back(back.normal[i]);
          component_ref.push_back(ref.normal[i]);
        }
        const bool dwa = compression == ExrCompression::Dwaa || compression == ExrCompression::Dwab;
        check(component, component_ref, dwa && axis == 1 ? Kept::Close : normal, axis == 0 ? "N.X" : axis == 1 ? "N.Y" : "N.Z");
      }
    }
  }
}

TEST_F(ExrFile, StoresMetadata) {
  const fs::path path = dir_ / "meta.exr";
  ImageWriteOptions options;
  options.metadata = {{"rtc:scene", "sponza.json"}, {"rtc:frame", "7"}};
  write_image(path, make_test_image(2, 2, false, false), options);

  const ImageFileInfo info = read_image_info(path);
  const auto has = [&](const std::string& key, const std::string& value) {
    return std::find(info.metadata.begin(), info.metadata.end(), std::pair(key, value)) !=
           info.metadata.end();
  };
  EXPECT_TRUE(has("rtc:scene", "sponza.json"));
  EXPECT_TRUE(has("rtc:frame", "7"));
}

// ---- PNG, TIFF, JPEG, PPM -------------------------------------------------------------------

using PngFile = ImageFileTest;

TEST_F(PngFile, EveryCodeValueRoundTripsExactly) {
  Image image(256, 2);
  for (int v = 0; v < 256; ++v) {
    for (int y = 0; y < 2; ++y) {
      float* p = image.pixel(v, y);
      const auto code = static_cast<std::uint8_t>(y == 0 ? v : 255 - v);
      p[0] = srgb8_to_linear(code);
      p[1] = srgb8_to_linear(static_cast<std::uint8_t>(255 - code));
      p[2] = srgb8_to_linear(code);
      p[3] = static_cast<float>(code) / 255.0f;
    }
  }
  const fs::path path = dir_ / "codes.png";
  write_image(path, image);

  const ImageFileInfo info = read_image_info(path);
  EXPECT_EQ(info.channel_names, (std::vector<std::string>{"R", "G", "B", "A"}));
  EXPECT_EQ(info.channel_types, std::vector<std::string>(4, "uint8"));
  const Image back = read_image(path);
  ASSERT_EQ(back.rgba.size(), image.rgba.size());
  for (std::size_t i = 0; i < image.rgba.size(); ++i) {
    ASSERT_EQ(back.rgba[i], image.rgba[i]) << "float " << i << ": " << hex(back.rgba[i])
                                           << " != " << hex(image.rgba[i]);
  }
}

TEST_F(PngFile, StoresTheSrgbCodeOfEachLinearValue) {
  constexpr std::uint32_t kSeed = 7;
  SCOPED_TRACE(fmt::format("seed {}", kSeed));
  std::mt19937 rng(kSeed);
  std::uniform_real_distribution<float> value(-0.25f, 1.25f);
  Image image(31, 5);
  for (float& v : image.rgba) v = value(rng);
  const fs::path path = dir_ / "random.png";
  write_image(path, image);

  const Image back = read_image(path);
  for (std::size_t i = 0; i < image.rgba.size(); ++i) {
    const float v = image.rgba[i];
    const bool alpha = i % 4 == 3;
    const float expected =
        alpha ? std::round(std::clamp(v, 0.0f, 1.0f) * 255.0f) / 255.0f
              : srgb8_to_linear(linear_to_srgb8(v));
    ASSERT_EQ(back.rgba[i], expected) << "float " << i << " was " << hex(v);
  }
}

TEST_F(PngFile, StoresMetadata) {
  const fs::path path = dir_ / "meta.png";
  ImageWriteOptions options;
  options.metadata = {{"rtc:scene", "cornell.json"}};
  write_image(path, make_test_image(2, 2, false, false), options);
  const ImageFileInfo info = read_image_info(path);
  EXPECT_NE(std::find(info.metadata.begin(), info.metadata.end(),
                      std::pair<std::string, std::string>("rtc:scene", "cornell.json")),
            info.metadata.end());
}

using OtherFormats = ImageFileTest;

TEST_F(OtherFormats, TiffIsFloatAndBitExact) {
  const Image image = make_test_image(6, 5, false, false);
  const fs::path path = dir_ / "frame.tif";
  write_image(path, image);
  EXPECT_EQ(read_image_info(path).channel_types, std::vector<std::string>(4, "float"));
  EXPECT_EQ(image_hash(read_image(path)), image_hash(image));
}

TEST_F(OtherFormats, PpmIsSrgbWithoutAlpha) {
  const Image image = make_test_image(6, 5, false, false);
  const fs::path path = dir_ / "frame.ppm";
  write_image(path, image);

  const ImageFileInfo info = read_image_info(path);
  EXPECT_EQ(info.channel_names.size(), 3u);
  const Image back = read_image(path);
  for (std::size_t i = 0; i < image.rgba.size(); ++i) {
    const float expected = i % 4 == 3 ? 1.0f : srgb8_to_linear(linear_to_srgb8(image.rgba[i]));
    ASSERT_EQ(back.rgba[i], expected) << "float " << i;
  }
}

TEST_F(OtherFormats, JpegKeepsAFlatColourClose) {
  Image image(16, 16);
  for (int y = 0; y < 16; ++y) {
    for (int x = 0; x < 16; ++x) {
      float* p = image.pixel(x, y);
      p[0] = srgb8_to_linear(200);
      p[1] = srgb8_to_linear(100);
      p[2] = srgb8_to_linear(50);
      p[3] = 0.5f;
    }
  }
  const fs::path path = dir_ / "frame.JPG";  // extensions are case-insensitive
  write_image(path, image);

  const Image back = read_image(path);
  const int expected[3] = {200, 100, 50};
  for (std::size_t i = 0; i < back.rgba.size(); i += 4) {
    for (std::size_t c = 0; c < 3; ++c) {
      EXPECT_NEAR(linear_to_srgb8(back.rgba[i + c]), expected[c], 3) << "float " << i + c;
    }
    EXPECT_EQ(back.rgba[i + 3], 1.0f);
  }
}

// ---- Writing: errors and atomicity -----------------------------------------------------------

using WriteImage = ImageFileTest;

TEST_F(WriteImage, MissingFolderIsAnErrorNamingThePath) {
  const fs::path path = dir_ / "no_such_folder" / "frame.exr";
  try {
    write_image(path, make_test_image(2, 2, false, false));
    FAIL() << "expected rtc::Error";
  } catch (const Error& error) {
    EXPECT_NE(std::string(error.what()).find(path.string()), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("does not exist"), std::string::npos)
        << error.what();
  }
  EXPECT_FALSE(fs::exists(dir_ / "no_such_folder"));
}

TEST_F(WriteImage, LeavesOnlyTheFinalFiles) {
  const Image first = make_test_image(8, 8, true, true);
  write_image(dir_ / "a.exr", first);
  write_image(dir_ / "b.png", first);
  write_image(dir_ / "c.tif", first);
  EXPECT_EQ(names_in(dir_), (std::set<std::string>{"a.exr", "b.png", "c.tif"}));

  // Writing over an existing frame replaces it, again with no leftovers.
  Image second = first;
  second.rgba[0] = 0.75f;
  write_image(dir_ / "a.exr", second);
  EXPECT_EQ(names_in(dir_), (std::set<std::string>{"a.exr", "b.png", "c.tif"}));
  EXPECT_EQ(read_image(dir_ / "a.exr").rgba[0], 0.75f);
}

TEST_F(WriteImage, ConcurrentWritesLeaveOnlyWholeFinalFiles) {
  // Four threads write four names, and all of them also write one shared name.
  const Image image = make_test_image(32, 32, true, true);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      for (int round = 0; round < 3; ++round) {
        write_image(dir_ / fmt::format("own_{}.exr", t), image);
        write_image(dir_ / "shared.exr", image);
      }
    });
  }
  for (std::thread& thread : threads) thread.join();
  EXPECT_EQ(names_in(dir_), (std::set<std::string>{"own_0.exr", "own_1.exr", "own_2.exr",
                                                   "own_3.exr", "shared.exr"}));
  EXPECT_EQ(image_hash(read_image(dir_ / "shared.exr")), image_hash(image));
}

// A write that runs out of room (here the file size limit, EFBIG; on a full disk ENOSPC) is an
// error naming the file and the reason, in every format, and leaves no file, whole or partial.
// OpenImageIO's PNG writer used to report success with an empty file, and libjpeg ended the
// process.
TEST_F(WriteImage, AFailedWriteIsAnErrorAndLeavesNoFile) {
  Image image = make_test_image(128, 128, true, true);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (float& v : image.rgba) v = u(rng);  // noise: no format compresses it below the limit
  struct sigaction ignore {}, saved {};
  ignore.sa_handler = SIG_IGN;
  ASSERT_EQ(::sigaction(SIGXFSZ, &ignore, &saved), 0);
  rlimit limit{}, saved_limit{};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &saved_limit), 0);
  limit = saved_limit;
  limit.rlim_cur = 4096;
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &limit), 0);
  std::vector<std::string> errors;
  for (const char* name : {"f.png", "f.jpg", "f.exr", "f.tif", "f.ppm"}) {
    try {
      write_image(dir_ / name, image);
      errors.push_back(std::string(name) + ": no error");
    } catch (const Error& error) {
      errors.push_back(error.what());
    }
  }
  ::setrlimit(RLIMIT_FSIZE, &saved_limit);
  ::sigaction(SIGXFSZ, &saved, nullptr);
  for (const std::string& e : errors) {
    EXPECT_NE(e.find("cannot write image '" + dir_.string()), std::string::npos) << e;
    EXPECT_NE(e.find("File too large"), std::string::npos) << e;
  }
  EXPECT_EQ(names_in(dir_), std::set<std::string>{});
}

TEST_F(WriteImage, FailedRenameLeavesNoTemporaryFile) {
  // The final name is taken by a folder, so the rename at the end fails.
  fs::create_directory(dir_ / "frame.exr");
  fs::create_directory(dir_ / "frame.png");
  EXPECT_THROW(write_image(dir_ / "frame.exr", make_test_image(4, 4, true, true)), Error);
  EXPECT_THROW(write_image(dir_ / "frame.png", make_test_image(4, 4, true, true)), Error);
  EXPECT_EQ(names_in(dir_), (std::set<std::string>{"frame.exr", "frame.png"}));
  EXPECT_TRUE(fs::is_empty(dir_ / "frame.exr"));
}

TEST_F(WriteImage, UnsupportedExtensionIsAnErrorNamingThePath) {
  const fs::path path = dir_ / "frame.bmp";
  try {
    write_image(path, make_test_image(2, 2, false, false));
    FAIL() << "expected rtc::Error";
  } catch (const Error& error) {
    EXPECT_NE(std::string(error.what()).find(path.string()), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find(".bmp"), std::string::npos) << error.what();
  }
  EXPECT_TRUE(fs::is_empty(dir_));
}

TEST_F(WriteImage, EmptyOrMisshapenImageIsAnError) {
  EXPECT_THROW(write_image(dir_ / "empty.exr", Image()), Error);
  Image short_rgba(4, 4);
  short_rgba.rgba.pop_back();
  EXPECT_THROW(write_image(dir_ / "short.exr", short_rgba), Error);
  EXPECT_TRUE(fs::is_empty(dir_));
}

TEST_F(WriteImage, ParentThatIsAFileIsAnError) {
  std::ofstream(dir_ / "plain_file") << "not a folder";
  EXPECT_THROW(write_image(dir_ / "plain_file" / "frame.exr", make_test_image(2, 2, false, false)),
               Error);
}

using ReadImage = ImageFileTest;

TEST_F(ReadImage, MissingFileIsAnErrorNamingThePath) {
  const fs::path path = dir_ / "absent.exr";
  try {
    (void)read_image(path);
    FAIL() << "expected rtc::Error";
  } catch (const Error& error) {
    EXPECT_NE(std::string(error.what()).find(path.string()), std::string::npos) << error.what();
  }
  EXPECT_THROW((void)read_image_info(path), Error);
}

TEST_F(ReadImage, GarbageFileIsAnError) {
  std::ofstream(dir_ / "garbage.exr") << "this is not an OpenEXR file";
  EXPECT_THROW((void)read_image(dir_ / "garbage.exr"), Error);
}

// ---- sRGB ------------------------------------------------------------------------------------

TEST(Srgb, ExactAtTheEndsAndClampsOutside) {
  EXPECT_EQ(linear_to_srgb8(0.0f), 0);
  EXPECT_EQ(linear_to_srgb8(-0.0f), 0);
  EXPECT_EQ(linear_to_srgb8(1.0f), 255);
  EXPECT_EQ(linear_to_srgb8(-1.0f), 0);
  EXPECT_EQ(linear_to_srgb8(2.0f), 255);
  EXPECT_EQ(linear_to_srgb8(kInf), 255);
  EXPECT_EQ(linear_to_srgb8(-kInf), 0);
  EXPECT_EQ(linear_to_srgb8(std::numeric_limits<float>::quiet_NaN()), 0);
  EXPECT_EQ(linear_to_srgb8(std::numeric_limits<float>::denorm_min()), 0);
  EXPECT_EQ(srgb8_to_linear(0), 0.0f);
  EXPECT_EQ(srgb8_to_linear(255), 1.0f);
}

TEST(Srgb, KnownValues) {
  // Codes from the exact IEC 61966-2-1 formula in 50-digit arithmetic (255 * encode shown).
  EXPECT_EQ(linear_to_srgb8(0.5f), 188);        // 187.516
  EXPECT_EQ(linear_to_srgb8(0.18f), 118);       // 117.646
  EXPECT_EQ(linear_to_srgb8(0.214f), 127);      // 127.489
  EXPECT_EQ(linear_to_srgb8(0.9f), 243);        // 243.445
  EXPECT_EQ(linear_to_srgb8(0.01f), 25);        // 25.462
  EXPECT_EQ(linear_to_srgb8(0.0031308f), 10);   // 10.315, the end of the linear segment
  EXPECT_EQ(linear_to_srgb8(0.001f), 3);        // 3.295
  EXPECT_EQ(linear_to_srgb8(0.0001f), 0);       // 0.329
  EXPECT_NEAR(srgb8_to_linear(188), 0.50289f, 1e-5f);
  EXPECT_NEAR(srgb8_to_linear(128), 0.21586f, 1e-5f);
}

TEST(Srgb, MonotoneOverFloatsInZeroToOne) {
  const std::uint32_t one_bits = std::bit_cast<std::uint32_t>(1.0f);
  std::uint8_t previous = 0;
  std::set<int> seen;
  // Every 61st float in [0, 1]: about 17 million values.
  for (std::uint32_t bits = 0; bits <= one_bits; bits += 61) {
    const std::uint8_t code = linear_to_srgb8(float_from_bits(bits));
    ASSERT_GE(code, previous) << "at " << hex(float_from_bits(bits));
    previous = code;
    seen.insert(code);
  }
  EXPECT_EQ(seen.size(), 256u);
}

TEST(Srgb, EveryStepIsAtTheExactRoundingPoint) {
  // For each code, find the first float that reaches it (the function is monotone), then
  // check against the double formula that the step sits at 255 * encode(x) = code - 0.5:
  // the step float is at or past it and the float before is short of it.
  const std::uint32_t one_bits = std::bit_cast<std::uint32_t>(1.0f);
  for (int code = 1; code <= 255; ++code) {
    std::uint32_t lo = 0;
    std::uint32_t hi = one_bits;
    while (lo < hi) {
      const std::uint32_t mid = lo + (hi - lo) / 2;
      if (linear_to_srgb8(float_from_bits(mid)) >= code) {
        hi = mid;
      } else {
        lo = mid + 1;
      }
    }
    const float step = float_from_bits(lo);
    const float before = float_from_bits(lo - 1);
    const double boundary = code - 0.5;
    // 1e-9 covers the error of std::pow; the gaps between neighbouring floats are far larger.
    EXPECT_GE(255.0 * srgb_encode_reference(step), boundary - 1e-9) << code << " " << hex(step);
    EXPECT_LT(255.0 * srgb_encode_reference(before), boundary + 1e-9) << code << " " << hex(before);
    EXPECT_EQ(linear_to_srgb8(step), code) << hex(step);
    EXPECT_EQ(linear_to_srgb8(before), code - 1) << hex(before);
  }
}

TEST(Srgb, DecodeIsNearestFloatAndRoundTrips) {
  for (int v = 0; v < 256; ++v) {
    const auto code = static_cast<std::uint8_t>(v);
    const float linear = srgb8_to_linear(code);
    EXPECT_EQ(linear_to_srgb8(linear), code) << "code " << v;
    const double exact = srgb_decode_reference(v / 255.0);
    // Nearest float: within half a float ulp (plus the reference's own tiny error).
    const double half_ulp =
        0.5 * (static_cast<double>(std::nextafter(linear, 2.0f)) - static_cast<double>(linear));
    EXPECT_LE(std::abs(static_cast<double>(linear) - exact), half_ulp * (1.0 + 1e-6))
        << "code " << v << " gives " << hex(linear);
  }
}

// ---- Frame names -----------------------------------------------------------------------------

TEST(FramePattern, HashRunIsZeroPaddedFrameNumber) {
  EXPECT_EQ(expand_frame_pattern("frames/f_####.exr", 7, true), "frames/f_0007.exr");
  EXPECT_EQ(expand_frame_pattern("frames/f_#.exr", 7, true), "frames/f_7.exr");
  EXPECT_EQ(expand_frame_pattern("f_######.png", 1234, false), "f_001234.png");
  EXPECT_EQ(expand_frame_pattern("run_##/f.exr", 3, true), "run_03/f.exr");
}

TEST(FramePattern, PrintfStyleIsAccepted) {
  EXPECT_EQ(expand_frame_pattern("frames/f_%04d.exr", 7, true), "frames/f_0007.exr");
  EXPECT_EQ(expand_frame_pattern("f_%d.exr", 42, true), "f_42.exr");
  EXPECT_EQ(expand_frame_pattern("f_%010d.exr", 5, true), "f_0000000005.exr");
  EXPECT_EQ(expand_frame_pattern("100%%_f%03d.exr", 9, true), "100%_f009.exr");
}

// With a printf-style placeholder '#' is an ordinary character, in folders and file names, so
// any name can be written; "%%" alone is no placeholder, so '#' runs still count beside it.
TEST(FramePattern, HashIsLiteralBesidePrintfStyle) {
  EXPECT_EQ(expand_frame_pattern("take#2/f_%04d.exr", 7, true), "take#2/f_0007.exr");
  EXPECT_EQ(expand_frame_pattern("f_##_%d.exr", 42, true), "f_##_42.exr");
  EXPECT_EQ(expand_frame_pattern("#%d#", 3, false), "#3#");
  EXPECT_EQ(expand_frame_pattern("100%%/f_##.exr", 3, true), "100%/f_03.exr");
  // Without a placeholder at all the frame number is inserted as usual.
  EXPECT_EQ(expand_frame_pattern("100%%.exr", 3, true), "100%_0003.exr");
}

TEST(FramePattern, WiderFrameNumbersAreNotCut) {
  EXPECT_EQ(expand_frame_pattern("f_##.exr", 123, true), "f_123.exr");
  EXPECT_EQ(expand_frame_pattern("f_%02d.exr", 12345, true), "f_12345.exr");
}

TEST(FramePattern, NoPlaceholderIsUnchangedForOneFrame) {
  EXPECT_EQ(expand_frame_pattern("out.exr", 7, false), "out.exr");
  EXPECT_EQ(expand_frame_pattern("renders/out", 0, false), "renders/out");
}

TEST(FramePattern, NoPlaceholderGetsNumberBeforeExtensionForManyFrames) {
  EXPECT_EQ(expand_frame_pattern("out.exr", 7, true), "out_0007.exr");
  EXPECT_EQ(expand_frame_pattern("renders/out.v2.png", 12, true), "renders/out.v2_0012.png");
  EXPECT_EQ(expand_frame_pattern("renders.v1/out", 3, true), "renders.v1/out_0003");
  EXPECT_EQ(expand_frame_pattern("renders/.hidden", 3, true), "renders/.hidden_0003");
  EXPECT_EQ(expand_frame_pattern("out.exr", 123456, true), "out_123456.exr");
}

// A scene's name as a file name's stem, also literal inside a frame pattern.
TEST(FramePattern, FileStemForKeepsOnlyPlainCharacters) {
  EXPECT_EQ(file_stem_for("spd-tree"), "spd-tree");
  EXPECT_EQ(file_stem_for("2CylinderEngine v1.2+x_y"), "2CylinderEngine_v1.2+x_y");
  EXPECT_EQ(file_stem_for("lab #2/take%3"), "lab__2_take_3");
  EXPECT_EQ(file_stem_for("caf\xc3\xa9"), "caf__");  // each byte of a non-ASCII letter
  EXPECT_EQ(file_stem_for(""), "scene");
  EXPECT_EQ(file_stem_for(".."), "scene");
  EXPECT_EQ(file_stem_for("/"), "_");
  // Whatever the name, the default pattern built on it expands to that stem and the number.
  EXPECT_EQ(expand_frame_pattern("out/" + file_stem_for("a#b%d/c") + "_####.png", 5, true), "out/a_b_d_c_0005.png");
  EXPECT_EQ(file_stem_for(std::string(300, 'x')), std::string(200, 'x'));  // a file name has 255 bytes at most
}

// rtc-master --out-dir: every character of the folder literal, the scene's name as a stem.
TEST(FramePattern, NumberedFramePatternTakesTheFolderLiterally) {
  EXPECT_EQ(expand_frame_pattern(numbered_frame_pattern("out/cluster", "spd-tree"), 7, true), "out/cluster/spd-tree_0007.png");
  EXPECT_EQ(expand_frame_pattern(numbered_frame_pattern("take#2/100%/", "a b"), 12, false), "take#2/100%/a_b_0012.png");
  EXPECT_EQ(expand_frame_pattern(numbered_frame_pattern("/", ""), 0, true), "/scene_0000.png");
}

TEST(FramePattern, BadPatternsThrowNamingThePattern) {
  const std::vector<std::string> bad = {
      "",             // empty
      "frames/",      // no file name
      "f_##_##.exr",  // two placeholders
      "f_%d_%d.exr",  // two printf placeholders
      "f_%s.exr",     // not a number
      "f_%4d.exr",    // space padding
      "f_%0d.exr",    // zero width
      "f_%011d.exr",  // wider than any int
      "f_%.exr",      // lone percent
      "f_%",          // percent at the end
  };
  for (const std::string& pattern : bad) {
    try {
      (void)expand_frame_pattern(pattern, 1, true);
      ADD_FAILURE() << "no error for '" << pattern << "'";
    } catch (const Error& error) {
      EXPECT_NE(std::string(error.what()).find(fmt::format("'{}'", pattern)), std::string::npos)
          << error.what();
    }
  }
  EXPECT_THROW((void)expand_frame_pattern("f_####.exr", -1, true), Error);
}

using OutputPattern = ImageFileTest;

// rtc-master's --out-dir and every --out folder: one check, one wording.
TEST_F(OutputPattern, FolderProblemNamesTheFolderAndTheReason) {
  const std::string d = dir_.string();
  EXPECT_EQ(folder_problem(dir_, true), "");
  EXPECT_EQ(folder_problem(dir_ / "missing", false), "folder '" + d + "/missing' does not exist");
  {
    std::ofstream(dir_ / "plain") << "x";
  }
  EXPECT_EQ(folder_problem(dir_ / "plain", true), "'" + d + "/plain' is not a folder");
  if (::geteuid() != 0) {  // root writes anywhere
    fs::create_directories(dir_ / "locked");
    fs::permissions(dir_ / "locked", fs::perms::owner_read | fs::perms::owner_exec);
    EXPECT_EQ(folder_problem(dir_ / "locked", false), "");
    EXPECT_EQ(folder_problem(dir_ / "locked", true), "cannot write to folder " + d + "/locked: Permission denied");
    fs::permissions(dir_ / "locked", fs::perms::owner_all);
  }
}

TEST_F(OutputPattern, CheckedBeforeRendering) {
  const auto error_of = [](const std::string& pattern, bool multiple) -> std::string {
    try {
      (void)check_output_pattern(pattern, 3, 3, multiple);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  };
  const std::string d = dir_.string();
  EXPECT_EQ(check_output_pattern(d + "/f_####.exr", 3, 5, true), dir_ / "f_0003.exr");
  EXPECT_EQ(error_of(d + "/f_####.exr", true), "");
  EXPECT_EQ(error_of(d + "/f.PNG", false), "");
  EXPECT_EQ(error_of(d + "/f_####.xyz", true),
            "--out: " + d + "/f_0003.xyz: unsupported extension '.xyz' (use .exr, .png, .tif, .tiff, .jpg, .jpeg or .ppm)");
  EXPECT_EQ(error_of("/dev/full", false),
            "--out: /dev/full: the name has no extension to choose the format by (use .exr, .png, .tif, .tiff, .jpg, "
            ".jpeg or .ppm)");
  EXPECT_EQ(error_of(d + "/missing/f.png", false),
            "--out: " + d + "/missing/f.png: folder '" + d + "/missing' does not exist");
  fs::create_directories(dir_ / "taken.png");
  EXPECT_EQ(error_of(d + "/taken.png", false), "--out: " + d + "/taken.png: is a folder");
  {
    std::ofstream(dir_ / "plain") << "x";
  }
  EXPECT_EQ(error_of(d + "/plain/f.png", false), "--out: " + d + "/plain/f.png: '" + d + "/plain' is not a folder");
  // The pattern's own errors come through.
  EXPECT_NE(error_of(d + "/f_##_##.exr", true).find("frame placeholders"), std::string::npos);
  // A '#' meant literally, in a folder name: the messages show the pattern and the way out.
  const std::string hint =
      "each run of '#' is the frame number, in folder names too; in a pattern with \"%04d\" for it every '#' is literal";
  EXPECT_EQ(error_of(d + "/take#2/f.png", false), "--out: " + d + "/take32/f.png: folder '" + d +
                                                     "/take32' does not exist (the pattern '" + d +
                                                     "/take#2/f.png' gives this name for frame 3: " + hint + ")");
  EXPECT_EQ(error_of(d + "/take#2/f_####.png", true),
            "output pattern '" + d + "/take#2/f_####.png': has 2 frame placeholders; a name can hold only one (" + hint + ")");
  fs::create_directories(dir_ / "take#2");
  EXPECT_EQ(error_of(d + "/take#2/f_%04d.png", true), "");
}

TEST_F(OutputPattern, EveryFrameIsChecked) {
  const auto error_of = [](const std::string& pattern, int first, int last) -> std::string {
    try {
      (void)check_output_pattern(pattern, first, last, last > first || pattern.find('#') != std::string::npos);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  };
  const std::string d = dir_.string();
  // A folder per frame: the second one is missing.
  fs::create_directories(dir_ / "run_00");
  EXPECT_EQ(error_of(d + "/run_##/f.png", 0, 0), "");
  const std::string hint =
      "each run of '#' is the frame number, in folder names too; in a pattern with \"%04d\" for it every '#' is literal";
  EXPECT_EQ(error_of(d + "/run_##/f.png", 0, 1), "--out: " + d + "/run_01/f.png: folder '" + d +
                                                     "/run_01' does not exist (the pattern '" + d +
                                                     "/run_##/f.png' gives this name for frame 1: " + hint + ")");
  // A later frame's name taken by a folder.
  fs::create_directories(dir_ / "f_0001.png");
  EXPECT_EQ(error_of(d + "/f_####.png", 0, 2),
            "--out: " + d + "/f_0001.png: is a folder (frame 1's name; the run's first is " + d + "/f_0000.png)");
  EXPECT_EQ(error_of(d + "/f_####.png", 2, 9), "");
  // Longer than a file name may be (the temporary name it is written through fits).
  const std::string long_stem(247, 'b');
  EXPECT_EQ(error_of(d + "/" + long_stem + ".png", 0, 0), "");
  EXPECT_EQ(error_of(d + "/" + long_stem + "_####.png", 0, 0),
            "--out: " + d + "/" + long_stem + "_0000.png: the file name is 256 bytes; a name may have at most 255");
}

TEST_F(OutputPattern, LongNamesAreWritten) {
  // 251 bytes of name and ".png": the temporary name write_image goes through must fit too.
  const fs::path path = dir_ / (std::string(251, 'b') + ".png");
  write_image(path, Image(4, 2));
  EXPECT_TRUE(fs::is_regular_file(path));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1);
}

TEST(OutputSize, JpegHoldsAtMost65500PixelsASide) {
  EXPECT_EQ(output_size_problem("f.jpg", 65500, 65500), "");
  EXPECT_EQ(output_size_problem("f.png", 65536, 1), "");
  EXPECT_EQ(output_size_problem("f.JPEG", 65501, 1),
            "a JPEG file holds at most 65500 pixels a side, and the frame is 65501x1 (use .png, .exr or .tif, or a "
            "smaller --width/--height)");
  EXPECT_NE(output_size_problem("f.jpg", 1, 70000), "");
  // write_image refuses such a frame with the reason, before libjpeg would end the process.
  const Image wide(65501, 1);
  try {
    write_image(fs::path(testing::TempDir()) / "wide.jpg", wide);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("a JPEG file holds at most 65500 pixels a side"), std::string::npos) << e.what();
  }
}

TEST(OutputSize, WriteScratchFollowsTheFormat) {
  ImageWriteOptions half;
  const std::uint64_t mib = std::uint64_t{1} << 20;
  // PNG: the 8-bit copy and the file's buffer; JPEG and PPM: 3 bytes a pixel.
  EXPECT_EQ(image_write_scratch_bytes("f.png", 100, 10, true, half), 4000 + 4000 + mib);
  EXPECT_EQ(image_write_scratch_bytes("f.ppm", 100, 10, false, half), 3000 + 3000 + mib);
  // EXR: half RGBA, float Z, half N; without depth and normals, RGBA only.
  EXPECT_EQ(image_write_scratch_bytes("f.exr", 100, 10, true, half), 1000 * (8 + 4 + 6) + mib);
  EXPECT_EQ(image_write_scratch_bytes("f.exr", 100, 10, false, half), 1000 * 8 + mib);
  ImageWriteOptions full;
  full.exr_type = ExrPixelType::Float;
  EXPECT_EQ(image_write_scratch_bytes("f.exr", 100, 10, true, full), 1000 * (16 + 4 + 12) + mib);
  EXPECT_EQ(image_write_scratch_bytes("f.tif", 100, 10, true, full), 1000 * 16 + mib);
  // The file's buffer is at most 1 GiB.
  EXPECT_EQ(image_write_scratch_bytes("f.tif", 32768, 32768, false, full), std::uint64_t{1} << 30);
  EXPECT_EQ(image_write_scratch_bytes("f.xyz", 100, 10, true, full), 0u);
}

// ---- Image, blit, hash -----------------------------------------------------------------------

TEST(Image, ConstructorFillsTheBackground) {
  const Image image(3, 2, true, true);
  EXPECT_EQ(image.rgba, std::vector<float>(24, 0.0f));
  EXPECT_EQ(image.depth, std::vector<float>(6, kInf));
  EXPECT_EQ(image.normal, std::vector<float>(18, 0.0f));
  const Image plain(3, 2);
  EXPECT_FALSE(plain.has_depth());
  EXPECT_FALSE(plain.has_normal());
}

TEST(Image, ResetIsTheConstructorInTheMemoryItHolds) {
  Image image(64, 32, true, true);
  std::fill(image.rgba.begin(), image.rgba.end(), 0.5f);
  std::fill(image.depth.begin(), image.depth.end(), 2.0f);
  std::fill(image.normal.begin(), image.normal.end(), -1.0f);
  const float* rgba = image.rgba.data();
  const float* depth = image.depth.data();
  const float* normal = image.normal.data();
  image.reset(64, 32, true, true);
  EXPECT_EQ(image.rgba.data(), rgba);  // no new memory for the same size
  EXPECT_EQ(image.depth.data(), depth);
  EXPECT_EQ(image.normal.data(), normal);
  const Image fresh(64, 32, true, true);
  EXPECT_EQ(image.rgba, fresh.rgba);
  EXPECT_EQ(image.depth, fresh.depth);
  EXPECT_EQ(image.normal, fresh.normal);

  // Smaller, without depth and normals: the same as a new one of that shape.
  image.reset(8, 4);
  EXPECT_EQ(image.width, 8);
  EXPECT_EQ(image.height, 4);
  EXPECT_EQ(image.rgba.data(), rgba);
  EXPECT_EQ(image.rgba, Image(8, 4).rgba);
  EXPECT_FALSE(image.has_depth());
  EXPECT_FALSE(image.has_normal());
  EXPECT_TRUE(image.has_shape(8, 4, false, false));
  EXPECT_FALSE(image.has_shape(8, 4, true, false));
  EXPECT_FALSE(image.has_shape(4, 8, false, false));
  // Larger than it ever was: new memory, background values.
  image.reset(128, 64, true, false);
  EXPECT_EQ(image.rgba, Image(128, 64).rgba);
  EXPECT_EQ(image.depth, Image(128, 64, true).depth);
  EXPECT_FALSE(image.has_normal());
}

TEST(Image, PixelIsRowMajorFromTheTop) {
  Image image(5, 3);
  EXPECT_EQ(image.pixel(0, 0), image.rgba.data());
  EXPECT_EQ(image.pixel(2, 1), image.rgba.data() + 4 * (1 * 5 + 2));
  EXPECT_EQ(image.pixel(4, 2), image.rgba.data() + 4 * 14);
}

TEST(Image, BlitCopiesEveryChannelIntoPlace) {
  Image frame(6, 5, true, true);
  const Image tile = make_test_image(3, 2, true, true);
  frame.blit(tile, 2, 3);
  for (int y = 0; y < 5; ++y) {
    for (int x = 0; x < 6; ++x) {
      const bool inside = x >= 2 && x < 5 && y >= 3 && y < 5;
      const auto i = static_cast<std::size_t>(y * 6 + x);
      const auto t = static_cast<std::size_t>((y - 3) * 3 + (x - 2));
      for (std::size_t c = 0; c < 4; ++c) {
        EXPECT_EQ(frame.rgba[4 * i + c], inside ? tile.rgba[4 * t + c] : 0.0f) << x << "," << y;
      }
      EXPECT_EQ(frame.depth[i], inside ? tile.depth[t] : kInf) << x << "," << y;
      for (std::size_t c = 0; c < 3; ++c) {
        EXPECT_EQ(frame.normal[3 * i + c], inside ? tile.normal[3 * t + c] : 0.0f);
      }
    }
  }
}

TEST(Image, BlitSkipsChannelsMissingOnEitherSide) {
  Image frame(4, 4, true, false);
  frame.blit(make_test_image(2, 2, false, true), 1, 1);
  EXPECT_EQ(frame.depth, std::vector<float>(16, kInf));
  EXPECT_FALSE(frame.has_normal());
  EXPECT_EQ(frame.pixel(1, 1)[2], 0.5f);
}

TEST(Image, BlitOutsideTheImageThrows) {
  Image frame(4, 4);
  const Image tile(2, 2);
  EXPECT_THROW(frame.blit(tile, 3, 0), Error);
  EXPECT_THROW(frame.blit(tile, 0, 3), Error);
  EXPECT_THROW(frame.blit(tile, -1, 0), Error);
  EXPECT_THROW(frame.blit(tile, std::numeric_limits<int>::max(), 0), Error);
  Image broken(2, 2);
  broken.rgba.resize(3);
  EXPECT_THROW(frame.blit(broken, 0, 0), Error);
  EXPECT_NO_THROW(frame.blit(tile, 2, 2));
}

TEST(ImageHash, ChangesWhenOneBitChanges) {
  const Image image = make_test_image(7, 5, true, true);
  const std::string base = image_hash(image);
  EXPECT_EQ(base.size(), 16u);
  EXPECT_EQ(image_hash(image), base);
  EXPECT_EQ(image_hash(Image(image)), base);

  const auto flip_lowest_bit = [](float& value) {
    value = std::bit_cast<float>(std::bit_cast<std::uint32_t>(value) ^ 1u);
  };
  Image changed = image;
  flip_lowest_bit(changed.rgba[17]);
  EXPECT_NE(image_hash(changed), base);
  changed = image;
  flip_lowest_bit(changed.depth[30]);
  EXPECT_NE(image_hash(changed), base);
  changed = image;
  flip_lowest_bit(changed.normal[0]);
  EXPECT_NE(image_hash(changed), base);
}

TEST(ImageHash, DistinguishesZeroSignsShapesAndChannels) {
  Image positive(2, 1);
  Image negative(2, 1);
  negative.rgba[0] = -0.0f;
  EXPECT_NE(image_hash(positive), image_hash(negative));
  EXPECT_NE(image_hash(Image(2, 1)), image_hash(Image(1, 2)));
  EXPECT_NE(image_hash(Image(2, 1)), image_hash(Image(2, 1, true, false)));
  EXPECT_NE(image_hash(Image(2, 1, true, false)), image_hash(Image(2, 1, false, true)));
}

TEST(ImageHash, IsFnv1aOfTheDocumentedBytes) {
  // Golden values from an independent FNV-1a: the hash must not change across machines.
  Image image(2, 1);
  image.rgba = {0.25f, 0.5f, 1.0f, 1.0f, -0.0f, 2.0f, 3.0f, 0.5f};
  EXPECT_EQ(image_hash(image), "196af026197ed64c");
  image.depth = {1.5f, kInf};
  image.normal = {0.0f, 0.0f, 1.0f, 0.0f, 1.0f, 0.0f};
  EXPECT_EQ(image_hash(image), "66412da4f4f800c0");
}

}  // namespace
}  // namespace rtc
