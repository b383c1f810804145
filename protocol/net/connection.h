// One framed rtc protocol connection over TCP or TLS over TCP (Asio, OpenSSL): reads whole
// messages, queues writes, and closes on the first malformed byte with a reason naming the peer.
// Shared by master and worker.
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <asio.hpp>
#include <asio/ssl.hpp>

#include "protocol/message.h"

namespace rtc::net {

/// "127.0.0.1:54321" for a connected socket ("unknown peer" if it has none).
[[nodiscard]] std::string peer_name(const asio::ip::tcp::socket& socket);

/// Parses "HOST:PORT" ("[v6]:PORT" for IPv6 literals); throws rtc::Error naming `what` and the
/// text for a missing or bad port.
struct HostPort {
  std::string host;
  std::uint16_t port = 0;
};
[[nodiscard]] HostPort parse_host_port(const std::string& text, const std::string& what);

/// A TLS stream over a TCP socket.
using TlsStream = asio::ssl::stream<asio::ip::tcp::socket>;

/// The master's TLS context: its certificate chain and private key (PEM files); TLS 1.2 or
/// later. Throws rtc::Error naming the file that cannot be read or does not match.
[[nodiscard]] std::shared_ptr<asio::ssl::context> tls_server_context(const std::string& cert_file,
                                                                     const std::string& key_file);
/// A worker's TLS context: trusts the certificates in `ca_file` (PEM: a CA, or the master's own
/// self-signed certificate) and nothing else; TLS 1.2 or later. Throws rtc::Error naming the file.
[[nodiscard]] std::shared_ptr<asio::ssl::context> tls_client_context(const std::string& ca_file);

/// Runs `stream`'s TLS handshake as `role`; when it has not finished within `timeout` the TCP
/// socket is closed, and `done` gets asio::error::operation_aborted. `done` runs once, on the
/// stream's executor.
void async_tls_handshake(std::shared_ptr<TlsStream> stream, asio::ssl::stream_base::handshake_type role,
                         std::chrono::milliseconds timeout, std::function<void(const asio::error_code&)> done);

/// Whether `ec` means the peer ended the stream: EOF, or a TLS peer closing without close_notify
/// (what Connection's own graceful close does: it shuts the TCP socket's sending side).
[[nodiscard]] bool is_end_of_stream(const asio::error_code& ec);

/// A framed message connection. Single-threaded: every member must be called on the thread
/// running the io_context, and every handler runs there. Owned by shared_ptr (the pending
/// operations keep it alive until it is closed).
class Connection : public std::enable_shared_from_this<Connection> {
 public:
  /// Called with each complete, valid message and its size on the wire (header + payload).
  using MessageHandler = std::function<void(protocol::Message&&, std::size_t wire_bytes)>;
  /// Called exactly once, when the connection closes for any reason, with the reason.
  using CloseHandler = std::function<void(const std::string& reason)>;

  Connection(asio::ip::tcp::socket socket, std::string peer);
  /// Over TLS: `stream` has finished its handshake.
  Connection(std::shared_ptr<TlsStream> stream, std::string peer);
  ~Connection();
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  /// Starts reading. A bad header, bad checksum or undecodable payload sends the peer an Error
  /// (code Version for a version mismatch, else Protocol) and closes the connection with
  /// "bad message from PEER: <decoder's reason>"; nothing more is read from it.
  void start(MessageHandler on_message, CloseHandler on_close);

  /// Queues a message (encoded now). Ignored after close.
  void send(const protocol::Message& message);
  /// Queues already-encoded bytes (one or more whole messages). Ignored after close.
  void send_encoded(std::vector<std::uint8_t> bytes);

  /// Closes now (pending writes are dropped) and reports `reason` to the close handler.
  void close(const std::string& reason);
  /// Sends what is queued, shuts down the sending side, then reads and discards until the peer
  /// closes (a graceful close: no reset that could destroy our last message before the peer
  /// reads it); `reason` goes to the close handler. Nothing the peer sends meanwhile is
  /// handled. Bounded: the socket is closed anyway after `timeout`.
  void close_after_flush(const std::string& reason,
                         std::chrono::milliseconds timeout = std::chrono::milliseconds(2000));

  /// Largest payload accepted from the peer from now on (at most protocol::kMaxPayload, the
  /// default); a larger announced payload is rejected from its header, before any allocation.
  /// A master keeps it small until the peer has authenticated.
  void set_max_payload(std::uint32_t bytes) { max_payload_ = bytes; }
  /// Bytes that may wait in the write queue; beyond that the peer is not reading and the
  /// connection is closed ("PEER is not reading: N MiB queued"). Default 256 MiB. Each queued
  /// message counts kQueuedMessageOverhead bytes besides its own, so that a flood of small ones
  /// (32-byte heartbeat acks) is bounded by the memory it takes, not by a third of it.
  void set_max_queued_bytes(std::size_t bytes) { max_queued_bytes_ = bytes; }
  [[nodiscard]] std::size_t max_queued_bytes() const { return max_queued_bytes_; }

  /// Called whenever the write queue becomes empty (e.g. to stream the next scene chunk).
  void set_drained_handler(std::function<void()> on_drained) { on_drained_ = std::move(on_drained); }

  [[nodiscard]] const std::string& peer() const { return peer_; }
  [[nodiscard]] bool tls() const { return tls_ != nullptr; }
  [[nodiscard]] bool is_open() const { return !closed_; }
  /// Whether the peer sent a message this end refused (a bad header, CRC or payload, one over
  /// the size limit): the close handler was then called at once, with the reason.
  [[nodiscard]] bool rejected_peer() const { return rejected_peer_; }
  [[nodiscard]] std::size_t queued_bytes() const { return queued_bytes_; }
  [[nodiscard]] std::uint64_t bytes_received() const { return bytes_received_; }
  [[nodiscard]] std::uint64_t bytes_sent() const { return bytes_sent_; }
  /// When the header of the message being handled arrived (link measurements time the payload
  /// from there, leaving out the request's round trip and the sender's preparation).
  [[nodiscard]] std::chrono::steady_clock::time_point header_arrived() const { return header_arrived_; }
  /// When bytes last arrived (read up to 64 KiB at a time), so a big message on a slow link
  /// counts as hearing from the peer while it keeps coming (heartbeat timeouts go by this). The
  /// epoch before anything arrived.
  [[nodiscard]] std::chrono::steady_clock::time_point bytes_arrived() const { return bytes_arrived_; }
  /// Bytes held for reading payloads too big for the read buffer: the largest recent such
  /// payload's size, kept between messages (0 while only smaller messages have come).
  [[nodiscard]] std::size_t payload_buffer_bytes() const { return payload_capacity_; }
  /// Makes the payload buffer at least `bytes` and touches every page of it now, so that a big
  /// message expected next (a link probe) is read into memory already mapped: a fresh 4 MiB took
  /// 13 ms of page faults on a VM, which a probe timed as link time. Not from a handler that still
  /// reads its message's bytes (handlers get decoded messages, so none does).
  void prepare_payload_buffer(std::size_t bytes);
  /// Reads made so far: one per fill of the read buffer (one system call, which may bring many
  /// messages or part of one), one per chunk of a payload too big for it.
  [[nodiscard]] std::uint64_t reads() const { return reads_; }
  /// Writes made so far, each of up to kGatherMessages queued messages (one system call while
  /// the socket takes them all).
  [[nodiscard]] std::uint64_t writes() const { return writes_; }

  /// Bytes asked for per read: every message of at most this size (header included) is decoded
  /// where it lies in the read buffer, so one read can bring many small ones (a worker's tile
  /// results, a master's tile assignments); a larger payload is read into the payload buffer.
  static constexpr std::size_t kReadBufferBytes = std::size_t{64} << 10;
  /// Queued messages sent by one gathered write at most (and kGatherBytes, unless one message
  /// alone is larger).
  static constexpr std::size_t kGatherMessages = 64;
  static constexpr std::size_t kGatherBytes = std::size_t{1} << 20;
  /// What a queued message costs besides its bytes: its own allocation's header and rounding,
  /// and its entry in the queue (measured: a flood of 32-byte messages took 2.3 times their bytes).
  static constexpr std::size_t kQueuedMessageOverhead = 48;
  /// A payload buffer up to this size is always kept.
  static constexpr std::size_t kKeptPayloadBytes = std::size_t{1} << 20;
  /// A larger one is given back after this many messages in a row under a quarter of its size.
  static constexpr int kSmallPayloadsToGiveBack = 64;

 private:
  /// Sends Error{code, text} to the peer and closes once that is sent; the close handler hears
  /// `reason` at once (the peer is done with, whether or not it reads the Error).
  void reject(const std::string& reason, protocol::ErrorCode code, const std::string& text);
  /// Calls the close handler with `reason`, at most once, and hands on no more messages
  /// (finish(), and reject() before the socket closes).
  void tell_owner_closed(const std::string& reason);
  /// Reads what the peer has sent, up to the read buffer's free space, then handles it.
  void read_more();
  /// Handles every whole message in the read buffer, in order, until it holds only part of
  /// one (then reads more), a payload too big for it begins (then reads that into the payload
  /// buffer), or the connection closes or drains.
  void handle_buffered();
  /// Checks a parsed header (`bytes`: its raw bytes); false, with the peer rejected, when it is
  /// bad or announces more than max_payload_.
  bool accept_header(const protocol::HeaderResult& parsed, const std::uint8_t* bytes);
  /// Decodes a payload and hands the message on; false when it was rejected.
  bool deliver(const protocol::Header& header, std::span<const std::uint8_t> payload);
  /// Counts a payload toward giving a big payload buffer back (kSmallPayloadsToGiveBack).
  void note_payload(std::size_t size);
  /// Reads payload bytes [done, payload_size_) a chunk at a time, then decodes the message.
  void read_payload_from(protocol::Header header, std::size_t done);
  /// The start of a message read's callback: false when the callback has nothing more to do,
  /// because the connection is closed or is draining before a close (close_after_flush), which
  /// then takes the read's result.
  bool read_returned(const asio::error_code& ec);
  /// Starts a gathered write of the queue's first messages, or ends a flush.
  void write_next();
  /// Schedules write_next after the handler now running, so messages queued by it (and by
  /// handlers of the same read) leave in one write.
  void schedule_write();
  void drain();
  void continue_drain(const asio::error_code& ec);
  void finish(const std::string& reason);
  /// The TCP socket under the stream (shutdown, close, options).
  asio::ip::tcp::socket& tcp() { return tls_ ? tls_->next_layer() : socket_; }
  /// Calls f(stream) with the TLS stream or the plain socket: every read and write goes through it.
  template <typename F>
  void with_stream(F&& f) {
    if (tls_) {
      f(*tls_);
    } else {
      f(socket_);
    }
  }

  asio::ip::tcp::socket socket_;     ///< the connection without TLS (unused with TLS)
  std::shared_ptr<TlsStream> tls_;  ///< the connection with TLS
  std::string peer_;
  MessageHandler on_message_;
  CloseHandler on_close_;
  std::function<void()> on_drained_;
  std::array<std::uint8_t, protocol::kHeaderSize> header_buf_{};  ///< drain()'s discarded bytes
  /// Bytes read and not yet handled: [read_begin_, read_end_) of read_buf_ (kReadBufferBytes).
  std::unique_ptr<std::uint8_t[]> read_buf_;
  std::size_t read_begin_ = 0;
  std::size_t read_end_ = 0;
  std::chrono::steady_clock::time_point read_at_{};  ///< when the last read returned
  bool header_pending_ = false;  ///< the header at read_begin_ was seen; its message is not all here
  std::uint64_t reads_ = 0;
  std::uint64_t writes_ = 0;
  std::size_t writing_count_ = 0;  ///< queue entries the write under way sends
  /// The payload being read: not zero-filled, and kept between messages (a fresh 16 MiB buffer
  /// a tile cost its zero fill and 4096 page faults). One over kKeptPayloadBytes is given back
  /// after kSmallPayloadsToGiveBack messages in a row under a quarter of its size (protocol.md).
  std::unique_ptr<std::uint8_t[]> payload_;
  std::size_t payload_capacity_ = 0;
  std::size_t payload_size_ = 0;
  int small_payloads_in_a_row_ = 0;
  std::deque<std::vector<std::uint8_t>> queue_;
  std::size_t queued_bytes_ = 0;
  std::size_t max_queued_bytes_ = 256u << 20;
  std::uint32_t max_payload_ = protocol::kMaxPayload;
  bool writing_ = false;  ///< a write is under way or scheduled (schedule_write)
  bool reading_ = false;  ///< an async read is outstanding
  bool closed_ = false;
  bool closing_after_flush_ = false;
  bool rejected_peer_ = false;
  std::string pending_close_reason_;
  std::unique_ptr<asio::steady_timer> flush_timer_;
  std::chrono::steady_clock::time_point header_arrived_{};
  std::chrono::steady_clock::time_point bytes_arrived_{};
  std::uint64_t bytes_received_ = 0;
  std::uint64_t bytes_sent_ = 0;
};

}  // namespace rtc::net
