// Image files through OpenImageIO: atomic writes (temporary file, fsync, rename) and reads.
#include "common/image/image.h"

#include <fcntl.h>
#include <unistd.h>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <cstddef>
#include <functional>
#include <iterator>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "common/base/error.h"

namespace rtc {
namespace {

namespace fs = std::filesystem;

using FileKind = ImageFileKind;

struct FileFormat {
  std::string_view extension;
  FileKind kind;
  const char* oiio_format;
};

constexpr FileFormat kFormats[] = {
    {".exr", FileKind::Exr, "openexr"}, {".png", FileKind::Png, "png"},
    {".tif", FileKind::Tiff, "tiff"},   {".tiff", FileKind::Tiff, "tiff"},
    {".jpg", FileKind::Jpeg, "jpeg"},   {".jpeg", FileKind::Jpeg, "jpeg"},
    {".ppm", FileKind::Ppm, "pnm"},
};

std::string lowercase(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

const FileFormat* find_format(const fs::path& path) {
  const std::string extension = lowercase(path.extension().string());
  for (const FileFormat& format : kFormats) {
    if (format.extension == extension) return &format;
  }
  return nullptr;
}

// Empty when the channel vectors match the size, else what is wrong.
std::string shape_problem(const Image& image) {
  if (image.width <= 0 || image.height <= 0) {
    return fmt::format("image is empty ({}x{})", image.width, image.height);
  }
  const std::size_t pixels =
      static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height);
  if (image.rgba.size() != 4 * pixels || (image.has_depth() && image.depth.size() != pixels) ||
      (image.has_normal() && image.normal.size() != 3 * pixels)) {
    return fmt::format("{}x{} image has {} RGBA, {} depth and {} normal floats", image.width,
                       image.height, image.rgba.size(), image.depth.size(), image.normal.size());
  }
  return {};
}

// What goes to OpenImageIO: a spec and the pixels interleaved in the spec's buffer type, whole
// (`whole`) or made a band of rows at a time (`rows`, EXR: its channels come from three arrays,
// and interleaving a whole 2048x2048 frame with depth and normals took a fresh 128 MiB a frame).
struct Encoded {
  OIIO::ImageSpec spec;
  OIIO::TypeDesc buffer_type;
  const void* whole = nullptr;       ///< the image's own floats, laid out as the file wants them
  std::vector<std::uint8_t> bytes;  ///< or the bytes the encoding made
  /// Interleaves rows [y0, y1) into `dst` (spec.nchannels floats a pixel).
  std::function<void(int y0, int y1, float* dst)> rows;
  /// The whole image's pixels (without `rows`).
  [[nodiscard]] const void* data() const { return bytes.empty() ? whole : bytes.data(); }
};

// Rows handed to OpenImageIO at once when Encoded::rows makes them: a multiple of the 16 rows
// of an EXR zip block; 64 rows of a 2048-wide frame with depth and normals are 4 MiB.
constexpr int kRowsPerWrite = 64;

Encoded encode_exr(const Image& image, const ImageWriteOptions& options) {
  const bool with_depth = options.write_depth && image.has_depth();
  const bool with_normal = options.write_normal && image.has_normal();
  const OIIO::TypeDesc color_type =
      options.exr_type == ExrPixelType::Half ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::FLOAT;
  std::vector<std::string> names = {"R", "G", "B", "A"};
  std::vector<OIIO::TypeDesc> types(4, color_type);
  if (with_depth) {
    names.emplace_back("Z");
    types.emplace_back(OIIO::TypeDesc::FLOAT);
  }
  if (with_normal) {
    names.insert(names.end(), {"N.X", "N.Y", "N.Z"});
    types.insert(types.end(), 3, color_type);
  }
  const int channels = static_cast<int>(names.size());

  Encoded out;
  out.spec = OIIO::ImageSpec(image.width, image.height, channels, color_type);
  out.spec.channelnames = names;
  if (std::any_of(types.begin(), types.end(), [&](OIIO::TypeDesc t) { return t != color_type; })) {
    out.spec.channelformats = types;
  }
  out.spec.alpha_channel = 3;
  out.spec.z_channel = with_depth ? 4 : -1;
  out.spec.attribute("compression", std::string(exr_compression_name(options.exr_compression)));
  out.buffer_type = OIIO::TypeDesc::FLOAT;
  if (!with_depth && !with_normal) {
    out.whole = image.rgba.data();
    return out;
  }
  const std::size_t width = static_cast<std::size_t>(image.width);
  out.rows = [&image, width, with_depth, with_normal](int y0, int y1, float* dst) {
    const std::size_t end = static_cast<std::size_t>(y1) * width;
    for (std::size_t i = static_cast<std::size_t>(y0) * width; i < end; ++i) {
      dst = std::copy_n(image.rgba.data() + 4 * i, 4, dst);
      if (with_depth) *dst++ = image.depth[i];
      if (with_normal) dst = std::copy_n(image.normal.data() + 3 * i, 3, dst);
    }
  };
  return out;
}

Encoded encode_tiff(const Image& image) {
  Encoded out;
  out.spec = OIIO::ImageSpec(image.width, image.height, 4, OIIO::TypeDesc::FLOAT);
  out.spec.alpha_channel = 3;
  out.spec.attribute("compression", "zip");
  out.buffer_type = OIIO::TypeDesc::FLOAT;
  out.whole = image.rgba.data();
  return out;
}

Encoded encode_srgb8(const Image& image, int channels) {
  Encoded out;
  out.spec = OIIO::ImageSpec(image.width, image.height, channels, OIIO::TypeDesc::UINT8);
  out.spec.alpha_channel = channels == 4 ? 3 : -1;
  out.spec.attribute("oiio:ColorSpace", "sRGB");
  // The bytes are final: stop OpenImageIO from un-premultiplying them on the way out.
  out.spec.attribute("oiio:UnassociatedAlpha", 1);
  out.buffer_type = OIIO::TypeDesc::UINT8;

  const std::size_t pixels = image.rgba.size() / 4;
  out.bytes.resize(pixels * static_cast<std::size_t>(channels));
  std::uint8_t* dst = out.bytes.data();
  for (std::size_t i = 0; i < pixels; ++i) {
    const float* src = image.rgba.data() + 4 * i;
    for (int c = 0; c < 3; ++c) *dst++ = linear_to_srgb8(src[c]);
    if (channels == 4) *dst++ = linear_to_unorm8(src[3]);
  }
  return out;
}

Encoded encode(FileKind kind, const Image& image, const ImageWriteOptions& options) {
  switch (kind) {
    case FileKind::Exr:
      return encode_exr(image, options);
    case FileKind::Tiff:
      return encode_tiff(image);
    case FileKind::Png:
      return encode_srgb8(image, 4);
    case FileKind::Jpeg:
      return encode_srgb8(image, 3);
    case FileKind::Ppm: {
      Encoded out = encode_srgb8(image, 3);
      out.spec.attribute("pnm:binary", 1);
      return out;
    }
  }
  RTC_CHECK(false, "unhandled image file kind");
  return {};
}

// Removes the temporary file unless it was renamed into place, whichever step failed.
class TempFile {
 public:
  explicit TempFile(fs::path path) : path_(std::move(path)) {}
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  ~TempFile() {
    if (!committed_) {
      std::error_code ignored;
      fs::remove(path_, ignored);
    }
  }
  [[nodiscard]] const fs::path& path() const { return path_; }
  void commit() { committed_ = true; }

 private:
  fs::path path_;
  bool committed_ = false;
};

// write_image's buffer for a file whose pixels take `pixel_bytes` uncompressed: room for them plus
// headers and offset tables, at most 1 GiB (image_write_scratch_bytes counts the same).
std::uint64_t file_buffer_bytes(std::uint64_t pixel_bytes) {
  return std::min<std::uint64_t>(pixel_bytes + (std::uint64_t{1} << 20), std::uint64_t{1} << 30);
}

fs::path temp_path_for(const fs::path& path) {
  // Same folder (so rename is atomic), hidden, unique per process and call, and keeping the
  // extension so nothing mistakes it for another format.
  // The stem is cut to 200 bytes, so that the temporary name is no longer than a name may be
  // (255 bytes) where the file's own name fits.
  static std::atomic<unsigned> counter{0};
  std::string stem = path.stem().string();
  if (stem.size() > 200) stem.resize(200);
  const std::string name = fmt::format(".{}.tmp-{}-{}{}", stem, ::getpid(), counter.fetch_add(1),
                                       path.extension().string().substr(0, 16));
  return path.parent_path() / name;
}

// Creates `path` (which must not exist) holding `bytes`, on disk (fsync), every write, the
// fsync and the close checked. Empty on success, else the reason (ENOSPC: "No space left on
// device").
std::string write_file(const fs::path& path, const std::vector<unsigned char>& bytes) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0) return std::error_code(errno, std::generic_category()).message();
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int write_errno = n < 0 ? errno : EIO;
      ::close(fd);
      return std::error_code(write_errno, std::generic_category()).message();
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) {
    const int fsync_errno = errno;
    ::close(fd);
    return std::error_code(fsync_errno, std::generic_category()).message();
  }
  if (::close(fd) != 0) return std::error_code(errno, std::generic_category()).message();
  return {};
}

// Empty on success, else the reason.
std::string flush_to_disk(const fs::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return std::error_code(errno, std::generic_category()).message();
  const int result = ::fsync(fd);
  const int fsync_errno = errno;
  ::close(fd);
  if (result != 0) return std::error_code(fsync_errno, std::generic_category()).message();
  return {};
}

Error read_error(const fs::path& path, const std::string& reason) {
  return Error(fmt::format("cannot read image '{}': {}", path.string(), reason));
}

std::unique_ptr<OIIO::ImageInput> open_input(const fs::path& path) {
  OIIO::ImageSpec config;
  // Hand back the stored values: no premultiplication of files with unassociated alpha.
  config.attribute("oiio:UnassociatedAlpha", 1);
  auto in = OIIO::ImageInput::open(path.string(), &config);
  if (!in) throw read_error(path, OIIO::geterror());
  return in;
}

int find_channel(const OIIO::ImageSpec& spec, std::string_view name) {
  for (int c = 0; c < spec.nchannels; ++c) {
    if (spec.channelnames[static_cast<std::size_t>(c)] == name) return c;
  }
  return -1;
}

bool says_linear(const OIIO::ImageSpec& spec) {
  const std::string space = lowercase(spec.get_string_attribute("oiio:ColorSpace"));
  return space == "linear" || space == "lin_srgb" || space == "scene_linear";
}

double srgb_to_linear_exact(double v) {
  return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
}

}  // namespace

namespace {
constexpr std::pair<ExrCompression, std::string_view> kExrCompressions[] = {
    {ExrCompression::None, "none"},   {ExrCompression::Rle, "rle"},   {ExrCompression::Zips, "zips"},
    {ExrCompression::Zip, "zip"},     {ExrCompression::Piz, "piz"},   {ExrCompression::Pxr24, "pxr24"},
    {ExrCompression::B44, "b44"},     {ExrCompression::B44a, "b44a"}, {ExrCompression::Dwaa, "dwaa"},
    {ExrCompression::Dwab, "dwab"},
};
}  // namespace

std::string_view exr_compression_name(ExrCompression c) {
  for (const auto& [value, name] : kExrCompressions) {
    if (value == c) return name;
  }
  return "zip";
}

std::optional<ExrCompression> parse_exr_compression(std::string_view name) {
  for (const auto& [value, known] : kExrCompressions) {
    if (known == name) return value;
  }
  return std::nullopt;
}

bool exr_compression_lossy(ExrCompression c, ExrPixelType type, bool with_depth) {
  switch (c) {
    case ExrCompression::Pxr24:  // rounds float channels, and Z is always float
      return type == ExrPixelType::Float || with_depth;
    case ExrCompression::Dwaa:  // R, G and B in either type
    case ExrCompression::Dwab:
      return true;
    case ExrCompression::B44:  // half channels only
    case ExrCompression::B44a:
      return type == ExrPixelType::Half;
    default:
      return false;
  }
}

std::string exr_compression_names() {
  std::string text;
  const std::size_t n = std::size(kExrCompressions);
  for (std::size_t i = 0; i < n; ++i) {
    if (i > 0) text += i + 1 == n ? " or " : ", ";
    text += kExrCompressions[i].second;
  }
  return text;
}

std::optional<ImageFileKind> image_file_kind(const std::filesystem::path& path) {
  const FileFormat* format = find_format(path);
  if (format == nullptr) return std::nullopt;
  return format->kind;
}

std::string output_file_problem(const fs::path& path) {
  if (find_format(path) == nullptr) {
    constexpr const char* kFormats = ".exr, .png, .tif, .tiff, .jpg, .jpeg or .ppm";
    return path.extension().empty()
               ? fmt::format("the name has no extension to choose the format by (use {})", kFormats)
               : fmt::format("unsupported extension '{}' (use {})", path.extension().string(), kFormats);
  }
  return folder_problem(path.parent_path().empty() ? fs::path(".") : path.parent_path(), false);
}

std::string folder_problem(const fs::path& folder, bool writable) {
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) {
    return fs::exists(folder, ec) ? fmt::format("'{}' is not a folder", folder.string())
                                  : fmt::format("folder '{}' does not exist", folder.string());
  }
  if (writable && ::access(folder.c_str(), W_OK) != 0) {
    return fmt::format("cannot write to folder {}: {}", folder.string(), std::strerror(errno));
  }
  return {};
}

std::string output_size_problem(const fs::path& path, int width, int height) {
  // libjpeg stores 16-bit sizes and refuses more than 65500 (JPEG_MAX_DIMENSION) by ending the
  // process through OpenImageIO.
  constexpr int kMaxJpegSide = 65500;
  if (image_file_kind(path) == FileKind::Jpeg && (width > kMaxJpegSide || height > kMaxJpegSide)) {
    return fmt::format("a JPEG file holds at most {} pixels a side, and the frame is {}x{} (use .png, .exr or .tif, "
                       "or a smaller --width/--height)",
                       kMaxJpegSide, width, height);
  }
  return {};
}

std::uint64_t image_write_scratch_bytes(const fs::path& path, int width, int height, bool aovs,
                                        const ImageWriteOptions& options) {
  const std::optional<FileKind> kind = image_file_kind(path);
  if (!kind) return 0;
  const std::uint64_t pixels = static_cast<std::uint64_t>(std::max(width, 0)) * static_cast<std::uint64_t>(std::max(height, 0));
  std::uint64_t file_bytes = 0;  // the pixels as the file stores them, uncompressed
  std::uint64_t converted = 0;   // encode_srgb8's copy
  switch (*kind) {
    case FileKind::Exr: {
      const std::uint64_t color = options.exr_type == ExrPixelType::Half ? 2 : 4;
      file_bytes = pixels * (4 * color + (aovs && options.write_depth ? 4 : 0) + (aovs && options.write_normal ? 3 * color : 0));
      break;
    }
    case FileKind::Tiff:
      file_bytes = pixels * 16;
      break;
    case FileKind::Png:
      file_bytes = converted = pixels * 4;
      break;
    case FileKind::Jpeg:
    case FileKind::Ppm:
      file_bytes = converted = pixels * 3;
      break;
  }
  return converted + file_buffer_bytes(file_bytes);
}

void write_image(const fs::path& path, const Image& image, const ImageWriteOptions& options) {
  const std::string name = path.string();
  const auto fail = [&](const std::string& reason) {
    return Error(fmt::format("cannot write image '{}': {}", name, reason));
  };
  if (const std::string problem = shape_problem(image); !problem.empty()) throw fail(problem);
  if (const std::string problem = output_file_problem(path); !problem.empty()) throw fail(problem);
  if (const std::string problem = output_size_problem(path, image.width, image.height); !problem.empty()) throw fail(problem);
  const FileFormat* format = find_format(path);

  Encoded encoded = encode(format->kind, image, options);
  for (const auto& [key, value] : options.metadata) encoded.spec.attribute(key, value);

  TempFile temp(temp_path_for(path));
  {
    // Encoded in memory where the format allows, then written here: some of OpenImageIO's writers
    // do not report a failed write (PNG wrote an empty file on a full disk and said nothing;
    // libjpeg ended the process), so the file's own writes are ours, each checked. The proxy
    // outlives the writer.
    std::vector<unsigned char> bytes;
    // Room for the pixels as the spec stores them, uncompressed, plus headers and offset tables:
    // what an uncompressed EXR takes, and more than a compressed file does. Untouched room costs
    // no memory; the buffer growing by doubling cost copies and fresh pages (a 2048x2048 float
    // EXR with Z and N, no compression: 134 MB grown through copies of 67, 34, ... MB).
    bytes.reserve(static_cast<std::size_t>(file_buffer_bytes(encoded.spec.image_bytes(/*native=*/true))));
    OIIO::Filesystem::IOVecOutput proxy(bytes);
    auto out = OIIO::ImageOutput::create(format->oiio_format);
    if (!out) throw fail(OIIO::geterror());
    const bool in_memory = out->supports("ioproxy");
    if (in_memory && !out->set_ioproxy(&proxy)) throw fail(out->geterror());
    if (!out->open(temp.path().string(), encoded.spec)) throw fail(out->geterror());
    if (encoded.rows) {
      const int band = std::min(kRowsPerWrite, image.height);
      std::vector<float> rows(static_cast<std::size_t>(band) * static_cast<std::size_t>(image.width) *
                              static_cast<std::size_t>(encoded.spec.nchannels));
      for (int y0 = 0; y0 < image.height; y0 += band) {
        const int y1 = std::min(y0 + band, image.height);
        encoded.rows(y0, y1, rows.data());
        if (!out->write_scanlines(y0, y1, 0, encoded.buffer_type, rows.data())) throw fail(out->geterror());
      }
    } else if (!out->write_image(encoded.buffer_type, encoded.data())) {
      throw fail(out->geterror());
    }
    if (!out->close()) throw fail(out->geterror());
    if (in_memory) {
      if (const std::string problem = write_file(temp.path(), bytes); !problem.empty()) {
        throw fail(fmt::format("cannot write '{}': {}", temp.path().string(), problem));
      }
    } else if (const std::string problem = flush_to_disk(temp.path()); !problem.empty()) {
      throw fail(fmt::format("cannot flush '{}': {}", temp.path().string(), problem));
    }
  }
  std::error_code ec;
  fs::rename(temp.path(), path, ec);
  if (ec) {
    throw fail(fmt::format("cannot rename '{}' to it: {}", temp.path().string(), ec.message()));
  }
  temp.commit();
}

Image read_image(const fs::path& path) {
  const auto in = open_input(path);
  const OIIO::ImageSpec& spec = in->spec();
  if (spec.deep) throw read_error(path, "deep images are not supported");
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0) {
    throw read_error(path, "it holds no pixels");
  }
  const int channels = spec.nchannels;

  int r = find_channel(spec, "R");
  int g = find_channel(spec, "G");
  int b = find_channel(spec, "B");
  if (r < 0 || g < 0 || b < 0) {
    // Unnamed channels go by position; one or two channels are gray (plus alpha).
    const int gray = find_channel(spec, "Y");
    if (channels >= 3 && gray < 0) {
      r = 0;
      g = 1;
      b = 2;
    } else {
      r = g = b = gray >= 0 ? gray : 0;
    }
  }
  int a = find_channel(spec, "A");
  if (a < 0) a = spec.alpha_channel;
  const int nx = find_channel(spec, "N.X");
  const int ny = find_channel(spec, "N.Y");
  const int nz = find_channel(spec, "N.Z");
  const bool with_normal = nx >= 0 && ny >= 0 && nz >= 0;
  // OpenImageIO's own guess (for names like "depth.Z") also takes "N.Z"; keep it off the others.
  int z = find_channel(spec, "Z");
  if (z < 0) z = spec.z_channel;
  if (z == r || z == g || z == b || z == a || z == nx || z == ny || z == nz) z = -1;

  const bool srgb = !spec.format.is_floating_point() && !says_linear(spec);
  const bool bytes = spec.format == OIIO::TypeDesc::UINT8 && spec.channelformats.empty();
  const std::size_t pixels =
      static_cast<std::size_t>(spec.width) * static_cast<std::size_t>(spec.height);
  const std::size_t stride = static_cast<std::size_t>(channels);

  // Decoded values, channel-interleaved like the file; 8-bit sRGB goes through the exact table.
  std::vector<float> values(pixels * stride);
  if (bytes) {
    std::vector<std::uint8_t> raw(pixels * stride);
    if (!in->read_image(0, 0, 0, channels, OIIO::TypeDesc::UINT8, raw.data())) {
      throw read_error(path, in->geterror());
    }
    for (std::size_t i = 0; i < raw.size(); ++i) {
      const int c = static_cast<int>(i % stride);
      const bool color = srgb && (c == r || c == g || c == b);
      values[i] = color ? srgb8_to_linear(raw[i]) : static_cast<float>(raw[i]) / 255.0f;
    }
  } else {
    if (!in->read_image(0, 0, 0, channels, OIIO::TypeDesc::FLOAT, values.data())) {
      throw read_error(path, in->geterror());
    }
    if (srgb) {
      for (std::size_t i = 0; i < values.size(); ++i) {
        const int c = static_cast<int>(i % stride);
        if (c == r || c == g || c == b) {
          values[i] = static_cast<float>(srgb_to_linear_exact(static_cast<double>(values[i])));
        }
      }
    }
  }

  Image image(spec.width, spec.height, z >= 0, with_normal);
  for (std::size_t i = 0; i < pixels; ++i) {
    const float* src = values.data() + i * stride;
    float* dst = image.rgba.data() + 4 * i;
    dst[0] = src[r];
    dst[1] = src[g];
    dst[2] = src[b];
    dst[3] = a >= 0 ? src[a] : 1.0f;
    if (z >= 0) image.depth[i] = src[z];
    if (with_normal) {
      image.normal[3 * i + 0] = src[nx];
      image.normal[3 * i + 1] = src[ny];
      image.normal[3 * i + 2] = src[nz];
    }
  }
  return image;
}

ImageFileInfo read_image_info(const fs::path& path) {
  const auto in = open_input(path);
  const OIIO::ImageSpec& spec = in->spec();
  ImageFileInfo info;
  info.width = spec.width;
  info.height = spec.height;
  for (int c = 0; c < spec.nchannels; ++c) {
    info.channel_names.push_back(spec.channelnames[static_cast<std::size_t>(c)]);
    info.channel_types.emplace_back(spec.channelformat(c).c_str());
  }
  for (const OIIO::ParamValue& param : spec.extra_attribs) {
    if (param.type() == OIIO::TypeDesc::STRING) {
      info.metadata.emplace_back(param.name().string(), param.get_string());
    }
  }
  return info;
}

}  // namespace rtc
