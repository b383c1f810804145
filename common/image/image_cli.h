// The EXR output options (--exr-float, --exr-compression, --no-depth, --no-normal), written once
// for rtc-render and rtc-master: registered, parsed into ImageWriteOptions, and warned about
// where they cannot apply.
#pragma once

#include <optional>
#include <string>
#include <utility>

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "common/base/error.h"
#include "common/image/image.h"

namespace rtc {

struct ImageCliOptions {
  bool exr_float = false;
  bool no_depth = false;
  bool no_normal = false;
  std::string exr_compression = "zip";
};

/// Registers the four options on `app`. `on_the_wire`: the channels left out travel no more
/// either (rtc-master), which the help says.
inline void add_image_write_options(CLI::App& app, ImageCliOptions& o, bool on_the_wire) {
  app.add_flag("--exr-float", o.exr_float, "write 32-bit float EXR channels instead of half");
  app.add_option("--exr-compression", o.exr_compression,
                 "EXR compression: none, rle, zips, zip, piz (all lossless), pxr24, b44, b44a, dwaa, dwab (lossy)")
      ->capture_default_str();
  const std::string wire = on_the_wire ? " (and off the wire)" : "";
  app.add_flag("--no-depth", o.no_depth, "leave the Z (depth) channel out of EXR files" + wire);
  app.add_flag("--no-normal", o.no_normal, "leave the N.X N.Y N.Z (normal) channels out of EXR files" + wire);
}

/// The write options they give; throws rtc::Error for an unknown --exr-compression (checked
/// before any scene is loaded).
[[nodiscard]] inline ImageWriteOptions parse_image_write_options(const ImageCliOptions& o) {
  const std::optional<ExrCompression> compression = parse_exr_compression(o.exr_compression);
  if (!compression) {
    throw Error("--exr-compression: expected " + exr_compression_names() + ", got \"" + o.exr_compression + "\"");
  }
  ImageWriteOptions w;
  w.exr_type = o.exr_float ? ExrPixelType::Float : ExrPixelType::Half;
  w.write_depth = !o.no_depth;
  w.write_normal = !o.no_normal;
  w.exr_compression = *compression;
  return w;
}

/// Warns, once the output is known, of EXR options given for output that is not EXR (`why_not`
/// says why: "X is not an EXR file", "no frames are written (no --out)"), so that none is
/// silently dropped, and of a lossy --exr-compression for EXR output.
inline void warn_about_image_options(const CLI::App& app, const ImageCliOptions& o, const ImageWriteOptions& w, bool exr,
                                     const std::string& why_not) {
  if (!exr) {
    for (const auto& [given, option] : {std::pair{o.exr_float, "--exr-float"}, std::pair{o.no_depth, "--no-depth"},
                                        std::pair{o.no_normal, "--no-normal"},
                                        std::pair{app.count("--exr-compression") > 0, "--exr-compression"}}) {
      if (given) spdlog::warn("{} applies to EXR output only; {}", option, why_not);
    }
  } else if (exr_compression_lossy(w.exr_compression, w.exr_type, w.write_depth)) {
    spdlog::warn("--exr-compression {} is lossy: the files' pixels are not the rendered ones", o.exr_compression);
  }
}

}  // namespace rtc
