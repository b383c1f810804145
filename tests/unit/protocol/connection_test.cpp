// net::Connection over loopback TCP: messages of every size arrive whole and in order while the
// connection keeps its payload buffer between messages, and gives a big one back once only
// small messages have come for a while; many small messages come in few reads and leave in few
// writes, streams of random messages cut at random places arrive whole and in order, and a
// handler's close or limit applies to the messages already read after its own.
#include "protocol/net/connection.h"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <functional>
#include <memory>
#include <random>
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
    // A message that fits the read buffer is decoded there; only bigger ones use this buffer.
    if (proto::kHeaderSize + payload > Connection::kReadBufferBytes) buffer = std::max(buffer, payload);
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

TEST(Connection, APreparedPayloadBufferTakesTheNextBigMessage) {
  // The master prepares the buffer before it asks for a link probe: the probe is read into it
  // (no new buffer), whole, and the header's and the last byte's arrival times bound its reading.
  asio::io_context io;
  Pair pair = connect_pair(io);
  const std::size_t size = 4u << 20;
  pair.receiver->prepare_payload_buffer(size + 64);
  EXPECT_EQ(pair.receiver->payload_buffer_bytes(), size + 64);
  pair.receiver->prepare_payload_buffer(1000);  // never shrinks it
  EXPECT_EQ(pair.receiver->payload_buffer_bytes(), size + 64);
  std::vector<std::uint8_t> received;
  std::size_t buffer = 0;
  bool ordered = false;
  pair.receiver->start(
      [&](proto::Message&& m, std::size_t) {
        received = std::move(std::get<proto::ProbeData>(m).bytes);
        buffer = pair.receiver->payload_buffer_bytes();
        ordered = pair.receiver->header_arrived() <= pair.receiver->bytes_arrived() &&
                  pair.receiver->bytes_arrived() <= std::chrono::steady_clock::now();
        io.stop();
      },
      [&](const std::string&) { io.stop(); });
  pair.sender->start([](proto::Message&&, std::size_t) {}, [](const std::string&) {});
  proto::ProbeData probe;
  probe.bytes = pattern(size, 3);
  pair.sender->send(probe);
  io.run_for(std::chrono::seconds(30));
  EXPECT_TRUE(received == pattern(size, 3));
  EXPECT_EQ(buffer, size + 64);
  EXPECT_TRUE(ordered);
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

/// `count` Heartbeats (seq 0, 1, ...) encoded back to back, then `tail` appended.
std::vector<std::uint8_t> heartbeats(int count, const std::vector<std::uint8_t>& tail = {}) {
  std::vector<std::uint8_t> bytes;
  for (int i = 0; i < count; ++i) {
    proto::Heartbeat hb;
    hb.seq = static_cast<std::uint64_t>(i);
    const std::vector<std::uint8_t> m = proto::encode(hb);
    bytes.insert(bytes.end(), m.begin(), m.end());
  }
  bytes.insert(bytes.end(), tail.begin(), tail.end());
  return bytes;
}

/// How receive()'s writer cuts the bytes: all in one write, one byte a write, or (any other
/// value, the seed) writes of random sizes from 1 byte to 256 KiB, some after a short pause so
/// that the receiver's reads end at random places.
constexpr std::uint32_t kAllAtOnce = 0, kOneByte = 1;

/// What receive()'s receiver saw.
struct Received {
  std::string closed;       ///< its close reason
  std::uint64_t reads = 0;  ///< Connection::reads()
  bool heard = false;       ///< a header arrived (Connection::header_arrived() was set)
};

/// Runs a receiver Connection over `bytes` written to it from a thread (cut as `writes` says),
/// then the writer closes. `on_message` gets each message and the receiver.
Received receive(const std::vector<std::uint8_t>& bytes, std::uint32_t writes,
                 const std::function<void(proto::Message&&, Connection&)>& on_message) {
  asio::io_context io;
  Sockets sockets = socket_pair(io);
  asio::ip::tcp::socket& client = sockets.client;
  client.set_option(asio::ip::tcp::no_delay(true));
  auto receiver = std::make_shared<Connection>(std::move(sockets.server), "peer");
  Received received;
  receiver->start([&](proto::Message&& m, std::size_t) { on_message(std::move(m), *receiver); },
                  [&](const std::string& reason) {
                    received.closed = reason;
                    io.stop();
                  });
  std::thread writer([&] {
    asio::error_code ec;
    if (writes == kOneByte) {
      for (std::size_t i = 0; i < bytes.size() && !ec; ++i) asio::write(client, asio::buffer(&bytes[i], 1), ec);
    } else if (writes != kAllAtOnce) {
      std::mt19937 rng(writes);
      for (std::size_t at = 0; at < bytes.size() && !ec;) {
        // Sizes spread over every scale: 1 byte to 256 KiB, as often small as large.
        const std::size_t scale = std::size_t{1} << std::uniform_int_distribution<int>(0, 18)(rng);
        const std::size_t n = std::min(bytes.size() - at, std::uniform_int_distribution<std::size_t>(1, scale)(rng));
        asio::write(client, asio::buffer(&bytes[at], n), ec);
        at += n;
        if (rng() % 8 == 0) std::this_thread::sleep_for(std::chrono::microseconds(200));
      }
    } else {
      asio::write(client, asio::buffer(bytes), ec);
    }
    client.shutdown(asio::ip::tcp::socket::shutdown_send, ec);  // the receiver reads the end of the stream
  });
  io.run_for(std::chrono::seconds(30));
  receiver->close("test over");  // a write still blocked then fails
  writer.join();
  received.reads = receiver->reads();
  received.heard = receiver->header_arrived() != std::chrono::steady_clock::time_point{};
  return received;
}

/// Checks messages as they arrive against `sent`, in order; the first that differs is reported.
struct InOrder {
  const std::vector<proto::Message>& sent;
  std::uint32_t seed;
  std::size_t got = 0;
  bool same = true;

  void take(const proto::Message& m) {
    if (got < sent.size() && same && proto::encode(m) != proto::encode(sent[got])) {
      ADD_FAILURE() << "seed " << seed << ": message " << got << " differs";
      same = false;
    }
    ++got;
  }
};

TEST(Connection, ManySmallMessagesComeInFewReadsWholeAndInOrder) {
  // Heartbeats (32 bytes each on the wire), then probes: one bigger than the read buffer that
  // starts in the same read as the last heartbeats, one exactly the read buffer on the wire and
  // one a byte more; then more heartbeats. Written at once: 3,000 heartbeats (94 KiB) first.
  // One byte a write (slow: a system call a byte): 200 heartbeats and the last probe only.
  const std::size_t exact = Connection::kReadBufferBytes - proto::kHeaderSize - 4;  // ProbeData: 4 + bytes
  for (const std::uint32_t writes : {kAllAtOnce, kOneByte}) {
    const bool one_at_a_time = writes == kOneByte;
    const int count = one_at_a_time ? 200 : 3000;
    std::vector<std::size_t> sizes{exact + 1};
    if (!one_at_a_time) sizes = {3 * Connection::kReadBufferBytes + 11, exact, exact + 1};
    std::vector<proto::ProbeData> probes(sizes.size());
    std::vector<std::uint8_t> tail;
    for (std::size_t i = 0; i < sizes.size(); ++i) {
      probes[i].bytes = pattern(sizes[i], static_cast<std::uint32_t>(3 + i));
      const std::vector<std::uint8_t> m = proto::encode(probes[i]);
      tail.insert(tail.end(), m.begin(), m.end());
    }
    const std::vector<std::uint8_t> after = heartbeats(100);
    tail.insert(tail.end(), after.begin(), after.end());
    const std::vector<std::uint8_t> bytes = heartbeats(count, tail);

    std::vector<std::uint64_t> seqs;
    std::size_t probes_seen = 0;
    const Received received = receive(
        bytes, writes,
        [&](proto::Message&& m, Connection&) {
          if (auto* hb = std::get_if<proto::Heartbeat>(&m)) seqs.push_back(hb->seq);
          if (auto* p = std::get_if<proto::ProbeData>(&m)) {
            EXPECT_EQ(seqs.size(), static_cast<std::size_t>(count)) << "the probes come after the first heartbeats";
            ASSERT_LT(probes_seen, probes.size());
            EXPECT_TRUE(p->bytes == probes[probes_seen].bytes) << "probe " << probes_seen << "'s bytes differ";
            ++probes_seen;
          }
        });
    const char* how = one_at_a_time ? "one byte a write" : "one write";
    EXPECT_EQ(received.closed, "peer closed the connection") << how;
    ASSERT_EQ(seqs.size(), static_cast<std::size_t>(count + 100)) << how;
    for (std::size_t i = 0; i < seqs.size(); ++i) {
      ASSERT_EQ(seqs[i], i < static_cast<std::size_t>(count) ? i : i - count) << how << ", message " << i;
    }
    EXPECT_EQ(probes_seen, probes.size()) << how;
    // Written at once, 3,103 messages and 320 KiB of payloads take a few dozen reads at most
    // (64 KiB a read while the socket holds that much); two reads a message (header, payload) would be 6,206.
    if (!one_at_a_time) {
      EXPECT_LT(received.reads, 200u);
    }
  }
}

/// `count` messages of random kinds and sizes: heartbeats, small probes, probes within 64 bytes
/// of the read buffer's size either way, and probes up to 5 read buffers long.
std::vector<proto::Message> random_messages(std::uint32_t seed, int count) {
  std::mt19937 rng(seed);
  std::vector<proto::Message> messages;
  for (int i = 0; i < count; ++i) {
    const unsigned kind = rng() % 8;
    if (kind < 3) {
      proto::Heartbeat hb;
      hb.seq = static_cast<std::uint64_t>(i);
      hb.sent_us = rng();
      messages.emplace_back(hb);
      continue;
    }
    std::size_t size = 0;
    const std::size_t edge = Connection::kReadBufferBytes - proto::kHeaderSize - 4;  // 64 KiB on the wire
    if (kind < 5) size = rng() % 200;
    else if (kind < 7) size = edge - 64 + rng() % 129;
    else size = rng() % (5 * Connection::kReadBufferBytes);
    proto::ProbeData probe;
    probe.bytes = pattern(size, seed * 1000u + static_cast<std::uint32_t>(i));
    messages.emplace_back(std::move(probe));
  }
  return messages;
}

TEST(Connection, RandomStreamsCutAnywhereArriveWholeAndInOrder) {
  // Seeded, so a failure names the seed that shows it again. Per seed: 150 messages (about 4 MB),
  // written in pieces of random sizes with random pauses, so that reads end in headers, in
  // payloads, on the read buffer's edge and past it.
  for (std::uint32_t seed = 2; seed < 14; ++seed) {
    const std::vector<proto::Message> sent = random_messages(seed, 150);
    std::vector<std::uint8_t> bytes;
    for (const proto::Message& m : sent) {
      const std::vector<std::uint8_t> e = proto::encode(m);
      bytes.insert(bytes.end(), e.begin(), e.end());
    }
    InOrder check{sent, seed};
    const Received received = receive(bytes, seed, [&](proto::Message&& m, Connection&) { check.take(m); });
    EXPECT_EQ(received.closed, "peer closed the connection") << "seed " << seed;
    EXPECT_EQ(check.got, sent.size()) << "seed " << seed;
  }
}

TEST(Connection, RandomMessagesQueuedInBurstsLeaveWholeAndInOrder) {
  // The sender's side: bursts of random messages (some over the 1 MiB a gathered write takes)
  // queued from handlers, gathered into writes, received by another Connection.
  for (std::uint32_t seed = 20; seed < 26; ++seed) {
    const std::vector<proto::Message> sent = random_messages(seed, 200);
    asio::io_context io;
    Pair pair = connect_pair(io);
    InOrder check{sent, seed};
    std::string closed;
    pair.receiver->start(
        [&](proto::Message&& m, std::size_t) {
          check.take(m);
          if (check.got == sent.size()) io.stop();
        },
        [&](const std::string& reason) {
          closed = reason;
          io.stop();
        });
    pair.sender->start([](proto::Message&&, std::size_t) {}, [](const std::string&) {});
    std::mt19937 rng(seed);
    std::size_t queued = 0;
    while (queued < sent.size()) {
      const std::size_t burst = std::min(sent.size() - queued, std::size_t{1} + rng() % 100);
      asio::post(io, [&, queued, burst] {
        for (std::size_t i = queued; i < queued + burst; ++i) pair.sender->send(sent[i]);
      });
      queued += burst;
    }
    io.run_for(std::chrono::seconds(30));
    EXPECT_EQ(check.got, sent.size()) << "seed " << seed << (closed.empty() ? "" : ": closed: " + closed);
    EXPECT_EQ(pair.sender->queued_bytes(), 0u) << "seed " << seed;
  }
}

TEST(Connection, AHandlersLimitAndFlushApplyToTheMessagesReadAfterItsOwn) {
  // All in one write, so the receiver holds the later messages when it handles the first.
  proto::ProbeData probe;
  probe.bytes = pattern(1000, 5);
  const std::vector<std::uint8_t> bytes = heartbeats(1, proto::encode(probe));
  int handled = 0;
  std::string closed = receive(bytes, kAllAtOnce, [&](proto::Message&&, Connection& c) {
    ++handled;
    c.set_max_payload(100);  // the probe's 1004 bytes are over it
  }).closed;
  EXPECT_EQ(handled, 1);
  EXPECT_NE(closed.find("bad message from peer: ProbeData payload of 1004 bytes exceeds the 100 allowed"),
            std::string::npos)
      << closed;

  const std::vector<std::uint8_t> five = heartbeats(5);
  handled = 0;
  closed = receive(five, kAllAtOnce, [&](proto::Message&&, Connection& c) {
    if (++handled == 2) c.close_after_flush("done after two");
  }).closed;
  EXPECT_EQ(handled, 2) << "nothing is handled after a close_after_flush";
  EXPECT_EQ(closed, "done after two");
}

TEST(Connection, AStreamEndingInsideAHeaderOrAPayloadIsNamed) {
  std::vector<std::uint8_t> bytes = heartbeats(2);
  bytes.resize(bytes.size() - 22);  // of the second message (16 + 16 bytes) its header's first 10
  int handled = 0;
  std::string closed = receive(bytes, kAllAtOnce, [&](proto::Message&&, Connection&) { ++handled; }).closed;
  EXPECT_EQ(handled, 1);
  EXPECT_EQ(closed, "peer sent half a message header (10 of 16 bytes): connection closed");

  bytes = heartbeats(1);
  bytes.resize(20);  // a small message's header and 4 of its 16 payload bytes: in the read buffer
  closed = receive(bytes, kAllAtOnce, [&](proto::Message&&, Connection&) { ++handled; }).closed;
  EXPECT_EQ(closed, "peer sent half a Heartbeat message (16 payload bytes announced): connection closed");

  // A message bigger than the read buffer, cut in its first read or after it: both are read on
  // into the payload buffer.
  proto::ProbeData probe;
  probe.bytes = pattern(100000, 9);
  for (const std::size_t cut : {std::size_t{20}, std::size_t{70000}}) {
    bytes = proto::encode(probe);
    bytes.resize(cut);
    closed = receive(bytes, kAllAtOnce, [&](proto::Message&&, Connection&) { ++handled; }).closed;
    EXPECT_EQ(closed, "peer sent half a ProbeData message (100004 payload bytes announced): connection closed")
        << "cut at " << cut;
  }
  EXPECT_EQ(handled, 1);
}

TEST(Connection, APeerWhoseFirstHeaderIsRefusedWasStillHeard) {
  // A worker tells "said nothing" from "said something we refuse" by header_arrived(): a
  // header of another protocol version must count as heard before it is refused.
  std::vector<std::uint8_t> bytes = heartbeats(1);
  const std::uint16_t other = proto::kVersion + 1;
  std::memcpy(bytes.data() + 4, &other, sizeof other);  // the version follows the 4-byte magic
  int handled = 0;
  const Received received = receive(bytes, kAllAtOnce, [&](proto::Message&&, Connection&) { ++handled; });
  EXPECT_EQ(handled, 0);
  EXPECT_NE(received.closed.find("bad message from peer"), std::string::npos) << received.closed;
  EXPECT_TRUE(received.heard) << "the refused header was heard";
}

TEST(Connection, MessagesQueuedInOneHandlerLeaveInFewWrites) {
  asio::io_context io;
  Pair pair = connect_pair(io);
  std::vector<std::uint64_t> seqs;
  pair.receiver->start(
      [&](proto::Message&& m, std::size_t) {
        if (auto* hb = std::get_if<proto::Heartbeat>(&m)) seqs.push_back(hb->seq);
        if (seqs.size() == 1000) io.stop();
      },
      [&](const std::string&) { io.stop(); });
  pair.sender->start([](proto::Message&&, std::size_t) {}, [](const std::string&) {});
  bool drained = false;
  pair.sender->set_drained_handler([&] { drained = true; });
  asio::post(io, [&] {
    for (int i = 0; i < 1000; ++i) {
      proto::Heartbeat hb;
      hb.seq = static_cast<std::uint64_t>(i);
      pair.sender->send(hb);
    }
  });
  io.run_for(std::chrono::seconds(30));
  ASSERT_EQ(seqs.size(), 1000u);
  for (std::size_t i = 0; i < seqs.size(); ++i) ASSERT_EQ(seqs[i], i);
  // kGatherMessages a write: 16 writes for 1,000 messages, one each before.
  EXPECT_EQ(pair.sender->writes(), (1000 + Connection::kGatherMessages - 1) / Connection::kGatherMessages);
  EXPECT_EQ(pair.sender->bytes_sent(), 1000u * (proto::kHeaderSize + 16));
  EXPECT_EQ(pair.sender->queued_bytes(), 0u);
  EXPECT_TRUE(drained);
}

TEST(Connection, SmallMessagesToAPeerThatDoesNotReadCountWhatTheyHold) {
  // A peer that reads nothing: the queue's limit is reached after limit / (bytes + overhead)
  // heartbeats, each 32 bytes on the wire (the socket's buffers take some before they fill).
  asio::io_context io;
  Pair pair = connect_pair(io);
  std::string closed;
  pair.sender->start([](proto::Message&&, std::size_t) {}, [&](const std::string& reason) { closed = reason; });
  const std::size_t limit = std::size_t{1} << 20;
  pair.sender->set_max_queued_bytes(limit);
  const std::size_t message = proto::kHeaderSize + 16;
  const std::size_t cost = message + Connection::kQueuedMessageOverhead;
  int sent = 0;
  asio::post(io, [&] {
    for (; sent < 1000000 && pair.sender->is_open(); ++sent) {
      proto::Heartbeat hb;
      hb.seq = static_cast<std::uint64_t>(sent);
      pair.sender->send(hb);
    }
    io.stop();
  });
  io.run_for(std::chrono::seconds(30));
  EXPECT_FALSE(pair.sender->is_open());
  EXPECT_NE(closed.find("is not reading"), std::string::npos) << closed;
  // All sent within one handler: nothing was written yet, so every message stayed queued.
  EXPECT_EQ(static_cast<std::size_t>(sent), limit / cost + 1) << "the message over the limit closes it";
}

}  // namespace
}  // namespace rtc::net
