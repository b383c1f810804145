// Per-frame and whole-run figures of the master (see frame_stats.h).
#include "master/frame_stats.h"

#include <algorithm>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "common/base/log.h"

namespace rtc {

namespace {

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string link_text(double bytes_per_s, double line_mbit_per_s, const std::string& source) {
  if (bytes_per_s <= 0) return "link capacity unknown";
  if (line_mbit_per_s > 0) {
    return fmt::format("{:.1f} Mbit/s of messages on {:.1f} Mbit/s {}", bytes_per_s * 8 / 1e6, line_mbit_per_s, source);
  }
  return fmt::format("{:.1f} Mbit/s {}", bytes_per_s * 8 / 1e6, source);
}

}  // namespace

std::string format_frame_line(const FrameStats& s) {
  // The frame rate counts from the previous frame's completion (frames overlap in flight), the
  // frame's own time from its first tile out: both are named, as they can differ a thousandfold
  // (a frame whose tiles all finished just after the one before it).
  std::string line = fmt::format("frame {} [seq {}]: {:.2f} fps (done ", s.frame, s.sequence, s.fps());
  if (s.sequence > 0) line += fmt::format("{:.1f} ms after the previous frame, ", s.interval_ms);
  line += fmt::format("{:.1f} ms after its first tile) | ", s.wall_ms);
  if (s.wire_bytes == 0) {
    line += "no pixels sent";
  } else {
    line += fmt::format("{:.3f} MB in, {:.1f} MB/s, {}+{} {:.2f}:1 | ", s.wire_bytes / 1e6, s.achieved_mb_per_s(),
                        s.wire_format, s.compression, s.compression_ratio());
    if (s.bound_fps() > 0) {
      line += fmt::format("link bound {:.2f} fps ({})", s.bound_fps(), link_text(s.link_bytes_per_s, s.link_line_mbit_per_s, s.link_source));
    } else {
      line += "link bound unknown (not measured yet)";
    }
  }
  if (!s.tiles_by_worker.empty()) {
    line += " | tiles";
    for (const auto& [name, n] : s.tiles_by_worker) line += fmt::format(" {}:{}", name, n);
  }
  if (s.temporal) {
    line += fmt::format(" | traced {}/{} tiles ({})", s.tiles_traced, s.tiles_total, s.temporal_why);
    if (s.tiles_traced == 0 && s.full_render_ms > 0) {
      line += fmt::format(", no work (a whole trace took {:.1f} ms)", s.full_render_ms);
    } else if (s.tiles_traced < s.tiles_total && s.full_render_ms > 0) {
      line += fmt::format(", work {:.1f} of {:.1f} ms ({:.1f}x less), {:.3f} of {:.3f} MB", s.render_ms, s.full_render_ms,
                          s.full_render_ms / std::max(s.render_ms, 1e-3), s.wire_bytes / 1e6, s.full_wire_bytes / 1e6);
    }
  }
  if (s.reissued_tiles > 0) line += fmt::format(" | {} tail tiles re-issued, {} duplicates dropped", s.reissued_tiles, s.duplicate_tiles);
  if (!s.written.empty()) line += " -> " + s.written;
  return line;
}

std::string frame_json(const FrameStats& s) {
  nlohmann::json j;
  j["type"] = "frame";
  j["sequence"] = s.sequence;
  j["frame"] = s.frame;
  j["wall_ms"] = s.wall_ms;
  j["interval_ms"] = s.interval_ms;
  j["fps"] = s.fps();
  j["wire_bytes"] = s.wire_bytes;
  j["pixel_bytes"] = s.pixel_bytes;
  j["raw_bytes"] = s.raw_bytes;
  j["compression_ratio"] = s.compression_ratio();
  j["achieved_mb_per_s"] = s.achieved_mb_per_s();
  j["wire_format"] = s.wire_format;
  j["compression"] = s.compression;
  j["link_mbit_per_s"] = s.link_bytes_per_s * 8 / 1e6;
  j["link_line_mbit_per_s"] = s.link_line_mbit_per_s;
  j["link_source"] = s.link_source;
  j["bound_fps"] = s.bound_fps();
  j["duplicate_tiles"] = s.duplicate_tiles;
  j["duplicate_bytes"] = s.duplicate_bytes;
  j["reissued_tiles"] = s.reissued_tiles;
  j["render_ms"] = s.render_ms;
  if (s.temporal) {
    j["temporal"] = {{"tiles_traced", s.tiles_traced}, {"tiles_total", s.tiles_total}, {"why", s.temporal_why},
                     {"mark_bytes", s.mark_bytes}, {"full_render_ms", s.full_render_ms},
                     {"full_wire_bytes", s.full_wire_bytes}};
  }
  j["rays"] = {{"primary", s.primary_rays}, {"shadow", s.shadow_rays}, {"reflection", s.reflection_rays}};
  j["tiles_by_worker"] = s.tiles_by_worker;
  if (!s.written.empty()) j["file"] = s.written;
  return j.dump();
}

void RunAccumulator::add(const FrameStats& f) {
  fps_.push_back(static_cast<float>(f.fps()));
  if (f.bound_fps() > 0) {
    bound_fps_.push_back(static_cast<float>(f.bound_fps()));
    achieved_.push_back(static_cast<float>(f.fps() / f.bound_fps()));
  }
  bytes_.push_back(static_cast<float>(f.wire_bytes));
  raw_ += f.raw_bytes;
  pixel_ += f.pixel_bytes;
  duplicate_tiles_ += f.duplicate_tiles;
  for (const auto& [name, n] : f.tiles_by_worker) {
    by_worker_[name] += n;
    tiles_ += n;
  }
  wire_format_ = f.wire_format;
  compression_ = f.compression;
  link_source_ = f.link_source;
  link_bytes_per_s_ = f.link_bytes_per_s;
  link_line_mbit_per_s_ = f.link_line_mbit_per_s;
}

RunSummary RunAccumulator::summarize(double total_s) const {
  RunSummary r;
  r.frames = frames();
  r.total_s = total_s;
  if (fps_.empty()) return r;
  const auto median_of = [](const std::vector<float>& v) {
    return median(std::vector<double>(v.begin(), v.end()));
  };
  r.median_fps = median_of(fps_);
  r.mean_fps = total_s > 0 ? fps_.size() / total_s : 0;
  r.median_bound_fps = median_of(bound_fps_);
  r.achieved_vs_bound = median_of(achieved_);
  r.bounded_frames = static_cast<std::uint32_t>(achieved_.size());
  r.median_bytes_per_frame = median_of(bytes_);
  r.compression_ratio = pixel_ > 0 ? static_cast<double>(raw_) / pixel_ : 1.0;
  r.duplicate_tiles = duplicate_tiles_;
  for (const auto& [name, n] : by_worker_) r.worker_share[name] = tiles_ ? static_cast<double>(n) / tiles_ : 0;
  r.wire_format = wire_format_;
  r.compression = compression_;
  r.link_source = link_source_;
  r.link_bytes_per_s = link_bytes_per_s_;
  r.link_line_mbit_per_s = link_line_mbit_per_s_;
  r.tiles = tiles_;
  return r;
}

RunSummary summarize(const std::vector<FrameStats>& frames, double total_s) {
  RunAccumulator run;
  for (const FrameStats& f : frames) run.add(f);
  return run.summarize(total_s);
}

std::string format_summary(const RunSummary& s) {
  if (s.frames == 0) {
    // No figure to give (they used to read "0.000 MB/frame (+ 1.00:1); ... share" with nothing).
    std::string out = "summary: no frame finished";
    if (s.frames_planned > 0) out += fmt::format(" of the {} asked for", s.frames_planned);
    if (!s.stopped.empty()) out += fmt::format(" ({})", s.stopped);
    return out;
  }
  std::string frames = counted(s.frames, "frame", "frames");
  if (s.frames_planned > 0 && s.frames < s.frames_planned) {
    frames = fmt::format("{} of {} frames ({}: {} not rendered)", s.frames, s.frames_planned,
                         s.stopped.empty() ? std::string("stopped") : s.stopped, s.frames_planned - s.frames);
  } else if (!s.stopped.empty()) {
    frames += fmt::format(" ({})", s.stopped);
  }
  // The run's own rate first: a median over frames that finish in bursts (temporal coherence
  // keeping most of a frame, frames in flight finishing together) can be far above it.
  std::string out = fmt::format("summary: {} in {:.2f} s: {:.2f} fps over the run (median of the frames' {:.2f} fps); "
                                "{:.3f} MB/frame ({}+{} {:.2f}:1)",
                                frames, s.total_s, s.mean_fps, s.median_fps, s.median_bytes_per_frame / 1e6,
                                s.wire_format, s.compression, s.compression_ratio);
  if (s.median_bound_fps > 0) {
    // Both medians over the same frames: those that sent pixels.
    out += fmt::format("; link bound {:.2f} fps ({}), achieved {:.1f}% of it", s.median_bound_fps,
                       link_text(s.link_bytes_per_s, s.link_line_mbit_per_s, s.link_source), 100.0 * s.achieved_vs_bound);
    if (s.bounded_frames < s.frames) {
      out += fmt::format(" (over the {} frames that sent pixels; {} sent none)", s.bounded_frames, s.frames - s.bounded_frames);
    }
    if (s.achieved_vs_bound > 1.0) {
      out += s.link_source == "given"
                 ? std::string(" (above the bound: the link is faster than --link-mbps says)")
                 : std::string(" (above the bound: the link measured slower than it is, as when a worker was still "
                               "loading the scene during the probe; --link-mbps gives the real figure)");
    }
  } else {
    out += "; link bound unknown";
  }
  out += "; share";
  for (const auto& [name, share] : s.worker_share) out += fmt::format(" {}:{:.1f}%", name, 100.0 * share);
  if (s.duplicate_tiles > 0) out += fmt::format("; {} duplicate tiles dropped", s.duplicate_tiles);
  if (s.writing) {
    out += fmt::format("; {} written", counted(s.frames_written, "frame", "frames"));
    if (s.frames_written > 0) out += fmt::format(" ({:.0f} ms each to encode and write)", 1e3 * s.write_s / s.frames_written);
    if (s.writer_held_s >= 0.05) {
      out += fmt::format(", new frames waited {:.2f} s for the writer (writing was the bottleneck then)", s.writer_held_s);
    }
  }
  if (s.frames > 0 && s.tiles > 0) {
    out += fmt::format("; master CPU {:.2f} s, network thread {:.3f} s ({:.2f} ms/frame, {:.1f} us/tile)", s.process_cpu_s,
                       s.io_cpu_s, 1e3 * s.io_cpu_s / s.frames, 1e6 * s.io_cpu_s / static_cast<double>(s.tiles));
  }
  return out;
}

std::string summary_json(const RunSummary& s) {
  nlohmann::json j;
  j["type"] = "summary";
  j["frames"] = s.frames;
  if (s.frames_planned > 0) j["frames_planned"] = s.frames_planned;
  j["stopped"] = s.stopped.empty() ? nlohmann::json(nullptr) : nlohmann::json(s.stopped);
  j["cut_short"] = s.cut_short;
  j["total_s"] = s.total_s;
  j["median_fps"] = s.median_fps;
  j["mean_fps"] = s.mean_fps;
  j["median_bound_fps"] = s.median_bound_fps;
  j["achieved_vs_bound"] = s.achieved_vs_bound;
  j["bounded_frames"] = s.bounded_frames;
  j["median_bytes_per_frame"] = s.median_bytes_per_frame;
  j["compression_ratio"] = s.compression_ratio;
  j["worker_share"] = s.worker_share;
  j["duplicate_tiles"] = s.duplicate_tiles;
  j["wire_format"] = s.wire_format;
  j["compression"] = s.compression;
  j["link_mbit_per_s"] = s.link_bytes_per_s * 8 / 1e6;
  j["link_line_mbit_per_s"] = s.link_line_mbit_per_s;
  j["link_source"] = s.link_source;
  j["tiles"] = s.tiles;
  j["master_io_cpu_s"] = s.io_cpu_s;
  j["master_process_cpu_s"] = s.process_cpu_s;
  if (s.writing) {
    j["frames_written"] = s.frames_written;
    j["write_s"] = s.write_s;
    j["writer_held_s"] = s.writer_held_s;
  }
  return j.dump();
}

}  // namespace rtc
