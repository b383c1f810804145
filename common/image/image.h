// Frames and tiles in memory, their files (EXR, PNG, TIFF, JPEG, PPM), sRGB and frame names.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace rtc {

/// A frame or tile: linear RGBA float, row 0 at the top; optional depth (primary hit
/// distance, +inf for background) and normal (world-space shading normal, 0 for background).
/// Alpha is stored as given: nothing here premultiplies or un-premultiplies. A plain value
/// type, not thread-safe for concurrent writes.
struct Image {
  int width = 0, height = 0;
  std::vector<float> rgba;    // 4 * width * height, pixel (x, y) at 4 * (y * width + x)
  std::vector<float> depth;   // empty or width * height
  std::vector<float> normal;  // empty or 3 * width * height

  Image() = default;
  /// Zero RGBA; depth +inf and normal 0 (the background values) when asked for.
  /// Negative sizes are a caller bug (RTC_CHECK).
  Image(int w, int h, bool with_depth = false, bool with_normal = false);

  /// Makes this image what Image(w, h, with_depth, with_normal) is, in the memory it already
  /// holds where that is large enough: no allocation and no fresh pages for an image of the
  /// same size (a master's frames; a fresh 64 MiB frame cost about 200 ms of page faults on a
  /// VM, measured 2026-12-02).
  void reset(int w, int h, bool with_depth = false, bool with_normal = false);

  /// The bytes Image(w, h, with_depth, with_normal) holds in its pixels: 16 a pixel for RGBA,
  /// 4 for depth, 12 for normals (callers check a frame fits in memory before making one).
  [[nodiscard]] static std::uint64_t bytes(int w, int h, bool with_depth, bool with_normal) {
    return std::uint64_t{static_cast<std::uint32_t>(w)} * static_cast<std::uint32_t>(h) *
           sizeof(float) * (4u + (with_depth ? 1u : 0u) + (with_normal ? 3u : 0u));
  }

  /// Whether this image is what Image(w, h, with_depth, with_normal) makes in size and channels
  /// (its pixel values aside).
  [[nodiscard]] bool has_shape(int w, int h, bool with_depth, bool with_normal) const;

  [[nodiscard]] bool has_depth() const { return !depth.empty(); }
  [[nodiscard]] bool has_normal() const { return !normal.empty(); }

  /// The 4 RGBA floats of pixel (x, y); bounds are checked in debug builds only.
  float* pixel(int x, int y);
  const float* pixel(int x, int y) const;

  /// Copies `tile` into this image at (x0, y0): RGBA always, depth and normal when present
  /// in both. Throws rtc::Error naming both rectangles when the tile does not fit, or when
  /// either image's channel vectors do not match its size (tiles arrive from peers).
  void blit(const Image& tile, int x0, int y0);
};

enum class ExrPixelType { Half, Float };

/// OpenEXR's compressions. None, Rle, Zips (zip a line), Zip (16 lines) and Piz keep every
/// bit. Pxr24 rounds float channels to 24 bits (Z always; half channels kept); B44 and B44a
/// lose detail of half channels (float ones kept); Dwaa and Dwab lose detail of R, G, B and
/// N.Y (a channel named Y is luminance to them; float ones first rounded to half) and keep A,
/// Z, N.X and N.Z exact.
enum class ExrCompression { None, Rle, Zips, Zip, Piz, Pxr24, B44, B44a, Dwaa, Dwab };

/// "none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab": OpenEXR's
/// (and OpenImageIO's "compression" attribute's) names.
[[nodiscard]] std::string_view exr_compression_name(ExrCompression c);
/// The compression of a name exr_compression_name gives, or nullopt.
[[nodiscard]] std::optional<ExrCompression> parse_exr_compression(std::string_view name);
/// Whether the compression may change pixel values of a file with RGBA and N stored as `type`,
/// and Z (always float) when `with_depth`.
[[nodiscard]] bool exr_compression_lossy(ExrCompression c, ExrPixelType type, bool with_depth);
/// "none, rle, zips, zip, piz, pxr24, b44, b44a, dwaa or dwab", for error messages.
[[nodiscard]] std::string exr_compression_names();

struct ImageWriteOptions {
  /// EXR storage of RGBA and N (Z is always float: depth needs more than half's 11 bits).
  ExrPixelType exr_type = ExrPixelType::Half;
  bool write_depth = true;   // EXR only: channel "Z" when the image has depth
  bool write_normal = true;  // EXR only: channels "N.X", "N.Y", "N.Z" when it has normals
  /// EXR only. A rendered 2048x2048 float frame with Z and N: zip (the default) about 1.0 s,
  /// 39 MB; piz 0.8 s, 35 MB; none 0.8-1.0 s, 134 MB (rtc-image-bench, 2026-12-04).
  ExrCompression exr_compression = ExrCompression::Zip;
  /// String attributes stored in the file header (EXR attributes, PNG text chunks, TIFF and
  /// JPEG where the format has room), e.g. {"rtc:scene", "sponza.json"}.
  std::vector<std::pair<std::string, std::string>> metadata;
};

/// Writes `image` in the format named by the extension (case-insensitive):
///   .exr         one part, channels "R" "G" "B" "A" (half or float per options), "Z" (float),
///                "N.X" "N.Y" "N.Z" (like RGBA), linear, options.exr_compression (zip);
///   .png         8-bit sRGB RGBA (linear_to_srgb8 on RGB, linear_to_unorm8 on alpha);
///   .tif/.tiff   32-bit float linear RGBA;
///   .jpg/.jpeg   8-bit sRGB RGB, alpha dropped;
///   .ppm         8-bit sRGB RGB (binary P6), alpha dropped.
/// The parent folder must exist (it is not created). The pixels go to a temporary file in the
/// same folder that is flushed to disk and then renamed over `path`, so a crash never leaves
/// a half-written frame under the final name. Throws rtc::Error naming the file and the reason
/// (missing folder, unknown extension, OpenImageIO's message); no temporary file is left behind.
/// EXR and TIFF headers carry the write time (OpenImageIO adds "DateTime" unless `metadata`
/// sets it), so compare frames with image_hash(read_image(...)), not file bytes.
/// Safe to call from several threads for different paths.
void write_image(const std::filesystem::path& path, const Image& image,
                 const ImageWriteOptions& options = {});

/// The file formats write_image knows, by extension (case-insensitive): .exr; .png; .tif/.tiff;
/// .jpg/.jpeg; .ppm. EXR and TIFF store float pixels; PNG, JPEG and PPM 8-bit sRGB.
enum class ImageFileKind { Exr, Png, Tiff, Jpeg, Ppm };

/// The kind write_image would write `path` as; std::nullopt for an unknown extension.
[[nodiscard]] std::optional<ImageFileKind> image_file_kind(const std::filesystem::path& path);

/// Why write_image cannot write `path` whatever the image: an extension it does not know, or a
/// folder that does not exist or is not a folder; empty when neither.
[[nodiscard]] std::string output_file_problem(const std::filesystem::path& path);

/// Why files cannot go into `folder`: it does not exist, is not a folder, or (when `writable`
/// is asked for) this process may not write to it; empty when none. The reason names the folder.
[[nodiscard]] std::string folder_problem(const std::filesystem::path& folder, bool writable);

/// Why write_image cannot write a `width` x `height` frame to `path`'s format (JPEG: at most
/// 65500 pixels a side); empty when it can. Known before rendering.
[[nodiscard]] std::string output_size_problem(const std::filesystem::path& path, int width, int height);

/// The memory write_image takes, besides the frame, to write a `width` x `height` frame to
/// `path`'s format (with depth and normals when `aovs`): its buffer for the file, and the 8-bit
/// copy of PNG, JPEG and PPM. For a memory check before rendering; 0 for an unknown format.
[[nodiscard]] std::uint64_t image_write_scratch_bytes(const std::filesystem::path& path, int width, int height,
                                                      bool aovs, const ImageWriteOptions& options);

/// Reads the first subimage of any OpenImageIO-readable file as linear float RGBA: 8- and
/// 16-bit integer files are sRGB-decoded on RGB (8-bit exactly, by srgb8_to_linear) unless
/// the file says it is linear, float files are taken as linear; alpha is 1 when absent, gray
/// files fill R, G and B. Depth comes from a "Z" channel and normals from "N.X" "N.Y" "N.Z"
/// when present. Throws rtc::Error naming the file and the reason. For tests and tools.
Image read_image(const std::filesystem::path& path);

/// What a file holds, read from its header only. For tests and tools.
struct ImageFileInfo {
  int width = 0, height = 0;
  std::vector<std::string> channel_names;  // in the order OpenImageIO reports them
  std::vector<std::string> channel_types;  // per channel: "half", "float", "uint8", ...
  std::vector<std::pair<std::string, std::string>> metadata;  // the string attributes
};

/// Throws rtc::Error naming the file and the reason.
ImageFileInfo read_image_info(const std::filesystem::path& path);

/// Exact sRGB transfer (IEC 61966-2-1) from linear, clamped to [0, 1], rounded to the nearest
/// 8-bit code: compares against the 255 exact rounding thresholds (precomputed floats), so
/// every machine gives the same code without calling pow(). NaN gives 0, +inf gives 255.
/// Scalar, about 10 ns, thread-safe.
std::uint8_t linear_to_srgb8(float linear);

/// The float nearest to the exact linear value of sRGB code `v`;
/// linear_to_srgb8(srgb8_to_linear(v)) == v for every v.
float srgb8_to_linear(std::uint8_t v);

/// A linear value in [0, 1] as an 8-bit code, as 8-bit files and rgba8 tiles store alpha:
/// v * 255 + 0.5 truncated; NaN and values <= 0 give 0, values >= 1 give 255. The inverse is
/// code / 255.0f (linear_to_unorm8(code / 255.0f) == code for every code). Thread-safe.
std::uint8_t linear_to_unorm8(float value);

/// The output file name for `frame` (>= 0):
///   "frames/f_####.exr" -> "frames/f_0007.exr" (a run of '#' gives the zero-padded width),
///   "frames/f_%04d.exr" -> "frames/f_0007.exr" (printf-style "%d" or "%0Nd"; "%%" is a '%'),
///   "out.exr" -> "out_0007.exr" when `multiple_frames`, else unchanged (no placeholder:
///   "_NNNN" goes before the file name's extension, or at the end when it has none).
/// Wider frame numbers are not cut ("f_##" with 123 gives "f_123"). A pattern with a printf-style
/// placeholder takes '#' literally ("take#2/f_%04d.exr" -> "take#2/f_0007.exr"). Throws
/// rtc::Error naming the pattern for an empty pattern or file name, more than one placeholder,
/// any other '%' sequence, or a negative frame.
std::string expand_frame_pattern(const std::string& pattern, int frame, bool multiple_frames);

/// `name` (a scene's name) as a file name's stem that is also a frame pattern's literal text:
/// every character but ASCII letters, digits, '.', '_', '+' and '-' becomes '_' (so no folder
/// separator, '#' or '%'), and an empty name or one of dots only gives "scene"; at most 200 bytes.
std::string file_stem_for(std::string_view name);

/// The frames of scene `scene_name` in `folder`, numbered: "<folder>/<file_stem_for(name)>_%04d.png"
/// with any '%' of the folder doubled, so every character of the folder is taken literally
/// ('#' too: the pattern is printf-style). rtc-master's --out-dir.
std::string numbered_frame_pattern(const std::string& folder, std::string_view scene_name);

/// What of `--out PATTERN` is known before the scene is loaded (which frames it has, and so the
/// names, are not): expand_frame_pattern's errors for `frame`, an unknown extension, and a
/// missing folder where the folder's name holds no frame number throw rtc::Error
/// ("--out: <name>: <reason>"). check_output_pattern checks the rest once the frames are known.
void check_output_pattern_early(const std::string& pattern, int frame, bool multiple_frames);

/// `--out PATTERN` checked before anything is rendered, for every frame from `first_frame` to
/// `last_frame`: expand_frame_pattern's errors, a frame's name that is a folder or longer than
/// 255 bytes, output_file_problem's, or a folder this process cannot write to throw rtc::Error
/// ("--out: <name>: <reason>"). Returns the first frame's name.
std::filesystem::path check_output_pattern(const std::string& pattern, int first_frame, int last_frame,
                                           bool multiple_frames);

/// 64-bit FNV-1a over the width, height, which channels are present and the bits of every
/// float (little-endian), as 16 lowercase hex digits: equal hashes mean equal frames bit for
/// bit (-0 and +0 differ, NaN payloads count). Same result on every machine.
std::string image_hash(const Image& image);

}  // namespace rtc
