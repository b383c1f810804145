// rtc-worker's client (see worker_client.h). One io_context thread talks to the master; render
// threads take tiles from a local queue, trace, encode and post the finished bytes back to it.
// A session number guards against results of a dead connection reaching the next one.
#include "worker/worker_client.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include <asio.hpp>
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>

#include "common/base/error.h"
#include "common/base/log.h"
#include "common/base/signal_name.h"
#include "common/base/timer.h"
#include "common/base/version.h"
#include "common/image/pixel_format.h"
#include "common/render/renderer.h"
#include "common/render/temporal.h"
#include "common/scene/serialize.h"
#include "protocol/auth.h"
#include "protocol/message.h"
#include "protocol/net/connection.h"

namespace rtc {

namespace {

using Clock = std::chrono::steady_clock;
namespace proto = protocol;

/// The scene a worker holds, with its renderer and the frames it has prepared. Shared by the
/// render threads; Renderer::prepare calls are serialized (they must not overlap), and may run
/// while other threads render tiles of frames prepared earlier.
class SceneSlot {
 public:
  SceneSlot(proto::Digest hash, Scene scene, const RenderOptions& options)
      : hash_(hash), renderer_(std::move(scene), options) {}

  [[nodiscard]] const proto::Digest& hash() const { return hash_; }
  [[nodiscard]] const Renderer& renderer() const { return renderer_; }

  /// The prepared state of `frame`. Threads asking for a frame that is already prepared never
  /// wait for another frame's kd-tree build: the map and the build have separate locks.
  std::shared_ptr<const FrameState> frame(int frame) {
    if (std::shared_ptr<const FrameState> state = find(frame)) return state;
    std::lock_guard build_lock(build_mutex_);
    if (std::shared_ptr<const FrameState> state = find(frame)) return state;  // built meanwhile
    const Timer timer;
    std::shared_ptr<const FrameState> state = renderer_.prepare(frame);
    // The first is the kd-tree build of the whole scene, which the first frame's tiles wait for
    // (a 2.1 M triangle scene: most of its first frame); later ones rebuild what moved.
    spdlog::log(first_prepare_ ? spdlog::level::info : spdlog::level::debug,
                "frame {} prepared (kd-tree{}) in {:.0f} ms", frame, first_prepare_ ? " of the whole scene" : "",
                timer.elapsed_ms());
    first_prepare_ = false;
    std::lock_guard lock(map_mutex_);
    // A few frames stay prepared (several are in flight); the oldest goes first.
    if (prepared_.size() >= 4) prepared_.pop_front();
    prepared_.emplace_back(frame, state);
    return state;
  }

 private:
  std::shared_ptr<const FrameState> find(int frame) {
    std::lock_guard lock(map_mutex_);
    for (const auto& [f, state] : prepared_) {
      if (f == frame) return state;
    }
    return nullptr;
  }

  proto::Digest hash_;
  Renderer renderer_;
  std::mutex build_mutex_;  // Renderer::prepare calls must not overlap
  bool first_prepare_ = true;  // guarded by build_mutex_
  std::mutex map_mutex_;    // guards prepared_
  std::deque<std::pair<int, std::shared_ptr<const FrameState>>> prepared_;
};

/// One thread that prepares frames the master announced (FrameSettings) before their first tile
/// arrives: without it every thread of every worker waits for the frame's kd-tree build at each
/// frame boundary, and the link idles (measured on 100 Mbit/s with 3 workers: 0.13 s of every
/// 0.83 s frame at 512x512 float).
class FramePreparer {
 public:
  FramePreparer() : thread_([this] { loop(); }) {}
  ~FramePreparer() {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    thread_.join();
  }
  FramePreparer(const FramePreparer&) = delete;
  FramePreparer& operator=(const FramePreparer&) = delete;

  /// Queues `frame` of `scene` (held weakly: a scene replaced meanwhile is not built for).
  void request(const std::shared_ptr<SceneSlot>& scene, int frame) {
    {
      std::lock_guard lock(mutex_);
      // A few at most: SceneSlot keeps 4 prepared frames, and more ahead would push out the
      // frames being rendered.
      if (requests_.size() >= 2) requests_.pop_front();
      requests_.emplace_back(scene, frame);
    }
    wake_.notify_one();
  }
  /// Drops the requests not yet started (a new connection or scene).
  void clear() {
    std::lock_guard lock(mutex_);
    requests_.clear();
  }

 private:
  void loop() {
    for (;;) {
      std::pair<std::weak_ptr<SceneSlot>, int> next;
      {
        std::unique_lock lock(mutex_);
        wake_.wait(lock, [this] { return stop_ || !requests_.empty(); });
        if (stop_) return;
        next = std::move(requests_.front());
        requests_.pop_front();
      }
      if (const std::shared_ptr<SceneSlot> scene = next.first.lock()) {
        try {
          (void)scene->frame(next.second);
        } catch (const std::exception& e) {
          // The render thread that needs this frame builds it again and reports the error.
          spdlog::debug("preparing frame {} ahead: {}", next.second, e.what());
        }
      }
    }
  }

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::pair<std::weak_ptr<SceneSlot>, int>> requests_;
  bool stop_ = false;
  std::thread thread_;  // last: started once the members it uses exist
};

struct TileJob {
  std::uint64_t session = 0;
  std::shared_ptr<SceneSlot> scene;
  proto::TileAssign tile;
  proto::FrameSettings settings;
  std::shared_ptr<const MarkGrid> marks;  ///< record temporal-coherence marks on it (MarkGrid message)
};

/// Render threads: each takes one tile at a time, traces it, encodes the pixels and hands the
/// encoded TileResult to `deliver` (which posts it to the network thread).
class RenderPool {
 public:
  using Deliver = std::function<void(std::uint64_t session, std::vector<std::uint8_t> message)>;
  using Fail = std::function<void(std::uint64_t session, std::string error)>;

  RenderPool(int threads, Deliver deliver, Fail fail) : deliver_(std::move(deliver)), fail_(std::move(fail)) {
    for (int i = 0; i < threads; ++i) threads_.emplace_back([this] { loop(); });
  }
  ~RenderPool() {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    for (std::thread& t : threads_) t.join();
  }
  RenderPool(const RenderPool&) = delete;
  RenderPool& operator=(const RenderPool&) = delete;

  void push(TileJob job) {
    {
      std::lock_guard lock(mutex_);
      jobs_.push_back(std::move(job));
    }
    wake_.notify_one();
  }
  /// Drops queued jobs of older sessions (a lost connection's tiles went back to the master).
  void set_session(std::uint64_t session) {
    std::lock_guard lock(mutex_);
    session_ = session;
    jobs_.erase(std::remove_if(jobs_.begin(), jobs_.end(), [&](const TileJob& j) { return j.session != session; }),
                jobs_.end());
  }

 private:
  void loop() {
    Image tile;
    std::vector<std::uint8_t> pixels;
    std::unique_ptr<MarkRecorder> recorder;
    std::shared_ptr<const MarkGrid> recorder_grid;
    for (;;) {
      TileJob job;
      {
        std::unique_lock lock(mutex_);
        wake_.wait(lock, [this] { return stop_ || !jobs_.empty(); });
        if (stop_) return;
        job = std::move(jobs_.front());
        jobs_.pop_front();
        if (job.session != session_) continue;
      }
      try {
        const std::shared_ptr<const FrameState> state = job.scene->frame(job.tile.frame);
        Timer timer;
        TileRayCounts counts;
        if (job.marks && job.marks != recorder_grid) {
          recorder = std::make_unique<MarkRecorder>(*job.marks);
          recorder_grid = job.marks;
        }
        MarkRecorder* marks = job.marks ? recorder.get() : nullptr;
        job.scene->renderer().render_tile(*state, static_cast<int>(job.tile.x), static_cast<int>(job.tile.y),
                                          static_cast<int>(job.tile.width), static_cast<int>(job.tile.height), tile,
                                          &counts, marks);
        const double render_ms = timer.elapsed_ms();
        proto::TileResult r;
        r.sequence = job.tile.sequence;
        r.frame = job.tile.frame;
        r.tile = job.tile.tile;
        r.x = job.tile.x;
        r.y = job.tile.y;
        r.width = job.tile.width;
        r.height = job.tile.height;
        r.wire_format = job.settings.wire_format;
        r.compression = job.settings.compression;
        r.channels = job.settings.channels;
        pixels.clear();
        r.raw_size = static_cast<std::uint32_t>(
            encode_tile_pixels(tile, static_cast<WireFormat>(job.settings.wire_format),
                               static_cast<Compression>(job.settings.compression), job.settings.channels, pixels));
        r.pixels = std::move(pixels);  // back after encoding: the thread keeps its buffer
        r.render_us = static_cast<std::uint32_t>(std::min(render_ms * 1000.0, 4e9));
        r.primary_rays = counts.primary;
        r.shadow_rays = counts.shadow;
        r.reflection_rays = counts.reflection;
        std::vector<std::uint8_t> message;
        if (marks != nullptr) {
          // The voxels its rays crossed travel just before the tile (protocol.md, TileMarks).
          TileMarks tm;
          marks->take(tm);
          proto::TileMarks pm;
          pm.sequence = job.tile.sequence;
          pm.tile = job.tile.tile;
          pm.shaded = tm.shaded;
          pm.path = std::move(tm.path);
          pm.shadow = std::move(tm.shadow);
          proto::encode_to(pm, message);
        }
        proto::encode_to(r, message);
        pixels = std::move(r.pixels);
        deliver_(job.session, std::move(message));
      } catch (const std::exception& e) {
        fail_(job.session, std::string("rendering tile ") + std::to_string(job.tile.tile) + " of frame " +
                               std::to_string(job.tile.frame) + ": " + e.what());
      }
    }
  }

  Deliver deliver_;
  Fail fail_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<TileJob> jobs_;
  std::uint64_t session_ = 0;
  bool stop_ = false;
  std::vector<std::thread> threads_;
};

std::string host_name() {
  char buf[256] = {};
  if (gethostname(buf, sizeof buf - 1) != 0) return "worker";
  return buf;
}

class WorkerClient {
 public:
  explicit WorkerClient(const WorkerOptions& options)
      : options_(options),
        threads_(options.threads > 0 ? options.threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()))),
        target_(net::parse_host_port(options.connect, "--connect")),
        signals_(io_, SIGINT, SIGTERM, SIGHUP),
        retry_timer_(io_),
        watchdog_(io_),
        pool_(threads_,
              [this](std::uint64_t session, std::vector<std::uint8_t> message) {
                asio::post(io_, [this, session, m = std::move(message)]() mutable {
                  if (session != session_ || !conn_) return;
                  if (tiles_outstanding_ > 0) --tiles_outstanding_;
                  conn_->send_encoded(std::move(m));
                  if (conn_ && !backlog_noted_ && conn_->queued_bytes() > kDefaultSendCap) {
                    backlog_noted_ = true;  // once a connection
                    spdlog::info("{} MiB of results wait to be sent: {} takes them slower than this worker renders "
                                 "them",
                                 conn_->queued_bytes() >> 20, conn_->peer());
                  }
                });
              },
              [this](std::uint64_t session, std::string error) {
                asio::post(io_, [this, session, error] {
                  if (session == session_ && conn_) fail_session(proto::ErrorCode::Internal, error);
                });
              }) {
    if (options_.name.empty()) options_.name = host_name();
    options_.name = options_.name.substr(0, proto::kMaxName);
    render_options_.isa = options_.isa;
    render_options_.kd_clip = options_.kd_clip;
    isa_ = options_.isa.value_or(best_isa());
    if (!options_.tls_ca.empty()) {
      tls_ = net::tls_client_context(options_.tls_ca);
      if (options_.tls_server_name.empty()) options_.tls_server_name = target_.host;
    }
  }

  int run() {
    spdlog::info("rtc-worker {}: {}, {} kernels, {}; master {}", build_id(),
                 counted(threads_, "render thread", "render threads"), isa_name(isa_), isa_packet_description(isa_), options_.connect);
    lost_since_ = Clock::now();
    signals_.async_wait([this](const asio::error_code& ec, int signal) {
      if (ec) return;
      if (conn_ && welcomed_) {
        spdlog::info("{}: saying goodbye to the master and exiting", signal_name(signal));
      } else {
        spdlog::info("{}: exiting (not connected to a master)", signal_name(signal));
      }
      exit_code_ = 0;
      finish(true);
    });
    connect();
    io_.run();
    return exit_code_;
  }

 private:
  // ---- connecting --------------------------------------------------------------------------

  // An rtc-master sends its challenge as soon as a plain connection opens; one that listens with
  // TLS waits for a TLS handshake instead, and closes the connection after its --auth-timeout.
  // (A master also closes a connection over its per-host limits without a word, saying why in
  // its own log.)
  static constexpr const char* kTlsHint =
      "the master may use TLS (its \"listening on\" line says \"TLS\", not \"no TLS\"): then give this worker "
      "--tls-ca";

  /// Nothing has come on the current connection, not even a message's header.
  [[nodiscard]] bool nothing_heard() const { return conn_->header_arrived() == Clock::time_point{}; }

  void connect() {
    if (finished_) return;
    auto socket = std::make_shared<asio::ip::tcp::socket>(io_);
    auto resolver = std::make_shared<asio::ip::tcp::resolver>(io_);
    auto timeout = std::make_shared<asio::steady_timer>(io_, std::chrono::seconds(5));
    timeout->async_wait([socket, resolver](const asio::error_code& ec) {
      if (ec) return;
      asio::error_code ignored;
      resolver->cancel();
      socket->close(ignored);
    });
    resolver->async_resolve(target_.host, std::to_string(target_.port),
                            [this, socket, resolver, timeout](const asio::error_code& ec,
                                                              const asio::ip::tcp::resolver::results_type& results) {
                              if (finished_) return;
                              if (ec) {
                                timeout->cancel();
                                return retry("cannot resolve " + target_.host + ": " + ec.message());
                              }
                              asio::async_connect(*socket, results,
                                                  [this, socket, timeout](const asio::error_code& e,
                                                                          const asio::ip::tcp::endpoint&) {
                                                    timeout->cancel();
                                                    if (finished_) return;
                                                    if (e) return retry(e == asio::error::operation_aborted
                                                                            ? std::string("connect timed out")
                                                                            : e.message());
                                                    if (tls_) return tls_handshake(std::move(*socket));
                                                    const std::string peer = "master " + net::peer_name(*socket);
                                                    on_connected(std::make_shared<net::Connection>(std::move(*socket), peer));
                                                  });
                            });
  }

  void retry(const std::string& why, bool connected = false) {
    if (finished_) return;
    const double down_s = std::chrono::duration<double>(Clock::now() - lost_since_).count();
    if (options_.retry_seconds > 0 && down_s >= options_.retry_seconds) {
      // The last try reached something that was no working master (garbage, a refused
      // handshake) or lost it: not "unreachable".
      if (connected) {
        spdlog::error("no working master at {} for {:.1f} s (the last connection was made, then: {}); giving up "
                      "(--retry-seconds {})",
                      options_.connect, down_s, why, options_.retry_seconds);
      } else {
        spdlog::error("master at {} unreachable for {:.1f} s (last: {}); giving up (--retry-seconds {})", options_.connect,
                      down_s, why, options_.retry_seconds);
      }
      exit_code_ = 1;
      return finish(false);
    }
    if (!retry_logged_ && !connected) {
      spdlog::info("master at {} not reachable ({}); retrying with back-off{}", options_.connect, why,
                   options_.retry_seconds > 0 ? fmt::format(" for up to {:g} s", options_.retry_seconds) : std::string());
      retry_logged_ = true;
    } else {
      spdlog::debug("master at {} not reachable ({}); next try in {} ms", options_.connect, why, backoff_ms_);
    }
    // The last wait ends at the deadline, so that the worker gives up at --retry-seconds and not
    // up to one back-off step (5 s) later: one more try is made there.
    int wait_ms = backoff_ms_;
    if (options_.retry_seconds > 0) {
      const double left_ms = (options_.retry_seconds - down_s) * 1000.0;
      wait_ms = static_cast<int>(std::clamp(std::ceil(left_ms), 0.0, static_cast<double>(wait_ms)));
    }
    retry_timer_.expires_after(std::chrono::milliseconds(wait_ms));
    retry_timer_.async_wait([this](const asio::error_code& ec) {
      if (!ec) connect();
    });
    backoff_ms_ = std::min(backoff_ms_ * 2, 5000);
  }

  // TLS: verify the master's certificate (signed by --tls-ca, naming the host), then the rtc
  // protocol over the encrypted stream. A certificate that fails verification is not retried:
  // waiting cannot make it trusted.
  void tls_handshake(asio::ip::tcp::socket socket) {
    const std::string peer = "master " + net::peer_name(socket);
    auto stream = std::make_shared<net::TlsStream>(std::move(socket), *tls_);
    // host_name_verification fails without saying why; note when it is the name that failed.
    auto name_failed = std::make_shared<bool>(false);
    stream->set_verify_callback([check = asio::ssl::host_name_verification(options_.tls_server_name), name_failed](
                                    bool preverified, asio::ssl::verify_context& ctx) mutable {
      const bool ok = check(preverified, ctx);
      if (preverified && !ok) *name_failed = true;
      return ok;
    });
    // SNI, for a master behind a TLS-terminating proxy; not for an IP address (RFC 6066 3).
    asio::error_code ignored;
    asio::ip::make_address(options_.tls_server_name, ignored);
    if (ignored) SSL_set_tlsext_host_name(stream->native_handle(), options_.tls_server_name.c_str());
    net::async_tls_handshake(stream, asio::ssl::stream_base::client, std::chrono::seconds(10),
                             [this, stream, peer, name_failed](const asio::error_code& ec) {
      if (finished_) return;
      if (!ec) return on_connected(std::make_shared<net::Connection>(stream, peer));
      const long verify = SSL_get_verify_result(stream->native_handle());
      if (verify != X509_V_OK) {
        const std::string why =
            *name_failed ? "it does not name \"" + options_.tls_server_name + "\" (give the name it carries with --tls-server-name)"
                         : std::string(X509_verify_cert_error_string(verify));
        spdlog::error("TLS: {}'s certificate is not trusted: {} (--tls-ca {}); exiting", peer, why, options_.tls_ca);
        exit_code_ = 1;
        return finish(false);
      }
      const std::string why = ec == asio::error::operation_aborted ? std::string("no TLS handshake within 10 s")
                                                                    : "TLS handshake failed: " + ec.message();
      spdlog::warn("connection to {} failed: {} (is the master running without --tls-cert?)", options_.connect, why);
      retry(why, /*connected=*/true);
    });
  }

  void on_connected(std::shared_ptr<net::Connection> conn) {
    ++session_;
    pool_.set_session(session_);
    preparer_.clear();
    const std::string peer = conn->peer();
    conn_ = std::move(conn);
    welcomed_ = false;
    heartbeat_ms_ = kDefaultHeartbeatMs;  // the previous master's interval is not this one's
    tiles_outstanding_ = 0;
    conn_->set_max_queued_bytes(kDefaultSendCap);
    backlog_noted_ = false;
    probes_this_session_ = 0;
    settings_.clear();
    mark_grid_.reset();
    scene_buffer_.clear();
    receiving_scene_ = false;
    last_heard_ = Clock::now();
    connected_at_ = last_heard_;
    watchdog_closed_ = false;
    const std::uint64_t session = session_;
    conn_->start([this, session](proto::Message&& m, std::size_t) {
                   if (session != session_) return;
                   last_heard_ = Clock::now();
                   current_type_ = proto::type_name(static_cast<std::uint16_t>(proto::type_of(m)));
                   std::visit([&](auto&& msg) { handle(std::move(msg)); }, std::move(m));
                 },
                 [this, session](const std::string& reason) { on_close(session, reason); });
    spdlog::debug("connected to {}{}", peer, conn_->tls() ? " (TLS)" : "");
    arm_watchdog();
  }

  void on_close(std::uint64_t session, const std::string& reason) {
    if (session != session_) return;
    const bool silent = conn_ && nothing_heard();
    const bool timed_out = watchdog_closed_;  // its reason already says that nothing was heard
    conn_.reset();
    ++session_;
    pool_.set_session(session_);
    watchdog_.cancel();
    if (finished_) return;
    if (goodbye_) {
      if (!options_.stay) return finish(false);
      goodbye_ = false;
    }
    if (auth_rejected_) {
      exit_code_ = 1;
      return finish(false);
    }
    if (welcomed_) {
      spdlog::warn("lost the master: {}; reconnecting", reason);
      lost_since_ = Clock::now();
      backoff_ms_ = 200;
      retry_logged_ = false;
    } else {
      // Reached, but the handshake failed (a bad message, a non-rtc server): say why every time.
      spdlog::warn("connection to {} failed before the master welcomed this worker: {}{}", options_.connect, reason,
                   !silent || tls_ ? std::string()
                   : timed_out ? std::string("; ") + kTlsHint
                               : std::string(" without a word from it; ") + kTlsHint);
    }
    retry(reason, /*connected=*/true);
  }

  // The master's heartbeats stop when it is gone without a FIN (a cable pulled, a host down).
  void arm_watchdog() {
    watchdog_.expires_after(std::chrono::seconds(1));
    watchdog_.async_wait([this](const asio::error_code& ec) {
      if (ec || !conn_) return;
      if (nothing_heard() && !tls_ && !silence_noted_ && Clock::now() - connected_at_ >= std::chrono::seconds(2)) {
        silence_noted_ = true;  // once a run: the close says it again
        // An rtc master speaks first, at once; a stopped or swamped one says nothing either.
        spdlog::warn("{} has said nothing in 2 s since the connection opened: it may be stopped or busy, or {}",
                     conn_->peer(), kTlsHint);
      }
      // 64 bits: a master's interval is any 32-bit number on the wire.
      const auto limit = std::chrono::milliseconds(std::max<std::uint64_t>(10000, 5 * std::uint64_t{heartbeat_ms_}));
      // A big message on its way (a scene chunk on a slow link) counts while its bytes keep coming.
      if (Clock::now() - std::max(last_heard_, conn_->bytes_arrived()) > limit) {
        watchdog_closed_ = true;
        conn_->close("nothing heard from the master for " + std::to_string(limit.count()) + " ms");
        return;
      }
      arm_watchdog();
    });
  }

  void finish(bool say_goodbye) {
    if (finished_) return;
    finished_ = true;
    asio::error_code ec;
    signals_.cancel(ec);
    signals_.clear(ec);  // a further Ctrl-C ends the process the usual way
    retry_timer_.cancel();
    watchdog_.cancel();
    if (conn_) {
      if (say_goodbye) {
        proto::Goodbye bye;
        bye.reason = "worker stopped by a signal";
        conn_->send(bye);
        conn_->close_after_flush("goodbye sent");
      } else {
        conn_->close("worker exiting");
      }
    }
  }

  void fail_session(proto::ErrorCode code, const std::string& why) {
    spdlog::error("{}: {}; closing and reconnecting", conn_ ? conn_->peer() : std::string("master"), why);
    if (!conn_) return;
    proto::ErrorMessage error;
    error.code = code;
    error.text = why.substr(0, proto::kMaxText);
    conn_->send(error);
    conn_->close_after_flush(why);
  }

  // ---- messages from the master ------------------------------------------------------------

  void handle(proto::Challenge&& m) {
    if (hello_sent_this_session_ == session_) return unexpected();
    hello_sent_this_session_ = session_;
    if (m.auth_required && options_.token.empty()) {
      spdlog::warn("{} requires a token and this worker has none (--token-file): authentication will fail", conn_->peer());
    }
    proto::Hello hello;
    hello.cores = std::max(1u, std::thread::hardware_concurrency());
    hello.threads = static_cast<std::uint32_t>(threads_);
    hello.isa = std::string(isa_name(isa_));
    hello.build_id = build_id().substr(0, proto::kMaxName);
    hello.name = options_.name;
    conn_->send(hello);
    proto::Auth auth;
    auth.proof = proto::auth_proof(options_.token, m.nonce);
    conn_->send(auth);
  }

  void handle(proto::Welcome&& m) {
    if (welcomed_) return unexpected();
    welcomed_ = true;
    heartbeat_ms_ = m.heartbeat_ms;
    max_outstanding_ = m.max_outstanding;
    backoff_ms_ = 200;
    retry_logged_ = false;
    spdlog::info("connected to {} as worker w{} (up to {} tiles at once)", conn_->peer(), m.worker_id, m.max_outstanding);
  }

  void handle(proto::SceneOffer&& m) {
    if (!welcomed_) return unexpected();
    m.name = printable(m.name);  // the master's words, logged below
    proto::SceneRequest request;
    request.hash = m.hash;
    if (scene_ && scene_->hash() == m.hash) {
      request.have = true;
      conn_->send(request);
      spdlog::info("scene {} ({}): already here, transfer skipped", m.name, proto::to_hex(m.hash).substr(0, 16));
      proto::SceneReady ready;
      ready.hash = m.hash;
      conn_->send(ready);
      return;
    }
    // A hostile size must not make us allocate: chunks are appended as they come.
    constexpr std::uint64_t kMaxSceneBytes = 16ull << 30;
    if (m.size == 0 || m.size > kMaxSceneBytes) {
      return fail_session(proto::ErrorCode::SceneInvalid, "scene offer of " + std::to_string(m.size) + " bytes is out of range");
    }
    scene_offer_ = m;
    scene_buffer_.clear();
    receiving_scene_ = true;
    scene_timer_.reset();
    conn_->send(request);
    spdlog::info("receiving scene {} ({:.1f} MB)", m.name, m.size / 1e6);
  }

  void handle(proto::SceneChunk&& m) {
    if (!receiving_scene_ || m.hash != scene_offer_.hash) return unexpected();
    if (m.offset != scene_buffer_.size() || scene_buffer_.size() + m.bytes.size() > scene_offer_.size) {
      return fail_session(proto::ErrorCode::SceneInvalid,
                          "scene chunk at offset " + std::to_string(m.offset) + " does not continue the " +
                              std::to_string(scene_buffer_.size()) + " bytes received of " +
                              std::to_string(scene_offer_.size));
    }
    scene_buffer_.insert(scene_buffer_.end(), m.bytes.begin(), m.bytes.end());
    if (scene_buffer_.size() < scene_offer_.size) return;
    receiving_scene_ = false;
    if (proto::sha256(scene_buffer_) != scene_offer_.hash) {
      return fail_session(proto::ErrorCode::SceneInvalid, "scene bytes do not match their SHA-256");
    }
    try {
      Scene scene = deserialize_scene(scene_buffer_, "scene from " + conn_->peer());
      scene_.reset();  // free the old scene's memory before building the new one
      scene_ = std::make_shared<SceneSlot>(scene_offer_.hash, std::move(scene), render_options_);
    } catch (const std::exception& e) {
      return fail_session(proto::ErrorCode::SceneInvalid, e.what());
    }
    std::vector<std::uint8_t>().swap(scene_buffer_);
    proto::SceneReady ready;
    ready.hash = scene_offer_.hash;
    ready.load_ms = static_cast<std::uint32_t>(scene_timer_.elapsed_ms());
    conn_->send(ready);
    spdlog::info("scene {} received and decoded in {:.0f} ms: {} triangles, {}x{}", scene_offer_.name,
                 scene_timer_.elapsed_ms(), scene_->renderer().scene().triangle_count(), scene_->renderer().scene().width,
                 scene_->renderer().scene().height);
  }

  void handle(proto::FrameSettings&& m) {
    if (!scene_) return unexpected();
    if (!wire_format_from_byte(m.wire_format) || !compression_from_byte(m.compression) ||
        (m.channels & ~(kChannelDepth | kChannelNormal)) != 0 ||
        (m.channels != 0 && m.wire_format == static_cast<std::uint8_t>(WireFormat::Rgba8))) {
      return fail_session(proto::ErrorCode::Protocol, "FrameSettings with an unknown pixel format " +
                                                          std::to_string(m.wire_format) + "/" +
                                                          std::to_string(m.compression) + "/" + std::to_string(m.channels));
    }
    if (settings_.size() >= 256) return fail_session(proto::ErrorCode::Protocol, "more than 256 frames in flight");
    settings_[m.sequence] = m;
    // Announced ahead of its tiles (protocol.md step 7): build its kd-tree now.
    preparer_.request(scene_, m.frame);
  }

  void handle(proto::TileAssign&& m) {
    const auto it = settings_.find(m.sequence);
    if (!scene_ || it == settings_.end() || it->second.frame != m.frame) {
      return fail_session(proto::ErrorCode::Protocol,
                          "TileAssign for frame sequence " + std::to_string(m.sequence) + " without its FrameSettings");
    }
    const Scene& scene = scene_->renderer().scene();
    const auto w = static_cast<std::uint64_t>(scene.width), h = static_cast<std::uint64_t>(scene.height);
    if (m.width == 0 || m.height == 0 || m.width > 4096 || m.height > 4096 || std::uint64_t{m.x} + m.width > w ||
        std::uint64_t{m.y} + m.height > h) {
      return fail_session(proto::ErrorCode::Protocol, "TileAssign rectangle " + std::to_string(m.x) + "," +
                                                          std::to_string(m.y) + " " + std::to_string(m.width) + "x" +
                                                          std::to_string(m.height) + " outside the " +
                                                          std::to_string(w) + "x" + std::to_string(h) + " frame");
    }
    const std::size_t raw = raw_tile_bytes(static_cast<int>(m.width), static_cast<int>(m.height),
                                           static_cast<WireFormat>(it->second.wire_format), it->second.channels);
    if (raw == 0 || max_encoded_tile_bytes(raw) + 128 > proto::kMaxPayload) {
      return fail_session(proto::ErrorCode::Protocol, "TileAssign of " + std::to_string(m.width) + "x" +
                                                          std::to_string(m.height) + " pixels cannot be sent back in one message");
    }
    // The master promised at most max_outstanding tiles at once (Welcome): more is a flood.
    const std::uint32_t most = std::max<std::uint32_t>(max_outstanding_, 2);
    if (tiles_outstanding_ >= most) {
      return fail_session(proto::ErrorCode::Protocol, "more than the " + std::to_string(max_outstanding_) +
                                                          " tiles at once the master announced");
    }
    // Each tile the master may hold out can wait in the send queue as a result (with its marks)
    // while the link is slower than the cores: the queue's limit, which tells a master that
    // stopped reading, must hold them all (a fixed 256 MiB closed a healthy connection once more
    // than 32 float tiles of 512x512 with depth and normals waited, and the work was thrown
    // away: Cluster.results_pile_up).
    const std::size_t per_tile = max_encoded_tile_bytes(raw) + 2 * proto::kHeaderSize + 128 +
                                 (mark_grid_ ? proto::max_payload(static_cast<std::uint16_t>(proto::MessageType::TileMarks)) : 0);
    if (const std::size_t needed = std::min(most * per_tile + kDefaultSendCap / 16, kMostSendCap);
        needed > conn_->max_queued_bytes()) {
      conn_->set_max_queued_bytes(needed);
    }
    ++tiles_outstanding_;
    pool_.push(TileJob{session_, scene_, m, it->second, mark_grid_});
  }

  void handle(proto::MarkGrid&& m) {
    if (!scene_) return unexpected();
    auto grid = std::make_shared<MarkGrid>();  // dims 0: no voxels, only the `shaded` flag
    for (int k = 0; k < 3; ++k) {
      grid->lo[k] = m.lo[k];
      grid->hi[k] = m.hi[k];
      grid->dims[k] = static_cast<int>(m.dims[k]);
    }
    try {
      check_mark_grid(*grid, "MarkGrid from " + conn_->peer());
    } catch (const Error& e) {
      return fail_session(proto::ErrorCode::Protocol, e.what());
    }
    mark_grid_ = std::move(grid);
    if (mark_grid_->empty()) {
      spdlog::info("temporal coherence: no mesh moves, so no voxels are recorded (frames differ only where lights move)");
    } else {
      spdlog::info("temporal coherence: recording the voxels each tile's rays cross on a {}x{}x{} grid", m.dims[0],
                   m.dims[1], m.dims[2]);
    }
  }

  void handle(proto::FrameEnd&& m) { settings_.erase(m.sequence); }

  void handle(proto::Heartbeat&& m) {
    proto::HeartbeatAck ack;
    ack.seq = m.seq;
    ack.sent_us = m.sent_us;
    conn_->send(ack);
  }

  void handle(proto::HeartbeatAck&&) {}

  void handle(proto::ProbeRequest&& m) {
    if (++probes_this_session_ > 4) return fail_session(proto::ErrorCode::Protocol, "more than 4 link probes");
    proto::ProbeData data;
    data.bytes.assign(m.bytes, 0);
    conn_->send(data);
  }

  void handle(proto::ErrorMessage&& m) {
    m.text = printable(m.text);  // the peer's words, before it has proved to be the master
    if (m.code == proto::ErrorCode::AuthFailed) {
      spdlog::error("{} rejected this worker: {} (check --token-file)", conn_->peer(), m.text);
      auth_rejected_ = true;
    } else {
      spdlog::error("{} reports an error: {}", conn_->peer(), m.text);
    }
    conn_->close("the master reported an error: " + m.text);
  }

  void handle(proto::Goodbye&& m) {
    spdlog::info("{} said goodbye: {}{}", conn_->peer(), printable(m.reason), options_.stay ? "; waiting for the next master" : "; exiting");
    goodbye_ = true;
    lost_since_ = Clock::now();
    conn_->close("goodbye");
  }

  template <class M>
  void handle(M&&) {
    unexpected();
  }

  void unexpected() { fail_session(proto::ErrorCode::Protocol, "unexpected " + current_type_ + " message"); }

  WorkerOptions options_;
  int threads_;
  net::HostPort target_;
  Isa isa_{};
  RenderOptions render_options_;
  asio::io_context io_;
  asio::signal_set signals_;
  asio::steady_timer retry_timer_, watchdog_;
  std::shared_ptr<net::Connection> conn_;
  std::shared_ptr<asio::ssl::context> tls_;  // --tls-ca given
  std::uint64_t session_ = 0;
  std::uint64_t hello_sent_this_session_ = 0;
  bool welcomed_ = false, goodbye_ = false, auth_rejected_ = false, finished_ = false, retry_logged_ = false;
  int exit_code_ = 0;
  int backoff_ms_ = 200;
  static constexpr std::uint32_t kDefaultHeartbeatMs = 1000;  ///< until a master's Welcome says its own
  std::uint32_t heartbeat_ms_ = kDefaultHeartbeatMs;
  std::uint32_t max_outstanding_ = 0;
  /// The send queue's limit on a new connection, raised to hold the results of every tile the
  /// master may have out (handle(TileAssign)).
  static constexpr std::size_t kDefaultSendCap = std::size_t{256} << 20;
  /// However many tiles a master announces: past this, it is taken as not reading.
  static constexpr std::size_t kMostSendCap = std::size_t{16} << 30;
  bool backlog_noted_ = false;  ///< the "results wait to be sent" line was logged on this connection
  std::uint32_t tiles_outstanding_ = 0;  // assigned and not yet sent back, this session
  std::shared_ptr<const MarkGrid> mark_grid_;  // from the master's MarkGrid, this session
  int probes_this_session_ = 0;
  Clock::time_point lost_since_, last_heard_, connected_at_;
  bool silence_noted_ = false;  // the no-challenge warning was given (once a run)
  bool watchdog_closed_ = false;  // this connection was closed by the watchdog (nothing heard in time)
  std::string current_type_;
  std::shared_ptr<SceneSlot> scene_;
  proto::SceneOffer scene_offer_;
  std::vector<std::uint8_t> scene_buffer_;
  bool receiving_scene_ = false;
  Timer scene_timer_;
  std::map<std::uint32_t, proto::FrameSettings> settings_;
  FramePreparer preparer_;
  RenderPool pool_;  // last: its threads stop before the members they use go away
};

}  // namespace

int run_worker(const WorkerOptions& options) {
  std::unique_ptr<tbb::global_control> limit;
  if (options.threads > 0) {
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  static_cast<std::size_t>(options.threads));
  }
  WorkerClient client(options);
  return client.run();
}

}  // namespace rtc
