// Runs a fuzz target over saved inputs without libFuzzer (ctest label fuzz): every file of the
// folders (and files) named on the command line, in name order, skipping names that start with
// a dot. A folder that does not exist is passed over (a target with no regressions yet has no
// regressions/<target>), but a run with no input at all fails. Built with the project's own
// compiler, so the release, asan and tsan presets all replay the corpus and the regressions.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "tests/fuzz/fuzz_support.h"

int main(int argc, char** argv) {
  namespace fs = std::filesystem;
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s CORPUS_DIR_OR_FILE...\n", argv[0]);
    return 2;
  }
  std::size_t total = 0;
  for (int a = 1; a < argc; ++a) {
    const fs::path root(argv[a]);
    std::error_code ec;
    std::vector<fs::path> files;
    if (fs::is_directory(root, ec)) {
      for (const auto& entry : fs::directory_iterator(root)) {
        if (entry.is_regular_file() && entry.path().filename().string().front() != '.') files.push_back(entry.path());
      }
      std::sort(files.begin(), files.end());
    } else if (fs::is_regular_file(root, ec)) {
      files.push_back(root);
    } else {
      std::printf("replay: no %s (nothing to replay there)\n", root.c_str());
      continue;
    }
    for (const fs::path& file : files) {
      std::ifstream in(file, std::ios::binary);
      const std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      if (!in.good() && !in.eof()) {
        std::fprintf(stderr, "replay: %s: read error\n", file.c_str());
        return 2;
      }
      std::fprintf(stderr, "replay: %s (%zu bytes)\n", file.c_str(), bytes.size());
      (void)LLVMFuzzerTestOneInput(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
      ++total;
    }
    std::printf("replay: %zu inputs from %s\n", files.size(), root.c_str());
  }
  if (total == 0) {
    std::fprintf(stderr, "replay: no inputs found\n");
    return 2;
  }
  std::printf("replay: %zu inputs, all passed\n", total);
  return 0;
}
