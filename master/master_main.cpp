// rtc-master: splits frames of a scene into tiles, hands them to rtc-worker processes over TCP,
// reassembles and writes the frames, and logs the frame rate next to the link-bound frame rate.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <new>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "common/base/cli_checks.h"
#include "common/base/error.h"
#include "common/base/frame_range.h"
#include "common/base/log.h"
#include "common/base/process_memory.h"
#include "common/image/image.h"
#include "common/image/image_cli.h"
#include "common/image/pixel_format.h"
#include "common/render/temporal_cli.h"
#include "common/scene/scene_cli.h"
#include "master/frame_writer.h"
#include "master/master_server.h"
#include "protocol/auth.h"
#include "protocol/net/connection.h"
#include "protocol/message.h"

namespace {

int run(int argc, char** argv) {
  CLI::App app{"rtc-master: render frames of a scene on rtc-worker processes connected over TCP"};
  rtc::SceneCliOptions scene_options;
  rtc::MasterOptions o;
  std::string frames_text, wire_text, compress_text = std::string(rtc::compression_name(rtc::kDefaultCompression)), token_file, log_level = "info";
  std::string temporal_text = "auto";
  rtc::add_scene_cli_options(app, scene_options);
  app.add_option("--listen", o.listen, "HOST:PORT to accept workers on; port 0 picks a free one; a non-loopback "
                                       "address needs --token-file")
      ->capture_default_str();
  auto* frames_opt = app.add_option("--frames", frames_text, "frames to render, A-B or A, inclusive (default: the scene's animation range)");
  app.add_option("--loop", o.loop_seconds, "render the frames over and over for this many seconds (a frame-rate run)")
      ->check(rtc::kNotNan)
      ->check(CLI::Range(0.001, 1e9))
      ->excludes(frames_opt);
  std::string out_dir;
  auto* out_opt = app.add_option("--out", o.out_pattern,
                                 "write frames to this pattern (#### = frame number, the sequence number with --loop; .png, "
                                 ".exr, ...); omitted: frames are discarded");
  app.add_option("--out-dir", out_dir,
                 "write frames to DIR/<scene>_NNNN.png, <scene> the scene's name as rtc-render names its "
                 "frames (instead of --out)")
      ->excludes(out_opt);
  app.add_option("--tile", o.tile_size, "tile size in pixels (default 32, 16 with temporal coherence)")
      ->check(CLI::Range(1, 4096));
  app.add_option("--wire", wire_text, "pixel format on the wire: rgba8 (sRGB, 4 B/px), half (8 B/px), float (16 B/px); "
                                      "default: rgba8; half (float with --exr-float) for .exr; float for .tif/.tiff");
  app.add_option("--compress", compress_text, "tile compression: none, lz4, zstd")->capture_default_str();
  app.add_option("--link-mbps", o.link_mbps, "the master's link rate in Mbit/s (e.g. 100 for Fast Ethernet) for the "
                                            "bandwidth-limited frame rate, which counts the 94.1% of it TCP over "
                                            "Ethernet leaves for messages (default: measured on the first worker's connection)")
      ->check(rtc::kNotNan)
      ->check(CLI::Range(0.001, 1e9));
  app.add_option("--token-file", token_file, "file holding the shared token workers must prove (HMAC, never sent)")->check(rtc::kNotEmpty);
  app.add_option("--tls-cert", o.tls_cert, "PEM certificate chain: every connection uses TLS (workers need --tls-ca)")
      ->check(CLI::ExistingFile);
  app.add_option("--tls-key", o.tls_key, "PEM private key of --tls-cert")->check(CLI::ExistingFile);
  app.add_option("--stats-json", o.stats_json, "write per-frame figures and a summary as JSON lines to this file")->check(rtc::kNotEmpty);
  app.add_option("--min-workers", o.min_workers, "start rendering once this many workers are ready")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  app.add_option("--wait-seconds", o.wait_seconds,
                 "give up (exit 1) when fewer than --min-workers workers are ready (have loaded the scene) this long after listening, or "
                 "none this long while frames are open during the run (the frames finished are written, those in flight "
                 "abandoned); 0: wait for ever")
      ->check(rtc::kNotNan)
      ->check(CLI::Range(0.0, 1e9))
      ->capture_default_str();
  app.add_option("--frames-in-flight", o.frames_in_flight, "frames handed out at once (workers never idle at frame ends)")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  app.add_option("--tiles-per-worker", o.tiles_per_worker, "tiles each worker holds at once (default: 2 x its threads + 2)")
      ->check(CLI::Range(2, 4096));
  app.add_option("--heartbeat-timeout", o.heartbeat_timeout_ms, "drop a worker silent for this many ms")
      ->check(CLI::Range(300, 3600000))
      ->capture_default_str();
  app.add_option("--heartbeat-interval", o.heartbeat_ms,
                 "ms between heartbeats (at most a third of --heartbeat-timeout); a worker treats a master "
                 "silent for 5 intervals, at least 10 s, as gone")
      ->check(CLI::Range(100, 1200000))
      ->capture_default_str();
  app.add_option("--max-connections-per-host", o.max_connections_per_host,
                 "connections one peer address may hold open at once (more are closed at once)")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  app.add_option("--max-unauthenticated-per-host", o.max_unauthenticated_per_host,
                 "of those, connections still authenticating")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  app.add_option("--auth-timeout", o.auth_timeout_ms, "close a connection that has not authenticated within this many ms")
      ->check(CLI::Range(100, 3600000))
      ->capture_default_str();
  app.add_option("--drain-seconds", o.drain_seconds, "after SIGINT/SIGTERM, time to finish the frames in flight")
      ->check(CLI::Range(0, 3600))
      ->capture_default_str();
  app.add_option("--ready-file", o.ready_file, "write the HOST:PORT listened on to this file once listening")->check(rtc::kNotEmpty);
  rtc::add_temporal_options(app, temporal_text, o.mark_cells, /*has_loop=*/true);
  rtc::ImageCliOptions image_options;
  rtc::add_image_write_options(app, image_options, /*on_the_wire=*/true);
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error, critical, off")->capture_default_str();
  if (const std::optional<int> status = rtc::parse_command_line(app, argc, argv, "rtc-master")) return *status;
  // A ready file left by a master that was killed outright (SIGKILL gives it no time to remove
  // it) would say that this one listens while it is still loading its scene: it goes first,
  // whatever else fails (said once logging is set up).
  bool removed_ready_file = false;
  if (!o.ready_file.empty()) {
    std::error_code ec;
    const std::filesystem::file_status status = std::filesystem::symlink_status(o.ready_file, ec);
    if (std::filesystem::is_directory(status)) throw rtc::Error("--ready-file: " + o.ready_file + " is a folder");
    if (std::filesystem::exists(status)) {
      if (!std::filesystem::remove(o.ready_file, ec)) {
        throw rtc::Error("--ready-file: cannot remove " + o.ready_file + ", left by an earlier run: " + ec.message());
      }
      removed_ready_file = true;
    }
  }
  rtc::init_logging(log_level);
  if (removed_ready_file) {
    spdlog::warn("--ready-file: removed {}, left by an earlier run (written again once this master listens)", o.ready_file);
  }

  // Options are checked before the (possibly long) scene load.
  const std::optional<rtc::Compression> compression = rtc::parse_compression(compress_text);
  if (!compression) throw rtc::Error("--compress: expected none, lz4 or zstd, got \"" + compress_text + "\"");
  o.compression = *compression;
  o.write_options = rtc::parse_image_write_options(image_options);
  const rtc::TemporalMode temporal_mode = rtc::parse_temporal_mode(temporal_text);
  (void)rtc::net::parse_host_port(o.listen, "--listen");
  if (o.tls_cert.empty() != o.tls_key.empty()) throw rtc::Error("--tls-cert and --tls-key go together");
  if (app.count("--out-dir") > 0 && out_dir.empty()) throw rtc::Error("--out-dir: the folder is empty");
  if (!out_dir.empty()) {  // named as such, and before the (possibly long) load
    if (const std::string problem = rtc::folder_problem(out_dir, true); !problem.empty()) {
      std::error_code ec;
      throw rtc::Error("--out-dir: " + problem + (std::filesystem::exists(out_dir, ec) ? "" : " (make it first)"));
    }
  }
  // The scene's name is known after the load; the file kind (PNG) and the folder are not.
  if (!out_dir.empty()) o.out_pattern = rtc::numbered_frame_pattern(out_dir, "scene");
  // EXR and TIFF store float pixels (write_image); PNG, JPEG and PPM store 8-bit sRGB.
  const std::optional<rtc::ImageFileKind> kind =
      o.out_pattern.empty() ? std::nullopt : rtc::image_file_kind(o.out_pattern);
  const bool exr = kind == rtc::ImageFileKind::Exr;
  const bool tiff = kind == rtc::ImageFileKind::Tiff;
  if (app.count("--wire") == 0) {  // an empty --wire "" is a bad word, not the default
    o.wire = exr ? (image_options.exr_float ? rtc::WireFormat::Float : rtc::WireFormat::Half)
                 : (tiff ? rtc::WireFormat::Float : rtc::WireFormat::Rgba8);
  } else {
    const std::optional<rtc::WireFormat> wire = rtc::parse_wire_format(wire_text);
    if (!wire) throw rtc::Error("--wire: expected rgba8, half or float, got \"" + wire_text + "\"");
    o.wire = *wire;
  }
  if ((exr || tiff) && o.wire == rtc::WireFormat::Rgba8) {
    throw rtc::Error("--wire rgba8 carries 8-bit sRGB pixels: float output (" + o.out_pattern + ") needs --wire half or float");
  }
  if (tiff && o.wire == rtc::WireFormat::Half) {
    spdlog::warn("--wire half with TIFF output: the files hold half-precision values (rtc-render writes float)");
  }
  if (exr && image_options.exr_float && o.wire == rtc::WireFormat::Half) {
    spdlog::warn("--exr-float with --wire half: the files hold half-precision values");
  }
  if (!exr && !tiff && o.wire != rtc::WireFormat::Rgba8 && !o.out_pattern.empty()) {
    spdlog::warn("--wire {} with 8-bit output ({}): the files equal rtc-render's only with --wire float or rgba8",
                 rtc::wire_format_name(o.wire), o.out_pattern);
  }
  if (exr) {
    o.channels = static_cast<std::uint8_t>((o.write_options.write_depth ? rtc::kChannelDepth : 0) |
                                           (o.write_options.write_normal ? rtc::kChannelNormal : 0));
  }
  rtc::warn_about_image_options(app, image_options, o.write_options, exr,
                                o.out_pattern.empty() ? std::string("no frames are written (no --out)")
                                                      : o.out_pattern + " is not an EXR file");
  // A tile's pixels travel in one message: the largest tile must fit its payload limit.
  const std::size_t tile_bytes = rtc::max_encoded_tile_bytes(rtc::raw_tile_bytes(o.tile_size, o.tile_size, o.wire, o.channels));
  if (tile_bytes == 0 || tile_bytes + 128 > rtc::protocol::kMaxPayload) {
    throw rtc::Error("--tile " + std::to_string(o.tile_size) + ": a " + std::string(rtc::wire_format_name(o.wire)) +
                     " tile of that size (with its EXR channels) exceeds the " +
                     std::to_string(rtc::protocol::kMaxPayload >> 20) + " MiB message limit; use a smaller --tile");
  }
  if (!token_file.empty()) o.token = rtc::protocol::read_token_file_warning_if_weak(token_file);
  // Three heartbeats fit in the timeout, so one late answer does not drop a worker.
  if (app.count("--heartbeat-interval") > 0 && o.heartbeat_ms > o.heartbeat_timeout_ms / 3) {
    throw rtc::Error("--heartbeat-interval " + std::to_string(o.heartbeat_ms) + ": more than a third of --heartbeat-timeout (" +
                     std::to_string(o.heartbeat_timeout_ms) + " ms); one late answer would drop a worker");
  }
  o.heartbeat_ms = std::min(o.heartbeat_ms, o.heartbeat_timeout_ms / 3);
  std::optional<rtc::FrameRange> requested;
  if (app.count("--frames") > 0) requested = rtc::parse_frame_range(frames_text);  // "" is an error too
  if (app.count("--out") > 0 && o.out_pattern.empty()) throw rtc::Error("--out: the pattern is empty");
  // What of --out is known before the (possibly long) load: the rest once the frames are known.
  if (app.count("--out") > 0) {
    rtc::check_output_pattern_early(o.out_pattern, o.loop_seconds > 0 ? 0 : (requested ? requested->first : 0),
                                    o.loop_seconds > 0 || (requested && requested->last > requested->first));
  }

  rtc::check_listen(o);  // before the (possibly long) load, as every other option
  const rtc::Scene scene = rtc::load_scene_from_cli(scene_options);
  if (!out_dir.empty()) o.out_pattern = rtc::numbered_frame_pattern(out_dir, scene.name);
  if (scene.width > 32768 || scene.height > 32768) {
    throw rtc::Error("scene " + rtc::scene_label(scene_options) +
                     ": " + std::to_string(scene.width) + "x" + std::to_string(scene.height) +
                     " exceeds the cluster's limit of 32768 pixels a side (use --width/--height)");
  }
  const rtc::FrameRange frames = requested.value_or(rtc::FrameRange{scene.animation.frame_begin, scene.animation.frame_end});
  rtc::check_frames_to_render(scene, frames.first, frames.last, scene_options);
  o.first_frame = frames.first;
  o.last_frame = frames.last;
  o.multiple_frames = frames.last > frames.first || o.loop_seconds > 0;
  o.temporal = rtc::choose_temporal(scene, temporal_mode, o.first_frame, o.last_frame, o.loop_seconds > 0);
  const bool temporal = o.temporal.on;
  // With temporal coherence the tile is the unit retraced: finer tiles retrace less.
  if (app.count("--tile") == 0 && temporal) o.tile_size = rtc::kTemporalTileSize;
  // Every frame open at once is held whole on the master (RGBA float and the EXR channels asked
  // for), and so is every finished frame waiting for the frame writer (with --out: a frame opens
  // only while fewer than FrameWriter::kMaxPending wait, so at most that many less one besides
  // the frames in flight); with temporal coherence one more: the canvas of every tile's latest
  // pixels. The frame writer writes one frame at a time, which takes a buffer for the file and,
  // for 8-bit files, a copy (image_write_scratch_bytes).
  const int first_file = o.loop_seconds > 0 ? 0 : frames.first;
  const std::uint64_t frame_bytes = rtc::Image::bytes(scene.width, scene.height, (o.channels & rtc::kChannelDepth) != 0,
                                                     (o.channels & rtc::kChannelNormal) != 0);
  const std::uint64_t frame_count = static_cast<std::uint64_t>(frames.last - frames.first) + 1;
  const std::uint64_t at_once = static_cast<std::uint64_t>(o.frames_in_flight) +
                                (o.out_pattern.empty() ? 0u : rtc::FrameWriter::kMaxPending - 1);
  const std::uint64_t held =
      (o.loop_seconds > 0 ? at_once : std::min<std::uint64_t>(at_once, frame_count)) + (temporal ? 1u : 0u);
  const std::uint64_t write_bytes =
      o.out_pattern.empty()
          ? 0u
          : rtc::image_write_scratch_bytes(rtc::expand_frame_pattern(o.out_pattern, first_file, o.multiple_frames),
                                           scene.width, scene.height, o.channels != 0, o.write_options);
  rtc::check_memory(std::to_string(held) + (held == 1 ? " frame" : " frames") + " of " + std::to_string(scene.width) +
                        "x" + std::to_string(scene.height) + " held at once" + (write_bytes > 0 ? ", and writing one" : ""),
                    frame_bytes * held + write_bytes, "use a smaller --width/--height or fewer --frames-in-flight");
  // With --loop files are numbered by sequence (0, 1, ...), not by scene frame.
  if (!o.out_pattern.empty()) {
    // Every frame's name (with --loop: the first's; the run has no last).
    const std::filesystem::path first_name =
        rtc::check_output_pattern(o.out_pattern, first_file, o.loop_seconds > 0 ? first_file : frames.last, o.multiple_frames);
    if (const std::string problem = rtc::output_size_problem(first_name, scene.width, scene.height); !problem.empty()) {
      throw rtc::Error("--out: " + first_name.string() + ": " + problem);
    }
  }
  return rtc::run_master(scene, o);
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "rtc-master: error: out of memory (std::bad_alloc): the process may use less memory than it needs here (ulimit -v, a container's limit)\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rtc-master: error: %s\n", e.what());
    return 1;
  }
}
