// Framed rtc protocol connections over Asio TCP.
#include "protocol/net/connection.h"

#include <algorithm>
#include <charconv>
#include <cstring>
#include <utility>

#include "common/base/error.h"

namespace rtc::net {

std::string peer_name(const asio::ip::tcp::socket& socket) {
  asio::error_code ec;
  const asio::ip::tcp::endpoint ep = socket.remote_endpoint(ec);
  if (ec) return "unknown peer";
  const std::string address = ep.address().to_string();
  return (ep.address().is_v6() ? "[" + address + "]" : address) + ":" + std::to_string(ep.port());
}

HostPort parse_host_port(const std::string& text, const std::string& what) {
  if (text.find("://") != std::string::npos || text.find('/') != std::string::npos) {
    throw Error(what + ": expected HOST:PORT (no scheme or path, e.g. 127.0.0.1:7878), got \"" + text + "\"");
  }
  const std::size_t colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == text.size()) {
    throw Error(what + ": expected HOST:PORT, got \"" + text + "\"");
  }
  HostPort hp;
  hp.host = text.substr(0, colon);
  if (hp.host.size() > 2 && hp.host.front() == '[' && hp.host.back() == ']') hp.host = hp.host.substr(1, hp.host.size() - 2);
  const std::string port = text.substr(colon + 1);
  unsigned value = 0;
  const auto [end, ec] = std::from_chars(port.data(), port.data() + port.size(), value);
  if (ec != std::errc() || end != port.data() + port.size() || value > 65535) {
    throw Error(what + ": bad port \"" + port + "\" in \"" + text + "\" (expected 0-65535)");
  }
  hp.port = static_cast<std::uint16_t>(value);
  return hp;
}

namespace {

void require_tls_1_2(asio::ssl::context& context) {
  context.set_options(asio::ssl::context::default_workarounds | asio::ssl::context::no_sslv2 |
                      asio::ssl::context::no_sslv3 | asio::ssl::context::no_tlsv1 | asio::ssl::context::no_tlsv1_1 |
                      asio::ssl::context::single_dh_use);
}

std::string tls_error(const asio::system_error& e) {
  std::string what = e.code().message();
  return what.empty() ? e.what() : what;
}

}  // namespace

std::shared_ptr<asio::ssl::context> tls_server_context(const std::string& cert_file, const std::string& key_file) {
  auto context = std::make_shared<asio::ssl::context>(asio::ssl::context::tls_server);
  require_tls_1_2(*context);
  try {
    context->use_certificate_chain_file(cert_file);
  } catch (const asio::system_error& e) {
    throw Error("--tls-cert " + cert_file + ": cannot use it as a PEM certificate chain: " + tls_error(e));
  }
  try {
    context->use_private_key_file(key_file, asio::ssl::context::pem);
  } catch (const asio::system_error& e) {
    throw Error("--tls-key " + key_file + ": cannot use it as the PEM private key of --tls-cert: " + tls_error(e));
  }
  return context;
}

std::shared_ptr<asio::ssl::context> tls_client_context(const std::string& ca_file) {
  auto context = std::make_shared<asio::ssl::context>(asio::ssl::context::tls_client);
  require_tls_1_2(*context);
  try {
    context->load_verify_file(ca_file);
  } catch (const asio::system_error& e) {
    throw Error("--tls-ca " + ca_file + ": cannot load it as PEM certificates: " + tls_error(e));
  }
  context->set_verify_mode(asio::ssl::verify_peer | asio::ssl::verify_fail_if_no_peer_cert);
  return context;
}

void async_tls_handshake(std::shared_ptr<TlsStream> stream, asio::ssl::stream_base::handshake_type role,
                         std::chrono::milliseconds timeout, std::function<void(const asio::error_code&)> done) {
  auto timer = std::make_shared<asio::steady_timer>(stream->get_executor(), timeout);
  timer->async_wait([stream](const asio::error_code& ec) {
    if (ec) return;
    asio::error_code ignored;
    stream->next_layer().close(ignored);  // the handshake then fails with operation_aborted
  });
  stream->async_handshake(role, [stream, timer, done = std::move(done)](const asio::error_code& ec) {
    timer->cancel();
    done(ec);
  });
}

bool is_end_of_stream(const asio::error_code& ec) {
  return ec == asio::error::eof || ec == asio::ssl::error::stream_truncated;
}

Connection::Connection(asio::ip::tcp::socket socket, std::string peer)
    : socket_(std::move(socket)), peer_(std::move(peer)) {
  asio::error_code ec;
  socket_.set_option(asio::ip::tcp::no_delay(true), ec);  // tiles are latency-bound at frame ends
}

Connection::Connection(std::shared_ptr<TlsStream> stream, std::string peer)
    : socket_(stream->get_executor()), tls_(std::move(stream)), peer_(std::move(peer)) {
  asio::error_code ec;
  tls_->next_layer().set_option(asio::ip::tcp::no_delay(true), ec);
}

Connection::~Connection() {
  asio::error_code ec;
  tcp().close(ec);
}

void Connection::start(MessageHandler on_message, CloseHandler on_close) {
  on_message_ = std::move(on_message);
  on_close_ = std::move(on_close);
  read_buf_ = std::make_unique_for_overwrite<std::uint8_t[]>(kReadBufferBytes);
  read_more();
}

bool Connection::read_returned(const asio::error_code& ec) {
  reading_ = false;
  if (closed_) return false;
  if (closing_after_flush_) {
    continue_drain(ec);  // what arrived is discarded; an error or the peer's close ends it
    return false;
  }
  return true;
}

void Connection::read_more() {
  if (closed_ || closing_after_flush_) return;
  // What is left is part of one message: it moves to the front, so the rest fits after it.
  if (read_begin_ > 0) {
    std::memmove(read_buf_.get(), read_buf_.get() + read_begin_, read_end_ - read_begin_);
    read_end_ -= read_begin_;
    read_begin_ = 0;
  }
  auto self = shared_from_this();
  reading_ = true;
  auto on_read = [this, self](const asio::error_code& ec, std::size_t n) {
    if (!read_returned(ec)) return;
    ++reads_;
    if (ec) {
      const std::size_t held = read_end_ - read_begin_;
      if (held >= protocol::kHeaderSize) {
        // Part of a message the header of which was accepted (handle_buffered stops short of
        // a whole one only then).
        const protocol::HeaderResult header =
            protocol::parse_header(std::span<const std::uint8_t, protocol::kHeaderSize>(
                read_buf_.get() + read_begin_, protocol::kHeaderSize));
        finish(peer_ + " sent half a " + protocol::type_name(header.header.type) + " message (" +
               std::to_string(header.header.payload_length) + " payload bytes announced): " +
               (is_end_of_stream(ec) ? std::string("connection closed") : ec.message()));
      } else if (held > 0) {
        finish(peer_ + " sent half a message header (" + std::to_string(held) + " of " +
               std::to_string(protocol::kHeaderSize) + " bytes): " +
               (is_end_of_stream(ec) ? std::string("connection closed") : ec.message()));
      } else {
        finish(is_end_of_stream(ec) ? peer_ + " closed the connection" : peer_ + ": " + ec.message());
      }
      return;
    }
    read_at_ = std::chrono::steady_clock::now();
    bytes_arrived_ = read_at_;
    read_end_ += n;
    handle_buffered();
  };
  with_stream([&](auto& stream) {
    stream.async_read_some(asio::buffer(read_buf_.get() + read_end_, kReadBufferBytes - read_end_), std::move(on_read));
  });
}

bool Connection::accept_header(const protocol::HeaderResult& parsed, const std::uint8_t* bytes) {
  if (parsed.status != protocol::DecodeStatus::Complete) {
    std::uint32_t magic = 0;
    std::uint16_t version = 0;
    std::memcpy(&magic, bytes, sizeof magic);
    std::memcpy(&version, bytes + 4, sizeof version);
    const bool version_mismatch = magic == protocol::kMagic && version != protocol::kVersion;
    reject("bad message from " + peer_ + ": " + parsed.error,
           version_mismatch ? protocol::ErrorCode::Version : protocol::ErrorCode::Protocol, parsed.error);
    return false;
  }
  const protocol::Header* header = &parsed.header;
  if (header->payload_length > max_payload_) {
    const std::string why = protocol::type_name(header->type) + " payload of " +
                            std::to_string(header->payload_length) + " bytes exceeds the " +
                            std::to_string(max_payload_) + " allowed at this point";
    reject("bad message from " + peer_ + ": " + why, protocol::ErrorCode::Protocol, why);
    return false;
  }
  return true;
}

void Connection::handle_buffered() {
  // Checked before every message: a handler may close the connection, start a flush before a
  // close (nothing more is handled then), or change max_payload_ for the next header.
  while (!closed_ && !closing_after_flush_) {
    const std::size_t held = read_end_ - read_begin_;
    if (held < protocol::kHeaderSize) break;
    const std::uint8_t* at = read_buf_.get() + read_begin_;
    const protocol::HeaderResult parsed =
        protocol::parse_header(std::span<const std::uint8_t, protocol::kHeaderSize>(at, protocol::kHeaderSize));
    // Before the header is judged: one refused (another version, say) still counts as heard.
    if (!header_pending_) header_arrived_ = read_at_;  // not again when the rest of its message comes
    if (!accept_header(parsed, at)) return;
    const std::size_t wire = protocol::kHeaderSize + parsed.header.payload_length;
    if (wire <= kReadBufferBytes) {
      if (held < wire) {
        header_pending_ = true;  // the rest of it comes with the next read
        break;
      }
      header_pending_ = false;
      read_begin_ += wire;
      note_payload(parsed.header.payload_length);
      if (!deliver(parsed.header, std::span<const std::uint8_t>(at + protocol::kHeaderSize, wire - protocol::kHeaderSize))) {
        return;
      }
      continue;
    }
    // Too big for the read buffer: the part already here starts the payload buffer, the rest is
    // read straight into it.
    header_pending_ = false;
    payload_size_ = parsed.header.payload_length;
    note_payload(payload_size_);
    if (payload_capacity_ < payload_size_) {
      payload_.reset();  // before the new one: never both at once
      payload_ = std::make_unique_for_overwrite<std::uint8_t[]>(payload_size_);
      payload_capacity_ = payload_size_;
    }
    const std::size_t here = held - protocol::kHeaderSize;  // < payload_size_, as wire > the buffer
    std::memcpy(payload_.get(), at + protocol::kHeaderSize, here);
    read_begin_ = read_end_ = 0;
    read_payload_from(parsed.header, here);
    return;
  }
  if (read_begin_ == read_end_) read_begin_ = read_end_ = 0;
  read_more();
}

void Connection::prepare_payload_buffer(std::size_t bytes) {
  if (payload_capacity_ >= bytes) return;
  payload_.reset();  // before the new one: never both at once
  payload_ = std::make_unique_for_overwrite<std::uint8_t[]>(bytes);
  std::memset(payload_.get(), 0, bytes);
  payload_capacity_ = bytes;
  small_payloads_in_a_row_ = 0;
}

void Connection::note_payload(std::size_t size) {
  // A big buffer that only small messages have used for a while (a worker's scene chunks, then
  // tile assignments) is given back. Not after one: heartbeats and marks come between tiles.
  if (payload_capacity_ > kKeptPayloadBytes && size < payload_capacity_ / 4) {
    if (++small_payloads_in_a_row_ >= kSmallPayloadsToGiveBack) {
      payload_.reset();
      payload_capacity_ = 0;
      small_payloads_in_a_row_ = 0;
    }
  } else {
    small_payloads_in_a_row_ = 0;
  }
}

bool Connection::deliver(const protocol::Header& header, std::span<const std::uint8_t> payload) {
  protocol::PayloadResult result = protocol::decode_payload(header, payload);
  if (result.status != protocol::DecodeStatus::Complete) {
    reject("bad message from " + peer_ + ": " + result.error, protocol::ErrorCode::Protocol, result.error);
    return false;
  }
  const std::size_t wire = protocol::kHeaderSize + header.payload_length;
  bytes_received_ += wire;
  on_message_(std::move(result.message), wire);
  return true;
}

void Connection::read_payload_from(protocol::Header header, std::size_t done) {
  if (done == payload_size_) {
    if (deliver(header, std::span<const std::uint8_t>(payload_.get(), payload_size_))) read_more();
    return;
  }
  // Up to the next multiple of the chunk: the part that came with the header leaves `done` just
  // short of one, and reads into the buffer at 64 KiB boundaries after it copy faster (a 1024-pixel
  // float tile's master took 8% longer with every read 16 bytes short of one).
  const std::size_t part = std::min(kReadBufferBytes - done % kReadBufferBytes, payload_size_ - done);
  auto self = shared_from_this();
  reading_ = true;
  auto on_payload = [this, self, header, done, part](const asio::error_code& ec, std::size_t) {
    if (!read_returned(ec)) return;
    ++reads_;
    if (ec) {
      finish(peer_ + " sent half a " + protocol::type_name(header.type) + " message (" +
             std::to_string(header.payload_length) + " payload bytes announced): " +
             (is_end_of_stream(ec) ? std::string("connection closed") : ec.message()));
      return;
    }
    bytes_arrived_ = std::chrono::steady_clock::now();
    read_payload_from(header, done + part);
  };
  with_stream([&](auto& stream) {
    asio::async_read(stream, asio::buffer(payload_.get() + done, part), std::move(on_payload));
  });
}

void Connection::send(const protocol::Message& message) {
  if (closed_ || closing_after_flush_) return;
  send_encoded(protocol::encode(message));
}

void Connection::send_encoded(std::vector<std::uint8_t> bytes) {
  if (closed_ || closing_after_flush_ || bytes.empty()) return;
  const std::size_t cost = bytes.size() + kQueuedMessageOverhead;
  if (queued_bytes_ + cost > max_queued_bytes_) {
    finish(peer_ + " is not reading: " + std::to_string((queued_bytes_ + cost) >> 20) + " MiB queued");
    return;
  }
  queued_bytes_ += cost;
  queue_.push_back(std::move(bytes));
  if (!writing_) schedule_write();
}

void Connection::schedule_write() {
  writing_ = true;
  auto self = shared_from_this();
  asio::post(tcp().get_executor(), [this, self] { write_next(); });
}

void Connection::write_next() {
  if (closed_) return;
  if (queue_.empty()) {
    writing_ = false;
    if (closing_after_flush_) {
      // Our side is done: send FIN, but close only when the peer closes (or the timer fires).
      // Closing with the peer's bytes unread would send it a reset, which can make it fail a
      // write before it reads our last message (a worker then took the master's Goodbye for a
      // lost connection and went on retrying).
      // Over TLS the same TCP half-close, without close_notify: the peer reads it as the end of
      // the stream (is_end_of_stream), and no TLS shutdown exchange can stall the close.
      asio::error_code ec;
      tcp().shutdown(asio::ip::tcp::socket::shutdown_send, ec);
      if (!reading_) drain();
      return;
    }
    if (on_drained_) on_drained_();
    return;
  }
  writing_ = true;
  // The queue's first messages in one write (one system call while the socket takes them all).
  std::vector<asio::const_buffer> buffers;
  std::size_t bytes = 0;
  for (const std::vector<std::uint8_t>& m : queue_) {
    if (buffers.size() == kGatherMessages || (!buffers.empty() && bytes + m.size() > kGatherBytes)) break;
    buffers.emplace_back(asio::buffer(m));
    bytes += m.size();
  }
  writing_count_ = buffers.size();
  ++writes_;
  auto self = shared_from_this();
  auto on_written = [this, self](const asio::error_code& ec, std::size_t n) {
    if (closed_) return;
    if (ec) {
      finish("writing to " + peer_ + ": " + ec.message());
      return;
    }
    bytes_sent_ += n;
    for (std::size_t i = 0; i < writing_count_; ++i) {
      queued_bytes_ -= queue_.front().size() + kQueuedMessageOverhead;
      queue_.pop_front();
    }
    write_next();
  };
  with_stream([&](auto& stream) { asio::async_write(stream, buffers, std::move(on_written)); });
}

void Connection::close(const std::string& reason) { finish(reason); }

void Connection::reject(const std::string& reason, protocol::ErrorCode code, const std::string& text) {
  // Tell the peer why when it can still listen (an old rtc build, a confused client), stop
  // reading, and close once that is sent (bounded by close_after_flush's timeout).
  protocol::ErrorMessage error;
  error.code = code;
  error.text = text.substr(0, protocol::kMaxText);
  send(error);
  close_after_flush(reason);
  if (closed_) return;  // the send failed, and finish() has told the owner
  // The owner hears now, not once the peer has read the Error or the flush has timed out (up
  // to 2 s later, when a master could have finished and logged the close at debug level).
  rejected_peer_ = true;
  tell_owner_closed(reason);
}

void Connection::close_after_flush(const std::string& reason, std::chrono::milliseconds timeout) {
  if (closed_ || closing_after_flush_) return;
  closing_after_flush_ = true;
  pending_close_reason_ = reason;
  flush_timer_ = std::make_unique<asio::steady_timer>(tcp().get_executor(), timeout);
  auto self = shared_from_this();
  flush_timer_->async_wait([this, self](const asio::error_code& ec) {
    if (!ec) finish(pending_close_reason_ + " (peer did not read the last bytes or close in time)");
  });
  if (!writing_) write_next();
}

void Connection::drain() {
  // Reads and discards what the peer still sends until it closes; bounded by the flush timer.
  auto self = shared_from_this();
  reading_ = true;
  auto on_read = [this, self](const asio::error_code& ec, std::size_t) {
    reading_ = false;
    if (closed_) return;
    continue_drain(ec);
  };
  with_stream([&](auto& stream) { stream.async_read_some(asio::buffer(header_buf_), std::move(on_read)); });
}

void Connection::continue_drain(const asio::error_code& ec) {
  // After close_after_flush(): the peer closing (or any read error) ends the connection,
  // anything it still sends is discarded by the next read.
  if (ec) {
    finish(pending_close_reason_);
  } else {
    drain();
  }
}

void Connection::finish(const std::string& reason) {
  if (closed_) return;
  closed_ = true;
  asio::error_code ec;
  tcp().shutdown(asio::ip::tcp::socket::shutdown_both, ec);
  tcp().close(ec);
  if (flush_timer_) flush_timer_->cancel();
  queue_.clear();
  queued_bytes_ = 0;
  on_drained_ = nullptr;
  tell_owner_closed(reason);
}

void Connection::tell_owner_closed(const std::string& reason) {
  // Once: the handler is moved out. It may drop the last outside reference; `self` keeps us
  // alive until it returns.
  auto self = shared_from_this();
  CloseHandler handler = std::move(on_close_);
  on_message_ = nullptr;
  if (handler) handler(reason);
}

}  // namespace rtc::net
