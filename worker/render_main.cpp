// rtc-render: the local frame-dump CLI. Renders frames of a scene (or the built-in one) on all
// cores and writes them as EXR/PNG through OpenImageIO.
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <new>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>
#include <tbb/info.h>

#include "common/base/cli_checks.h"
#include "common/base/error.h"
#include "common/base/frame_range.h"
#include "common/base/isa.h"
#include "common/base/log.h"
#include "common/base/process_memory.h"
#include "common/base/progress.h"
#include "common/base/signal_name.h"
#include "common/base/timer.h"
#include "common/image/image.h"
#include "common/image/image_cli.h"
#include "common/render/render_kernels.h"
#include "common/render/renderer.h"
#include "common/render/temporal_cli.h"
#include "common/render/temporal_render.h"
#include "common/scene/load.h"
#include "common/scene/scene_cli.h"

namespace {

// Ctrl-C, SIGTERM and SIGHUP. While a frame renders nothing of it is on disk, so a signal then
// ends the program at once (the frames written before are whole). While a frame is written (to
// a temporary file that is then renamed into place) the write is finished first and the program
// stops after it, so that no temporary file or half a frame is left behind. g_phase: 0 rendering,
// 1 writing, 2 ending; g_stop_signal is set before the phase is read (see on_stop_signal).
std::atomic<int> g_phase{0};
std::atomic<int> g_stop_signal{0};
static_assert(std::atomic<int>::is_always_lock_free);

/// Ends the process by `signo` itself (async-signal-safe), so that a calling shell sees a death
/// by the signal (a script's loop over scenes stops at Ctrl-C) and $? is 128 + signo.
[[noreturn]] void die_by(int signo) {
  struct sigaction plain {};
  plain.sa_handler = SIG_DFL;
  sigemptyset(&plain.sa_mask);
  ::sigaction(signo, &plain, nullptr);
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, signo);
  ::pthread_sigmask(SIG_UNBLOCK, &set, nullptr);
  ::raise(signo);
  ::_exit(128 + signo);
}

extern "C" void on_stop_signal(int signo) {
  g_stop_signal.store(signo);
  int rendering = 0;
  if (g_phase.compare_exchange_strong(rendering, 2)) {
    static const char kMessage[] = "\nrtc-render: interrupted; the frames written before it are complete\n";
    (void)!::write(STDERR_FILENO, kMessage, sizeof kMessage - 1);
    die_by(signo);
  }
  // Writing (or already ending): the write finishes, then the frame loop stops.
}

/// A signal ignored when the program started (nohup's SIGHUP, SIGINT in a shell's background
/// job) stays ignored. SA_RESTART: a signal during the write must not fail the write's system
/// calls with EINTR (libpng writes through stdio, which does not retry).
void install_stop_handlers() {
  struct sigaction action {};
  action.sa_handler = on_stop_signal;
  action.sa_flags = SA_RESTART;
  sigemptyset(&action.sa_mask);
  for (const int signo : {SIGINT, SIGTERM, SIGHUP}) {
    struct sigaction old {};
    if (::sigaction(signo, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;
    ::sigaction(signo, &action, nullptr);
  }
}

/// Writes a frame with stop signals held back until the file is in place.
void write_frame(const std::string& path, const rtc::Image& image, const rtc::ImageWriteOptions& options) {
  int rendering = 0;
  if (!g_phase.compare_exchange_strong(rendering, 1)) {
    for (;;) ::pause();  // a handler is ending the program
  }
  try {
    rtc::write_image(path, image, options);
  } catch (const std::exception& e) {
    g_phase.store(0);
    // The error is what ends the run; a signal that came during the write is named beside it.
    if (const int signo = g_stop_signal.load(); signo != 0) {
      throw rtc::Error(std::string(e.what()) + " (" + rtc::signal_name(signo) + " came during the write)");
    }
    throw;
  }
  g_phase.store(0);
}

int run(int argc, char** argv) {
  // Before any thread starts: a build's freed scratch stays for the next (process_memory.h).
  const rtc::FreedMemoryPolicy freed_memory = rtc::keep_freed_memory();
  install_stop_handlers();
  CLI::App app{"rtc-render: render frames of a scene to image files (EXR, TIFF, PNG, JPEG, PPM) on this machine"};
  rtc::SceneCliOptions scene_options;
  std::string frames_text;
  std::string out_pattern;
  int threads = 0, tile = 32;
  std::string isa_text, log_level = "info", kd_clip = "auto", temporal_text = "auto";
  int mark_cells = rtc::kDefaultMarkCells;
  bool single_rays = false, no_specialise = false, no_skip_empty = false, rebuild_moving = false;
  rtc::add_scene_cli_options(app, scene_options);
  app.add_option("--frames", frames_text, "frames to render, A-B or A, inclusive (default: the scene's animation range)");
  app.add_option("--out", out_pattern,
                 "output file pattern; #### is the zero-padded frame number; the extension picks the "
                 "format (.exr, .tif/.tiff, .png, .jpg/.jpeg, .ppm) (default: out/<scene>_####.png, out/<scene>.png for one frame)");
  app.add_option("--threads", threads, "render threads (default: all cores)")->check(CLI::Range(1, 1024));
  app.add_option("--tile", tile, "tile size in pixels (does not change a pixel; default 32, 16 with temporal coherence)")
      ->check(CLI::Range(1, 4096));
  app.add_option("--isa", isa_text, "kernel ISA: sse4 (4-wide packets), avx2 (8-wide) or avx512 (16-wide); default: the best this CPU and build support")->check(rtc::kNotEmpty);
  rtc::add_kd_clip_option(app, kd_clip);
  rtc::add_temporal_options(app, temporal_text, mark_cells, /*has_loop=*/false);
  app.add_flag("--single-rays", single_rays, "trace one ray at a time instead of packets (same pixels)");
  app.add_flag("--no-specialise", no_specialise,
               "the general tile kernel instead of the one specialised to the scene's features (same pixels)");
  app.add_flag("--no-skip-empty", no_skip_empty,
               "trace primary rays that miss the scene's bounds instead of skipping them (same pixels)");
  app.add_flag("--rebuild-moving-trees", rebuild_moving,
               "rebuild a moving mesh's kd-tree in world space whenever it moves instead of building it once in "
               "object space and transforming the rays (for timing; pixels differ only by float rounding)");
  rtc::ImageCliOptions image_options;
  rtc::add_image_write_options(app, image_options, /*on_the_wire=*/false);
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error, critical, off")->capture_default_str();
  if (const std::optional<int> status = rtc::parse_command_line(app, argc, argv, "rtc-render")) return *status;

  rtc::init_logging(log_level);
  rtc::log_freed_memory_policy(freed_memory);
  // Options are checked before the (possibly long) scene load.
  std::optional<rtc::Isa> isa;
  if (!isa_text.empty()) {
    try {
      isa = rtc::parse_isa(isa_text);
    } catch (const rtc::Error& e) {
      throw rtc::Error(std::string("--isa: ") + e.what());
    }
  }
  const rtc::ImageWriteOptions write_options = rtc::parse_image_write_options(image_options);
  std::optional<rtc::FrameRange> requested_frames;
  if (app.count("--frames") > 0) requested_frames = rtc::parse_frame_range(frames_text);  // "" is an error too
  if (app.count("--out") > 0 && out_pattern.empty()) throw rtc::Error("--out: the pattern is empty");
  // What of --out is known before the (possibly long) load: the rest once the frames are known.
  if (!out_pattern.empty()) {
    rtc::check_output_pattern_early(out_pattern, requested_frames ? requested_frames->first : 0,
                                    requested_frames && requested_frames->last > requested_frames->first);
  }
  std::unique_ptr<tbb::global_control> limit;
  if (threads > 0) {
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  static_cast<std::size_t>(threads));
  }

  rtc::Scene scene = rtc::load_scene_from_cli(scene_options);

  const rtc::FrameRange frames = requested_frames.value_or(rtc::FrameRange{scene.animation.frame_begin, scene.animation.frame_end});
  const bool multiple = frames.last > frames.first;
  rtc::check_frames_to_render(scene, frames.first, frames.last, scene_options);
  const bool default_out = out_pattern.empty();
  if (default_out) out_pattern = "out/" + rtc::file_stem_for(scene.name) + (multiple ? "_####.png" : ".png");
  const std::filesystem::path first_name(rtc::expand_frame_pattern(out_pattern, frames.first, multiple));
  // Depth and normals are kept for EXR files only, unless both are left out.
  const bool aovs = rtc::image_file_kind(first_name) == rtc::ImageFileKind::Exr &&
                    (write_options.write_depth || write_options.write_normal);
  if (const std::string problem = rtc::output_size_problem(first_name, scene.width, scene.height); !problem.empty()) {
    throw rtc::Error("--out: " + first_name.string() + ": " + problem);
  }
  // Each frame is held whole (RGBA float, and depth and normals for EXR unless both are left
  // out), and writing it takes a buffer for the file and, for 8-bit files, a copy. Checked
  // before the default output folder is made, so a refused run leaves nothing behind.
  rtc::check_memory("a " + std::to_string(scene.width) + "x" + std::to_string(scene.height) + " frame and its writing",
                    rtc::Image::bytes(scene.width, scene.height, aovs, aovs) +
                        rtc::image_write_scratch_bytes(first_name, scene.width, scene.height, aovs, write_options),
                    aovs ? "use a smaller --width/--height, or --no-depth --no-normal" : "use a smaller --width/--height");
  if (default_out) {
    std::error_code ec;
    std::filesystem::create_directories("out", ec);
    if (ec) throw rtc::Error("cannot make out/, the output folder when no --out is given: " + ec.message() + " (give --out)");
  }
  // A bad pattern, extension or output folder, for any frame, is reported before anything is rendered.
  const std::filesystem::path first_out = rtc::check_output_pattern(out_pattern, frames.first, frames.last, multiple);
  rtc::warn_about_image_options(app, image_options, write_options,
                                rtc::image_file_kind(first_out) == rtc::ImageFileKind::Exr,
                                first_out.string() + " is not an EXR file");

  rtc::RenderOptions options;
  options.isa = isa;
  options.packets = !single_rays;
  options.kd_clip = rtc::parse_kd_clip(kd_clip);
  options.aovs = aovs;
  options.specialise = !no_specialise;
  options.skip_empty = !no_skip_empty;
  options.instance_moving_meshes = !rebuild_moving;
  rtc::Renderer renderer(std::move(scene), options);
  spdlog::info("kernels: {}, {}, {} threads", rtc::isa_name(renderer.isa()),
               single_rays ? std::string("single rays") : rtc::isa_packet_description(renderer.isa()),
               threads > 0 ? threads : static_cast<int>(tbb::info::default_concurrency()));

  const bool tty = isatty(STDERR_FILENO) != 0;
  std::unique_ptr<rtc::TemporalFrames> temporal;
  const rtc::TemporalMode temporal_mode = rtc::parse_temporal_mode(temporal_text);
  const rtc::TemporalChoice temporal_choice = rtc::choose_temporal(renderer.scene(), temporal_mode, frames.first, frames.last);
  if (temporal_choice.on) {
    if (app.count("--tile") == 0) tile = rtc::kTemporalTileSize;  // the unit retraced: finer is cheaper
    temporal = std::make_unique<rtc::TemporalFrames>(renderer, tile, mark_cells, frames.first, frames.last);
    const rtc::MarkGrid& g = temporal->grid();
    if (g.empty() && !temporal_choice.moves) {
      spdlog::info("temporal coherence on: nothing moves over the frames (after the first, nothing is traced); tiles of {} "
                   "pixels", tile);
    } else if (g.empty()) {
      spdlog::info("temporal coherence on: no mesh moves (frames differ only where lights move); tiles of {} pixels", tile);
    } else {
      spdlog::info("temporal coherence on: {}x{}x{} voxels over [{:.4g} {:.4g} {:.4g}]-[{:.4g} {:.4g} {:.4g}], where meshes "
                   "move; tiles of {} pixels",
                   g.dims.x, g.dims.y, g.dims.z, g.lo.x, g.lo.y, g.lo.z, g.hi.x, g.hi.y, g.hi.z, tile);
    }
  } else if (temporal_mode == rtc::TemporalMode::On || (multiple && temporal_mode == rtc::TemporalMode::Auto)) {
    // (--temporal on is off for a single frame: said, since it was asked for)
    spdlog::info("temporal coherence off ({}){}", temporal_choice.why_off, multiple ? ": every frame traced whole" : "");
  }
  double last_full_ms = 0;
  rtc::Timer run_timer;
  for (int f = frames.first; f <= frames.last; ++f) {
    rtc::Timer frame_timer;
    const double cpu_start = rtc::process_cpu_ms();
    if (f == frames.first) {
      // The first prepare builds the kd-tree of the whole scene: seconds for millions of
      // triangles, with nothing on the screen otherwise.
      spdlog::info("frame {}: building the kd-tree of {} triangles", f, renderer.scene().triangle_count());
    }
    const std::shared_ptr<const rtc::FrameState> state = renderer.prepare(f);
    if (f == frames.first) {
      const rtc::RenderOptions& o = renderer.options();
      spdlog::info("scene features: {}; tile kernel: {}", rtc::describe(state->features),
                   rtc::render_kernels(renderer.isa())
                       .kernel_name(*state, rtc::TileKernelOptions{o.packets, o.specialise, o.skip_empty}, o.aovs));
    }
    const double prepare_ms = frame_timer.elapsed_ms();
    const double cpu_before = rtc::process_cpu_ms();
    const double prepare_cpu_ms = cpu_before - cpu_start;
    const auto pixels = static_cast<std::uint64_t>(state->width) * static_cast<std::uint64_t>(state->height);
    rtc::ProgressBar progress(pixels, "frame " + std::to_string(f), "px");
    rtc::TileRayCounts counts;
    rtc::Image full_image;
    const rtc::Image* image = &full_image;
    rtc::TemporalFrames::Report report;
    if (temporal) {
      image = &temporal->render(*state, &report, tty ? &progress : nullptr);
      counts = report.counts;
    } else {
      full_image = renderer.render_frame(*state, tile, tty ? &progress : nullptr, &counts);
    }
    progress.finish();
    const double render_ms = frame_timer.elapsed_ms() - prepare_ms;
    const double render_cpu_ms = rtc::process_cpu_ms() - cpu_before;
    std::string temporal_note;
    if (temporal) {
      const rtc::TemporalPlan& p = report.plan;
      if (p.full) {
        last_full_ms = render_ms;
        temporal_note = fmt::format(" | all {} tiles traced ({})", report.tiles, p.why);
      } else {
        temporal_note = fmt::format(" | {}/{} tiles retraced ({}; {} voxels changed; crossed by rays {}, by shadow rays {})",
                                    p.dirty_count, report.tiles, p.why, p.changed_voxels, p.by_path, p.by_shadow);
        if (p.dirty_count == 0 && last_full_ms > 0) {
          // Nothing traced: a ratio would only measure the bookkeeping ("499.7x faster").
          temporal_note += fmt::format(", nothing traced (the last full frame took {:.0f} ms)", last_full_ms);
        } else if (last_full_ms > 0) {
          temporal_note += fmt::format(", {:.1f}x faster than the last full frame", last_full_ms / std::max(render_ms, 1e-3));
        }
      }
    }
    const std::string path = rtc::expand_frame_pattern(out_pattern, f, multiple);
    write_frame(path, *image, write_options);
    const double seconds = std::max(render_ms, 1e-3) / 1000.0;
    std::printf("frame %d: wrote %s (%dx%d) in %.3f s: prepare %.0f ms (cpu %.0f ms), render %.0f ms (cpu %.0f ms), %.2f M rays/s "
                "(%llu primary, %llu of them skipped as empty space, %llu shadow, %llu reflection)%s\n",
                f, path.c_str(), state->width, state->height, frame_timer.elapsed_ms() / 1000.0, prepare_ms,
                prepare_cpu_ms, render_ms, render_cpu_ms, static_cast<double>(counts.total()) / seconds / 1e6,
                static_cast<unsigned long long>(counts.primary), static_cast<unsigned long long>(counts.primary_skipped),
                static_cast<unsigned long long>(counts.shadow), static_cast<unsigned long long>(counts.reflection),
                temporal_note.c_str());
    std::fflush(stdout);
    if (const int signo = g_stop_signal.load(); signo != 0) {
      std::fprintf(stderr, "rtc-render: interrupted by %s while frame %d was written: stopped after it (%s)%s\n",
                   rtc::signal_name(signo).c_str(), f, path.c_str(),
                   f < frames.last ? fmt::format("; frames {}-{} not rendered", f + 1, frames.last).c_str() : "");
      std::fflush(stderr);
      die_by(signo);
    }
  }
  if (multiple) {
    std::printf("rendered frames %d-%d (%d frames) in %.1f s; the last: %s\n", frames.first, frames.last,
                frames.last - frames.first + 1, run_timer.elapsed_ms() / 1000.0,
                rtc::expand_frame_pattern(out_pattern, frames.last, multiple).c_str());
  }
  // The frames are on disk; a report that never reached standard output (a full disk, a closed
  // descriptor) still fails the run.
  if (std::fflush(stdout) != 0 || std::ferror(stdout) != 0) {
    throw rtc::Error("standard output: the frames' report could not be written (the frames themselves were)");
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const rtc::Error& e) {
    std::fprintf(stderr, "rtc-render: error: %s\n", e.what());
    return 1;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "rtc-render: error: out of memory (std::bad_alloc): the process may use less memory than it needs here (ulimit -v, a container's limit)\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rtc-render: error: %s\n", e.what());
    return 1;
  }
}
