// rtc_protocol: byte-level test vectors for every message, every malformation the decoder must
// reject (with its reason), prefixes, back-to-back framing, seeded random and bit-flip fuzzing,
// and the authentication primitives (known-answer tests) and token files.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <zlib.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <random>
#include <set>
#include <string>
#include <string_view>
#include <type_traits>
#include <variant>
#include <vector>

#include "common/base/error.h"
#include "protocol/auth.h"
#include "protocol/message.h"

namespace rtc::protocol {
namespace {

using ::testing::HasSubstr;
using Bytes = std::vector<std::uint8_t>;

// ---- Building expected bytes by hand. ----

Bytes cat(std::initializer_list<Bytes> parts) {
  Bytes out;
  for (const Bytes& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}
// `n` bytes counting up from `first` (0x00, 0x01, ...): a digest whose byte order shows.
Bytes iota(std::uint8_t first, std::size_t n = 32) {
  Bytes out(n);
  for (std::size_t i = 0; i < n; ++i) out[i] = static_cast<std::uint8_t>(first + i);
  return out;
}
Bytes ascii(std::string_view s) { return Bytes(s.begin(), s.end()); }
Digest digest_iota(std::uint8_t first) {
  Digest d{};
  for (std::size_t i = 0; i < d.size(); ++i) d[i] = static_cast<std::uint8_t>(first + i);
  return d;
}
Bytes payload_of(const Bytes& message) { return Bytes(message.begin() + kHeaderSize, message.end()); }

// A well-formed header (right magic, version, length and CRC) around any payload, so the
// payload decoder sees exactly the bytes a test wants it to see.
Bytes frame(std::uint16_t type, const Bytes& payload) {
  const auto length = static_cast<std::uint32_t>(payload.size());
  const std::uint32_t crc = crc32(payload);
  Bytes out = {'R', 'T', 'C', '1', 0x01, 0x00, static_cast<std::uint8_t>(type), static_cast<std::uint8_t>(type >> 8)};
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(length >> (8 * i)));
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(crc >> (8 * i)));
  out.insert(out.end(), payload.begin(), payload.end());
  return out;
}
Bytes frame(MessageType type, const Bytes& payload) { return frame(static_cast<std::uint16_t>(type), payload); }

// ---- Field-by-field comparison (the structs have no operator==). ----

void expect_same(const Challenge& a, const Challenge& b) {
  EXPECT_EQ(a.nonce, b.nonce);
  EXPECT_EQ(a.auth_required, b.auth_required);
  EXPECT_EQ(a.master_build, b.master_build);
}
void expect_same(const Hello& a, const Hello& b) {
  EXPECT_EQ(a.protocol_version, b.protocol_version);
  EXPECT_EQ(a.cores, b.cores);
  EXPECT_EQ(a.threads, b.threads);
  EXPECT_EQ(a.isa, b.isa);
  EXPECT_EQ(a.build_id, b.build_id);
  EXPECT_EQ(a.name, b.name);
}
void expect_same(const Auth& a, const Auth& b) { EXPECT_EQ(a.proof, b.proof); }
void expect_same(const Welcome& a, const Welcome& b) {
  EXPECT_EQ(a.worker_id, b.worker_id);
  EXPECT_EQ(a.heartbeat_ms, b.heartbeat_ms);
  EXPECT_EQ(a.max_outstanding, b.max_outstanding);
}
void expect_same(const SceneOffer& a, const SceneOffer& b) {
  EXPECT_EQ(a.hash, b.hash);
  EXPECT_EQ(a.size, b.size);
  EXPECT_EQ(a.name, b.name);
}
void expect_same(const SceneRequest& a, const SceneRequest& b) {
  EXPECT_EQ(a.hash, b.hash);
  EXPECT_EQ(a.have, b.have);
}
void expect_same(const SceneChunk& a, const SceneChunk& b) {
  EXPECT_EQ(a.hash, b.hash);
  EXPECT_EQ(a.offset, b.offset);
  EXPECT_EQ(a.bytes, b.bytes);
}
void expect_same(const SceneReady& a, const SceneReady& b) {
  EXPECT_EQ(a.hash, b.hash);
  EXPECT_EQ(a.load_ms, b.load_ms);
}
void expect_same(const FrameSettings& a, const FrameSettings& b) {
  EXPECT_EQ(a.sequence, b.sequence);
  EXPECT_EQ(a.frame, b.frame);
  EXPECT_EQ(a.wire_format, b.wire_format);
  EXPECT_EQ(a.compression, b.compression);
  EXPECT_EQ(a.channels, b.channels);
}
void expect_same(const TileAssign& a, const TileAssign& b) {
  EXPECT_EQ(a.sequence, b.sequence);
  EXPECT_EQ(a.frame, b.frame);
  EXPECT_EQ(a.tile, b.tile);
  EXPECT_EQ(a.x, b.x);
  EXPECT_EQ(a.y, b.y);
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
}
void expect_same(const TileResult& a, const TileResult& b) {
  EXPECT_EQ(a.sequence, b.sequence);
  EXPECT_EQ(a.frame, b.frame);
  EXPECT_EQ(a.tile, b.tile);
  EXPECT_EQ(a.x, b.x);
  EXPECT_EQ(a.y, b.y);
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  EXPECT_EQ(a.wire_format, b.wire_format);
  EXPECT_EQ(a.compression, b.compression);
  EXPECT_EQ(a.channels, b.channels);
  EXPECT_EQ(a.raw_size, b.raw_size);
  EXPECT_EQ(a.render_us, b.render_us);
  EXPECT_EQ(a.primary_rays, b.primary_rays);
  EXPECT_EQ(a.shadow_rays, b.shadow_rays);
  EXPECT_EQ(a.reflection_rays, b.reflection_rays);
  EXPECT_EQ(a.pixels, b.pixels);
}
void expect_same(const Heartbeat& a, const Heartbeat& b) {
  EXPECT_EQ(a.seq, b.seq);
  EXPECT_EQ(a.sent_us, b.sent_us);
}
void expect_same(const HeartbeatAck& a, const HeartbeatAck& b) {
  EXPECT_EQ(a.seq, b.seq);
  EXPECT_EQ(a.sent_us, b.sent_us);
}
void expect_same(const ErrorMessage& a, const ErrorMessage& b) {
  EXPECT_EQ(a.code, b.code);
  EXPECT_EQ(a.text, b.text);
}
void expect_same(const Goodbye& a, const Goodbye& b) { EXPECT_EQ(a.reason, b.reason); }
void expect_same(const ProbeRequest& a, const ProbeRequest& b) { EXPECT_EQ(a.bytes, b.bytes); }
void expect_same(const ProbeData& a, const ProbeData& b) { EXPECT_EQ(a.bytes, b.bytes); }
void expect_same(const FrameEnd& a, const FrameEnd& b) { EXPECT_EQ(a.sequence, b.sequence); }
void expect_same(const MarkGrid& a, const MarkGrid& b) {
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(a.lo[k], b.lo[k]);
    EXPECT_EQ(a.hi[k], b.hi[k]);
    EXPECT_EQ(a.dims[k], b.dims[k]);
  }
}
void expect_same(const TileMarks& a, const TileMarks& b) {
  EXPECT_EQ(a.sequence, b.sequence);
  EXPECT_EQ(a.tile, b.tile);
  EXPECT_EQ(a.shaded, b.shaded);
  EXPECT_EQ(a.path, b.path);
  EXPECT_EQ(a.shadow, b.shadow);
}

void expect_same_message(const Message& a, const Message& b) {
  ASSERT_EQ(a.index(), b.index());
  std::visit([&b](const auto& x) { expect_same(x, std::get<std::decay_t<decltype(x)>>(b)); }, a);
}

// ---- One sample of every type with its payload spelled out byte by byte. ----

struct Vector {
  const char* name;
  Message message;
  Bytes payload;
};

std::vector<Vector> vectors() {
  std::vector<Vector> v;
  v.push_back({"Challenge", Challenge{digest_iota(0x00), true, "m1"},
               cat({iota(0x00),                     // nonce
                    {0x01},                         // auth_required
                    {0x02, 0, 0, 0, 'm', '1'}})});  // master_build
  v.push_back({"Hello", Hello{1, 16, 0x01020304, "avx2", "rtc 0.1.0", "w1"},
               cat({{0x01, 0x00},                             // protocol_version
                    {0x10, 0, 0, 0},                          // cores
                    {0x04, 0x03, 0x02, 0x01},                 // threads
                    {0x04, 0, 0, 0, 'a', 'v', 'x', '2'},      // isa
                    {0x09, 0, 0, 0}, ascii("rtc 0.1.0"),      // build_id
                    {0x02, 0, 0, 0, 'w', '1'}})});            // name
  v.push_back({"Auth", Auth{digest_iota(0x40)}, iota(0x40)});
  v.push_back({"Welcome", Welcome{7, 1000, 4},
               {0x07, 0, 0, 0, 0xe8, 0x03, 0, 0, 0x04, 0, 0, 0}});
  v.push_back({"SceneOffer", SceneOffer{digest_iota(0x80), 0x0000000100000002ull, "cornell"},
               cat({iota(0x80),                                    // hash
                    {0x02, 0, 0, 0, 0x01, 0, 0, 0},                // size
                    {0x07, 0, 0, 0}, ascii("cornell")})});         // name
  v.push_back({"SceneRequest", SceneRequest{digest_iota(0x20), true}, cat({iota(0x20), {0x01}})});
  v.push_back({"SceneRequestNotHave", SceneRequest{digest_iota(0x21), false}, cat({iota(0x21), {0x00}})});
  v.push_back({"SceneChunk", SceneChunk{digest_iota(0x10), 0x1122334455667788ull, {0xde, 0xad, 0xbe, 0xef}},
               cat({iota(0x10),                                          // hash
                    {0x88, 0x77, 0x66, 0x55, 0x44, 0x33, 0x22, 0x11},    // offset
                    {0x04, 0, 0, 0, 0xde, 0xad, 0xbe, 0xef}})});         // bytes
  v.push_back({"SceneReady", SceneReady{digest_iota(0x30), 250}, cat({iota(0x30), {0xfa, 0, 0, 0}})});
  v.push_back({"FrameSettings", FrameSettings{0x01020304, -1, 2, 1, 3},
               {0x04, 0x03, 0x02, 0x01,     // sequence
                0xff, 0xff, 0xff, 0xff,     // frame
                0x02, 0x01, 0x03}});        // wire_format, compression, channels
  v.push_back({"TileAssign", TileAssign{11, 5, 0x102, 32, 64, 32, 16},
               {0x0b, 0, 0, 0, 0x05, 0, 0, 0, 0x02, 0x01, 0, 0, 0x20, 0, 0, 0, 0x40, 0, 0, 0, 0x20, 0, 0, 0,
                0x10, 0, 0, 0}});
  v.push_back({"TileResult",
               TileResult{0x100, 3, 9, 0, 32, 32, 32, 1, 2, 0, 4096, 0x12345, 1024, 0x100000000ull, 7, {1, 2, 3}},
               {0x00, 0x01, 0, 0,                    // sequence
                0x03, 0, 0, 0,                       // frame
                0x09, 0, 0, 0,                       // tile
                0x00, 0, 0, 0,                       // x
                0x20, 0, 0, 0,                       // y
                0x20, 0, 0, 0,                       // width
                0x20, 0, 0, 0,                       // height
                0x01, 0x02, 0x00,                    // wire_format, compression, channels
                0x00, 0x10, 0, 0,                    // raw_size
                0x45, 0x23, 0x01, 0,                 // render_us
                0x00, 0x04, 0, 0, 0, 0, 0, 0,        // primary_rays
                0x00, 0, 0, 0, 0x01, 0, 0, 0,        // shadow_rays
                0x07, 0, 0, 0, 0, 0, 0, 0,           // reflection_rays
                0x03, 0, 0, 0, 0x01, 0x02, 0x03}});  // pixels
  v.push_back({"Heartbeat", Heartbeat{1, 0x0102030405060708ull},
               {0x01, 0, 0, 0, 0, 0, 0, 0, 0x08, 0x07, 0x06, 0x05, 0x04, 0x03, 0x02, 0x01}});
  v.push_back({"HeartbeatAck", HeartbeatAck{2, 0xffffffffffffffffull},
               {0x02, 0, 0, 0, 0, 0, 0, 0, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff}});
  v.push_back({"Error", ErrorMessage{ErrorCode::AuthFailed, "bad token"},
               cat({{0x03, 0x00, 0x09, 0, 0, 0}, ascii("bad token")})});
  v.push_back({"ErrorTimeout", ErrorMessage{ErrorCode::Timeout, "slow"},
               cat({{0x06, 0x00, 0x04, 0, 0, 0}, ascii("slow")})});
  v.push_back({"Goodbye", Goodbye{"bye"}, {0x03, 0, 0, 0, 'b', 'y', 'e'}});
  v.push_back({"GoodbyeEmpty", Goodbye{""}, {0x00, 0, 0, 0}});
  v.push_back({"ProbeRequest", ProbeRequest{1u << 20}, {0x00, 0x00, 0x10, 0x00}});
  v.push_back({"ProbeData", ProbeData{{9, 8, 7}}, {0x03, 0, 0, 0, 0x09, 0x08, 0x07}});
  v.push_back({"FrameEnd", FrameEnd{42}, {0x2a, 0, 0, 0}});
  // 0.5 = 0x3fe0000000000000, 1 = 0x3ff0..., -2 = 0xc000..., 3 = 0x4008...
  // Empty lists: counts 0, then zlib's stream of nothing at level 1 (header 78 01, an empty
  // final block 03 00, Adler-32 of nothing 00 00 00 01).
  v.push_back({"TileMarks", TileMarks{7, 3, true, {}, {}},
               {0x07, 0, 0, 0, 0x03, 0, 0, 0, 0x01, 0, 0, 0, 0, 0, 0, 0, 0, 0x08, 0, 0, 0,
                0x78, 0x01, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01}});
  v.push_back({"MarkGrid", MarkGrid{{0.5, -2.0, 0.5}, {1.0, 3.0, 1.0}, {2, 3, 300}},
               {0, 0, 0, 0, 0, 0, 0xe0, 0x3f, 0, 0, 0, 0, 0, 0, 0x00, 0xc0, 0, 0, 0, 0, 0, 0, 0xe0, 0x3f,
                0, 0, 0, 0, 0, 0, 0xf0, 0x3f, 0, 0, 0, 0, 0, 0, 0x08, 0x40, 0, 0, 0, 0, 0, 0, 0xf0, 0x3f,
                0x02, 0, 0, 0, 0x03, 0, 0, 0, 0x2c, 0x01, 0, 0}});
  return v;
}

DecodeResult decode_bytes(const Bytes& b) { return decode(std::span<const std::uint8_t>(b)); }

// Expects decode(b) to be Bad with a reason containing `what`.
void expect_bad(const Bytes& b, std::string_view what) {
  const DecodeResult r = decode_bytes(b);
  EXPECT_EQ(r.status, DecodeStatus::Bad) << "expected Bad with \"" << what << "\"";
  EXPECT_THAT(r.error, HasSubstr(std::string(what)));
  EXPECT_EQ(r.consumed, 0u);
}

// ---- Test vectors. ----

TEST(MessageEncode, EveryTypeMatchesItsHandWrittenPayload) {
  std::set<std::size_t> types_seen;
  for (const Vector& v : vectors()) {
    SCOPED_TRACE(v.name);
    const Bytes encoded = encode(v.message);
    ASSERT_EQ(encoded.size(), kHeaderSize + v.payload.size());
    EXPECT_EQ(payload_of(encoded), v.payload);
    // The header around it: magic, version, type, length, CRC.
    EXPECT_EQ(encoded, frame(type_of(v.message), v.payload));
    types_seen.insert(v.message.index());
  }
  EXPECT_EQ(types_seen.size(), std::variant_size_v<Message>) << "a message type has no test vector";
}

TEST(MessageEncode, FullHeadersMatchHandWrittenBytes) {
  // CRCs from Python's zlib.crc32 over the payloads above.
  EXPECT_EQ(encode(Challenge{digest_iota(0x00), true, "m1"}),
            cat({{'R', 'T', 'C', '1', 0x01, 0x00, 0x01, 0x00, 0x27, 0, 0, 0, 0x79, 0xe5, 0x6d, 0xa1},
                 iota(0x00), {0x01, 0x02, 0, 0, 0, 'm', '1'}}));
  EXPECT_EQ(encode(Welcome{7, 1000, 4}),
            Bytes({'R', 'T', 'C', '1', 0x01, 0x00, 0x04, 0x00, 0x0c, 0, 0, 0, 0xfe, 0x9c, 0xf2, 0xe1,  //
                   0x07, 0, 0, 0, 0xe8, 0x03, 0, 0, 0x04, 0, 0, 0}));
  EXPECT_EQ(encode(TileAssign{11, 5, 0x102, 32, 64, 32, 16}),
            Bytes({'R', 'T', 'C', '1', 0x01, 0x00, 0x0a, 0x00, 0x1c, 0, 0, 0, 0xce, 0x6c, 0x3d, 0xf4,  //
                   0x0b, 0, 0, 0, 0x05, 0, 0, 0, 0x02, 0x01, 0, 0, 0x20, 0, 0, 0, 0x40, 0, 0, 0, 0x20, 0, 0, 0,
                   0x10, 0, 0, 0}));
  EXPECT_EQ(encode(ErrorMessage{ErrorCode::AuthFailed, "bad token"}),
            cat({{'R', 'T', 'C', '1', 0x01, 0x00, 0x0e, 0x00, 0x0f, 0, 0, 0, 0x97, 0x51, 0xaf, 0xce},
                 {0x03, 0x00, 0x09, 0, 0, 0}, ascii("bad token")}));
  // A Goodbye without a reason is just its u32 length 0.
  EXPECT_EQ(encode(Goodbye{""}), Bytes({'R', 'T', 'C', '1', 0x01, 0x00, 0x0f, 0x00, 0x04, 0, 0, 0,  //
                                        0x1c, 0xdf, 0x44, 0x21, 0x00, 0, 0, 0}));
}

TEST(MessageEncode, EncodeToAppends) {
  Bytes out = {0xaa, 0xbb};
  encode_to(FrameEnd{42}, out);
  encode_to(Heartbeat{1, 2}, out);
  EXPECT_EQ(out, cat({{0xaa, 0xbb}, encode(FrameEnd{42}), encode(Heartbeat{1, 2})}));
}

TEST(MessageDecode, EveryTypeRoundTripsFieldByField) {
  for (const Vector& v : vectors()) {
    SCOPED_TRACE(v.name);
    const Bytes encoded = encode(v.message);
    const DecodeResult r = decode_bytes(encoded);
    ASSERT_EQ(r.status, DecodeStatus::Complete) << r.error;
    EXPECT_EQ(r.consumed, encoded.size());
    EXPECT_EQ(type_of(r.message), type_of(v.message));
    expect_same_message(r.message, v.message);
  }
}

TEST(MessageDecode, HandWrittenBytesDecode) {
  for (const Vector& v : vectors()) {
    SCOPED_TRACE(v.name);
    const DecodeResult r = decode_bytes(frame(type_of(v.message), v.payload));
    ASSERT_EQ(r.status, DecodeStatus::Complete) << r.error;
    expect_same_message(r.message, v.message);
  }
}

TEST(MessageDecode, EveryProperPrefixNeedsMore) {
  for (const Vector& v : vectors()) {
    SCOPED_TRACE(v.name);
    const Bytes encoded = encode(v.message);
    for (std::size_t n = 0; n < encoded.size(); ++n) {
      const DecodeResult r = decode(std::span<const std::uint8_t>(encoded).first(n));
      ASSERT_EQ(r.status, DecodeStatus::NeedMore) << "prefix of " << n << " bytes: " << r.error;
      EXPECT_EQ(r.consumed, 0u);
    }
  }
}

TEST(MessageDecode, BackToBackMessagesDecodeInTurn) {
  const Bytes first = encode(TileAssign{1, 2, 3, 4, 5, 6, 7});
  const Bytes second = encode(Goodbye{"done"});
  Bytes stream = cat({first, second, {'R', 'T'}});
  std::span<const std::uint8_t> rest(stream);

  DecodeResult r = decode(rest);
  ASSERT_EQ(r.status, DecodeStatus::Complete) << r.error;
  EXPECT_EQ(r.consumed, first.size());
  expect_same_message(r.message, TileAssign{1, 2, 3, 4, 5, 6, 7});
  rest = rest.subspan(r.consumed);

  r = decode(rest);
  ASSERT_EQ(r.status, DecodeStatus::Complete) << r.error;
  EXPECT_EQ(r.consumed, second.size());
  expect_same_message(r.message, Goodbye{"done"});
  rest = rest.subspan(r.consumed);

  // The start of a third message.
  EXPECT_EQ(decode(rest).status, DecodeStatus::NeedMore);
}

/// A TileMarks payload with the given counts and zlib-packed bytes (as the encoder lays it out).
Bytes marks_payload(std::uint32_t n, std::uint32_t m, const Bytes& raw, bool pack = true) {
  Bytes packed = raw;
  if (pack) {
    uLongf size = compressBound(static_cast<uLong>(raw.size()));
    packed.resize(size);
    EXPECT_EQ(compress2(packed.data(), &size, raw.data(), static_cast<uLong>(raw.size()), 1), Z_OK);
    packed.resize(size);
  }
  Bytes p = {7, 0, 0, 0, 3, 0, 0, 0, 1};
  for (const std::uint32_t v : {n, m, static_cast<std::uint32_t>(packed.size())}) {
    for (int i = 0; i < 4; ++i) p.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  p.insert(p.end(), packed.begin(), packed.end());
  return p;
}

PayloadResult decode_marks(const Bytes& payload) {
  Header h;
  h.version = kVersion;
  h.type = static_cast<std::uint16_t>(MessageType::TileMarks);
  h.payload_length = static_cast<std::uint32_t>(payload.size());
  h.crc = crc32(payload);
  return decode_payload(h, payload);
}

TEST(MessageTypes, TileMarksRoundTripAndLayout) {
  // Voxels as varint deltas: 5, 300 (delta 295 = 0xa7 0x02), 301 (1); shadow 128 (0x80 0x01),
  // then zlib.
  const TileMarks marks{7, 3, true, {5, 300, 301}, {128}};
  const PayloadResult r = decode_marks(marks_payload(3, 1, {0x05, 0xa7, 0x02, 0x01, 0x80, 0x01}));
  ASSERT_EQ(r.status, DecodeStatus::Complete) << r.error;
  expect_same(std::get<TileMarks>(r.message), marks);
  const Bytes wire = encode(marks);
  const DecodeResult back = decode_bytes(wire);
  ASSERT_EQ(back.status, DecodeStatus::Complete) << back.error;
  expect_same(std::get<TileMarks>(back.message), marks);
  // A big mark list packs to a fraction of its varints.
  TileMarks big{1, 2, false, {}, {}};
  for (std::uint32_t v = 0; v < 20000; v += 3) big.path.push_back(v);
  for (std::uint32_t v = 5; v < 20000; v += 7) big.shadow.push_back(v);
  const Bytes big_wire = encode(big);
  EXPECT_LT(big_wire.size(), 2000u);
  const DecodeResult big_back = decode_bytes(big_wire);
  ASSERT_EQ(big_back.status, DecodeStatus::Complete) << big_back.error;
  expect_same(std::get<TileMarks>(big_back.message), big);
  const DecodeResult empty = decode_bytes(encode(TileMarks{}));
  ASSERT_EQ(empty.status, DecodeStatus::Complete) << empty.error;
}

TEST(MessageTypes, BadMarksAreRejected) {
  // Voxels that do not ascend; a varint past 32 bits; fewer voxels than counted; bytes beyond
  // them; not zlib; a count over the limit.
  for (const Bytes& payload : {marks_payload(2, 0, {0x05, 0x00}), marks_payload(1, 0, {0xff, 0xff, 0xff, 0xff, 0x7f}),
                               marks_payload(3, 0, {0x01, 0x01}), marks_payload(1, 0, {0x01, 0x01}),
                               marks_payload(1, 0, {0x01, 0x02, 0x03}, false),
                               marks_payload(kMaxMarkVoxels + 1, 0, {0x01})}) {
    EXPECT_EQ(decode_marks(payload).status, DecodeStatus::Bad);
  }
  MarkGrid g{{0, 0, 0}, {1, 1, 1}, {4, 0, 4}};
  const Bytes b = encode(g);
  const DecodeResult r = decode_bytes(b);
  EXPECT_EQ(r.status, DecodeStatus::Bad);
  EXPECT_NE(r.error.find("dims[1] is 0"), std::string::npos) << r.error;
}

TEST(MessageTypes, NamesAndTypes) {
  EXPECT_EQ(type_name(11), "TileResult");
  EXPECT_EQ(type_name(14), "Error");
  EXPECT_EQ(type_name(1), "Challenge");
  EXPECT_EQ(type_name(18), "FrameEnd");
  EXPECT_EQ(type_name(0), "unknown type 0");
  EXPECT_EQ(type_name(99), "unknown type 99");
  EXPECT_EQ(type_of(ErrorMessage{}), MessageType::Error);
  EXPECT_EQ(type_of(FrameEnd{}), MessageType::FrameEnd);
  for (const Vector& v : vectors()) {
    const auto type = static_cast<std::uint16_t>(type_of(v.message));
    EXPECT_TRUE(std::string_view(v.name).starts_with(type_name(type))) << v.name;
  }
}

TEST(MessageLimits, FixedSizeTypesHaveExactLimits) {
  EXPECT_EQ(max_payload(static_cast<std::uint16_t>(MessageType::TileAssign)), 28u);
  EXPECT_EQ(max_payload(static_cast<std::uint16_t>(MessageType::Welcome)), 12u);
  EXPECT_EQ(max_payload(static_cast<std::uint16_t>(MessageType::TileResult)), kMaxPayload);
  EXPECT_EQ(max_payload(0), 0u);
  EXPECT_EQ(max_payload(21), 0u);
  EXPECT_EQ(max_payload(0xffff), 0u);
  for (const Message& m : {Message(Auth{}), Message(Welcome{}), Message(SceneRequest{}), Message(SceneReady{}),
                           Message(FrameSettings{}), Message(TileAssign{}), Message(Heartbeat{}),
                           Message(HeartbeatAck{}), Message(ProbeRequest{}), Message(FrameEnd{}),
                           Message(MarkGrid{})}) {
    const auto type = static_cast<std::uint16_t>(type_of(m));
    EXPECT_EQ(max_payload(type), encode(m).size() - kHeaderSize) << type_name(type);
  }
}

// protocol.md is the wire format's reference for other implementations: its header row names the
// range of types and its table every type's name and payload limit, which must be the code's.
TEST(MessageLimits, ProtocolMdTableMatchesTheCode) {
  const std::filesystem::path doc = std::filesystem::path(RTC_TEST_DATA) / "../../../protocol/protocol.md";
  std::ifstream in(doc);
  ASSERT_TRUE(in) << doc;
  const std::uint16_t last = static_cast<std::uint16_t>(std::variant_size_v<Message>);
  std::set<std::uint16_t> documented;
  bool header_row = false;
  for (std::string line; std::getline(in, line);) {
    if (line.find("| type   | message type, 1..") != std::string::npos) {
      header_row = true;
      EXPECT_THAT(line, HasSubstr("1.." + std::to_string(last) + " ")) << "protocol.md's header row";
    }
    // Rows of the type table: "| 7    | SceneChunk    | master -> worker | 1048620 (44 + 1 MiB) |".
    std::vector<std::string> cells;
    for (std::size_t at = line.find('|'); at != std::string::npos;) {
      const std::size_t next = line.find('|', at + 1);
      if (next == std::string::npos) break;
      std::string cell = line.substr(at + 1, next - at - 1);
      cell.erase(0, cell.find_first_not_of(' '));
      cell.erase(cell.find_last_not_of(' ') + 1);
      cells.push_back(cell);
      at = next;
    }
    if (cells.size() != 4 || (cells[2].find("->") == std::string::npos && cells[2] != "either way")) continue;
    if (cells[0].empty() || cells[0].find_first_not_of("0123456789") != std::string::npos) continue;
    const auto type = static_cast<std::uint16_t>(std::stoi(cells[0]));
    documented.insert(type);
    EXPECT_EQ(cells[1], type_name(type)) << "protocol.md, type " << type;
    EXPECT_EQ(cells[3].substr(0, cells[3].find(' ')), std::to_string(max_payload(type)))
        << "protocol.md's limit of " << type_name(type);
  }
  EXPECT_TRUE(header_row) << "protocol.md has no header row naming the types' range";
  for (std::uint16_t type = 1; type <= last; ++type) {
    EXPECT_TRUE(documented.count(type) == 1) << "protocol.md's table lacks type " << type << " (" << type_name(type) << ")";
  }
  EXPECT_EQ(documented.size(), last);
}

TEST(MessageLimits, LargestValidMessageOfEachVariableTypeFitsExactly) {
  const std::string name(kMaxName, 'n');
  const std::string text(kMaxText, 't');
  TileResult big_tile{.sequence = 1, .frame = 2, .width = 64, .height = 64};
  big_tile.pixels.assign(kMaxPayload - 67, 0x5a);
  const std::vector<Message> largest = {
      Challenge{{}, true, name},
      Hello{kVersion, 1, 1, name, name, name},
      SceneOffer{{}, 1, name},
      SceneChunk{{}, 0, Bytes(kMaxSceneChunk, 0x11)},
      ErrorMessage{ErrorCode::Internal, text},
      Goodbye{text},
      ProbeData{Bytes(kMaxProbe, 0x22)},
      big_tile,
  };
  for (const Message& m : largest) {
    const auto type = static_cast<std::uint16_t>(type_of(m));
    SCOPED_TRACE(type_name(type));
    const Bytes encoded = encode(m);
    EXPECT_EQ(encoded.size() - kHeaderSize, max_payload(type));
    const DecodeResult r = decode_bytes(encoded);
    ASSERT_EQ(r.status, DecodeStatus::Complete) << r.error;
    expect_same_message(r.message, m);
  }
}

TEST(MessageLimits, EveryTypeRejectsALengthOverItsLimitFromTheHeaderAlone) {
  const auto last = static_cast<std::uint16_t>(std::variant_size_v<Message>);
  for (std::uint16_t type = 1; type <= last; ++type) {
    SCOPED_TRACE(type_name(type));
    const std::uint32_t limit = max_payload(type);
    ASSERT_GT(limit, 0u);
    Bytes header = frame(type, {});
    // At the limit: a header alone needs more; one byte over: bad at once.
    for (int i = 0; i < 4; ++i) header[8 + i] = static_cast<std::uint8_t>(limit >> (8 * i));
    EXPECT_EQ(decode_bytes(header).status, DecodeStatus::NeedMore);
    for (int i = 0; i < 4; ++i) header[8 + i] = static_cast<std::uint8_t>((limit + 1) >> (8 * i));
    expect_bad(header, type_name(type) + " payload of " + std::to_string(limit + 1) + " bytes exceeds its limit of " +
                           std::to_string(limit));
  }
}

// ---- Malformations: each is Bad with a reason that names what is wrong. ----

TEST(MessageMalformed, BadMagicSaysNotAnRtcPeer) {
  expect_bad(ascii("GET / HTTP/1.1\r\nHost: x\r\n\r\n"), "bad magic 0x20544547 (not an rtc peer?)");
  Bytes b = encode(FrameEnd{1});
  b[3] = '2';
  expect_bad(b, "(not an rtc peer?)");
}

TEST(MessageMalformed, VersionMismatchNamesBothVersions) {
  Bytes b = encode(FrameEnd{1});
  b[4] = 2;
  expect_bad(b, "protocol version 2, this build speaks 1");
  b[4] = 0;
  b[5] = 1;
  expect_bad(b, "protocol version 256, this build speaks 1");
}

TEST(MessageMalformed, UnknownTypeIsBad) {
  expect_bad(frame(99, {}), "unknown message type 99");
  expect_bad(frame(0, {}), "unknown message type 0");
  expect_bad(frame(21, {0, 0, 0, 0}), "unknown message type 21");
}

TEST(MessageMalformed, OverLongPayloadRejectedBeforeItArrives) {
  Bytes header = frame(MessageType::TileAssign, {});
  header[8] = 0xff;  // 99999999 = 0x05f5e0ff
  header[9] = 0xe0;
  header[10] = 0xf5;
  header[11] = 0x05;
  ASSERT_EQ(header.size(), kHeaderSize);
  expect_bad(header, "TileAssign payload of 99999999 bytes exceeds its limit of 28");
  const HeaderResult h = parse_header(header);
  EXPECT_EQ(h.status, DecodeStatus::Bad);
  EXPECT_EQ(h.error, "TileAssign payload of 99999999 bytes exceeds its limit of 28");
  // Over kMaxPayload for the biggest type too.
  Bytes tile_result = frame(MessageType::TileResult, {});
  tile_result[11] = 0x10;  // 256 MiB
  expect_bad(tile_result, "TileResult payload of 268435456 bytes exceeds its limit of 67108864");
}

TEST(MessageMalformed, CrcMismatchIsBad) {
  Bytes b = encode(Welcome{7, 1000, 4});
  b[kHeaderSize + 1] ^= 0x01;
  expect_bad(b, "Welcome: CRC mismatch (header 0xe1f29cfe");
  Bytes c = encode(Welcome{7, 1000, 4});
  c[12] ^= 0x80;  // the CRC field itself
  expect_bad(c, "Welcome: CRC mismatch");
}

TEST(MessageMalformed, TruncatedFieldsNameTheTypeAndField) {
  // TileAssign with the height missing.
  expect_bad(frame(MessageType::TileAssign, Bytes(24, 1)), "TileAssign: height at byte 24: truncated");
  expect_bad(frame(MessageType::Welcome, Bytes(5, 1)), "Welcome: heartbeat_ms at byte 4: truncated");
  expect_bad(frame(MessageType::Auth, Bytes(31, 1)), "Auth: proof at byte 0: needs 32 bytes, 31 left");
  expect_bad(frame(MessageType::Goodbye, {}), "Goodbye: reason at byte 0: truncated");
  expect_bad(frame(MessageType::FrameEnd, {1, 2, 3}), "FrameEnd: sequence at byte 0: truncated");
  // A string whose length says more than is there.
  expect_bad(frame(MessageType::Goodbye, {10, 0, 0, 0, 'a', 'b'}), "Goodbye: reason at byte 4: needs 10 bytes, 2 left");
  // A blob whose length says more than is there.
  expect_bad(frame(MessageType::SceneChunk, cat({iota(0), Bytes(8, 0), {100, 0, 0, 0, 1, 2, 3, 4}})),
             "SceneChunk: bytes at byte 44: needs 100 bytes, 4 left");
  // TileResult missing its pixel blob.
  Bytes tile = payload_of(encode(TileResult{.width = 1, .height = 1}));
  ASSERT_EQ(tile.size(), 67u);
  tile.resize(65);
  expect_bad(frame(MessageType::TileResult, tile), "TileResult: pixels at byte 63: truncated: needs 4 bytes, 2 left");
  // Hello cut inside the build id.
  Bytes hello = payload_of(encode(Hello{kVersion, 4, 4, "sse42", "rtc", "w"}));
  ASSERT_EQ(hello.size(), 31u);
  hello.resize(25);
  expect_bad(frame(MessageType::Hello, hello), "Hello: build_id at byte 23: needs 3 bytes, 2 left");
}

TEST(MessageMalformed, TrailingBytesAreBad) {
  // Fixed-size types: the header's length already gives the extra byte away.
  expect_bad(frame(MessageType::FrameEnd, {1, 0, 0, 0, 9}), "FrameEnd payload of 5 bytes exceeds its limit of 4");
  // Variable-size types: the payload decoder finds bytes after the last field.
  Bytes offer = payload_of(encode(SceneOffer{{}, 10, "s"}));
  offer.push_back(0x2a);
  expect_bad(frame(MessageType::SceneOffer, offer), "SceneOffer: payload at byte 45: 1 trailing bytes");
  Bytes goodbye = payload_of(encode(Goodbye{"x"}));
  goodbye.push_back(0);
  goodbye.push_back(0);
  expect_bad(frame(MessageType::Goodbye, goodbye), "Goodbye: payload at byte 5: 2 trailing bytes");
}

TEST(MessageMalformed, OverLongStringsAreBad) {
  // isa's length prefix says 257, over kMaxName.
  const Bytes hello = cat({{0x01, 0x00, 4, 0, 0, 0, 4, 0, 0, 0}, {0x01, 0x01, 0, 0}, Bytes(20, 'a')});
  expect_bad(frame(MessageType::Hello, hello), "Hello: isa at byte 14: length 257 exceeds the limit 256");
  expect_bad(frame(MessageType::Goodbye, {0x01, 0x10, 0, 0, 'x'}),
             "Goodbye: reason at byte 4: length 4097 exceeds the limit 4096");
  expect_bad(frame(MessageType::Error, {0x01, 0x00, 0xff, 0xff, 0xff, 0xff}),
             "Error: text at byte 6: length 4294967295 exceeds");
  expect_bad(frame(MessageType::Challenge, cat({iota(0), {0x00, 0x01, 0x01, 0, 0}})),
             "Challenge: master_build at byte 37: length 257 exceeds the limit 256");
  expect_bad(frame(MessageType::SceneChunk, cat({iota(0), Bytes(8, 0), {0x01, 0x00, 0x10, 0x00}})),
             "SceneChunk: bytes at byte 44: length 1048577 exceeds the limit 1048576");
  expect_bad(frame(MessageType::ProbeData, {0x01, 0x00, 0x00, 0x01}),
             "ProbeData: bytes at byte 4: length 16777217 exceeds");
}

TEST(MessageMalformed, InvalidBoolBytesAreBad) {
  expect_bad(frame(MessageType::Challenge, cat({iota(0), {0x02}, {0, 0, 0, 0}})),
             "Challenge: auth_required at byte 33: invalid bool byte 2 (must be 0 or 1)");
  expect_bad(frame(MessageType::SceneRequest, cat({iota(0), {0xff}})),
             "SceneRequest: have at byte 33: invalid bool byte 255");
}

TEST(MessageMalformed, HelloWithAnotherProtocolVersionIsBad) {
  const Bytes hello = payload_of(encode(Hello{2, 4, 4, "sse42", "rtc", "w"}));
  EXPECT_EQ(hello[0], 0x02);
  expect_bad(frame(MessageType::Hello, hello), "Hello: protocol_version 2, this build speaks 1");
}

TEST(MessageMalformed, TilesWithZeroSizeAreBad) {
  expect_bad(encode(TileAssign{.sequence = 1, .width = 0, .height = 16}), "TileAssign: width is 0");
  expect_bad(encode(TileAssign{.sequence = 1, .width = 16, .height = 0}), "TileAssign: height is 0");
  expect_bad(encode(TileResult{.sequence = 1, .width = 0, .height = 16}), "TileResult: width is 0");
  expect_bad(encode(TileResult{.sequence = 1, .width = 16, .height = 0}), "TileResult: height is 0");
}

TEST(MessageMalformed, SceneChunkOffsetOverflowIsBad) {
  expect_bad(encode(SceneChunk{{}, 0xffffffffffffffffull, {1, 2, 3, 4}}),
             "SceneChunk: offset 18446744073709551615 + 4 bytes overflows");
  expect_bad(encode(SceneChunk{{}, 0xfffffffffffffffdull, {1, 2, 3, 4}}), "overflows");
  // Ending exactly at 2^64 - 1 is fine.
  EXPECT_EQ(decode_bytes(encode(SceneChunk{{}, 0xfffffffffffffffbull, {1, 2, 3, 4}})).status, DecodeStatus::Complete);
}

TEST(MessageMalformed, UnknownErrorCodesAreBad) {
  expect_bad(frame(MessageType::Error, {0x00, 0x00, 0, 0, 0, 0}), "Error: code at byte 2: unknown error code 0");
  expect_bad(frame(MessageType::Error, {0x07, 0x00, 0, 0, 0, 0}), "Error: code at byte 2: unknown error code 7");
  for (std::uint16_t code = 1; code <= 5; ++code)
    EXPECT_EQ(decode_bytes(frame(MessageType::Error, {static_cast<std::uint8_t>(code), 0, 0, 0, 0, 0})).status,
              DecodeStatus::Complete);
}

TEST(MessageMalformed, ProbeRequestOver16MiBIsBad) {
  expect_bad(frame(MessageType::ProbeRequest, {0x01, 0x00, 0x00, 0x01}),
             "ProbeRequest: bytes at byte 4: asks for 16777217 bytes, over the limit 16777216");
  EXPECT_EQ(decode_bytes(encode(ProbeRequest{kMaxProbe})).status, DecodeStatus::Complete);
}

TEST(MessageMalformed, DecodePayloadChecksItsArguments) {
  const Bytes welcome = encode(Welcome{7, 1000, 4});
  const HeaderResult h = parse_header(welcome);
  ASSERT_EQ(h.status, DecodeStatus::Complete);
  EXPECT_EQ(h.header.version, kVersion);
  EXPECT_EQ(h.header.type, static_cast<std::uint16_t>(MessageType::Welcome));
  EXPECT_EQ(h.header.payload_length, 12u);
  EXPECT_EQ(h.header.crc, 0xe1f29cfeu);
  const Bytes payload = payload_of(welcome);
  EXPECT_EQ(decode_payload(h.header, payload).status, DecodeStatus::Complete);
  const PayloadResult short_payload = decode_payload(h.header, std::span<const std::uint8_t>(payload).first(8));
  EXPECT_EQ(short_payload.status, DecodeStatus::Bad);
  EXPECT_THAT(short_payload.error, HasSubstr("Welcome: payload of 8 bytes, the header says 12"));
  Header unknown = h.header;
  unknown.type = 77;
  EXPECT_THAT(decode_payload(unknown, payload).error, HasSubstr("unknown message type 77"));
  EXPECT_EQ(parse_header(std::span<const std::uint8_t>(welcome).first(15)).status, DecodeStatus::NeedMore);
}

TEST(MessageEncodeDeathTest, FieldsOverTheirLimitAreCallerBugs) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_DEATH((void)encode(Goodbye{std::string(kMaxText + 1, 'x')}), "Goodbye.reason");
  EXPECT_DEATH((void)encode(Hello{kVersion, 1, 1, std::string(kMaxName + 1, 'x'), "", ""}), "Hello.isa");
  EXPECT_DEATH((void)encode(SceneChunk{{}, 0, Bytes(kMaxSceneChunk + 1)}), "SceneChunk.bytes");
  EXPECT_DEATH((void)encode(ProbeData{Bytes(kMaxProbe + 1)}), "ProbeData.bytes");
}

// ---- Fuzzing with fixed seeds: never crash, never throw, only the three outcomes. ----

// A Complete decode must re-encode to exactly the bytes it consumed (the encoding is canonical).
void check_outcome(std::span<const std::uint8_t> bytes, const DecodeResult& r) {
  switch (r.status) {
    case DecodeStatus::Complete: {
      ASSERT_GE(r.consumed, kHeaderSize);
      ASSERT_LE(r.consumed, bytes.size());
      const Bytes again = encode(r.message);
      ASSERT_TRUE(std::equal(again.begin(), again.end(), bytes.begin(), bytes.begin() + r.consumed));
      ASSERT_EQ(again.size(), r.consumed);
      break;
    }
    case DecodeStatus::NeedMore:
      EXPECT_EQ(r.consumed, 0u);
      break;
    case DecodeStatus::Bad:
      EXPECT_EQ(r.consumed, 0u);
      EXPECT_FALSE(r.error.empty());
      break;
  }
}

TEST(MessageFuzz, RandomBytesNeverCrash) {
  constexpr std::uint32_t kSeed = 20240611;
  SCOPED_TRACE("seed " + std::to_string(kSeed));
  std::mt19937 rng(kSeed);
  int complete = 0;
  for (int iteration = 0; iteration < 20000; ++iteration) {
    SCOPED_TRACE("iteration " + std::to_string(iteration));
    // Pure noise fails at the magic; most iterations get a real magic (random header fields)
    // or a whole valid header, so the header checks and payload decoders see noise too.
    const std::uint32_t mode = rng() % 4;
    // 0 and one past the last type (unknown) besides every known one.
    const auto type = static_cast<std::uint16_t>(rng() % (std::variant_size_v<Message> + 2));
    const std::uint32_t limit = max_payload(type);
    const std::size_t length = (rng() % 2 == 0 && limit > 0 && limit <= 64) ? limit : rng() % 160;
    Bytes b(length);
    for (std::uint8_t& x : b) x = static_cast<std::uint8_t>(rng());
    if (mode == 1) {
      b = cat({{'R', 'T', 'C', '1'}, b});
    } else if (mode >= 2) {
      b = frame(type, b);
    }
    const DecodeResult r = decode_bytes(b);
    check_outcome(b, r);
    if (::testing::Test::HasFatalFailure()) return;
    complete += r.status == DecodeStatus::Complete;
  }
  EXPECT_GT(complete, 100) << "the fuzzer rarely reached a payload decoder's success path";
}

TEST(MessageFuzz, BitFlipsAreBadOrRarelyComplete) {
  constexpr std::uint32_t kSeed = 77;
  SCOPED_TRACE("seed " + std::to_string(kSeed));
  std::mt19937 rng(kSeed);
  const std::vector<Vector> samples = vectors();
  int bad = 0;
  int complete = 0;
  for (int iteration = 0; iteration < 20000; ++iteration) {
    SCOPED_TRACE("iteration " + std::to_string(iteration));
    const Vector& v = samples[rng() % samples.size()];
    Bytes b = encode(v.message);
    const int flips = 1 + static_cast<int>(rng() % 3);
    for (int i = 0; i < flips; ++i) b[rng() % b.size()] ^= static_cast<std::uint8_t>(1u << (rng() % 8));
    const DecodeResult r = decode_bytes(b);
    check_outcome(b, r);
    if (::testing::Test::HasFatalFailure()) return;
    if (r.status == DecodeStatus::NeedMore) {
      // Only a flipped length bit may ask for more, and then the header must be valid.
      const HeaderResult h = parse_header(b);
      ASSERT_EQ(h.status, DecodeStatus::Complete);
      ASSERT_GT(kHeaderSize + h.header.payload_length, b.size());
    }
    bad += r.status == DecodeStatus::Bad;
    complete += r.status == DecodeStatus::Complete;
  }
  EXPECT_GT(bad, 19000);
  EXPECT_LT(complete, 500);
}

// ---- Authentication. ----

TEST(Crc32, KnownAnswer) {
  EXPECT_EQ(crc32(ascii("123456789")), 0xcbf43926u);
  EXPECT_EQ(crc32({}), 0u);
}

TEST(Sha256, KnownAnswers) {
  // FIPS 180-2 appendix B.1 and the empty string.
  EXPECT_EQ(to_hex(sha256(ascii("abc"))), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(to_hex(sha256({})), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
}

TEST(AuthProof, MatchesHmacSha256KnownAnswers) {
  // Expected values from Python: hmac.new(token, b"rtc-auth-v1" + nonce, hashlib.sha256).
  EXPECT_EQ(to_hex(auth_proof("Jefe", digest_iota(0x00))),
            "1ac8635ef1a7f8c9f4725c2ee64a63e022037abdf520f1c81da3f60136c550c2");
  EXPECT_EQ(to_hex(auth_proof("Jefe", digest_iota(0x01))),
            "60909b5998a2ed781f19b06aba7b6e8a3e70e17c3c1293413f14f2e8b7603910");
  EXPECT_EQ(to_hex(auth_proof("", digest_iota(0x00))),
            "bc56138e518ed95777917ae4fdec4b8fd057d6a0ca1c069c187769b5fc388063");
  // A key longer than SHA-256's 64-byte block is hashed first (RFC 2104).
  EXPECT_EQ(to_hex(auth_proof(std::string(100, 'a'), digest_iota(0x00))),
            "77b30b9f10ebbd9ecaf221502f12265fe06b83663ed2ea345ba4280a3452ddd7");
}

TEST(AuthProof, DependsOnTokenAndNonce) {
  const Nonce n1 = digest_iota(0x00);
  const Nonce n2 = digest_iota(0x01);
  EXPECT_EQ(auth_proof("secret", n1), auth_proof("secret", n1));
  EXPECT_NE(auth_proof("secret", n1), auth_proof("secret", n2));
  EXPECT_NE(auth_proof("secret", n1), auth_proof("Secret", n1));
  EXPECT_NE(auth_proof("secret", n1), auth_proof("", n1));
  // The token is used as bytes: an embedded NUL is part of it.
  EXPECT_NE(auth_proof(std::string_view("ab\0c", 4), n1), auth_proof("ab", n1));
}

TEST(AuthProof, ConstantTimeEquality) {
  const Digest a = digest_iota(0x00);
  Digest b = a;
  EXPECT_TRUE(equal_constant_time(a, b));
  b[31] ^= 1;
  EXPECT_FALSE(equal_constant_time(a, b));
  b = a;
  b[0] ^= 0x80;
  EXPECT_FALSE(equal_constant_time(a, b));
}

TEST(AuthProof, RandomNoncesDiffer) {
  const Nonce a = random_nonce();
  const Nonce b = random_nonce();
  EXPECT_NE(a, b);
  EXPECT_NE(a, Nonce{});
}

TEST(AuthProof, ToHexIsLowercase) {
  EXPECT_EQ(to_hex(Bytes{0x00, 0xab, 0xff, 0x10}), "00abff10");
  EXPECT_EQ(to_hex(Bytes{}), "");
}

// A fresh directory under the system temp dir, removed afterwards.
class TokenFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("rtc_protocol_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::filesystem::path write(const std::string& name, std::string_view content) {
    const std::filesystem::path path = dir_ / name;
    std::ofstream out(path, std::ios::binary);
    out.write(content.data(), static_cast<std::streamsize>(content.size()));
    return path;
  }
  // The rtc::Error message read_token_file throws for `path` ("" if it does not throw).
  static std::string error_of(const std::filesystem::path& path) {
    try {
      (void)read_token_file(path);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  }

  std::filesystem::path dir_;
};

TEST_F(TokenFile, StripsTrailingWhitespaceOnly) {
  EXPECT_EQ(read_token_file(write("a", "s3cret\n")), "s3cret");
  EXPECT_EQ(read_token_file(write("b", "  two words \t\r\n\n")), "  two words");
  EXPECT_EQ(read_token_file(write("c", "x")), "x");
}

TEST(WeakToken, ShortTokensGetAWarningNamingTheFileAndTheFix) {
  EXPECT_EQ(weak_token_warning(std::string(16, 'k'), "t"), "");
  EXPECT_EQ(weak_token_warning(std::string(64, 'k'), "t"), "");
  const std::string warning = weak_token_warning("abc", "/run/token");
  EXPECT_NE(warning.find("--token-file /run/token: the token is 3 bytes;"), std::string::npos) << warning;
  EXPECT_NE(warning.find("16 or more random bytes"), std::string::npos) << warning;
  EXPECT_NE(weak_token_warning(std::string(15, 'k'), "t"), "");
}

TEST_F(TokenFile, AcceptsExactly4096Bytes) {
  EXPECT_EQ(read_token_file(write("max", std::string(4096, 'k') + "\n")), std::string(4096, 'k'));
}

TEST_F(TokenFile, MissingFileNamesThePath) {
  const std::filesystem::path missing = dir_ / "nope";
  const std::string error = error_of(missing);
  EXPECT_THAT(error, HasSubstr(missing.string() + ": cannot read token file"));
}

TEST_F(TokenFile, DirectoryIsUnreadable) {
  EXPECT_THAT(error_of(dir_), HasSubstr(dir_.string() + ": cannot read token file: it is a directory"));
}

TEST_F(TokenFile, EmptyOrWhitespaceIsAnError) {
  const std::filesystem::path empty = write("empty", "");
  EXPECT_THAT(error_of(empty), HasSubstr(empty.string() + ": token file is empty"));
  const std::filesystem::path blank = write("blank", " \n\t\n");
  EXPECT_THAT(error_of(blank), HasSubstr(blank.string() + ": token file is empty"));
}

TEST_F(TokenFile, OverLongTokenIsAnError) {
  const std::filesystem::path long_token = write("long", std::string(4097, 'k'));
  EXPECT_THAT(error_of(long_token), HasSubstr(long_token.string() + ": token of 4097 bytes, over the limit of 4096"));
  const std::filesystem::path huge = write("huge", std::string(1 << 20, 'k'));
  EXPECT_THAT(error_of(huge), HasSubstr(huge.string() + ": token file over 65536 bytes"));
}

TEST_F(TokenFile, NulByteIsAnError) {
  const std::filesystem::path nul = write("nul", std::string_view("ab\0cd\n", 6));
  EXPECT_THAT(error_of(nul), HasSubstr(nul.string() + ": token contains a NUL byte at offset 2"));
}

}  // namespace
}  // namespace rtc::protocol
