// net::Connection over loopback TCP: messages of every size arrive whole and in order while the
// connection keeps its payload buffer between messages, and gives a big one back once only
// small messages have come for a while.
#include "protocol/net/connection.h"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace rtc::net {
namespace {

namespace proto = rtc::protocol;

/// A connected pair of TCP sockets on 127.0.0.1, both on `io`.
struct Sockets {
  asio::ip::tcp::socket client, server;
};

Sockets socket_pair(asio::io_context& io) {
  asio::ip::tcp::acceptor acceptor(io, asio::ip::tcp::endpoint(asio::ip::make_address("127.0.0.1"), 0));
  Sockets s{asio::ip::tcp::socket(io), asio::ip::tcp::socket(io)};
  s.client.connect(acceptor.local_endpoint());
  acceptor.accept(s.server);
  return s;
}

/// A connected pair of Connections on 127.0.0.1, both on `io`.
struct Pair {
  std::shared_ptr<Connection> sender, receiver;
};

Pair connect_pair(asio::io_context& io) {
  Sockets s = socket_pair(io);
  Pair pair;
  pair.sender = std::make_shared<Connection>(std::move(s.client), "sender");
  pair.receiver = std::make_shared<Connection>(std::move(s.server), "receiver");
  return pair;
}

/// Bytes whose every position and message are told apart (a stale buffer's bytes would show).
std::vector<std::uint8_t> pattern(std::size_t size, std::uint32_t seed) {
  std::vector<std::uint8_t> bytes(size);
  std::uint32_t x = seed * 2654435761u + 1;
  for (std::uint8_t& b : bytes) {
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    b = static_cast<std::uint8_t>(x);
  }
  return bytes;
}

TEST(Connection, PayloadsOfEverySizeArriveWholeWhileTheBufferIsKeptAndGivenBack) {
  // Each message's payload is ProbeData: a 4-byte length and the bytes.
  const std::size_t big = 3u << 20;
  const int small = Connection::kSmallPayloadsToGiveBack;
  std::vector<std::size_t> sizes = {big};
  for (int i = 0; i < small - 1; ++i) sizes.push_back(10 + i);  // one short of giving it back
  sizes.push_back(big - 5);  // read into the kept buffer, with the last message's bytes in it
  for (int i = 0; i < small; ++i) sizes.push_back(i % 7);  // given back at the last of these
  sizes.insert(sizes.end(), {(5u << 20) / 2, 5u << 20, (5u << 20) - 1, 0, (4u << 20) + 7, 1, proto::kMaxProbe});
  // The buffer each message was read into, as the receiver holds it when the message arrives.
  std::vector<std::size_t> expected_buffer;
  std::size_t buffer = 0;
  int small_in_a_row = 0;
  for (const std::size_t size : sizes) {
    const std::size_t payload = size + 4;
    if (buffer > Connection::kKeptPayloadBytes && payload < buffer / 4) {
      if (++small_in_a_row == small) buffer = small_in_a_row = 0;
    } else {
      small_in_a_row = 0;
    }
    buffer = std::max(buffer, payload);
    expected_buffer.push_back(buffer);
  }
  EXPECT_EQ(expected_buffer[small], big + 4);      // kept through the small messages
  EXPECT_LT(expected_buffer[2 * small], 1u << 20);  // given back

  asio::io_context io;
  Pair pair = connect_pair(io);
  std::vector<std::vector<std::uint8_t>> received;
  std::vector<std::size_t> buffers;
  std::string closed;
  pair.receiver->start(
      [&](proto::Message&& m, std::size_t wire) {
        auto* probe = std::get_if<proto::ProbeData>(&m);
        ASSERT_NE(probe, nullptr);
        EXPECT_EQ(wire, proto::kHeaderSize + 4 + probe->bytes.size());
        received.push_back(std::move(probe->bytes));
        buffers.push_back(pair.receiver->payload_buffer_bytes());
        if (received.size() == sizes.size()) io.stop();
      },
      [&](const std::string& reason) {
        closed = reason;
        io.stop();
      });
  pair.sender->start([](proto::Message&&, std::size_t) {}, [](const std::string&) {});
  for (std::size_t i = 0; i < sizes.size(); ++i) {
    proto::ProbeData probe;
    probe.bytes = pattern(sizes[i], static_cast<std::uint32_t>(i));
    pair.sender->send(probe);
  }
  io.run_for(std::chrono::seconds(30));
  EXPECT_EQ(closed, "");
  ASSERT_EQ(received.size(), sizes.size());
  for (std::size_t i = 0; i < sizes.size(); ++i) {
    EXPECT_EQ(received[i].size(), sizes[i]) << "message " << i;
    EXPECT_TRUE(received[i] == pattern(sizes[i], static_cast<std::uint32_t>(i))) << "message " << i << " differs";
  }
  EXPECT_EQ(buffers, expected_buffer);
  std::uint64_t wire = 0;
  for (const std::size_t size : sizes) wire += proto::kHeaderSize + 4 + size;
  EXPECT_EQ(pair.receiver->bytes_received(), wire);
}

TEST(Connection, ABadPayloadAfterAGoodOneOfTheSameSizeIsStillCaught) {
  // The kept buffer holds the first message's bytes; the second's CRC must be checked against
  // its own bytes, so a corrupted copy of the same size is refused.
  asio::io_context io;
  Sockets sockets = socket_pair(io);
  asio::ip::tcp::socket& client = sockets.client;
  auto receiver = std::make_shared<Connection>(std::move(sockets.server), "peer");
  int messages = 0;
  std::string closed;
  receiver->start([&](proto::Message&&, std::size_t) { ++messages; },
                  [&](const std::string& reason) {
                    closed = reason;
                    io.stop();
                  });
  proto::ProbeData probe;
  probe.bytes = pattern(2u << 20, 7);
  std::vector<std::uint8_t> bytes = proto::encode(probe);
  std::vector<std::uint8_t> bad = bytes;
  bad[bad.size() / 2] ^= 0x40;  // one payload bit: the CRC no longer matches
  bytes.insert(bytes.end(), bad.begin(), bad.end());
  // Written from a thread of its own: 4 MiB may not fit the socket buffers before the receiver
  // reads. The receiver's close ends a write still under way with an error, which is expected.
  std::thread writer([&] {
    asio::error_code ignored;
    asio::write(client, asio::buffer(bytes), ignored);
  });
  io.run_for(std::chrono::seconds(30));
  receiver->close("test over");  // a write still blocked then fails
  writer.join();
  EXPECT_EQ(messages, 1);
  EXPECT_NE(closed.find("bad message from peer"), std::string::npos) << closed;
}

}  // namespace
}  // namespace rtc::net
