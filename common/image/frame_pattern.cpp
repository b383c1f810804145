// Output file names for frame sequences: "f_####.exr", "f_%04d.exr" or an inserted "_NNNN".
#include "common/image/image.h"

#include <cstddef>
#include <algorithm>
#include <filesystem>
#include <string>
#include <string_view>
#include <system_error>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "common/base/error.h"

namespace rtc {
namespace {

// Wide enough for any int frame number (2147483647 has 10 digits).
constexpr std::size_t kMaxPrintfWidth = 10;
constexpr std::size_t kInsertedWidth = 4;
constexpr std::size_t kMaxStemBytes = 200;
// NAME_MAX on Linux file systems.
constexpr std::size_t kMaxFileNameBytes = 255;

std::string zero_padded(int frame, std::size_t width) {
  std::string digits = std::to_string(frame);
  if (digits.size() < width) digits.insert(0, width - digits.size(), '0');
  return digits;
}

// For errors where a '#' the user meant literally may have been taken for the frame number.
constexpr const char* kHashHint =
    "each run of '#' is the frame number, in folder names too; in a pattern with \"%04d\" for it "
    "every '#' is literal";

// Whether a '%' at `i` begins "%%", a literal '%' (printf's rule), rather than a placeholder.
bool is_escaped_percent(const std::string& pattern, std::size_t i) {
  return i + 1 < pattern.size() && pattern[i + 1] == '%';
}

[[noreturn]] void bad_pattern(const std::string& pattern, const std::string& reason) {
  throw Error(fmt::format("output pattern '{}': {}", pattern, reason));
}

}  // namespace

std::string expand_frame_pattern(const std::string& pattern, int frame, bool multiple_frames) {
  if (pattern.empty()) bad_pattern(pattern, "is empty");
  if (frame < 0) bad_pattern(pattern, fmt::format("frame number {} is negative", frame));
  if (pattern.back() == '/') bad_pattern(pattern, "has no file name");

  // A pattern with a printf-style placeholder treats '#' as an ordinary character, as printf
  // does, so a folder or file name with a '#' in it can be written ("take#2/f_%04d.exr").
  bool printf_style = false;
  for (std::size_t j = 0; j < pattern.size() && !printf_style; ++j) {
    if (pattern[j] != '%') continue;
    if (is_escaped_percent(pattern, j)) {
      ++j;
    } else {
      printf_style = true;
    }
  }

  std::string out;
  int placeholders = 0;
  std::size_t i = 0;
  while (i < pattern.size()) {
    const char c = pattern[i];
    if (c == '#' && !printf_style) {
      std::size_t end = i;
      while (end < pattern.size() && pattern[end] == '#') ++end;
      out += zero_padded(frame, end - i);
      ++placeholders;
      i = end;
    } else if (c == '%') {
      if (is_escaped_percent(pattern, i)) {
        out += '%';
        i += 2;
        continue;
      }
      // Only "%d" and "%0Nd": space padding or other conversions make odd file names.
      std::size_t end = i + 1;
      std::size_t width = 0;
      if (end < pattern.size() && pattern[end] == '0') {
        ++end;
        const std::size_t digits_begin = end;
        while (end < pattern.size() && pattern[end] >= '0' && pattern[end] <= '9' &&
               end - digits_begin < 3) {
          width = 10 * width + static_cast<std::size_t>(pattern[end] - '0');
          ++end;
        }
        if (width == 0 || width > kMaxPrintfWidth) end = pattern.size();  // reported below
      }
      if (end >= pattern.size() || pattern[end] != 'd') {
        bad_pattern(pattern, fmt::format("unsupported placeholder at offset {} (use a run of '#', "
                                         "\"%d\" or \"%0Nd\" with N from 1 to {}, and \"%%\" "
                                         "for '%')",
                                         i, kMaxPrintfWidth));
      }
      out += zero_padded(frame, width);
      ++placeholders;
      i = end + 1;
    } else {
      out += c;
      ++i;
    }
  }
  if (placeholders > 1) {
    bad_pattern(pattern, fmt::format("has {} frame placeholders; a name can hold only one{}", placeholders,
                                     printf_style ? std::string() : fmt::format(" ({})", kHashHint)));
  }
  if (placeholders == 0 && multiple_frames) {
    // The extension belongs to the file name only ("v1.2/out" has none); a leading dot is a
    // hidden file, not an extension.
    const std::size_t name_begin = out.rfind('/') == std::string::npos ? 0 : out.rfind('/') + 1;
    const std::size_t dot = out.rfind('.');
    const std::size_t insert_at =
        (dot == std::string::npos || dot <= name_begin) ? out.size() : dot;
    out.insert(insert_at, fmt::format("_{}", zero_padded(frame, kInsertedWidth)));
  }
  return out;
}

std::string file_stem_for(std::string_view name) {
  std::string out(name);
  bool dots_only = true;
  for (char& c : out) {
    const bool keep = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                      c == '.' || c == '_' || c == '+' || c == '-';
    if (!keep) c = '_';
    dots_only = dots_only && c == '.';
  }
  // A name longer than a file name may be (255 bytes, with the frame number and extension).
  if (out.size() > kMaxStemBytes) out.resize(kMaxStemBytes);
  return dots_only ? std::string("scene") : out;
}

std::string numbered_frame_pattern(const std::string& folder, std::string_view scene_name) {
  std::string out;
  for (const char c : folder) {
    out += c;
    if (c == '%') out += '%';
  }
  if (!out.empty() && out.back() != '/') out += '/';
  return out + file_stem_for(scene_name) + "_%04d.png";
}

void check_output_pattern_early(const std::string& pattern, int frame, bool multiple_frames) {
  const std::filesystem::path path(expand_frame_pattern(pattern, frame, multiple_frames));
  const std::size_t slash = pattern.rfind('/');
  const bool folder_varies = slash != std::string::npos && pattern.find_first_of("#%") < slash;
  if (image_file_kind(path) && folder_varies) return;  // the folder is known per frame, after the load
  if (const std::string problem = output_file_problem(path); !problem.empty()) {
    throw Error("--out: " + path.string() + ": " + problem);
  }
}

std::filesystem::path check_output_pattern(const std::string& pattern, int first_frame, int last_frame,
                                           bool multiple_frames) {
  const std::filesystem::path first(expand_frame_pattern(pattern, first_frame, multiple_frames));
  // Where '#'s in the pattern's folder become the frame number, the message shows the pattern and
  // says so (a folder with a '#' in its name is the likely intent).
  const std::size_t slash = pattern.rfind('/');
  const bool hashes = slash != std::string::npos && pattern.substr(0, slash).find('#') != std::string::npos &&
                      first.parent_path().string().find('#') == std::string::npos;
  std::error_code ec;
  std::filesystem::path checked_folder;  // never empty once set: "." stands for no folder
  // Every frame's name, so that no run stops halfway: a later frame's folder missing (a pattern
  // in the folder's name), a later frame's name taken by a folder.
  for (int frame = first_frame; frame <= std::max(first_frame, last_frame); ++frame) {
    const std::filesystem::path path =
        frame == first_frame ? first : std::filesystem::path(expand_frame_pattern(pattern, frame, multiple_frames));
    const auto bad = [&](const std::string& reason) {
      const bool later = frame != first_frame;
      return Error("--out: " + path.string() + ": " + reason +
                   (hashes ? fmt::format(" (the pattern '{}' gives this name for frame {}: {})", pattern, frame, kHashHint)
                           : later ? fmt::format(" (frame {}'s name; the run's first is {})", frame, first.string())
                                   : std::string()));
    };
    if (std::filesystem::is_directory(path, ec)) throw bad("is a folder");
    const std::size_t name_bytes = path.filename().string().size();
    if (name_bytes > kMaxFileNameBytes) {
      throw bad(fmt::format("the file name is {} bytes; a name may have at most {}", name_bytes, kMaxFileNameBytes));
    }
    const std::filesystem::path folder = path.parent_path().empty() ? "." : path.parent_path();
    if (folder == checked_folder) continue;
    checked_folder = folder;
    // write_image's own checks, then what only writing finds out.
    if (const std::string problem = output_file_problem(path); !problem.empty()) throw bad(problem);
    if (const std::string problem = folder_problem(folder, true); !problem.empty()) throw bad(problem);
  }
  if (std::filesystem::exists(first, ec)) {
    spdlog::warn("--out: {} exists: {} overwritten", first.string(),
                 multiple_frames ? "it and the run's other frames are" : "it is");
  }
  return first;
}

}  // namespace rtc
