// Load-time comparison behind the loader choices in common/scene/*_loader.cpp: this project's
// loaders against tinyobjloader and Assimp on the same files (best of N runs, page cache warm).
// Not a test (speed is never asserted); build with `cmake --build <dir> --target
// scene_load_timing` and run `scene_load_timing [runs] file...`.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <tiny_obj_loader.h>

#include "common/scene/load.h"
#include "common/scene/mesh_file.h"

namespace {

template <typename F>
double best_ms(int runs, F&& f) {
  double best = 1e300;
  for (int r = 0; r < runs; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    const auto t1 = std::chrono::steady_clock::now();
    best = std::min(best, std::chrono::duration<double, std::milli>(t1 - t0).count());
  }
  return best;
}

}  // namespace

int main(int argc, char** argv) {
  int first = 1;
  int runs = 5;
  if (argc > 1 && std::atoi(argv[1]) > 0) {
    runs = std::atoi(argv[1]);
    first = 2;
  }
  for (int i = first; i < argc; ++i) {
    const std::string path = argv[i];
    const std::string ext = path.substr(path.find_last_of('.') + 1);
    if (ext == "json") {
      const double scene = best_ms(runs, [&] { (void)rtc::load_scene(path); });
      std::printf("%s\n  load_scene      %8.1f ms\n", path.c_str(), scene);
      continue;
    }
    std::size_t triangles = 0;
    const double own =
        best_ms(runs, [&] { triangles = rtc::load_mesh_file(path).mesh.triangles.size(); });
    std::printf("%s: %zu triangles\n  rtc loader      %8.1f ms\n", path.c_str(), triangles, own);
    if (ext == "obj") {
      const double tiny = best_ms(runs, [&] {
        tinyobj::ObjReaderConfig config;
        config.triangulate = false;
        tinyobj::ObjReader reader;
        if (!reader.ParseFromFile(path, config)) std::printf("  tinyobjloader error\n");
      });
      std::printf("  tinyobjloader   %8.1f ms (parse only)\n", tiny);
    }
    if (ext != "nff") {
      const double assimp = best_ms(runs, [&] {
        Assimp::Importer importer;
        if (importer.ReadFile(path, aiProcess_ValidateDataStructure) == nullptr) {
          std::printf("  assimp error: %s\n", importer.GetErrorString());
        }
      });
      std::printf("  Assimp ReadFile %8.1f ms (parse only)\n", assimp);
    }
  }
  return 0;
}
