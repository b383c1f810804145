// Per-frame and whole-run figures of the master: frame rate, bytes on the wire, compression,
// and the frame rate the link's bandwidth allows (link capacity / bytes per frame).
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace rtc {

/// Share of an Ethernet line's bytes that carry TCP payload (rtc's messages) with a 1500-byte
/// MTU and TCP timestamps: 1448 payload bytes per 1538 on the wire (preamble and start 8, MAC
/// header 14, IP 20, TCP 20 + timestamps 12, FCS 4, inter-frame gap 12). A 100 Mbit/s line
/// carries 94.1 Mbit/s of messages, the figure iperf3 reports on Fast Ethernet.
inline constexpr double kTcpPayloadPerEthernetByte = 1448.0 / 1538.0;

/// Bytes of rtc messages per second a line of `line_mbit_per_s` (a --link-mbps figure) carries.
[[nodiscard]] inline double link_payload_bytes_per_s(double line_mbit_per_s) {
  return line_mbit_per_s * 1e6 / 8 * kTcpPayloadPerEthernetByte;
}

struct FrameStats {
  std::uint32_t sequence = 0;
  int frame = 0;
  double wall_ms = 0;      ///< first tile handed out -> last tile in
  double interval_ms = 0;  ///< previous frame completed -> this one (wall_ms for the first)
  std::uint64_t wire_bytes = 0;     ///< accepted tile results on the wire (headers included)
  std::uint64_t pixel_bytes = 0;    ///< their pixel payloads as sent (compressed)
  std::uint64_t raw_bytes = 0;      ///< their pixel payloads before compression
  std::uint64_t duplicate_bytes = 0;  ///< re-issued copies that arrived second (dropped)
  std::uint32_t duplicate_tiles = 0;
  std::uint32_t reissued_tiles = 0;
  double render_ms = 0;  ///< sum of the workers' tile times
  std::uint64_t primary_rays = 0, shadow_rays = 0, reflection_rays = 0;
  std::map<std::string, std::uint32_t> tiles_by_worker;
  double link_bytes_per_s = 0;  ///< rtc message bytes the link carries per second; 0: unknown yet
  double link_line_mbit_per_s = 0;  ///< the line rate given (--link-mbps); 0 when measured
  std::string link_source;      ///< "given", "measured" or "unknown"
  std::string wire_format, compression;
  std::string written;  ///< output file, empty when frames are discarded
  /// Temporal coherence (common/render/temporal.h); `temporal` false when it is off.
  bool temporal = false;
  std::uint32_t tiles_traced = 0, tiles_total = 0;  ///< tiles handed out / in the frame
  std::string temporal_why;            ///< e.g. "first frame", "1 mesh and 0 lights moved"
  std::uint64_t mark_bytes = 0;        ///< TileMarks messages on the wire (in wire_bytes)
  double full_render_ms = 0;           ///< render_ms of the last frame traced whole (0: none yet)
  std::uint64_t full_wire_bytes = 0;   ///< wire_bytes of that frame

  [[nodiscard]] double fps() const { return interval_ms > 0 ? 1000.0 / interval_ms : 0.0; }
  [[nodiscard]] double achieved_mb_per_s() const { return interval_ms > 0 ? wire_bytes / interval_ms / 1000.0 : 0.0; }
  [[nodiscard]] double compression_ratio() const { return pixel_bytes > 0 ? static_cast<double>(raw_bytes) / pixel_bytes : 1.0; }
  /// Link capacity (as message bytes) / message bytes per frame; 0 when the capacity is unknown.
  [[nodiscard]] double bound_fps() const { return link_bytes_per_s > 0 && wire_bytes > 0 ? link_bytes_per_s / wire_bytes : 0.0; }
};

/// One log line: "frame 3 [seq 3]: 41.2 ms, 24.3 fps | 1.23 MB in, 29.8 MB/s, rgba8+lz4 2.41:1 |
/// link bound 11.2 fps (94.1 Mbit/s of messages on 100.0 Mbit/s given) | tiles w1:150 w2:150".
[[nodiscard]] std::string format_frame_line(const FrameStats& s);
/// One JSON object (no newline) with every field above plus the derived figures.
[[nodiscard]] std::string frame_json(const FrameStats& s);

struct RunSummary {
  std::uint32_t frames = 0;
  std::uint32_t frames_planned = 0;  ///< the frames asked for (0: a --loop run); filled by the master
  std::string stopped;               ///< why the run ended early ("stopped by SIGINT"); empty if it did not
  /// A signal cut the run short (frames asked for not rendered, a --loop stopped before its
  /// time): the master exits 128 + its number. False when the drain finished every frame.
  bool cut_short = false;
  double total_s = 0;
  double median_fps = 0, mean_fps = 0;
  double median_bound_fps = 0;  ///< 0 when unknown
  /// fps / bound fps, the median over the frames with a bound (those that sent pixels: with
  /// temporal coherence a frame where nothing moved sends none); 0 when none had one.
  double achieved_vs_bound = 0;
  std::uint32_t bounded_frames = 0;  ///< the frames with a bound
  double median_bytes_per_frame = 0;
  double compression_ratio = 1;
  std::map<std::string, double> worker_share;  ///< fraction of accepted tiles
  std::uint32_t duplicate_tiles = 0;
  std::string wire_format, compression, link_source;
  double link_bytes_per_s = 0;
  double link_line_mbit_per_s = 0;
  std::uint64_t tiles = 0;  ///< tiles accepted over the run
  /// The master's CPU time from the first frame to the last: its network thread (dispatch,
  /// decoding, reassembly, bookkeeping), and the whole process (adds the frame writer's
  /// encoding). Filled by the master after summarize().
  double io_cpu_s = 0, process_cpu_s = 0;
  /// The frame writer (--out, --out-dir), filled by the master: frames on disk, the wall time its
  /// thread spent encoding and writing them, and how long new frames waited for it (it holds
  /// FrameWriter::kMaxPending frames; while they are all taken, no frame opens: writing was the
  /// bottleneck for that time). `writing` is false when no frame was to be written (--no-out).
  bool writing = false;
  std::uint32_t frames_written = 0;
  double write_s = 0, writer_held_s = 0;
};
/// The run's figures, frame by frame, kept small: a --loop run of hours at hundreds of frames a
/// second must not keep every FrameStats (half a kilobyte each with its strings and map). 16
/// bytes a frame for the medians (8 hours at 100 fps: 46 MB), sums for everything else.
class RunAccumulator {
 public:
  void add(const FrameStats& f);
  [[nodiscard]] std::uint32_t frames() const { return static_cast<std::uint32_t>(fps_.size()); }
  [[nodiscard]] RunSummary summarize(double total_s) const;

 private:
  std::vector<float> fps_, bound_fps_, achieved_, bytes_;
  std::uint64_t raw_ = 0, pixel_ = 0, tiles_ = 0;
  std::uint32_t duplicate_tiles_ = 0;
  std::map<std::string, std::uint64_t> by_worker_;
  std::string wire_format_, compression_, link_source_;
  double link_bytes_per_s_ = 0, link_line_mbit_per_s_ = 0;
};

/// The summary of `frames` (RunAccumulator over them).
[[nodiscard]] RunSummary summarize(const std::vector<FrameStats>& frames, double total_s);
/// Multi-line summary for the log.
[[nodiscard]] std::string format_summary(const RunSummary& s);
[[nodiscard]] std::string summary_json(const RunSummary& s);

}  // namespace rtc
