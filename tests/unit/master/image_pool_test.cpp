// ImagePool and FrameWriter: a master's finished frames give their memory to the next frames.
#include "master/image_pool.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <unistd.h>

#include "common/image/image.h"
#include "master/frame_writer.h"

namespace rtc {
namespace {

TEST(ImagePool, AnEmptyPoolMakesAFreshImage) {
  ImagePool pool(2);
  const Image image = pool.take_for_overwrite(16, 8, true, false);
  EXPECT_EQ(image.width, 16);
  EXPECT_EQ(image.height, 8);
  EXPECT_EQ(image.rgba, Image(16, 8).rgba);
  EXPECT_EQ(image.depth, Image(16, 8, true).depth);
  EXPECT_FALSE(image.has_normal());
}

TEST(ImagePool, AnImageOfTheSameShapeComesBackAsItWas) {
  ImagePool pool(2);
  Image image = pool.take_for_overwrite(16, 8, true, true);
  std::fill(image.rgba.begin(), image.rgba.end(), 0.25f);
  const float* memory = image.rgba.data();
  pool.give(std::move(image));
  EXPECT_EQ(pool.kept(), 1u);
  const Image again = pool.take_for_overwrite(16, 8, true, true);
  EXPECT_EQ(pool.kept(), 0u);
  EXPECT_EQ(again.rgba.data(), memory);
  // Not filled again: the caller writes every pixel.
  EXPECT_EQ(again.rgba, std::vector<float>(again.rgba.size(), 0.25f));
  EXPECT_EQ(again.depth.size(), 16u * 8u);
  EXPECT_EQ(again.normal.size(), 3u * 16u * 8u);
}

TEST(ImagePool, AnotherShapeIsMadeAfresh) {
  ImagePool pool(2);
  Image image = pool.take_for_overwrite(16, 8, false, false);
  std::fill(image.rgba.begin(), image.rgba.end(), 0.25f);
  pool.give(std::move(image));
  // Smaller, or the same size with depth: the background values, as a new image has them.
  const Image smaller = pool.take_for_overwrite(8, 8, false, false);
  EXPECT_EQ(smaller.width, 8);
  EXPECT_EQ(smaller.rgba, Image(8, 8).rgba);
  pool.give(Image(smaller));
  const Image with_depth = pool.take_for_overwrite(8, 8, true, false);
  EXPECT_EQ(with_depth.rgba, Image(8, 8).rgba);
  EXPECT_EQ(with_depth.depth, std::vector<float>(64, std::numeric_limits<float>::infinity()));
}

TEST(ImagePool, KeepsAtMostItsLimit) {
  ImagePool pool(2);
  for (int i = 0; i < 5; ++i) pool.give(Image(4, 4));
  EXPECT_EQ(pool.kept(), 2u);
  ImagePool none(0);
  none.give(Image(4, 4));
  EXPECT_EQ(none.kept(), 0u);
}

TEST(FrameWriter, WrittenAndFailedFramesGiveTheirImagesBack) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("rtc_image_pool_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  ImagePool pool(4);
  std::vector<std::string> errors;
  {
    FrameWriter writer(ImageWriteOptions{}, [&](const std::string& e) { errors.push_back(e); }, &pool);
    writer.submit((dir / "a.png").string(), Image(8, 8));
    writer.submit((dir / "no_such_folder" / "b.png").string(), Image(8, 8));  // fails
    ASSERT_TRUE(writer.flush_for(std::chrono::seconds(30)));
    EXPECT_EQ(pool.kept(), 2u);
    // The summary's "N frames written": the one on disk, not the one that failed.
    const FrameWriter::Totals totals = writer.totals();
    EXPECT_EQ(totals.written, 1u);
    EXPECT_EQ(totals.failed, 1u);
    EXPECT_GT(totals.write_s, 0.0);
  }
  EXPECT_TRUE(std::filesystem::exists(dir / "a.png"));
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].find("no_such_folder"), std::string::npos) << errors[0];
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace rtc
