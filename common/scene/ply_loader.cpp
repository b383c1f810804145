// PLY loader (ascii, binary_little_endian, binary_big_endian), hand-written.
//
// Measured on the dev container (2 cores, files in the page cache, best of 9 runs, Release -O3,
// `scene_load_timing 9 <file>` from tests/unit/scene), loading into rtc::Mesh; the Assimp 5.2
// figures are its ReadFile alone, before any conversion:
//   spd-mount-s10.ply (2,097,920 tris, 38 MiB, binary)  this loader  49 ms   Assimp 368 ms
//   spd-balls.ply     (1,417,154 tris, 26 MiB, binary)  this loader  18 ms   Assimp 238 ms
//   Wuson.ply         (3,732 tris, 0.9 MiB, ascii)      this loader 3.3 ms   Assimp 6.8 ms
// The binary fast path maps the file (FileBytes), copies float x/y/z records in one go and
// feeds `list uchar int` faces straight to the MeshBuilder.
// The reader validates everything it reads: header syntax, property types, element counts
// (binary: against the bytes left, before allocating, and by the file size for elements
// without properties; ascii: against the data lines), list lengths, index range, finite
// coordinates within float range (double properties) and truncation. A header line without a
// keyword (Wuson.ply's third line) is skipped with a warning, as Assimp does.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "common/base/error.h"
#include "common/base/log.h"
#include "common/scene/file_bytes.h"
#include "common/scene/mesh_builder.h"
#include "common/scene/mesh_file.h"
#include "common/scene/text_cursor.h"

namespace rtc {
namespace {

enum class PlyFormat { ascii, binary_le, binary_be };
enum class PlyType : std::uint8_t { i8, u8, i16, u16, i32, u32, f32, f64 };

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::f32;
  bool is_list = false;
  PlyType count_type = PlyType::u8;
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> properties;
  std::uint64_t header_line = 0;
};

bool parse_type(std::string_view word, PlyType& type) {
  struct Name {
    std::string_view name;
    PlyType type;
  };
  static constexpr Name kNames[] = {
      {"char", PlyType::i8},    {"int8", PlyType::i8},     {"uchar", PlyType::u8},
      {"uint8", PlyType::u8},   {"short", PlyType::i16},   {"int16", PlyType::i16},
      {"ushort", PlyType::u16}, {"uint16", PlyType::u16},  {"int", PlyType::i32},
      {"int32", PlyType::i32},  {"uint", PlyType::u32},    {"uint32", PlyType::u32},
      {"float", PlyType::f32},  {"float32", PlyType::f32}, {"double", PlyType::f64},
      {"float64", PlyType::f64}};
  for (const Name& n : kNames) {
    if (n.name == word) {
      type = n.type;
      return true;
    }
  }
  return false;
}

std::size_t type_size(PlyType t) {
  switch (t) {
    case PlyType::i8:
    case PlyType::u8:
      return 1;
    case PlyType::i16:
    case PlyType::u16:
      return 2;
    case PlyType::i32:
    case PlyType::u32:
    case PlyType::f32:
      return 4;
    case PlyType::f64:
      return 8;
  }
  return 1;
}

bool is_integer(PlyType t) { return t != PlyType::f32 && t != PlyType::f64; }

template <typename T>
T load_bytes(const unsigned char* p, bool swap) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (swap) {
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
  }
  T value;
  std::memcpy(&value, b, sizeof(T));
  return value;
}

/// One binary scalar as double (exact for every PLY type).
double load_scalar(const unsigned char* p, PlyType t, bool swap) {
  switch (t) {
    case PlyType::i8:
      return static_cast<std::int8_t>(p[0]);
    case PlyType::u8:
      return p[0];
    case PlyType::i16:
      return load_bytes<std::int16_t>(p, swap);
    case PlyType::u16:
      return load_bytes<std::uint16_t>(p, swap);
    case PlyType::i32:
      return load_bytes<std::int32_t>(p, swap);
    case PlyType::u32:
      return load_bytes<std::uint32_t>(p, swap);
    case PlyType::f32:
      return load_bytes<float>(p, swap);
    case PlyType::f64:
      return load_bytes<double>(p, swap);
  }
  return 0.0;
}

class PlyReader {
 public:
  explicit PlyReader(const std::filesystem::path& path)
      : file_(path.string()),
        storage_(path),
        bytes_(storage_.view()),
        builder_(path.stem().string(), path.string()) {}

  MeshFile read() {
    const std::uint64_t header_lines = read_header();
    swap_ = format_ == PlyFormat::binary_be;
    std::optional<TextCursor> text;
    if (format_ == PlyFormat::ascii) {
      const std::string_view data = bytes_.substr(pos_);
      text.emplace(data, file_, false, header_lines + 1);
      data_lines_ = static_cast<std::uint64_t>(std::count(data.begin(), data.end(), '\n')) +
                    (data.empty() || data.back() == '\n' ? 0 : 1);
    }
    for (const PlyElement& element : elements_) {
      check_fits(element);
      if (&element == vertex_element_) {
        read_vertices(element, text ? &*text : nullptr);
        vertices_done_ = true;
      } else if (&element == face_element_ && !text && vertices_done_ &&
                 element.properties.size() == 1) {
        read_faces_binary(element);
      } else {
        read_other(element, text ? &*text : nullptr);
      }
    }
    if (text) {
      if (!text->next_token().empty()) {
        spdlog::warn("{}:{}: data after the last element ignored", file_, text->line());
      }
    } else if (pos_ < bytes_.size()) {
      spdlog::warn("{}: {} bytes after the last element ignored", file_, bytes_.size() - pos_);
    }
    build_triangles();
    MeshFile file;
    file.mesh = builder_.finish();
    file.materials.emplace_back();
    return file;
  }

 private:
  [[noreturn]] void fail(std::uint64_t line, const std::string& message) const {
    throw_at(file_, line, message);
  }

  // --- header ---------------------------------------------------------------------------

  /// Parses the header, leaves pos_ at the first data byte, returns the header's line count.
  std::uint64_t read_header() {
    std::uint64_t line_no = 0;
    bool warned_unknown = false;
    std::size_t at = 0;
    for (;;) {
      if (at >= bytes_.size()) fail(line_no, "header has no end_header line (truncated file?)");
      std::size_t end = bytes_.find('\n', at);
      if (end == std::string_view::npos) end = bytes_.size();
      std::string_view line(bytes_.data() + at, end - at);
      if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
      at = end + 1;
      ++line_no;
      TextCursor words(line, file_, false);
      const std::string_view key = words.next_token();
      if (line_no == 1) {
        if (key != "ply" || words.more_on_line()) {
          fail(1, "not a PLY file (the first line must be \"ply\")");
        }
        continue;
      }
      if (key == "end_header") {
        pos_ = end == bytes_.size() ? end : at;
        break;
      }
      if (key == "format") {
        const std::string_view name = words.next_token();
        const std::string_view version = words.next_token();
        if (name == "ascii") {
          format_ = PlyFormat::ascii;
        } else if (name == "binary_little_endian") {
          format_ = PlyFormat::binary_le;
        } else if (name == "binary_big_endian") {
          format_ = PlyFormat::binary_be;
        } else {
          fail(line_no, "unknown PLY format " + quoted(name));
        }
        if (version != "1.0") fail(line_no, "unsupported PLY version " + quoted(version));
        has_format_ = true;
      } else if (key == "element") {
        PlyElement element;
        element.name = std::string(words.next_token());
        std::int64_t count = -1;
        if (element.name.empty() || !parse_int(words.next_token(), count) || count < 0) {
          fail(line_no, "bad element line (expected \"element <name> <count>\")");
        }
        element.count = static_cast<std::uint64_t>(count);
        element.header_line = line_no;
        elements_.push_back(std::move(element));
      } else if (key == "property") {
        if (elements_.empty()) fail(line_no, "property before the first element");
        PlyProperty property;
        std::string_view type_word = words.next_token();
        if (type_word == "list") {
          property.is_list = true;
          if (!parse_type(words.next_token(), property.count_type) ||
              !is_integer(property.count_type)) {
            fail(line_no, "bad list count type (expected an integer type)");
          }
          type_word = words.next_token();
        }
        if (!parse_type(type_word, property.type)) {
          fail(line_no, "unknown property type " + quoted(type_word));
        }
        property.name = std::string(words.next_token());
        if (property.name.empty()) fail(line_no, "property without a name");
        elements_.back().properties.push_back(std::move(property));
      } else if (key != "comment" && key != "obj_info" && !key.empty() && !warned_unknown) {
        // Wuson.ply's third line is a comment without the keyword; Assimp skips it too.
        spdlog::warn("{}:{}: header line without a PLY keyword skipped: {}", file_, line_no,
                     quoted(line));
        warned_unknown = true;
      }
    }
    if (!has_format_) fail(0, "header has no format line");
    for (const PlyElement& element : elements_) {
      if (element.name == "vertex" && vertex_element_ == nullptr) vertex_element_ = &element;
      if (element.name == "face" && face_element_ == nullptr) face_element_ = &element;
    }
    if (vertex_element_ == nullptr) fail(0, "no \"element vertex\" in the header");
    if (face_element_ == nullptr) fail(0, "no \"element face\" in the header (a point cloud?)");
    for (int axis = 0; axis < 3; ++axis) {
      const std::string name(1, static_cast<char>('x' + axis));
      xyz_[axis] = find_scalar(*vertex_element_, name);
      if (xyz_[axis] < 0) {
        fail(vertex_element_->header_line, "element vertex has no scalar property " + name);
      }
    }
    const char* normal_names[3] = {"nx", "ny", "nz"};
    int found = 0;
    for (int axis = 0; axis < 3; ++axis) {
      normal_[axis] = find_scalar(*vertex_element_, normal_names[axis]);
      found += normal_[axis] >= 0 ? 1 : 0;
    }
    has_normals_ = found == 3;
    for (std::size_t i = 0; i < face_element_->properties.size(); ++i) {
      const PlyProperty& p = face_element_->properties[i];
      if (p.is_list && (p.name == "vertex_indices" || p.name == "vertex_index")) {
        if (!is_integer(p.type)) {
          fail(face_element_->header_line, "face vertex indices must have an integer type");
        }
        index_property_ = i;
        break;
      }
    }
    if (index_property_ == kNoProperty) {
      fail(face_element_->header_line, "element face has no list property vertex_indices");
    }
    return line_no;
  }

  static int find_scalar(const PlyElement& element, const std::string& name) {
    for (std::size_t i = 0; i < element.properties.size(); ++i) {
      if (element.properties[i].name == name && !element.properties[i].is_list) {
        return static_cast<int>(i);
      }
    }
    return -1;
  }

  // --- data -----------------------------------------------------------------------------

  [[nodiscard]] std::size_t remaining() const { return bytes_.size() - pos_; }
  [[nodiscard]] const unsigned char* data_at(std::size_t pos) const {
    return reinterpret_cast<const unsigned char*>(bytes_.data()) + pos;
  }

  /// Fails before anything is allocated (or looped over) unless `element.count` items fit in
  /// what is left. Binary: each item takes at least its fixed part (lists empty); an element
  /// without properties takes no bytes, so its count is bounded by the file size instead.
  /// Ascii: one line per item, two bytes per value.
  void check_fits(const PlyElement& element) const {
    if (format_ == PlyFormat::ascii && element.count > data_lines_) {
      fail(element.header_line,
           "element " + element.name + " declares " + std::to_string(element.count) +
               " items but the data has only " + std::to_string(data_lines_) +
               " lines (one item per line)");
    }
    std::size_t min_size = 0;
    for (const PlyProperty& p : element.properties) {
      min_size += format_ == PlyFormat::ascii ? 2 : type_size(p.is_list ? p.count_type : p.type);
    }
    if (min_size == 0 && element.count > bytes_.size()) {
      fail(element.header_line,
           "element " + element.name + " has no properties but declares " +
               std::to_string(element.count) + " items, more than the file's " +
               std::to_string(bytes_.size()) + " bytes");
    }
    if (min_size > 0 && element.count > remaining() / min_size) {
      fail(0, "truncated file: element " + element.name + " declares " +
                  std::to_string(element.count) + " items of at least " + std::to_string(min_size) +
                  " bytes but only " + std::to_string(remaining()) + " bytes remain");
    }
  }

  static std::string item_name(const PlyElement& element, std::uint64_t item) {
    return element.name + " " + std::to_string(item);
  }

  /// One value: binary at pos_ (bounds-checked) or the next ascii token.
  double value(TextCursor* text, PlyType type, const PlyElement& element, std::uint64_t item) {
    if (text == nullptr) {
      const std::size_t size = type_size(type);
      if (remaining() < size) {
        fail(0, "truncated file: " + item_name(element, item) + " of " +
                    std::to_string(element.count) + " ends past the end of the file");
      }
      const double v = load_scalar(data_at(pos_), type, swap_);
      pos_ += size;
      return v;
    }
    const std::string_view token = text->next_token();
    if (token.empty()) {
      fail(text->line(), "truncated file: " + item_name(element, item) + " of " +
                             std::to_string(element.count) + " ends early");
    }
    if (is_integer(type)) {
      std::int64_t v = 0;
      if (!parse_int(token, v)) {
        fail(text->line(), item_name(element, item) + ": bad integer " + quoted(token));
      }
      return static_cast<double>(v);
    }
    float v = 0.0f;
    if (!parse_finite_float(token, v)) {
      fail(text->line(), item_name(element, item) + ": bad number " + quoted(token) +
                             " (expected a finite number)");
    }
    return v;
  }

  /// (x, y, z) as floats; fails naming the item unless every value is finite and within float
  /// range (a double property beyond FLT_MAX would overflow the conversion).
  glm::vec3 to_vec3(double x, double y, double z, const PlyElement& element, std::uint64_t item,
                    std::uint64_t line, const char* what) const {
    const double v[3] = {x, y, z};
    for (const double c : v) {
      if (!std::isfinite(c)) {
        fail(line, item_name(element, item) + ": non-finite " + what +
                       fmt::format(" ({}, {}, {})", x, y, z));
      }
      if (std::abs(c) > static_cast<double>(std::numeric_limits<float>::max())) {
        fail(line, item_name(element, item) + ": " + what + fmt::format(" ({}, {}, {})", x, y, z) +
                       " is out of float range");
      }
    }
    return {static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)};
  }

  void check_finite(const glm::vec3& v, const PlyElement& element, std::uint64_t item,
                    std::uint64_t line, const char* what) const {
    if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) {
      fail(line, item_name(element, item) + ": non-finite " + what + " (" + std::to_string(v.x) +
                     ", " + std::to_string(v.y) + ", " + std::to_string(v.z) + ")");
    }
  }

  void read_vertices(const PlyElement& element, TextCursor* text) {
    builder_.reserve(static_cast<std::size_t>(element.count), 0);
    bool fixed = text == nullptr;
    std::size_t record_size = 0;
    for (const PlyProperty& p : element.properties) {
      fixed = fixed && !p.is_list;
      record_size += type_size(p.type);
    }
    if (fixed && !swap_ && !has_normals_ && element.properties.size() == 3 && xyz_[0] == 0 &&
        xyz_[1] == 1 && xyz_[2] == 2 && element.properties[0].type == PlyType::f32 &&
        element.properties[1].type == PlyType::f32 && element.properties[2].type == PlyType::f32) {
      // The pack's layout (float x, y, z, little-endian): one copy, then the finiteness check.
      static_assert(sizeof(glm::vec3) == 12);
      const std::uint32_t first =
          builder_.add_vertices(data_at(pos_), static_cast<std::size_t>(element.count));
      pos_ += static_cast<std::size_t>(element.count) * 12;
      for (std::uint64_t item = 0; item < element.count; ++item) {
        check_finite(builder_.position(first + static_cast<std::uint32_t>(item)), element, item, 0,
                     "coordinate");
      }
      return;
    }
    if (fixed) {
      // Fixed-size binary records (check_fits has bounded the count): offsets computed once.
      std::size_t offset[6] = {};
      PlyType type[6] = {};
      for (int w = 0; w < 6; ++w) {
        const int prop = w < 3 ? xyz_[w] : normal_[w - 3];
        if (prop < 0) continue;
        for (int i = 0; i < prop; ++i) offset[w] += type_size(element.properties[i].type);
        type[w] = element.properties[prop].type;
      }
      for (std::uint64_t item = 0; item < element.count; ++item) {
        const unsigned char* record = data_at(pos_);
        pos_ += record_size;
        double v[6] = {};
        for (int w = 0; w < (has_normals_ ? 6 : 3); ++w) {
          v[w] = load_scalar(record + offset[w], type[w], swap_);
        }
        const glm::vec3 p = to_vec3(v[0], v[1], v[2], element, item, 0, "coordinate");
        if (!has_normals_) {
          builder_.add_vertex(p);
          continue;
        }
        builder_.add_vertex(p, to_vec3(v[3], v[4], v[5], element, item, 0, "normal"));
      }
      return;
    }
    std::vector<double> values(element.properties.size());
    for (std::uint64_t item = 0; item < element.count; ++item) {
      for (std::size_t i = 0; i < element.properties.size(); ++i) {
        const PlyProperty& p = element.properties[i];
        if (p.is_list) {
          skip_list(text, p, element, item);
        } else {
          values[i] = value(text, p.type, element, item);
        }
      }
      const std::uint64_t line = text != nullptr ? text->line() : 0;
      const glm::vec3 p = to_vec3(values[xyz_[0]], values[xyz_[1]], values[xyz_[2]], element, item,
                                  line, "coordinate");
      if (!has_normals_) {
        builder_.add_vertex(p);
        continue;
      }
      builder_.add_vertex(p, to_vec3(values[normal_[0]], values[normal_[1]], values[normal_[2]],
                                     element, item, line, "normal"));
    }
  }

  std::size_t list_length(TextCursor* text, const PlyProperty& p, const PlyElement& element,
                          std::uint64_t item) {
    const double n = value(text, p.count_type, element, item);
    // Binary: the items must fit in what is left; ascii: at least two bytes each.
    const std::size_t left = text == nullptr ? remaining() / type_size(p.type) : bytes_.size() / 2;
    if (n < 0 || n > static_cast<double>(left)) {
      fail(text != nullptr ? text->line() : 0, item_name(element, item) + ": bad list length " +
                                                   std::to_string(static_cast<std::int64_t>(n)) +
                                                   (n < 0 ? "" : " (truncated file?)"));
    }
    return static_cast<std::size_t>(n);
  }

  void skip_list(TextCursor* text, const PlyProperty& p, const PlyElement& element,
                 std::uint64_t item) {
    const std::size_t n = list_length(text, p, element, item);
    if (text == nullptr) {
      pos_ += n * type_size(p.type);
      return;
    }
    for (std::size_t k = 0; k < n; ++k) value(text, p.type, element, item);
  }

  /// Binary face element holding only the index list, vertices already read: triangles go
  /// straight to the builder. Specialised for the common count/index types.
  void read_faces_binary(const PlyElement& element) {
    const PlyProperty& p = element.properties[0];
    if (p.count_type == PlyType::u8 && p.type == PlyType::i32 && !swap_) {
      read_faces_typed<std::uint8_t, std::int32_t>(element);
    } else if (p.count_type == PlyType::u8 && p.type == PlyType::u32 && !swap_) {
      read_faces_typed<std::uint8_t, std::uint32_t>(element);
    } else {
      read_other(element, nullptr);
    }
  }

  template <typename CountT, typename IndexT>
  void read_faces_typed(const PlyElement& element) {
    static_assert(sizeof(CountT) == 1, "corners[] holds up to 255 indices");
    const std::uint32_t vertex_count = builder_.vertex_count();
    builder_.reserve(0, static_cast<std::size_t>(element.count));
    std::uint32_t corners[256];
    for (std::uint64_t item = 0; item < element.count; ++item) {
      if (remaining() < sizeof(CountT)) {
        fail(0, "truncated file: face " + std::to_string(item) + " of " +
                    std::to_string(element.count) + " ends past the end of the file");
      }
      const std::size_t n = load_bytes<CountT>(data_at(pos_), false);
      pos_ += sizeof(CountT);
      if (n < 3) {
        fail(0, "face " + std::to_string(item) + " has " + std::to_string(n) +
                    " vertices (a face needs at least 3)");
      }
      if (remaining() / sizeof(IndexT) < n) {
        fail(0, "truncated file: face " + std::to_string(item) + " of " +
                    std::to_string(element.count) + " ends past the end of the file");
      }
      for (std::size_t k = 0; k < n; ++k) {
        const IndexT index = load_bytes<IndexT>(data_at(pos_ + k * sizeof(IndexT)), false);
        // A negative index turns into a huge unsigned one here.
        if (static_cast<std::uint64_t>(static_cast<std::int64_t>(index)) >= vertex_count) {
          fail(0, "face " + std::to_string(item) + ": vertex index " + std::to_string(index) +
                      " out of range (" + std::to_string(vertex_count) + " vertices)");
        }
        corners[k] = static_cast<std::uint32_t>(index);
      }
      pos_ += n * sizeof(IndexT);
      for (std::size_t k = 1; k + 1 < n; ++k) {
        builder_.add_triangle(corners[0], corners[k], corners[k + 1]);
      }
    }
  }

  // Faces are kept as (size, indices) and triangulated once all elements are read, since a
  // file may list faces before vertices.
  void read_other(const PlyElement& element, TextCursor* text) {
    const bool is_face = &element == face_element_;
    if (is_face) {
      face_sizes_.reserve(static_cast<std::size_t>(element.count));
      face_indices_.reserve(static_cast<std::size_t>(element.count) * 3);
      if (text != nullptr) face_lines_.reserve(static_cast<std::size_t>(element.count));
    }
    for (std::uint64_t item = 0; item < element.count; ++item) {
      for (std::size_t i = 0; i < element.properties.size(); ++i) {
        const PlyProperty& p = element.properties[i];
        if (!p.is_list) {
          value(text, p.type, element, item);
        } else if (!is_face || i != index_property_) {
          skip_list(text, p, element, item);
        } else {
          read_index_list(text, p, element, item);
        }
      }
    }
  }

  void read_index_list(TextCursor* text, const PlyProperty& p, const PlyElement& element,
                       std::uint64_t item) {
    const std::size_t n = list_length(text, p, element, item);
    const std::uint64_t line = text != nullptr ? text->line() : 0;
    if (n < 3) {
      fail(line, item_name(element, item) + " has " + std::to_string(n) +
                     " vertices (a face needs at least 3)");
    }
    face_sizes_.push_back(static_cast<std::uint32_t>(n));
    if (text != nullptr) face_lines_.push_back(line);
    for (std::size_t k = 0; k < n; ++k) {
      const double index = value(text, p.type, element, item);
      if (index < 0 || index >= 4294967295.0) {
        fail(text != nullptr ? text->line() : 0,
             item_name(element, item) + ": vertex index " +
                 std::to_string(static_cast<std::int64_t>(index)) + " out of range");
      }
      face_indices_.push_back(static_cast<std::uint32_t>(index));
    }
  }

  void build_triangles() {
    const std::uint32_t vertex_count = builder_.vertex_count();
    builder_.reserve(0, face_sizes_.size());
    std::size_t at = 0;
    for (std::size_t face = 0; face < face_sizes_.size(); ++face) {
      const std::uint32_t n = face_sizes_[face];
      const std::uint32_t* corners = face_indices_.data() + at;
      at += n;
      for (std::uint32_t k = 0; k < n; ++k) {
        if (corners[k] >= vertex_count) {
          fail(face_lines_.empty() ? 0 : face_lines_[face],
               "face " + std::to_string(face) + ": vertex index " + std::to_string(corners[k]) +
                   " out of range (" + std::to_string(vertex_count) + " vertices)");
        }
      }
      for (std::uint32_t k = 1; k + 1 < n; ++k) {
        builder_.add_triangle(corners[0], corners[k], corners[k + 1]);
      }
    }
  }

  static constexpr std::size_t kNoProperty = std::numeric_limits<std::size_t>::max();

  std::string file_;
  FileBytes storage_;
  std::string_view bytes_;
  MeshBuilder builder_;
  std::size_t pos_ = 0;
  PlyFormat format_ = PlyFormat::ascii;
  bool has_format_ = false;
  bool swap_ = false;
  std::vector<PlyElement> elements_;
  const PlyElement* vertex_element_ = nullptr;
  const PlyElement* face_element_ = nullptr;
  int xyz_[3] = {-1, -1, -1};
  int normal_[3] = {-1, -1, -1};
  bool has_normals_ = false;
  bool vertices_done_ = false;
  std::uint64_t data_lines_ = 0;  // ascii: lines after end_header
  std::size_t index_property_ = kNoProperty;
  std::vector<std::uint32_t> face_sizes_;
  std::vector<std::uint32_t> face_indices_;
  std::vector<std::uint64_t> face_lines_;
};

}  // namespace

MeshFile load_ply(const std::filesystem::path& path) { return PlyReader(path).read(); }

}  // namespace rtc
