// rtc-master's server (see master_server.h). All state lives on the one thread that runs the
// io_context: no locks, and every handler sees a consistent queue. Frames are encoded and
// written by FrameWriter on a thread of its own.
#include "master/master_server.h"

#include <algorithm>
#include <chrono>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <ctime>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <utility>

#include <asio.hpp>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "common/base/error.h"
#include "common/base/log.h"
#include "common/base/signal_name.h"
#include "common/base/version.h"
#include "common/image/pixel_format.h"
#include "common/scene/serialize.h"
#include "master/frame_stats.h"
#include "master/frame_writer.h"
#include "master/host_log_budget.h"
#include "master/image_pool.h"
#include "master/tile_queue.h"
#include "protocol/auth.h"
#include "protocol/message.h"
#include "protocol/net/connection.h"

namespace rtc {

namespace {

using Clock = std::chrono::steady_clock;
namespace proto = protocol;

// The reason a file operation that sets errno failed; set errno to 0 before it (iostreams need
// not set it at all).
std::string errno_reason() { return errno != 0 ? std::string(std::strerror(errno)) : std::string("unknown reason"); }

double ms_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

/// Copies the rectangle (x, y, w, h) of `src` into the same place of `dst` (same size and
/// channels): a clean tile's pixels from the canvas into a new frame.
void copy_rect(const Image& src, Image& dst, int x, int y, int w, int h) {
  for (int row = y; row < y + h; ++row) {
    const std::size_t first = static_cast<std::size_t>(row) * static_cast<std::size_t>(src.width) + static_cast<std::size_t>(x);
    const auto n = static_cast<std::size_t>(w);
    std::copy_n(src.rgba.begin() + static_cast<std::ptrdiff_t>(4 * first), 4 * n, dst.rgba.begin() + static_cast<std::ptrdiff_t>(4 * first));
    if (!src.depth.empty() && !dst.depth.empty()) {
      std::copy_n(src.depth.begin() + static_cast<std::ptrdiff_t>(first), n, dst.depth.begin() + static_cast<std::ptrdiff_t>(first));
    }
    if (!src.normal.empty() && !dst.normal.empty()) {
      std::copy_n(src.normal.begin() + static_cast<std::ptrdiff_t>(3 * first), 3 * n,
                  dst.normal.begin() + static_cast<std::ptrdiff_t>(3 * first));
    }
  }
}

struct Worker {
  enum class State { AwaitHello, AwaitAuth, Scene, Ready, Closed };

  TileQueue::WorkerId id = 0;
  std::shared_ptr<net::Connection> conn;
  std::string host;   // the peer's address without the port (connection limits)
  /// "w3" once it has authenticated (workers are numbered in the order they do, so connections
  /// refused before use no number), "#5" (the connection's count) until then; used in the logs
  /// and the per-frame tile counts.
  std::string label;
  State state = State::AwaitHello;
  proto::Nonce nonce{};
  proto::Hello hello;
  std::unique_ptr<asio::steady_timer> auth_timer;
  Clock::time_point last_heard;
  std::set<std::uint32_t> announced;  // sequences whose FrameSettings it has
  std::uint64_t scene_offset = 0;     // next scene byte to send
  std::size_t max_outstanding = 2;
  std::uint32_t threads = 1;
  bool probing = false;
  Clock::time_point probe_sent;
  std::map<std::pair<std::uint32_t, std::uint32_t>, Clock::time_point> assigned_at;  // (seq, tile)
  std::uint64_t tiles_accepted = 0;
  /// TileMarks received for tiles whose TileResult has not come yet, by (seq, tile), with
  /// their bytes on the wire.
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::pair<proto::TileMarks, std::size_t>> pending_marks;
  bool rejected = false;  // an Error was sent; closing once it is flushed
  bool said_hello = false;  // its Hello has come (hello and threads hold what it said)
  /// Since when it has held tiles without returning one: its last result, or the assignment
  /// that gave an idle worker work. A worker past Master::stalled_after() is named once.
  Clock::time_point waiting_since;
  bool stall_noted = false;

  [[nodiscard]] std::string describe() const {
    std::string s = label + " (" + (hello.name.empty() ? std::string("?") : hello.name) + " at " + conn->peer();
    if (said_hello) {
      // The threads its share is sized by (the claim clamped to 1..256), and the claim where it differs.
      s += ", " + std::to_string(threads) + (threads == 1 ? " thread" : " threads") +
           (hello.threads != threads ? " (claims " + std::to_string(hello.threads) + ")" : std::string()) + ", " + hello.isa;
    }
    return s + ")";
  }
};

struct OpenFrame {
  std::uint32_t sequence = 0;
  int frame = 0;
  std::uint64_t plan = 0;  ///< TemporalTracker plan id (temporal coherence)
  /// The frame's pixels, taken from the pool by Master::pixels_of at the first tile written into
  /// it, not when the frame opens: a fresh one costs its whole size in page faults, and the
  /// frames opened together at the start of a run held back their first tiles until all were
  /// made (8 frames of 2048x2048 float with depth and normals, 1 GiB: 3.6-5 s on a VM).
  Image image;
  bool has_image = false;
  bool started = false;
  bool to_trace = false;  ///< has tiles to trace, or that may be (temporal coherence): announced to workers
  Clock::time_point started_at;
  FrameStats stats;
};

/// --listen resolved, and refused off loopback without a token.
asio::ip::tcp::endpoint listen_endpoint(asio::io_context& io, const MasterOptions& options) {
  const net::HostPort hp = net::parse_host_port(options.listen, "--listen");
  asio::ip::tcp::resolver resolver(io);
  asio::error_code ec;
  const auto results = resolver.resolve(hp.host, std::to_string(hp.port),
                                        asio::ip::resolver_base::passive | asio::ip::resolver_base::numeric_service, ec);
  if (ec || results.empty()) throw Error("--listen " + options.listen + ": cannot resolve " + hp.host + ": " + ec.message());
  const asio::ip::tcp::endpoint endpoint = *results.begin();
  if (!endpoint.address().is_loopback() && options.token.empty()) {
    throw Error("--listen " + options.listen + " is not a loopback address: anyone who can reach it could take "
                "tiles and the scene; give --token-file so workers must prove the token");
  }
  return endpoint;
}

class Master {
 public:
  Master(const Scene& scene, const MasterOptions& options)
      : options_(options),
        width_(scene.width),
        height_(scene.height),
        queue_(scene.width, scene.height, options.tile_size),
        scene_bytes_(serialize_scene(scene)),
        scene_hash_(proto::sha256(scene_bytes_)),
        scene_name_(scene.name),
        acceptor_(io_),
        signals_(io_, SIGINT, SIGTERM),
        tick_(io_) {
    if (!options_.tls_cert.empty() || !options_.tls_key.empty()) {
      if (options_.tls_cert.empty() || options_.tls_key.empty()) throw Error("--tls-cert and --tls-key go together");
      tls_ = net::tls_server_context(options_.tls_cert, options_.tls_key);
    }
    if (!options_.stats_json.empty()) {
      errno = 0;
      stats_file_.open(options_.stats_json, std::ios::out | std::ios::trunc);
      if (!stats_file_) {
        throw Error("--stats-json: cannot open " + options_.stats_json + " for writing: " +
                    errno_reason());
      }
    }
    if (!options_.out_pattern.empty()) {
      writer_ = std::make_unique<FrameWriter>(
          options_.write_options,
          [this](const std::string& error) { asio::post(io_, [this, error] { fatal("writing frames: " + error); }); },
          &frame_pool_);
    }
    if (options_.link_mbps > 0) {
      // A given figure is a line rate; the tiles' bytes are TCP payload, ~6% less (measured on
      // a 100 Mbit/s netns link: 1.38 fps against a bound of 1.49 counting the line rate, 1.40
      // counting the payload; tests/deploy/netns/README.md).
      link_bytes_per_s_ = link_payload_bytes_per_s(options_.link_mbps);
      link_source_ = "given";
    }
    next_frame_ = options_.first_frame;
    if (options_.temporal.on) {
      tracker_ = std::make_unique<TemporalTracker>(
          scene, mark_grid_for(scene, options_.mark_cells, options_.first_frame, options_.last_frame),
                                                   queue_.tiles_per_frame());
      canvas_ = Image(width_, height_, (options_.channels & kChannelDepth) != 0, (options_.channels & kChannelNormal) != 0);
    }
  }

  Master(const Master&) = delete;
  Master& operator=(const Master&) = delete;
  ~Master() { remove_ready_file(); }  // a run that ended by an exception

  int run() {
    listen();
    accept();
    signals_.async_wait([this](const asio::error_code& ec, int signal) { on_signal(ec, signal); });
    schedule_tick();
    spdlog::info("scene {}: {} bytes serialized, sha256 {}…; {}x{}, {} tiles of {} px per frame; wire {}+{}", scene_name_,
                 scene_bytes_.size(), proto::to_hex(scene_hash_).substr(0, 16), width_, height_,
                 queue_.tiles_per_frame(), options_.tile_size, wire_format_name(options_.wire),
                 compression_name(options_.compression));
    if (tracker_) {
      const MarkGrid& g = tracker_->grid();
      if (g.empty() && !options_.temporal.moves) {
        spdlog::info("temporal coherence on: nothing moves over the frames; after the first frame nothing is traced");
      } else if (g.empty()) {
        spdlog::info("temporal coherence on: no mesh moves; after the first frame only tiles shaded by a moved light are traced");
      } else {
        spdlog::info("temporal coherence on: after the first frame only tiles whose rays crossed space a moving mesh left or "
                     "entered are traced; {}x{}x{} voxels over [{:.4g} {:.4g} {:.4g}]-[{:.4g} {:.4g} {:.4g}]",
                     g.dims.x, g.dims.y, g.dims.z, g.lo.x, g.lo.y, g.lo.z, g.hi.x, g.hi.y, g.hi.z);
      }
    } else {
      spdlog::info("temporal coherence off ({})", options_.temporal.why_off);
    }
    io_.run();
    if (writer_) {
      // The last frames' writes, the late-signal handler still listening (arm_late_signal): a
      // first signal must not kill the master before they are on disk. A large frame takes
      // seconds to encode: say what is left, every 5 s.
      const Clock::time_point flush_start = Clock::now();
      const FrameWriter::Totals at_start = writer_->totals();
      const std::size_t left_at_start = at_start.pending;
      if (left_at_start > 0) spdlog::info("writing the last {} to disk", counted(left_at_start, "frame", "frames"));
      Clock::time_point last_note = flush_start;
      while (!writer_->flush_for(std::chrono::milliseconds(100))) {
        io_.restart();
        io_.poll();
        if (const Clock::time_point now = Clock::now(); ms_between(last_note, now) >= 5000) {
          last_note = now;
          spdlog::info("still writing: {} of the last {} frames left after {:.0f} s", writer_->pending(), left_at_start,
                       ms_between(flush_start, now) / 1e3);
        }
      }
      // (Every write has ended here: the counts are final.)
      if (const std::size_t failed = writer_->totals().failed - at_start.failed; left_at_start > 0 && failed == 0) {
        spdlog::info("the last {} written in {:.2f} s", counted(left_at_start, "frame", "frames"),
                     ms_between(flush_start, Clock::now()) / 1e3);
      } else if (left_at_start > 0) {
        spdlog::error("{} of the last {} could not be written (the first error is below)", failed,
                      counted(left_at_start, "frame", "frames"));
      }
      io_.restart();
      io_.poll();  // a signal in the last wait is noted too
      // A write that failed after the loop stopped (the last frames) must still fail the run.
      if (fatal_error_.empty() && !writer_->first_error().empty()) {
        fatal_error_ = "writing frames: " + writer_->first_error();
        spdlog::error("{}", fatal_error_);
      }
    }
    {
      // Nothing handles a signal from here on: the default action again.
      asio::error_code ec;
      signals_.clear(ec);
    }
    const double total_s = run_started_ && finished_.frames() > 0
                               ? std::chrono::duration<double>(last_complete_ - run_start_).count()
                               : 0.0;
    RunSummary summary = finished_.summarize(total_s);
    if (options_.loop_seconds <= 0) {
      summary.frames_planned = static_cast<std::uint32_t>(options_.last_frame - options_.first_frame + 1);
    }
    summary.stopped = stop_reason_;
    summary.cut_short = cut_short();
    if (writer_) {
      const FrameWriter::Totals written = writer_->totals();
      summary.writing = true;
      summary.frames_written = static_cast<std::uint32_t>(written.written);
      summary.write_s = written.write_s;
      summary.writer_held_s = writer_held_s_;
    }
    if (run_started_) {
      summary.io_cpu_s = cpu_seconds(CLOCK_THREAD_CPUTIME_ID) - io_cpu_at_start_;  // this is the io thread
      summary.process_cpu_s = cpu_seconds(CLOCK_PROCESS_CPUTIME_ID) - process_cpu_at_start_;
      // The two clocks are read at slightly different moments: with the other threads idle the
      // thread's could come out a few hundred ns above the whole process's.
      summary.io_cpu_s = std::min(summary.io_cpu_s, summary.process_cpu_s);
    }
    spdlog::info("{}", format_summary(summary));
    if (stats_file_.is_open()) {
      stats_file_ << summary_json(summary) << '\n';
      stats_file_.flush();
      if (!stats_file_ && fatal_error_.empty()) fatal_error_ = "--stats-json " + options_.stats_json + ": write failed";
    }
    if (!fatal_error_.empty()) throw Error(fatal_error_);
    // A run a signal cut short exits 128 + the signal's number, as a shell expects of an
    // interrupted program, so that `rtc-master ... && next-step` does not take it for a whole
    // run; the frames it finished are written all the same. A signal that came once every frame
    // was rendered (or during the goodbyes) leaves the run whole: 0.
    if (summary.cut_short) {
      spdlog::info("exit status {} (128 + {}): the run was cut short", 128 + stop_signal_, signal_name(stop_signal_));
      return 128 + stop_signal_;
    }
    return 0;
  }

 private:
  // ---- listening and accepting -------------------------------------------------------------

  void listen() {
    const asio::ip::tcp::endpoint endpoint = listen_endpoint(io_, options_);
    asio::error_code ec;
    acceptor_.open(endpoint.protocol(), ec);
    if (!ec) acceptor_.set_option(asio::ip::tcp::acceptor::reuse_address(true), ec);
    if (!ec) acceptor_.bind(endpoint, ec);
    if (!ec) acceptor_.listen(asio::socket_base::max_listen_connections, ec);
    if (ec) throw Error("--listen " + options_.listen + ": " + ec.message());
    const asio::ip::tcp::endpoint local = acceptor_.local_endpoint();
    const std::string address = local.address().to_string();
    listening_on_ = (local.address().is_v6() ? "[" + address + "]" : address) + ":" + std::to_string(local.port());
    spdlog::info("rtc-master {} listening on {} ({}, {}), waiting for {}", build_id(), listening_on_,
                 options_.token.empty() ? "no token: loopback only" : "token required", tls_ ? "TLS" : "no TLS",
                 counted(options_.min_workers, "worker", "workers"));
    last_wait_log_ = Clock::now();  // the line above says it; the next in 5 s
    short_since_ = last_wait_log_;   // --wait-seconds counts from here
    if (!options_.ready_file.empty()) {
      const std::string tmp = options_.ready_file + ".tmp";
      std::error_code fs_ec;
      {
        errno = 0;
        std::ofstream f(tmp, std::ios::trunc);
        f << listening_on_ << '\n';
        f.close();
        if (!f) {
          const std::string reason = errno_reason();
          std::filesystem::remove(tmp, fs_ec);
          throw Error("--ready-file: cannot write " + options_.ready_file + " (through " + tmp + "): " + reason);
        }
      }
      std::filesystem::rename(tmp, options_.ready_file, fs_ec);
      if (fs_ec) {
        const std::string reason = fs_ec.message();
        std::filesystem::remove(tmp, fs_ec);
        throw Error("--ready-file: cannot rename " + tmp + " to " + options_.ready_file + ": " + reason);
      }
      ready_file_written_ = true;
    }
  }

  /// The ready file says "listening on HOST:PORT": it goes when the master stops listening, so a
  /// script never finds a finished master's address (or the last run's) and waits on it. Only
  /// while it still holds this master's address: another master given the same path keeps its own.
  void remove_ready_file() noexcept {
    if (!ready_file_written_) return;
    ready_file_written_ = false;
    try {
      std::ifstream in(options_.ready_file);
      std::string line;
      if (!std::getline(in, line) || line != listening_on_) return;
      in.close();
      std::error_code ec;
      std::filesystem::remove(options_.ready_file, ec);
      if (ec) spdlog::warn("--ready-file: cannot remove {}: {}", options_.ready_file, ec.message());
    } catch (const std::exception&) {
      // Left in place: a stale address is what a ready file meant before.
    }
  }

  void accept() {
    acceptor_.async_accept([this](const asio::error_code& ec, asio::ip::tcp::socket socket) {
      if (ec == asio::error::operation_aborted || done_) return;
      if (ec) {
        // EMFILE and friends: log and keep accepting after a pause rather than spinning.
        spdlog::warn("accept on {}: {}", listening_on_, ec.message());
        auto timer = std::make_shared<asio::steady_timer>(io_, std::chrono::milliseconds(100));
        timer->async_wait([this, timer](const asio::error_code&) { accept(); });
        return;
      }
      on_accept(std::move(socket));
      accept();
    });
  }

  void on_accept(asio::ip::tcp::socket socket) {
    const std::string peer = net::peer_name(socket);
    asio::error_code endpoint_ec;
    const std::string host = socket.remote_endpoint(endpoint_ec).address().to_string();
    // TLS handshakes under way count as connections that have not authenticated.
    const auto handshaking = tls_handshakes_.find(host);
    int unauthenticated = handshaking == tls_handshakes_.end() ? 0 : handshaking->second;
    int open = unauthenticated;
    for (const auto& [other_id, other] : workers_) {
      if (other->state == Worker::State::Closed || other->host != host) continue;
      ++open;
      unauthenticated += other->state == Worker::State::AwaitHello || other->state == Worker::State::AwaitAuth;
    }
    // Refused before anything is sent or allocated for it: closing the socket is the answer.
    if (open >= options_.max_connections_per_host || unauthenticated >= options_.max_unauthenticated_per_host) {
      if (std::string note; connection_log_.allow(host, Clock::now(), note)) {
        spdlog::warn("refused connection from {}: {} already has {} open connection(s), {} not authenticated "
                     "(limits {} and {}: --max-connections-per-host, --max-unauthenticated-per-host){}",
                     peer, host, open, unauthenticated, options_.max_connections_per_host,
                     options_.max_unauthenticated_per_host, note);
      }
      socket.close(endpoint_ec);
      return;
    }
    if (!tls_) {
      add_connection(std::make_shared<net::Connection>(std::move(socket), peer), peer, host);
      return;
    }
    // TLS: the handshake first, within the time a connection has to authenticate; the rtc
    // protocol (Challenge first) starts once it is done.
    auto stream = std::make_shared<net::TlsStream>(std::move(socket), *tls_);
    ++tls_handshakes_[host];
    net::async_tls_handshake(stream, asio::ssl::stream_base::server, std::chrono::milliseconds(options_.auth_timeout_ms),
                             [this, stream, peer, host](const asio::error_code& ec) {
      if (--tls_handshakes_[host] == 0) tls_handshakes_.erase(host);
      if (done_) return;
      if (ec) {
        if (std::string note; connection_log_.allow(host, Clock::now(), note)) {
          spdlog::warn("TLS handshake with {} failed: {}{}", peer,
                       ec == asio::error::operation_aborted
                           ? "no handshake within " + std::to_string(options_.auth_timeout_ms) + " ms (a worker without --tls-ca?)"
                           : ec.message(),
                       note);
        }
        return;
      }
      add_connection(std::make_shared<net::Connection>(stream, peer), peer, host);
    });
  }

  // A new connection (TLS already established, if any): challenge it to authenticate.
  void add_connection(std::shared_ptr<net::Connection> conn, const std::string& peer, const std::string& host) {
    const TileQueue::WorkerId id = ++last_worker_id_;
    auto w = std::make_unique<Worker>();
    w->id = id;
    w->label = "#" + std::to_string(id);
    w->host = host;
    w->conn = std::move(conn);
    w->nonce = proto::random_nonce();
    w->last_heard = Clock::now();
    w->auth_timer = std::make_unique<asio::steady_timer>(io_, std::chrono::milliseconds(options_.auth_timeout_ms));
    w->auth_timer->async_wait([this, id](const asio::error_code& ec) {
      if (ec) return;
      Worker* worker = find(id);
      if (worker && worker->state != Worker::State::Ready && worker->state != Worker::State::Scene &&
          worker->state != Worker::State::Closed) {
        // Timeout, not AuthFailed: a slow peer (a long round trip, a stalled machine) may try
        // again, where a wrong token makes the worker stop.
        reject(*worker, proto::ErrorCode::Timeout,
               "did not authenticate within " + std::to_string(options_.auth_timeout_ms) + " ms");
      }
    });
    Worker& ref = *w;
    workers_.emplace(id, std::move(w));
    spdlog::debug("connection from {} ({})", peer, ref.label);
    // Before authentication only Hello, Auth and Heartbeat make sense: a peer must not make us
    // allocate a 64 MiB tile buffer before it has proven the token.
    ref.conn->set_max_payload(4096);
    ref.conn->set_max_queued_bytes(64u << 20);
    ref.conn->start([this, id](proto::Message&& m, std::size_t wire) { on_message(id, std::move(m), wire); },
                    [this, id](const std::string& reason) { on_close(id, reason); });
    proto::Challenge challenge;
    challenge.nonce = ref.nonce;
    challenge.auth_required = !options_.token.empty();
    challenge.master_build = build_id().substr(0, proto::kMaxName);
    ref.conn->send(challenge);
  }

  Worker* find(TileQueue::WorkerId id) {
    const auto it = workers_.find(id);
    return it == workers_.end() || it->second->state == Worker::State::Closed || it->second->rejected
               ? nullptr
               : it->second.get();
  }

  // ---- messages --------------------------------------------------------------------------

  void on_message(TileQueue::WorkerId id, proto::Message&& message, std::size_t wire) {
    Worker* w = find(id);
    if (!w) return;
    w->last_heard = Clock::now();
    current_type_ = proto::type_name(static_cast<std::uint16_t>(proto::type_of(message)));
    std::visit([&](auto&& m) { handle(*w, std::move(m), wire); }, std::move(message));
  }

  void handle(Worker& w, proto::Hello&& m, std::size_t) {
    if (w.state != Worker::State::AwaitHello) return unexpected(w, "Hello");
    w.hello = std::move(m);
    w.said_hello = true;
    // What the peer says of itself is logged: no control character of it reaches the log.
    w.hello.name = printable(w.hello.name);
    w.hello.isa = printable(w.hello.isa);
    w.hello.build_id = printable(w.hello.build_id);
    // A worker's claim sizes its share of the queue: keep a hostile one from hoarding every tile.
    w.threads = std::clamp<std::uint32_t>(w.hello.threads, 1, 256);
    w.state = Worker::State::AwaitAuth;
  }

  void handle(Worker& w, proto::Auth&& m, std::size_t) {
    if (w.state != Worker::State::AwaitAuth) return unexpected(w, "Auth");
    if (!options_.token.empty() && !proto::equal_constant_time(m.proof, proto::auth_proof(options_.token, w.nonce))) {
      return reject(w, proto::ErrorCode::AuthFailed, "authentication failed (wrong or missing token)");
    }
    w.auth_timer->cancel();
    w.conn->set_max_payload(proto::kMaxPayload);
    w.max_outstanding = options_.tiles_per_worker > 0 ? static_cast<std::size_t>(options_.tiles_per_worker)
                                                      : std::max<std::size_t>(2, 2 * w.threads + 2);
    const std::uint32_t number = ++last_worker_number_;
    w.label = "w" + std::to_string(number);
    if (w.hello.build_id != build_id()) {
      spdlog::warn("{}: build \"{}\" differs from the master's \"{}\": its pixels may differ", w.describe(),
                   w.hello.build_id, build_id());
    }
    proto::Welcome welcome;
    welcome.worker_id = number;
    welcome.heartbeat_ms = static_cast<std::uint32_t>(options_.heartbeat_ms);
    welcome.max_outstanding = static_cast<std::uint32_t>(w.max_outstanding);
    w.conn->send(welcome);
    proto::SceneOffer offer;
    offer.hash = scene_hash_;
    offer.size = scene_bytes_.size();
    offer.name = scene_name_.substr(0, proto::kMaxName);
    w.conn->send(offer);
    w.state = Worker::State::Scene;
  }

  void handle(Worker& w, proto::SceneRequest&& m, std::size_t) {
    if (w.state != Worker::State::Scene || m.hash != scene_hash_) return unexpected(w, "SceneRequest");
    if (m.have) {
      spdlog::debug("{} has the scene already", w.describe());
      return;
    }
    const TileQueue::WorkerId id = w.id;
    w.scene_offset = 0;
    w.conn->set_drained_handler([this, id] {
      if (Worker* worker = find(id)) send_scene_chunks(*worker);
    });
    send_scene_chunks(w);
  }

  // Keeps at most a few chunks queued: a slow link holds the scene here, not in the socket queue.
  void send_scene_chunks(Worker& w) {
    while (w.scene_offset < scene_bytes_.size() && w.conn->queued_bytes() < 4 * proto::kMaxSceneChunk) {
      proto::SceneChunk chunk;
      chunk.hash = scene_hash_;
      chunk.offset = w.scene_offset;
      const std::size_t n = std::min<std::size_t>(proto::kMaxSceneChunk, scene_bytes_.size() - w.scene_offset);
      chunk.bytes.assign(scene_bytes_.begin() + static_cast<std::ptrdiff_t>(w.scene_offset),
                         scene_bytes_.begin() + static_cast<std::ptrdiff_t>(w.scene_offset + n));
      w.scene_offset += n;
      w.conn->send(chunk);
    }
    if (w.scene_offset >= scene_bytes_.size()) w.conn->set_drained_handler(nullptr);
  }

  void handle(Worker& w, proto::SceneReady&& m, std::size_t) {
    if (w.state != Worker::State::Scene || m.hash != scene_hash_) return unexpected(w, "SceneReady");
    w.state = Worker::State::Ready;
    if (tracker_) {
      const MarkGrid& g = tracker_->grid();
      proto::MarkGrid grid;
      for (int k = 0; k < 3; ++k) {
        grid.lo[k] = g.lo[k];
        grid.hi[k] = g.hi[k];
        grid.dims[k] = static_cast<std::uint32_t>(g.dims[k]);
      }
      w.conn->send(grid);
    }
    spdlog::info("worker {} joined: {} cores, build {}; scene ready in {} ms; {} tiles outstanding at most",
                 w.describe(), w.hello.cores, w.hello.build_id, m.load_ms, w.max_outstanding);
    if (link_bytes_per_s_ <= 0 && !probe_running_) {
      proto::ProbeRequest probe;
      probe.bytes = options_.probe_bytes;
      w.probing = true;
      w.conn->prepare_payload_buffer(options_.probe_bytes + 64);  // its size prefix and more
      w.probe_sent = Clock::now();
      probe_running_ = true;
      w.conn->send(probe);
      // Tiles wait while the probe runs, but not for long: after 5 s the run goes on (a slow
      // link); the probe still counts when it arrives.
      probe_timer_ = std::make_unique<asio::steady_timer>(io_, std::chrono::seconds(5));
      probe_timer_->async_wait([this](const asio::error_code& ec) {
        if (ec || !probe_running_) return;
        spdlog::warn("link probe not finished after 5 s: rendering meanwhile (give --link-mbps on slow links)");
        end_probe();
        dispatch();
      });
    }
    announce_open_frames(w);  // none while the probe runs: end_probe() does
    maybe_start();
    dispatch();
  }

  void handle(Worker& w, proto::ProbeData&& m, std::size_t wire) {
    if (!w.probing) return unexpected(w, "ProbeData");
    w.probing = false;
    end_probe();
    // Timed from the arrival of the probe's header to that of its last byte: the request's round
    // trip, the worker's preparation and the master's decoding (a CRC and a copy of 4 MiB into
    // fresh memory: 14 ms on a VM, where the bytes took 8) are left out, TCP's ramp-up is not
    // (it is part of the link).
    const Clock::time_point now = Clock::now();
    const double seconds =
        std::max(1e-6, std::chrono::duration<double>(w.conn->bytes_arrived() - w.conn->header_arrived()).count());
    link_bytes_per_s_ = static_cast<double>(wire - proto::kHeaderSize) / seconds;
    link_source_ = "measured";
    spdlog::info("link measured on {}: {:.1f} Mbit/s ({:.1f} MiB in {:.1f} ms; {:.1f} ms after the request); the link "
                 "bound uses it",
                 w.describe(), link_bytes_per_s_ * 8 / 1e6, m.bytes.size() / 1048576.0, seconds * 1000,
                 ms_between(w.probe_sent, now));
    dispatch();
  }

  // Tiles a later frame left waiting on a trace that just reported: trace them for that frame,
  // or give them the pixels just traced (already in the canvas).
  void decide_waiting(const std::vector<TemporalDecision>& decisions) {
    for (const TemporalDecision& d : decisions) {
      const auto sit = plan_sequence_.find(d.plan);
      if (sit == plan_sequence_.end()) continue;
      const auto fit = frames_.find(sit->second);
      if (fit == frames_.end()) continue;
      OpenFrame& f = fit->second;
      if (d.trace) {
        queue_.release(static_cast<int>(f.sequence), d.tile);
        ++f.stats.tiles_traced;
      } else {
        const TileRect& t = queue_.rect(d.tile);
        copy_rect(canvas_, pixels_of(f), static_cast<int>(t.x), static_cast<int>(t.y), static_cast<int>(t.width),
                  static_cast<int>(t.height));
        queue_.keep(static_cast<int>(f.sequence), d.tile);
      }
    }
  }

  void handle(Worker& w, proto::TileMarks&& m, std::size_t wire) {
    if (w.state != Worker::State::Ready || !tracker_) return unexpected(w, "TileMarks");
    if (!queue_.holds(w.id, static_cast<int>(m.sequence), m.tile)) {
      return reject(w, proto::ErrorCode::Protocol,
                    "sent marks for tile " + std::to_string(m.tile) + " of frame sequence " + std::to_string(m.sequence) +
                        " that it was not given");
    }
    const std::uint32_t voxels = tracker_->grid().voxel_count();
    if ((!m.path.empty() && m.path.back() >= voxels) || (!m.shadow.empty() && m.shadow.back() >= voxels)) {
      return reject(w, proto::ErrorCode::Protocol,
                    "sent marks for tile " + std::to_string(m.tile) + " outside the " + std::to_string(voxels) +
                        "-voxel mark grid");
    }
    const auto key = std::make_pair(m.sequence, m.tile);
    w.pending_marks[key] = {std::move(m), wire};
  }

  /// How a result differs from its tile's assignment (rectangle, scene frame, pixel format),
  /// each field with the value sent and the one assigned; empty when it matches. `frame` is the
  /// open frame of its sequence, null once that frame is finished.
  std::string result_mismatch(const proto::TileResult& r, const OpenFrame* frame) const {
    const TileRect& rect = queue_.rect(r.tile);
    std::string out;
    const auto differs = [&out](const std::string& what, const auto& sent, const auto& assigned) {
      out += fmt::format("{}{} {} (assigned {})", out.empty() ? "" : ", ", what, sent, assigned);
    };
    if (r.x != rect.x || r.y != rect.y || r.width != rect.width || r.height != rect.height) {
      differs("rectangle", fmt::format("{}x{} at ({}, {})", r.width, r.height, r.x, r.y),
              fmt::format("{}x{} at ({}, {})", rect.width, rect.height, rect.x, rect.y));
    }
    if (frame != nullptr && r.frame != frame->frame) differs("scene frame", r.frame, frame->frame);
    if (r.wire_format != static_cast<std::uint8_t>(options_.wire)) {
      differs("wire format", static_cast<int>(r.wire_format), wire_format_name(options_.wire));
    }
    if (r.compression != static_cast<std::uint8_t>(options_.compression)) {
      differs("compression", static_cast<int>(r.compression), compression_name(options_.compression));
    }
    if (r.channels != options_.channels) differs("channels", static_cast<int>(r.channels), static_cast<int>(options_.channels));
    return out;
  }

  void handle(Worker& w, proto::TileResult&& r, std::size_t wire) {
    if (w.state != Worker::State::Ready) return unexpected(w, "TileResult");
    if (!queue_.holds(w.id, static_cast<int>(r.sequence), r.tile)) {
      return reject(w, proto::ErrorCode::Protocol,
                    "sent a result for tile " + std::to_string(r.tile) + " of frame sequence " +
                        std::to_string(r.sequence) + " that it does not hold (never given, or already returned)");
    }
    const auto fit = frames_.find(r.sequence);
    if (const std::string mismatch = result_mismatch(r, fit == frames_.end() ? nullptr : &fit->second);
        !mismatch.empty()) {
      return reject(w, proto::ErrorCode::Protocol,
                    "tile " + std::to_string(r.tile) + " of frame sequence " + std::to_string(r.sequence) +
                        ": the result does not match its assignment: " + mismatch);
    }
    const auto key = std::make_pair(r.sequence, r.tile);
    w.waiting_since = Clock::now();
    if (w.stall_noted) {
      w.stall_noted = false;
      spdlog::info("worker {} returns tiles again", w.describe());
    }
    const auto sent = w.assigned_at.find(key);
    if (sent != w.assigned_at.end()) {
      const double ms = ms_between(sent->second, Clock::now());
      tile_latency_ms_ = tile_latency_ms_ <= 0 ? ms : 0.9 * tile_latency_ms_ + 0.1 * ms;
      w.assigned_at.erase(sent);
    }
    // A tile another worker finished meanwhile is checked all the same (into scratch that no
    // frame reads): a worker that sends bad pixels is dropped whether or not it was first.
    const std::string error = decode_tile_pixels(r.pixels, r.raw_size, static_cast<int>(r.width),
                                                 static_cast<int>(r.height), options_.wire, options_.compression,
                                                 r.channels, tile_);
    if (!error.empty()) return reject(w, proto::ErrorCode::Protocol, "bad pixels in tile " + std::to_string(r.tile) + ": " + error);
    const TileOutcome outcome = queue_.complete(w.id, static_cast<int>(r.sequence), r.tile);
    std::optional<std::pair<proto::TileMarks, std::size_t>> marks;
    if (const auto mit = w.pending_marks.find(key); mit != w.pending_marks.end()) {
      marks = std::move(mit->second);
      w.pending_marks.erase(mit);
    }
    if (outcome == TileOutcome::Accepted) {
      worker_failures_in_a_row_ = 0;
      failed_workers_.clear();
      OpenFrame& f = fit->second;
      pixels_of(f).blit(tile_, static_cast<int>(r.x), static_cast<int>(r.y));
      FrameStats& s = f.stats;
      if (tracker_) {
        TileMarks tm;
        if (marks) {
          tm.shaded = marks->first.shaded;
          tm.path = std::move(marks->first.path);
          tm.shadow = std::move(marks->first.shadow);
          s.wire_bytes += marks->second;
          s.mark_bytes += marks->second;
        }
        canvas_.blit(tile_, static_cast<int>(r.x), static_cast<int>(r.y));
        // No marks (a worker that sent none): the tile is traced again next time.
        decide_waiting(tracker_->done(r.tile, f.plan, marks ? &tm : nullptr));
      }
      s.wire_bytes += wire;
      s.pixel_bytes += r.pixels.size();
      s.raw_bytes += r.raw_size;
      s.render_ms += r.render_us / 1000.0;
      s.primary_rays += r.primary_rays;
      s.shadow_rays += r.shadow_rays;
      s.reflection_rays += r.reflection_rays;
      ++s.tiles_by_worker[w.label];
      ++w.tiles_accepted;
    } else if (fit != frames_.end()) {
      ++fit->second.stats.duplicate_tiles;
      fit->second.stats.duplicate_bytes += wire;
    }
    finish_frames();
    dispatch();
  }

  void handle(Worker& w, proto::Heartbeat&& m, std::size_t) {
    if (w.state != Worker::State::Ready && w.state != Worker::State::Scene) return unexpected(w, "Heartbeat");
    proto::HeartbeatAck ack;
    ack.seq = m.seq;
    ack.sent_us = m.sent_us;
    w.conn->send(ack);
  }
  void handle(Worker&, proto::HeartbeatAck&&, std::size_t) {}

  void handle(Worker& w, proto::ErrorMessage&& m, std::size_t) {
    m.text = printable(m.text);
    spdlog::error("{} reports an error (code {}): {}", w.describe(), static_cast<int>(m.code), m.text);
    const Worker::State state = w.state;  // closing sets it to Closed
    w.conn->close("it reported an error: " + m.text);
    // A worker that fails to render or to decode the scene comes back and is handed the same
    // work: an error every worker hits (a frame's camera a worker refuses, a scene too big for
    // them) would otherwise cycle until someone kills the master. Only a worker's own failure
    // counts: one that has authenticated and reports a render error (Internal) or a scene it
    // could not decode (SceneInvalid). The run ends once such errors have come
    // kWorkerFailuresToGiveUp times with no tile finished in between and no ready worker is left
    // that has not failed meanwhile: one broken machine among good ones, which may still be
    // building their trees, does not end it.
    const bool own_failure = (m.code == proto::ErrorCode::Internal && state == Worker::State::Ready) ||
                             (m.code == proto::ErrorCode::SceneInvalid &&
                              (state == Worker::State::Scene || state == Worker::State::Ready));
    if (!own_failure) return;
    ++worker_failures_in_a_row_;
    failed_workers_.insert(worker_identity(w));
    if (worker_failures_in_a_row_ < kWorkerFailuresToGiveUp) return;
    for (const auto& [id, other] : workers_) {
      if (other->rejected || other->state != Worker::State::Ready || !other->conn->is_open()) continue;
      if (failed_workers_.count(worker_identity(*other)) == 0) return;  // a worker that has not failed yet
    }
    fatal(std::to_string(worker_failures_in_a_row_) + " worker errors in a row from " +
          std::to_string(failed_workers_.size()) + (failed_workers_.size() == 1 ? " worker" : " workers") +
          ", no tile finished in between and no other worker ready; the last, from " + w.describe() + ": " + m.text);
  }

  /// A worker across its reconnections: its host and the name it gives.
  static std::string worker_identity(const Worker& w) { return w.host + "/" + w.hello.name; }

  void handle(Worker& w, proto::Goodbye&& m, std::size_t) {
    w.conn->close("it said goodbye: " + printable(m.reason));
  }

  template <class M>
  void handle(Worker& w, M&&, std::size_t) {
    unexpected(w, current_type_);
  }

  void unexpected(Worker& w, const std::string& type) {
    reject(w, proto::ErrorCode::Protocol, "sent an unexpected " + type + " message");
  }

  // Tells the peer why (if it is still listening), logs with its address, and closes it.
  void reject(Worker& w, proto::ErrorCode code, const std::string& why) {
    spdlog::warn("worker {}: {}; closing the connection", w.describe(), why);
    // Nothing more from or to it counts; its tiles go back now, not when the socket closes.
    w.rejected = true;
    queue_.worker_lost(w.id);
    proto::ErrorMessage error;
    error.code = code;
    error.text = why.substr(0, proto::kMaxText);
    w.conn->send(error);
    w.conn->close_after_flush(why);
  }

  void on_close(TileQueue::WorkerId id, const std::string& reason) {
    const auto it = workers_.find(id);
    if (it == workers_.end()) return;
    Worker& w = *it->second;
    const Worker::State was = w.state;
    w.state = Worker::State::Closed;
    if (w.auth_timer) w.auth_timer->cancel();
    if (w.probing) end_probe();
    const std::size_t requeued = queue_.worker_lost(id);
    if (was == Worker::State::Ready || was == Worker::State::Scene) {
      if (done_) {
        spdlog::debug("worker {} closed: {}", w.describe(), reason);
      } else {
        // Leaving with tiles unfinished (killed, lost) is worth a warning, and so is a bad message;
        // an idle one's goodbye is not.
        spdlog::log(requeued > 0 || w.conn->rejected_peer() ? spdlog::level::warn : spdlog::level::info, "worker {} left: {}; {} tiles back in the queue",
                    w.describe(), reason, requeued);
      }
    } else if (std::string note; !done_ && connection_log_.allow(w.host, Clock::now(), note)) {
      spdlog::warn("connection from {} closed before it authenticated: {}{}", w.conn->peer(), reason, note);
    }
    // Erase later: we may be inside one of this worker's handlers.
    asio::post(io_, [this, id] {
      workers_.erase(id);
      if (done_ && workers_.empty()) io_.stop();
      if (!done_) dispatch();
    });
  }

  // ---- scheduling -------------------------------------------------------------------------

  std::size_t ready_workers() const {
    std::size_t n = 0;
    for (const auto& [id, w] : workers_) n += w->state == Worker::State::Ready ? 1 : 0;
    return n;
  }

  /// Whether nothing renders for want of workers: before the run, fewer ready than
  /// --min-workers; after its start, none ready with frames open.
  [[nodiscard]] bool short_of_workers() const {
    const std::size_t ready = ready_workers();
    return run_started_ ? ready == 0 && queue_.frames_open() > 0
                        : ready < static_cast<std::size_t>(options_.min_workers);
  }

  /// Every 5 s while short_of_workers() (some may be ready already): how many are ready and how
  /// many are taking the scene.
  void log_waiting(Clock::time_point now) {
    const std::size_t ready = ready_workers();
    const auto needed = static_cast<std::size_t>(options_.min_workers);
    if (!short_of_workers() || ms_between(last_wait_log_, now) < 5000) return;
    last_wait_log_ = now;
    std::size_t loading = 0;
    for (const auto& [id, w] : workers_) loading += w->state == Worker::State::Scene ? 1 : 0;
    const std::string loading_text = loading == 0 ? "" : fmt::format(", {} taking the scene", loading);
    if (run_started_) {
      spdlog::info("waiting for workers on {}: none ready{}; {} tiles waiting", listening_on_, loading_text,
                   queue_.waiting());
    } else {
      spdlog::info("waiting for workers on {}: {} of the {} needed to start ready{}", listening_on_, ready, needed,
                   loading_text);
    }
  }

  /// --wait-seconds: ends the run (exit 1) once the master has been short of workers
  /// (short_of_workers) that long without a break; true when it did. The frames finished before
  /// are written; those in flight are abandoned. Not while a signal's drain runs (that has its
  /// own limit, --drain-seconds).
  bool give_up_waiting(Clock::time_point now) {
    if (!short_of_workers() || stopping_ || done_) {
      short_since_.reset();
      return false;
    }
    if (!short_since_) short_since_ = now;
    if (options_.wait_seconds <= 0 || ms_between(*short_since_, now) < options_.wait_seconds * 1000.0) return false;
    const std::string waited = fmt::format("{:g} s (--wait-seconds)", options_.wait_seconds);
    if (run_started_) {
      const int sequence = queue_.open_frames().front();
      const auto it = frames_.find(static_cast<std::uint32_t>(sequence));
      const std::string frame = it == frames_.end() ? "" : fmt::format("frame {} [seq {}] open, ", it->second.frame, sequence);
      fatal(fmt::format("no worker ready for {} with {}{} waiting: giving up", waited, frame,
                        counted(queue_.waiting(), "tile", "tiles")));
    } else {
      // Those still taking the scene, and how far: a --wait-seconds too short for the scene's
      // transfer and load shows here.
      const std::size_t total = scene_bytes_.size();
      const bool mb = total >= 100'000;  // small scenes in bytes, not "0.0 MB"
      const auto amount = [mb](std::uint64_t n) {
        return mb ? fmt::format("{:.1f}", static_cast<double>(n) / 1e6) : std::to_string(n);
      };
      const char* unit = mb ? "MB" : "bytes";
      std::string loading;
      for (const auto& [id, w] : workers_) {
        if (w->state != Worker::State::Scene) continue;
        const std::string how = w->scene_offset >= total
                                    ? fmt::format("all {} {} sent, loading", amount(total), unit)
                                    : fmt::format("{} of {} {} sent", amount(w->scene_offset), amount(total), unit);
        loading += fmt::format("{} {}: {}", loading.empty() ? "; still taking the scene:" : ";", w->describe(), how);
      }
      fatal(fmt::format("{} of the {} needed ready after {}: giving up before the first frame{}", ready_workers(),
                        counted(options_.min_workers, "worker", "workers"), waited, loading));
    }
    return true;
  }

  /// A long frame says how far it is every 10 s (after the last frame line or progress line):
  /// the oldest open frame's tiles done, and the time since it opened.
  void log_frame_progress(Clock::time_point now) {
    if (!run_started_ || queue_.frames_open() == 0 || ms_between(last_progress_log_, now) < 10000) return;
    last_progress_log_ = now;
    const int sequence = queue_.open_frames().front();
    const auto it = frames_.find(static_cast<std::uint32_t>(sequence));
    if (it == frames_.end()) return;
    const std::uint32_t done = queue_.tiles_done(sequence);
    const std::uint32_t total = queue_.tiles_per_frame();
    spdlog::info("frame {} [seq {}]: {} of {} tiles done ({:.0f}%) after {:.0f} s; {} ready", it->second.frame, sequence,
                 done, total, 100.0 * done / total, ms_between(it->second.started_at, now) / 1e3,
                 counted(ready_workers(), "worker", "workers"));
  }

  void maybe_start() {
    if (run_started_ || ready_workers() < static_cast<std::size_t>(options_.min_workers)) return;
    run_started_ = true;
    run_start_ = Clock::now();
    short_since_.reset();  // --wait-seconds: the wait before the run is over
    io_cpu_at_start_ = cpu_seconds(CLOCK_THREAD_CPUTIME_ID);
    process_cpu_at_start_ = cpu_seconds(CLOCK_PROCESS_CPUTIME_ID);
    last_complete_ = run_start_;
    last_progress_log_ = run_start_;
    const std::string frames = options_.first_frame == options_.last_frame
                                   ? "frame " + std::to_string(options_.first_frame)
                                   : "frames " + std::to_string(options_.first_frame) + "-" + std::to_string(options_.last_frame);
    spdlog::info("{} ready: rendering {}{}", counted(ready_workers(), "worker", "workers"), frames,
                 options_.loop_seconds > 0 ? " in a loop for " + std::to_string(options_.loop_seconds) + " s" : "");
  }

  // The frame's image, taken from the pool at its first use (OpenFrame::image). Every pixel is
  // written before the frame is: each tile is traced or kept.
  Image& pixels_of(OpenFrame& f) {
    if (!f.has_image) {
      f.image = frame_pool_.take_for_overwrite(width_, height_, (options_.channels & kChannelDepth) != 0,
                                               (options_.channels & kChannelNormal) != 0);
      f.has_image = true;
    }
    return f.image;
  }

  // A new frame can be opened right now (not only "more frames will come").
  bool can_open_frame() const { return frame_slot_free() && !writer_full(); }
  // Every condition but the frame writer's room.
  bool frame_slot_free() const {
    return run_started_ && queue_.frames_open() < static_cast<std::size_t>(options_.frames_in_flight) && more_frames();
  }
  bool writer_full() const { return writer_ && writer_->pending() >= FrameWriter::kMaxPending; }

  bool more_frames() const {
    if (stopping_ || done_) return false;
    if (options_.loop_seconds > 0) {
      return !run_started_ || std::chrono::duration<double>(Clock::now() - run_start_).count() < options_.loop_seconds;
    }
    return next_frame_ <= options_.last_frame;
  }

  /// Times how long the frame writer keeps frames from opening (all kMaxPending of its places
  /// taken while a frame could otherwise open), for the summary.
  void note_writer_hold(Clock::time_point now, bool held) {
    if (held && !writer_held_since_) writer_held_since_ = now;
    if (!held && writer_held_since_) {
      writer_held_s_ += ms_between(*writer_held_since_, now) / 1e3;
      writer_held_since_.reset();
    }
  }

  void open_frames() {
    while (can_open_frame()) {
      OpenFrame f;
      f.sequence = next_sequence_++;
      f.frame = next_frame_;
      f.stats.sequence = f.sequence;
      f.stats.frame = f.frame;
      f.stats.wire_format = std::string(wire_format_name(options_.wire));
      f.stats.compression = std::string(compression_name(options_.compression));
      std::uint32_t traced = queue_.tiles_per_frame();
      if (tracker_) {
        // Temporal coherence: only the dirty tiles are handed out; the others keep the pixels
        // of their last trace, which are final (a tile still out is always dirty).
        const TemporalPlan plan = tracker_->plan(f.frame);
        f.plan = plan.id;
        traced = plan.dirty_count;
        f.stats.temporal = true;
        f.stats.tiles_traced = plan.dirty_count;
        f.stats.tiles_total = queue_.tiles_per_frame();
        f.stats.temporal_why = plan.why;
        f.stats.full_render_ms = full_render_ms_;
        f.stats.full_wire_bytes = full_wire_bytes_;
        for (const TileRect& t : queue_.tiles()) {
          if (plan.dirty[t.index] == TemporalPlan::kKeep) {
            copy_rect(canvas_, pixels_of(f), static_cast<int>(t.x), static_cast<int>(t.y),
                      static_cast<int>(t.width), static_cast<int>(t.height));
          }
        }
        queue_.open_frame(static_cast<int>(f.sequence), &plan.dirty);
        plan_sequence_[plan.id] = f.sequence;
        traced += plan.waiting;  // may be traced: announce the frame
      } else {
        queue_.open_frame(static_cast<int>(f.sequence));
      }
      // The frame's clock starts with its first tile handed out (assign()); a frame that ends
      // without one (nothing to trace, or its waiting tiles all kept) counts from its opening.
      // Before 2026-11-23 such a frame with waiting tiles logged the time since the clock's
      // epoch (71767457.6 ms in a temporal run).
      f.started_at = Clock::now();
      if (traced == 0) f.started = true;
      f.to_trace = traced > 0;
      frames_.emplace(f.sequence, std::move(f));
      announce_to_ready_workers();
      next_frame_ = next_frame_ >= options_.last_frame ? options_.first_frame : next_frame_ + 1;
      if (options_.loop_seconds <= 0 && next_frame_ == options_.first_frame) next_frame_ = options_.last_frame + 1;
    }
    if (writer_) note_writer_hold(Clock::now(), frame_slot_free() && writer_full());
  }

  void dispatch() {
    if (done_) return;
    open_frames();
    // A frame with nothing to trace (temporal coherence) is done as it opens.
    for (int guard = 0; guard < 1024 && queue_.oldest_done(); ++guard) {
      finish_frames();
      if (done_) return;
      open_frames();
    }
    // While the link probe runs nobody else sends: tiles on the same link would make the
    // capacity look smaller than it is (measured: 75 instead of 95 Mbit/s on a 100 Mbit link).
    if (probe_running_) return;
    const Clock::time_point now = Clock::now();
    // The tail: nothing waits and no frame can be opened, so idle cores may take a copy of a
    // straggler's tile (also mid-run: a frame stuck on one tile holds up the frames behind it).
    const bool tail = queue_.waiting() == 0 && !can_open_frame();
    // A tile is a straggler's when it has been out for 3 times the usual round trip (20 ms at least).
    const auto reissue_before = now - std::chrono::microseconds(static_cast<std::int64_t>(
                                          1000 * std::max(20.0, 3 * tile_latency_ms_)));
    for (auto& [id, wp] : workers_) {
      Worker& w = *wp;
      if (w.state != Worker::State::Ready || w.probing || w.rejected) continue;
      while (queue_.outstanding(w.id) < w.max_outstanding) {
        std::optional<TileAssignment> a = queue_.next_for(w.id, now);
        if (!a && tail && queue_.outstanding(w.id) < w.threads) a = queue_.reissue_for(w.id, reissue_before);
        if (!a) break;
        assign(w, *a, now);
        if (!w.conn->is_open() || w.state != Worker::State::Ready || w.rejected) {
          queue_.worker_lost(w.id);  // sending closed it (not reading): the tile goes back
          break;
        }
      }
    }
  }

  // FrameSettings once per worker and frame: when the frame opens (the worker builds its
  // kd-tree while it still traces the frame before), at the latest with its first tile.
  //
  // Not while the link probe runs: a kd-tree build on every core of the probing worker (or of
  // any worker on the same machine, as with launch-local.sh) slowed the probe's 4 MiB from 8 to
  // 50 ms on loopback, and the link bound with it. Tiles wait for the probe anyway.
  void announce(Worker& w, const OpenFrame& f) {
    if (probe_running_) return;
    if (!w.announced.insert(f.sequence).second) return;
    proto::FrameSettings settings;
    settings.sequence = f.sequence;
    settings.frame = f.frame;
    settings.wire_format = static_cast<std::uint8_t>(options_.wire);
    settings.compression = static_cast<std::uint8_t>(options_.compression);
    settings.channels = options_.channels;
    w.conn->send(settings);
  }

  void announce_open_frames(Worker& w) {
    for (const auto& [sequence, f] : frames_) {
      if (f.to_trace) announce(w, f);
    }
  }

  /// The link probe is over (its data came, its 5 s ran out, or its worker left): the frames
  /// held back from every worker meanwhile are announced, and their kd-tree builds begin.
  void end_probe() {
    probe_running_ = false;
    if (probe_timer_) probe_timer_->cancel();
    announce_to_ready_workers();
  }

  /// Every open frame with tiles to trace, to every ready worker not yet told of it.
  void announce_to_ready_workers() {
    for (auto& [id, w] : workers_) {
      if (w->state == Worker::State::Ready && !w->rejected) announce_open_frames(*w);
    }
  }

  void assign(Worker& w, const TileAssignment& a, Clock::time_point now) {
    const auto sequence = static_cast<std::uint32_t>(a.frame);
    OpenFrame& f = frames_.at(sequence);
    if (!f.started) {
      f.started = true;
      f.started_at = now;
    }
    if (a.reissue) ++f.stats.reissued_tiles;
    if (queue_.outstanding(w.id) <= 1) w.waiting_since = now;  // this tile is its only one: it was idle
    announce(w, f);
    proto::TileAssign t;
    t.sequence = sequence;
    t.frame = f.frame;
    t.tile = a.rect.index;
    t.x = a.rect.x;
    t.y = a.rect.y;
    t.width = a.rect.width;
    t.height = a.rect.height;
    w.assigned_at[{sequence, a.rect.index}] = now;
    w.conn->send(t);
  }

  void finish_frames() {
    while (const std::optional<int> done = queue_.pop_done_frame()) {
      const auto sequence = static_cast<std::uint32_t>(*done);
      auto node = frames_.extract(sequence);
      OpenFrame& f = node.mapped();
      plan_sequence_.erase(f.plan);
      const Clock::time_point now = Clock::now();
      f.stats.wall_ms = ms_between(f.started_at, now);
      // The first frame's interval is its own wall time (frame_stats.h): from the run's start it
      // would also hold the link probe and the other workers' start.
      f.stats.interval_ms = finished_.frames() == 0 ? f.stats.wall_ms : ms_between(last_complete_, now);
      last_complete_ = now;
      last_progress_log_ = now;
      f.stats.link_bytes_per_s = link_bytes_per_s_;
      f.stats.link_line_mbit_per_s = link_source_ == "given" ? options_.link_mbps : 0.0;
      f.stats.link_source = link_bytes_per_s_ > 0 ? link_source_ : "unknown";
      if (f.stats.temporal && f.stats.tiles_traced == f.stats.tiles_total) {
        full_render_ms_ = f.stats.render_ms;
        full_wire_bytes_ = f.stats.wire_bytes;
      } else if (f.stats.temporal && f.stats.full_render_ms <= 0) {
        // Planned while the first frame was still out (frames in flight): frames finish in
        // order, so the whole one it is compared with is known now.
        f.stats.full_render_ms = full_render_ms_;
        f.stats.full_wire_bytes = full_wire_bytes_;
      }
      for (auto& [id, w] : workers_) {
        if (w->state != Worker::State::Closed && w->announced.erase(sequence)) {
          proto::FrameEnd end;
          end.sequence = sequence;
          w->conn->send(end);
        }
      }
      if (writer_) {
        // With --loop the same scene frame comes round again: number files by sequence then.
        const int number = options_.loop_seconds > 0 ? static_cast<int>(sequence) : f.frame;
        f.stats.written = expand_frame_pattern(options_.out_pattern, number, options_.multiple_frames);
        writer_->submit(f.stats.written, std::move(pixels_of(f)));
      } else {
        frame_pool_.give(std::move(pixels_of(f)));
      }
      finished_.add(f.stats);
      spdlog::info("{}{}", format_frame_line(f.stats), progress_text(now));
      if (stats_file_.is_open()) {
        stats_file_ << frame_json(f.stats) << '\n';
        stats_file_.flush();
        if (!stats_file_) return fatal("--stats-json " + options_.stats_json + ": write failed (disk full?)");
      }
    }
    if (run_started_ && !more_frames() && queue_.frames_open() == 0) {
      shutdown(stopping_ ? "the master was stopped" : "all frames done");
    }
  }

  // ---- timers, signals, shutdown ----------------------------------------------------------

  void schedule_tick() {
    tick_.expires_after(std::chrono::milliseconds(20));
    tick_.async_wait([this](const asio::error_code& ec) {
      if (ec || done_) return;
      on_tick();
      schedule_tick();
    });
  }

  void on_tick() {
    const Clock::time_point now = Clock::now();
    if (ms_between(last_heartbeat_, now) >= options_.heartbeat_ms) {
      last_heartbeat_ = now;
      ++heartbeat_seq_;
      for (auto& [id, w] : workers_) {
        if (w->state == Worker::State::Closed) continue;
        // A big message on its way (a probe, a large tile) counts as hearing from it while its
        // bytes keep coming: its start alone did, and a 4 MiB probe or a 16 MiB tile on a link
        // slower than its size over the timeout was dropped mid-message, and probed again on
        // every reconnection.
        const Clock::time_point heard = std::max(w->last_heard, w->conn->bytes_arrived());
        if (ms_between(heard, now) > options_.heartbeat_timeout_ms) {
          w->conn->close("missed heartbeats: nothing heard for " + std::to_string(options_.heartbeat_timeout_ms) + " ms");
          continue;
        }
        if (w->state == Worker::State::Ready && !w->stall_noted && !w->rejected && queue_.outstanding(w->id) > 0 &&
            now - w->waiting_since > stalled_after()) {
          // Heard from (it answers heartbeats) but returning nothing: render threads stuck, a
          // machine swapping, a peer that hoards. Its tiles go to others once overdue.
          w->stall_noted = true;
          spdlog::warn("worker {} holds {} tiles and has returned none in {:.1f} s (the usual round trip is {:.0f} ms), "
                       "though it answers heartbeats: other workers take its tiles once they are overdue",
                       w->describe(), queue_.outstanding(w->id), std::chrono::duration<double>(now - w->waiting_since).count(),
                       tile_latency_ms_);
        }
        if (w->state == Worker::State::Ready || w->state == Worker::State::Scene) {
          proto::Heartbeat hb;
          hb.seq = heartbeat_seq_;
          hb.sent_us = static_cast<std::uint64_t>(
              std::chrono::duration_cast<std::chrono::microseconds>(now.time_since_epoch()).count());
          w->conn->send(hb);
        }
      }
    }
    log_waiting(now);
    if (give_up_waiting(now)) return;
    log_frame_progress(now);
    // The tail of a frame may need re-issuing although no message arrived.
    if (run_started_) {
      finish_frames();
      dispatch();
    }
  }

  /// How long a worker may hold tiles without returning one before it is named: 10 s, or 10
  /// times the usual round trip of a tile where that is longer.
  [[nodiscard]] std::chrono::milliseconds stalled_after() const {
    return std::chrono::milliseconds(static_cast<std::int64_t>(std::max(10000.0, 10 * tile_latency_ms_)));
  }

  // " | 11 of 24 frames, 0:00:03 left" (from the mean time a frame so far), or for --loop the
  // seconds gone of the loop's; after the frame line, so that the log shows how far a long run is.
  std::string progress_text(Clock::time_point now) const {
    const double elapsed_s = std::chrono::duration<double>(now - run_start_).count();
    if (options_.loop_seconds > 0) return fmt::format(" | {:.0f} of {} s", elapsed_s, options_.loop_seconds);
    const std::uint64_t planned = static_cast<std::uint64_t>(options_.last_frame - options_.first_frame) + 1;
    const std::uint64_t done = finished_.frames();  // this frame included
    if (done >= planned) return fmt::format(" | {} of {} frames", done, planned);
    const auto left_s = static_cast<std::uint64_t>(std::llround(elapsed_s / static_cast<double>(done) *
                                                                  static_cast<double>(planned - done)));
    return fmt::format(" | {} of {} frames, {}:{:02d}:{:02d} left", done, planned, left_s / 3600, left_s / 60 % 60,
                       left_s % 60);
  }

  void on_signal(const asio::error_code& ec, int signal) {
    if (ec || done_) return;
    const std::string name = signal_name(signal);
    if (stop_signal_ == 0) {
      stop_signal_ = signal;
      // --loop: frames would still have come (a --frames run compares the frames finished with
      // those asked for at the end).
      signal_left_frames_ = more_frames();
    }
    if (stopping_ || queue_.frames_open() == 0) {
      if (queue_.frames_open() > 0) spdlog::warn("{} again: abandoning the frames in flight", name);
      abandon_open_frames();
      shutdown(std::string("stopped by ") + name);
      return;
    }
    stopping_ = true;
    stop_reason_ = std::string("stopped by ") + name;
    spdlog::info("{}: taking no new frames; finishing {} in flight (up to {} s; signal again to abandon them)", name,
                 queue_.frames_open(), options_.drain_seconds);
    signals_.async_wait([this](const asio::error_code& e, int s) { on_signal(e, s); });
    drain_timer_ = std::make_unique<asio::steady_timer>(io_, std::chrono::seconds(options_.drain_seconds));
    drain_timer_->async_wait([this](const asio::error_code& e) {
      if (e || done_) return;
      spdlog::warn("frames still in flight after {} s: abandoning them", options_.drain_seconds);
      abandon_open_frames();
      shutdown("drain time over");
    });
  }

  /// After shutdown begins (all frames done, the drain over, a second signal): the goodbyes and
  /// the last frames' writes still run. A signal then is noted and they finish; a further one
  /// ends the process the usual way (the default action, restored here).
  void arm_late_signal() {
    signals_.async_wait([this](const asio::error_code& e, int s) {
      if (e) return;
      spdlog::warn("{}: finishing the goodbyes and the last frames' writes; signal again to stop at once", signal_name(s));
      asio::error_code ec;
      signals_.clear(ec);
    });
  }

  /// Whether a signal ended the run before all it was asked for: frames of a --frames range not
  /// rendered, or a --loop stopped before its time or with frames abandoned.
  [[nodiscard]] bool cut_short() const {
    if (stop_signal_ == 0) return false;
    if (options_.loop_seconds <= 0) {
      return finished_.frames() < static_cast<std::uint64_t>(options_.last_frame - options_.first_frame) + 1;
    }
    return signal_left_frames_ || frames_abandoned_;
  }

  void abandon_open_frames() {
    frames_abandoned_ = frames_abandoned_ || !queue_.open_frames().empty();
    for (const int sequence : queue_.open_frames()) {
      const auto it = frames_.find(static_cast<std::uint32_t>(sequence));
      if (it != frames_.end()) {
        spdlog::warn("frame {} [seq {}] abandoned unfinished: not written", it->second.frame, sequence);
        frames_.erase(it);
      }
      queue_.drop_frame(sequence);
    }
  }

  void fatal(const std::string& error) {
    if (fatal_error_.empty()) fatal_error_ = error;
    spdlog::error("{}", error);
    abandon_open_frames();
    shutdown("the master failed: " + error);
  }

  void shutdown(const std::string& reason) {
    if (done_) return;
    done_ = true;
    if (stop_reason_.empty() && reason != "all frames done") stop_reason_ = reason;
    note_writer_hold(Clock::now(), false);  // no frame opens from here: the final writes are no hold
    spdlog::info("shutting down: {}", reason);
    asio::error_code ec;
    acceptor_.close(ec);
    remove_ready_file();
    signals_.cancel(ec);
    arm_late_signal();
    tick_.cancel();
    if (drain_timer_) drain_timer_->cancel();
    if (probe_timer_) probe_timer_->cancel();
    for (auto& [id, w] : workers_) {
      if (w->state == Worker::State::Closed) continue;
      if (w->auth_timer) w->auth_timer->cancel();
      proto::Goodbye bye;
      bye.reason = reason.substr(0, proto::kMaxText);
      w->conn->send(bye);
      w->conn->close_after_flush("goodbye sent");
    }
    if (workers_.empty()) io_.stop();
    stop_timer_ = std::make_unique<asio::steady_timer>(io_, std::chrono::seconds(3));
    stop_timer_->async_wait([this](const asio::error_code& e) {
      if (!e) io_.stop();
    });
  }

  MasterOptions options_;
  int width_, height_;
  TileQueue queue_;
  std::vector<std::uint8_t> scene_bytes_;
  proto::Digest scene_hash_;
  std::string scene_name_;

  static double cpu_seconds(clockid_t clock) {
    timespec ts{};
    ::clock_gettime(clock, &ts);
    return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
  }

  double io_cpu_at_start_ = 0, process_cpu_at_start_ = 0;  // at the first frame's start
  asio::io_context io_;
  std::shared_ptr<asio::ssl::context> tls_;       // --tls-cert/--tls-key given
  std::map<std::string, int> tls_handshakes_;      // per peer address, TLS handshakes under way
  HostLogBudget connection_log_;  // the warnings about connections that never became workers
  asio::ip::tcp::acceptor acceptor_;
  asio::signal_set signals_;
  asio::steady_timer tick_;
  std::unique_ptr<asio::steady_timer> drain_timer_, stop_timer_, probe_timer_;
  std::string listening_on_;

  std::map<TileQueue::WorkerId, std::unique_ptr<Worker>> workers_;
  TileQueue::WorkerId last_worker_id_ = 0;  ///< connections accepted (the workers_ keys)
  std::uint32_t last_worker_number_ = 0;    ///< workers authenticated (their labels, Welcome::worker_id)
  std::map<std::uint32_t, OpenFrame> frames_;
  std::uint32_t next_sequence_ = 0;
  int next_frame_ = 0;
  Image tile_;  // scratch for decoding
  std::unique_ptr<TemporalTracker> tracker_;  // null: temporal coherence off
  Image canvas_;                              // every tile's latest pixels (temporal coherence)
  std::map<std::uint64_t, std::uint32_t> plan_sequence_;  // tracker plan id -> frame sequence
  double full_render_ms_ = 0;                 // the last frame traced whole: workers' time
  std::uint64_t full_wire_bytes_ = 0;         // and its bytes on the wire
  std::string current_type_;  // of the message being handled, for errors
  double tile_latency_ms_ = 0;

  bool run_started_ = false;
  Clock::time_point run_start_, last_complete_, last_heartbeat_, last_wait_log_, last_progress_log_;
  std::optional<Clock::time_point> short_since_;  ///< since when short_of_workers() held (give_up_waiting)
  std::optional<Clock::time_point> writer_held_since_;  // see note_writer_hold
  double writer_held_s_ = 0;
  int stop_signal_ = 0;               ///< the first SIGINT or SIGTERM, 0 if none came
  bool signal_left_frames_ = false;   ///< more frames would have come when it did
  bool frames_abandoned_ = false;     ///< open frames were dropped unfinished
  std::string stop_reason_;  ///< why the run ended before its last frame; empty when it did not
  std::uint64_t heartbeat_seq_ = 0;
  double link_bytes_per_s_ = 0;
  std::string link_source_ = "unknown";
  bool probe_running_ = false;
  bool stopping_ = false;
  bool done_ = false;
  bool ready_file_written_ = false;  // by listen(), to be removed when the master stops listening
  std::string fatal_error_;
  /// Render or scene errors reported by workers since the last tile accepted, and which workers
  /// (worker_identity) reported them (fatal at kWorkerFailuresToGiveUp with no other worker
  /// ready: retrying such work does not help).
  int worker_failures_in_a_row_ = 0;
  std::set<std::string> failed_workers_;
  static constexpr int kWorkerFailuresToGiveUp = 8;
  /// Finished frames' images, for the next frames (declared before the writer, which gives
  /// them back from its thread).
  ImagePool frame_pool_{static_cast<std::size_t>(options_.frames_in_flight) + FrameWriter::kMaxPending};
  std::unique_ptr<FrameWriter> writer_;
  std::ofstream stats_file_;
  RunAccumulator finished_;  // every frame written, for the summary
};

}  // namespace

void check_listen(const MasterOptions& options) {
  asio::io_context io;
  const asio::ip::tcp::endpoint endpoint = listen_endpoint(io, options);
  if (endpoint.port() == 0) return;  // any free port will do
  // Bound and closed at once (no connection, so no TIME_WAIT): a port another program listens
  // on is named now rather than after the scene's load. run_master binds it again.
  asio::ip::tcp::acceptor probe(io);
  asio::error_code ec;
  probe.open(endpoint.protocol(), ec);
  if (!ec) probe.set_option(asio::ip::tcp::acceptor::reuse_address(true), ec);
  if (!ec) probe.bind(endpoint, ec);
  if (ec) throw Error("--listen " + options.listen + ": " + ec.message());
}

int run_master(const Scene& scene, const MasterOptions& options) {
  Master master(scene, options);
  return master.run();
}

}  // namespace rtc
