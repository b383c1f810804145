// glTF 2.0 (.gltf + .bin, .glb) loader through Assimp: node matrices and instancing are baked
// into one world-space mesh, materials come from baseColorFactor.
//
// Measured (dev container, Release, page cache, best of 9): 2CylinderEngine.glb (121,496
// triangles after instancing, 110,336 after dropping degenerates) loads in 9.6 ms, of which
// Assimp's ReadFile is 6.0 ms. No hand-written reader: glTF files here are small.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <assimp/Importer.hpp>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include "common/base/error.h"
#include "common/base/log.h"
#include "common/scene/material_values.h"
#include "common/scene/mesh_builder.h"
#include "common/scene/mesh_file.h"

namespace rtc {
namespace {

glm::dmat4 to_glm(const aiMatrix4x4& m) {
  // Assimp is row-major (a1..a4 is the first row); glm is column-major.
  glm::dmat4 out;
  const ai_real* rows[4] = {&m.a1, &m.b1, &m.c1, &m.d1};
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) out[c][r] = rows[r][c];
  }
  return out;
}

constexpr double kFloatMax = std::numeric_limits<float>::max();

/// The largest |component|; NaN when any component is NaN.
double max_abs(const glm::dvec3& v) {
  if (std::isnan(v.x) || std::isnan(v.y) || std::isnan(v.z)) return v.x + v.y + v.z;
  return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)});
}

Material to_material(const aiMaterial& source, const std::string& file) {
  Material m;
  aiString name;
  if (source.Get(AI_MATKEY_NAME, name) == AI_SUCCESS && name.length > 0) m.name = name.C_Str();
  aiColor4D color;
  if (source.Get(AI_MATKEY_BASE_COLOR, color) == AI_SUCCESS ||
      source.Get(AI_MATKEY_COLOR_DIFFUSE, color) == AI_SUCCESS) {
    m.diffuse = glm::vec3(color.r, color.g, color.b);
    m.opacity = color.a;
  }
  aiColor3D emissive;
  if (source.Get(AI_MATKEY_COLOR_EMISSIVE, emissive) == AI_SUCCESS) {
    m.emission = glm::vec3(emissive.r, emissive.g, emissive.b);
  }
  const std::string what = "material \"" + m.name + "\"";
  m.diffuse = checked_color(m.diffuse, what + " base colour", file, 0);
  m.emission = checked_color(m.emission, what + " emissive colour", file, 0);
  if (!std::isfinite(m.opacity)) throw_at(file, 0, what + ": non-finite base colour alpha");
  return m;
}

class GltfReader {
 public:
  explicit GltfReader(const std::filesystem::path& path)
      : file_(path.string()), builder_(path.stem().string(), path.string()) {}

  MeshFile read() {
    Assimp::Importer importer;
    // No post-processing that merges, reorders or drops geometry: triangle order must follow
    // the file (source_index) and degenerate triangles are counted here, not by Assimp.
    const aiScene* scene = importer.ReadFile(file_, aiProcess_ValidateDataStructure);
    if (scene == nullptr) throw_at(file_, 0, std::string("glTF: ") + importer.GetErrorString());
    if ((scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE) != 0 || scene->mRootNode == nullptr) {
      throw_at(file_, 0, "glTF: incomplete scene (no node hierarchy)");
    }
    scene_ = scene;
    // Material ids: identical materials (the engine repeats them) share one slot.
    material_of_.resize(scene->mNumMaterials);
    for (unsigned i = 0; i < scene->mNumMaterials; ++i) {
      const Material m = to_material(*scene->mMaterials[i], file_);
      std::uint32_t id = 0;
      while (id < materials_.size() && !(materials_[id] == m)) ++id;
      if (id == materials_.size()) materials_.push_back(m);
      material_of_[i] = id;
    }
    if (materials_.empty()) materials_.emplace_back();
    visit(*scene->mRootNode, glm::dmat4(1.0), 0);
    MeshFile file;
    file.mesh = builder_.finish();
    file.materials = std::move(materials_);
    return file;
  }

 private:
  void visit(const aiNode& node, const glm::dmat4& parent, int depth) {
    if (depth > 256) throw_at(file_, 0, "glTF: node hierarchy deeper than 256 levels");
    const glm::dmat4 world = parent * to_glm(node.mTransformation);
    for (unsigned i = 0; i < node.mNumMeshes; ++i) {
      if (node.mMeshes[i] >= scene_->mNumMeshes) {
        throw_at(
            file_, 0,
            std::string("glTF: node \"") + node.mName.C_Str() + "\" references a missing mesh");
      }
      add_instance(*scene_->mMeshes[node.mMeshes[i]], world, node);
    }
    for (unsigned c = 0; c < node.mNumChildren; ++c) visit(*node.mChildren[c], world, depth + 1);
  }

  void add_instance(const aiMesh& mesh, const glm::dmat4& world, const aiNode& node) {
    const glm::dmat3 normal_matrix = glm::transpose(glm::inverse(glm::dmat3(world)));
    const bool normals = mesh.mNormals != nullptr;
    const std::uint32_t first = builder_.vertex_count();
    builder_.reserve(mesh.mNumVertices, mesh.mNumFaces);
    for (unsigned v = 0; v < mesh.mNumVertices; ++v) {
      const aiVector3D& p = mesh.mVertices[v];
      const glm::dvec3 world_position(world * glm::dvec4(p.x, p.y, p.z, 1.0));
      // Checked in double: converting a value beyond FLT_MAX to float is undefined.
      if (!(max_abs(world_position) <= kFloatMax)) {
        throw_at(file_, 0,
                 std::string("glTF: mesh \"") + mesh.mName.C_Str() + "\" in node \"" +
                     node.mName.C_Str() + "\": vertex " + std::to_string(v) +
                     " has a non-finite position or one outside the float range");
      }
      const glm::vec3 position(world_position);
      if (!normals) {
        builder_.add_vertex(position);
        continue;
      }
      const aiVector3D& n = mesh.mNormals[v];
      glm::dvec3 world_normal = normal_matrix * glm::dvec3(n.x, n.y, n.z);
      const double largest = max_abs(world_normal);
      if (!(largest <= kFloatMax)) {
        // Only the direction matters (the builder normalises): scale it into float range.
        world_normal = std::isfinite(largest) ? world_normal / largest : glm::dvec3(0.0);
      }
      builder_.add_vertex(position, glm::vec3(world_normal));
    }
    builder_.set_material(
        mesh.mMaterialIndex < material_of_.size() ? material_of_[mesh.mMaterialIndex] : 0);
    for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
      const aiFace& face = mesh.mFaces[f];
      if (face.mNumIndices < 3) continue;  // points and lines are not surfaces
      for (unsigned k = 0; k < face.mNumIndices; ++k) {
        if (face.mIndices[k] >= mesh.mNumVertices) {
          throw_at(file_, 0,
                   std::string("glTF: mesh \"") + mesh.mName.C_Str() + "\": face " +
                       std::to_string(f) + " index " + std::to_string(face.mIndices[k]) +
                       " out of range (" + std::to_string(mesh.mNumVertices) + " vertices)");
        }
      }
      for (unsigned k = 1; k + 1 < face.mNumIndices; ++k) {
        builder_.add_triangle(first + face.mIndices[0], first + face.mIndices[k],
                              first + face.mIndices[k + 1]);
      }
    }
  }

  std::string file_;
  MeshBuilder builder_;
  const aiScene* scene_ = nullptr;
  std::vector<Material> materials_;
  std::vector<std::uint32_t> material_of_;
};

}  // namespace

MeshFile load_gltf(const std::filesystem::path& path) { return GltfReader(path).read(); }

}  // namespace rtc
