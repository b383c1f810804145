// load_mesh_file: picks the loader by file extension.
#include "common/scene/mesh_file.h"

#include <algorithm>
#include <cctype>
#include <string>

#include "common/base/error.h"

namespace rtc {
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

}  // namespace

MeshFile load_mesh_file(const std::filesystem::path& path, const MeshLoadOptions& options) {
  const std::string file = path.string();
  const std::string ext = lower(path.extension().string());
  const std::string inner = lower(path.stem().extension().string());
  if (ext == ".gz" || ext == ".xz" || ext == ".bz2" || ext == ".zst") {
    throw_at(file, 0,
             "compressed " + (inner.empty() ? std::string("file") : inner.substr(1)) +
                 "; decompress it first (e.g. " + (ext == ".gz" ? "gunzip -k " : "xz -dk ") +
                 path.filename().string() + ") and load the result");
  }
  if (const std::string why = missing_file_reason(file); !why.empty()) throw_at(file, 0, why);
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw_at(file, 0, "is a folder, not a mesh or scene file");
  if (ext == ".obj") return load_obj(path);
  if (ext == ".ply") return load_ply(path);
  if (ext == ".gltf" || ext == ".glb") return load_gltf(path);
  if (ext == ".nff") return load_nff(path, options.tessellation);
  throw_at(file, 0,
           "unknown mesh format \"" + ext + "\" (expected .obj, .ply, .gltf, .glb or .nff)");
}

}  // namespace rtc
