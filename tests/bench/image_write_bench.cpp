// rtc-image-bench: Google Benchmark timings of rtc::write_image, the master's frame writer's one
// job, on a 2048x2048 frame of the built-in scene with depth and normals. Each format the master writes: EXR float and half with Z and N,
// TIFF, PNG; EXR with Z and N under other --exr-compression choices than the default zip. The files go to $TMPDIR (default /tmp) and are removed. Speed is reported here, never
// asserted (not part of ctest). Run: build/release/tests/bench/rtc-image-bench
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <system_error>

#include <unistd.h>

#include "common/image/image.h"
#include "common/render/renderer.h"
#include "common/scene/load.h"

namespace {

constexpr int kSize = 2048;

// A frame as a renderer leaves it: the built-in scene at 2048x2048, one sample a pixel, depth
// and normals (zip compresses a rendered frame far less than a smooth made-up one).
const rtc::Image& frame() {
  static const rtc::Image image = [] {
    rtc::Scene scene = rtc::default_scene();
    scene.width = kSize;
    scene.height = kSize;
    rtc::Renderer renderer(std::move(scene));
    return renderer.render_frame(*renderer.prepare(0));
  }();
  return image;
}

std::filesystem::path out_path(const char* extension) {
  const char* dir = std::getenv("TMPDIR");
  return std::filesystem::path(dir != nullptr && *dir != '\0' ? dir : "/tmp") /
         ("rtc-image-bench-" + std::to_string(::getpid()) + extension);
}

void write(benchmark::State& state, const char* extension, const rtc::ImageWriteOptions& options) {
  const rtc::Image& image = frame();
  const std::filesystem::path path = out_path(extension);
  for (auto _ : state) {
    rtc::write_image(path, image, options);
    state.PauseTiming();
    std::error_code ignored;
    state.counters["file_MB"] = static_cast<double>(std::filesystem::file_size(path, ignored)) / 1e6;
    std::filesystem::remove(path, ignored);
    state.ResumeTiming();
  }
  state.counters["frame_MB"] = static_cast<double>(rtc::Image::bytes(kSize, kSize, true, true)) / 1e6;
}

void ExrFloatZN(benchmark::State& state) {
  rtc::ImageWriteOptions o;
  o.exr_type = rtc::ExrPixelType::Float;
  write(state, ".exr", o);
}
void ExrHalfZN(benchmark::State& state) { write(state, ".exr", {}); }
void ExrHalfRgba(benchmark::State& state) {
  rtc::ImageWriteOptions o;
  o.write_depth = false;
  o.write_normal = false;
  write(state, ".exr", o);
}
void Tiff(benchmark::State& state) { write(state, ".tif", {}); }
void Png(benchmark::State& state) { write(state, ".png", {}); }

// The same frame with each other --exr-compression (the ones above are zip).
void ExrZN(benchmark::State& state, rtc::ExrPixelType type, rtc::ExrCompression compression) {
  rtc::ImageWriteOptions o;
  o.exr_type = type;
  o.exr_compression = compression;
  write(state, ".exr", o);
}

BENCHMARK(ExrFloatZN)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(ExrZN, float_none, rtc::ExrPixelType::Float, rtc::ExrCompression::None)
    ->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(ExrZN, float_zips, rtc::ExrPixelType::Float, rtc::ExrCompression::Zips)
    ->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(ExrZN, float_piz, rtc::ExrPixelType::Float, rtc::ExrCompression::Piz)
    ->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(ExrZN, float_pxr24, rtc::ExrPixelType::Float, rtc::ExrCompression::Pxr24)
    ->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(ExrZN, half_none, rtc::ExrPixelType::Half, rtc::ExrCompression::None)
    ->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(ExrZN, half_piz, rtc::ExrPixelType::Half, rtc::ExrCompression::Piz)
    ->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(ExrZN, half_dwaa, rtc::ExrPixelType::Half, rtc::ExrCompression::Dwaa)
    ->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(ExrHalfZN)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(ExrHalfRgba)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(Tiff)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(Png)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
