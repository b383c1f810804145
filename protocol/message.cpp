// rtc's wire protocol: encoding messages and decoding untrusted bytes without throwing. The
// byte layouts are written out in protocol/protocol.md and above each encoder below.
#include "protocol/message.h"

#include <zlib.h>

#include <algorithm>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iterator>
#include <limits>
#include <new>
#include <type_traits>
#include <utility>

#include "common/base/byte_io.h"
#include "common/base/error.h"

namespace rtc::protocol {
namespace {

constexpr std::size_t kDigestSize = 32;
/// Bytes of a u32-length-prefixed string or blob holding at most `n` bytes.
constexpr std::uint32_t prefixed(std::size_t n) { return static_cast<std::uint32_t>(4 + n); }
/// TileResult's fixed fields before the pixel blob's length prefix.
constexpr std::uint32_t kTileResultFixed = 4 + 4 + 4 + 4 * 4 + 3 + 4 + 4 + 3 * 8;
constexpr std::uint32_t kMaxTilePixels = kMaxPayload - kTileResultFixed - 4;
/// TileMarks: sequence, tile, shaded, the two counts, the packed size and the zlib stream of the
/// voxels as LEB128 varint deltas (at most 5 bytes each before compression).
constexpr std::uint32_t kMaxMarkVarintBytes = 2 * 5 * kMaxMarkVoxels;
constexpr std::uint32_t kMaxMarkPacked = kMaxMarkVarintBytes + kMaxMarkVarintBytes / 500 + 64;  // deflate's bound
constexpr std::uint32_t kTileMarksMax = 4 + 4 + 1 + 4 + 4 + 4 + kMaxMarkPacked;
static_assert(kTileMarksMax <= kMaxPayload);

// Message's alternatives are in MessageType order: alternative i is type i + 1.
template <MessageType type, class T>
constexpr bool kAlternativeIs =
    std::is_same_v<std::variant_alternative_t<static_cast<std::size_t>(type) - 1, Message>, T>;
static_assert(kAlternativeIs<MessageType::Challenge, Challenge> && kAlternativeIs<MessageType::Hello, Hello> &&
                  kAlternativeIs<MessageType::Auth, Auth> && kAlternativeIs<MessageType::Welcome, Welcome> &&
                  kAlternativeIs<MessageType::SceneOffer, SceneOffer> &&
                  kAlternativeIs<MessageType::SceneRequest, SceneRequest> &&
                  kAlternativeIs<MessageType::SceneChunk, SceneChunk> &&
                  kAlternativeIs<MessageType::SceneReady, SceneReady> &&
                  kAlternativeIs<MessageType::FrameSettings, FrameSettings> &&
                  kAlternativeIs<MessageType::TileAssign, TileAssign> &&
                  kAlternativeIs<MessageType::TileResult, TileResult> &&
                  kAlternativeIs<MessageType::Heartbeat, Heartbeat> &&
                  kAlternativeIs<MessageType::HeartbeatAck, HeartbeatAck> &&
                  kAlternativeIs<MessageType::Error, ErrorMessage> && kAlternativeIs<MessageType::Goodbye, Goodbye> &&
                  kAlternativeIs<MessageType::ProbeRequest, ProbeRequest> &&
                  kAlternativeIs<MessageType::ProbeData, ProbeData> && kAlternativeIs<MessageType::FrameEnd, FrameEnd> &&
                  kAlternativeIs<MessageType::MarkGrid, MarkGrid> && kAlternativeIs<MessageType::TileMarks, TileMarks>,
              "Message's alternatives must follow MessageType's numbers");

constexpr std::uint16_t kFirstType = 1;
constexpr std::uint16_t kLastType = static_cast<std::uint16_t>(std::variant_size_v<Message>);

// Indexed by type - 1.
constexpr const char* kTypeNames[] = {
    "Challenge",    "Hello",      "Auth",          "Welcome",      "SceneOffer", "SceneRequest",
    "SceneChunk",   "SceneReady", "FrameSettings", "TileAssign",   "TileResult", "Heartbeat",
    "HeartbeatAck", "Error",      "Goodbye",       "ProbeRequest", "ProbeData",  "FrameEnd",
    "MarkGrid",     "TileMarks",
};
static_assert(std::size(kTypeNames) == kLastType);

// Largest payload per type: exact for fixed-size messages, the field limits for the rest.
constexpr std::uint32_t kMaxPayloads[] = {
    kDigestSize + 1 + prefixed(kMaxName),        // Challenge: nonce, auth_required, master_build
    2 + 4 + 4 + 3 * prefixed(kMaxName),          // Hello: version, cores, threads, isa, build_id, name
    kDigestSize,                                 // Auth: proof
    3 * 4,                                       // Welcome
    kDigestSize + 8 + prefixed(kMaxName),        // SceneOffer: hash, size, name
    kDigestSize + 1,                             // SceneRequest: hash, have
    kDigestSize + 8 + prefixed(kMaxSceneChunk),  // SceneChunk: hash, offset, bytes
    kDigestSize + 4,                             // SceneReady: hash, load_ms
    4 + 4 + 3,                                   // FrameSettings
    4 + 4 + 4 + 4 * 4,                           // TileAssign
    kMaxPayload,                                 // TileResult
    8 + 8,                                       // Heartbeat
    8 + 8,                                       // HeartbeatAck
    2 + prefixed(kMaxText),                      // Error: code, text
    prefixed(kMaxText),                          // Goodbye: reason
    4,                                           // ProbeRequest
    prefixed(kMaxProbe),                         // ProbeData
    4,                                           // FrameEnd
    6 * 8 + 3 * 4,                               // MarkGrid: lo, hi, dims
    kTileMarksMax,                               // TileMarks: sequence, tile, shaded, 2 voxel lists
};
static_assert(std::size(kMaxPayloads) == kLastType);
static_assert(kTileResultFixed + 4 + kMaxTilePixels == kMaxPayload);

bool known_type(std::uint16_t type) { return type >= kFirstType && type <= kLastType; }

std::string hex32(std::uint32_t v) {
  char buffer[16];
  std::snprintf(buffer, sizeof buffer, "0x%08" PRIx32, v);
  return buffer;
}

// ---- Encoding: fields in declaration order, little-endian (protocol/protocol.md). ----

void put_digest(ByteWriter& w, const std::array<std::uint8_t, 32>& d) { w.raw(d.data(), d.size()); }
void put_bool(ByteWriter& w, bool b) { w.u8(b ? 1 : 0); }
void put_str(ByteWriter& w, const std::string& s, std::size_t max_len, const char* what) {
  RTC_CHECK(s.size() <= max_len, what);
  w.str(s);
}
void put_blob(ByteWriter& w, const std::vector<std::uint8_t>& b, std::size_t max_len, const char* what) {
  RTC_CHECK(b.size() <= max_len, what);
  w.blob(b);
}

// nonce[32] | auth_required u8 | master_build str
void put(ByteWriter& w, const Challenge& m) {
  put_digest(w, m.nonce);
  put_bool(w, m.auth_required);
  put_str(w, m.master_build, kMaxName, "Challenge.master_build over kMaxName bytes");
}
// protocol_version u16 | cores u32 | threads u32 | isa str | build_id str | name str
void put(ByteWriter& w, const Hello& m) {
  w.u16(m.protocol_version);
  w.u32(m.cores);
  w.u32(m.threads);
  put_str(w, m.isa, kMaxName, "Hello.isa over kMaxName bytes");
  put_str(w, m.build_id, kMaxName, "Hello.build_id over kMaxName bytes");
  put_str(w, m.name, kMaxName, "Hello.name over kMaxName bytes");
}
// proof[32]
void put(ByteWriter& w, const Auth& m) { put_digest(w, m.proof); }
// worker_id u32 | heartbeat_ms u32 | max_outstanding u32
void put(ByteWriter& w, const Welcome& m) {
  w.u32(m.worker_id);
  w.u32(m.heartbeat_ms);
  w.u32(m.max_outstanding);
}
// hash[32] | size u64 | name str
void put(ByteWriter& w, const SceneOffer& m) {
  put_digest(w, m.hash);
  w.u64(m.size);
  put_str(w, m.name, kMaxName, "SceneOffer.name over kMaxName bytes");
}
// hash[32] | have u8
void put(ByteWriter& w, const SceneRequest& m) {
  put_digest(w, m.hash);
  put_bool(w, m.have);
}
// hash[32] | offset u64 | bytes blob
void put(ByteWriter& w, const SceneChunk& m) {
  put_digest(w, m.hash);
  w.u64(m.offset);
  put_blob(w, m.bytes, kMaxSceneChunk, "SceneChunk.bytes over kMaxSceneChunk");
}
// hash[32] | load_ms u32
void put(ByteWriter& w, const SceneReady& m) {
  put_digest(w, m.hash);
  w.u32(m.load_ms);
}
// sequence u32 | frame i32 | wire_format u8 | compression u8 | channels u8
void put(ByteWriter& w, const FrameSettings& m) {
  w.u32(m.sequence);
  w.i32(m.frame);
  w.u8(m.wire_format);
  w.u8(m.compression);
  w.u8(m.channels);
}
// The fields TileAssign and TileResult begin with, in this order:
// sequence u32 | frame i32 | tile u32 | x u32 | y u32 | width u32 | height u32
template <typename Tile>
void put_tile_head(ByteWriter& w, const Tile& m) {
  w.u32(m.sequence);
  w.i32(m.frame);
  w.u32(m.tile);
  w.u32(m.x);
  w.u32(m.y);
  w.u32(m.width);
  w.u32(m.height);
}
template <typename Tile>
void get_tile_head(ByteReader& r, Tile& m) {
  m.sequence = r.u32("sequence");
  m.frame = r.i32("frame");
  m.tile = r.u32("tile");
  m.x = r.u32("x");
  m.y = r.u32("y");
  m.width = r.u32("width");
  m.height = r.u32("height");
}
// sequence u32 | frame i32 | tile u32 | x u32 | y u32 | width u32 | height u32
void put(ByteWriter& w, const TileAssign& m) { put_tile_head(w, m); }
// sequence u32 | frame i32 | tile u32 | x, y, width, height u32 | wire_format, compression,
// channels u8 | raw_size u32 | render_us u32 | primary_rays, shadow_rays, reflection_rays u64 |
// pixels blob
void put(ByteWriter& w, const TileResult& m) {
  put_tile_head(w, m);
  w.u8(m.wire_format);
  w.u8(m.compression);
  w.u8(m.channels);
  w.u32(m.raw_size);
  w.u32(m.render_us);
  w.u64(m.primary_rays);
  w.u64(m.shadow_rays);
  w.u64(m.reflection_rays);
  put_blob(w, m.pixels, kMaxTilePixels, "TileResult.pixels over the payload limit");
}
// seq u64 | sent_us u64
void put(ByteWriter& w, const Heartbeat& m) {
  w.u64(m.seq);
  w.u64(m.sent_us);
}
// seq u64 | sent_us u64
void put(ByteWriter& w, const HeartbeatAck& m) {
  w.u64(m.seq);
  w.u64(m.sent_us);
}
// code u16 | text str
void put(ByteWriter& w, const ErrorMessage& m) {
  w.u16(static_cast<std::uint16_t>(m.code));
  put_str(w, m.text, kMaxText, "ErrorMessage.text over kMaxText bytes");
}
// reason str
void put(ByteWriter& w, const Goodbye& m) { put_str(w, m.reason, kMaxText, "Goodbye.reason over kMaxText bytes"); }
// bytes u32
void put(ByteWriter& w, const ProbeRequest& m) { w.u32(m.bytes); }
// bytes blob
void put(ByteWriter& w, const ProbeData& m) { put_blob(w, m.bytes, kMaxProbe, "ProbeData.bytes over 16 MiB"); }
// sequence u32
void put(ByteWriter& w, const FrameEnd& m) { w.u32(m.sequence); }
// lo f64[3] | hi f64[3] | dims u32[3]
void put(ByteWriter& w, const MarkGrid& m) {
  for (const double v : m.lo) w.f64(v);
  for (const double v : m.hi) w.f64(v);
  for (const std::uint32_t v : m.dims) w.u32(v);
}
void put_varints(std::vector<std::uint8_t>& out, const std::vector<std::uint32_t>& voxels) {
  RTC_CHECK(voxels.size() <= kMaxMarkVoxels, "TileMarks list over kMaxMarkVoxels");
  std::uint32_t last = 0;
  for (const std::uint32_t v : voxels) {
    RTC_CHECK(v >= last, "TileMarks voxels must ascend");
    std::uint32_t d = v - last;
    last = v;
    while (d >= 0x80) {
      out.push_back(static_cast<std::uint8_t>(d | 0x80));
      d >>= 7;
    }
    out.push_back(static_cast<std::uint8_t>(d));
  }
}
// sequence u32 | tile u32 | shaded u8 | path count u32 | shadow count u32 | packed size u32 |
// zlib stream of both lists' varint deltas (mark lists pack several times smaller)
void put(ByteWriter& w, const TileMarks& m) {
  w.u32(m.sequence);
  w.u32(m.tile);
  put_bool(w, m.shaded);
  w.u32(static_cast<std::uint32_t>(m.path.size()));
  w.u32(static_cast<std::uint32_t>(m.shadow.size()));
  std::vector<std::uint8_t> raw;
  put_varints(raw, m.path);
  put_varints(raw, m.shadow);
  uLongf packed_size = compressBound(static_cast<uLong>(raw.size()));
  std::vector<std::uint8_t> packed(packed_size);
  const int rc = compress2(packed.data(), &packed_size, raw.data(), static_cast<uLong>(raw.size()), 1);
  RTC_CHECK(rc == Z_OK && packed_size <= kMaxMarkPacked, "TileMarks: zlib compress2 failed");
  w.u32(static_cast<std::uint32_t>(packed_size));
  w.raw(packed.data(), packed_size);
}

// ---- Decoding: the reader fails stickily; validation below adds what a field must satisfy. ----

void get_digest(ByteReader& r, std::array<std::uint8_t, 32>& d, const char* what) {
  const std::span<const std::uint8_t> b = r.take(d.size(), what);
  if (r.ok()) std::memcpy(d.data(), b.data(), d.size());
}
bool get_bool(ByteReader& r, const char* what) {
  const std::uint8_t v = r.u8(what);
  if (v > 1) r.fail(what, "invalid bool byte " + std::to_string(v) + " (must be 0 or 1)");
  return v == 1;
}
std::vector<std::uint8_t> get_blob(ByteReader& r, std::size_t max_len, const char* what) {
  const std::span<const std::uint8_t> b = r.blob(max_len, what);
  return {b.begin(), b.end()};
}

void get(ByteReader& r, Challenge& m) {
  get_digest(r, m.nonce, "nonce");
  m.auth_required = get_bool(r, "auth_required");
  m.master_build = r.str(kMaxName, "master_build");
}
void get(ByteReader& r, Hello& m) {
  m.protocol_version = r.u16("protocol_version");
  m.cores = r.u32("cores");
  m.threads = r.u32("threads");
  m.isa = r.str(kMaxName, "isa");
  m.build_id = r.str(kMaxName, "build_id");
  m.name = r.str(kMaxName, "name");
}
void get(ByteReader& r, Auth& m) { get_digest(r, m.proof, "proof"); }
void get(ByteReader& r, Welcome& m) {
  m.worker_id = r.u32("worker_id");
  m.heartbeat_ms = r.u32("heartbeat_ms");
  m.max_outstanding = r.u32("max_outstanding");
}
void get(ByteReader& r, SceneOffer& m) {
  get_digest(r, m.hash, "hash");
  m.size = r.u64("size");
  m.name = r.str(kMaxName, "name");
}
void get(ByteReader& r, SceneRequest& m) {
  get_digest(r, m.hash, "hash");
  m.have = get_bool(r, "have");
}
void get(ByteReader& r, SceneChunk& m) {
  get_digest(r, m.hash, "hash");
  m.offset = r.u64("offset");
  m.bytes = get_blob(r, kMaxSceneChunk, "bytes");
}
void get(ByteReader& r, SceneReady& m) {
  get_digest(r, m.hash, "hash");
  m.load_ms = r.u32("load_ms");
}
void get(ByteReader& r, FrameSettings& m) {
  m.sequence = r.u32("sequence");
  m.frame = r.i32("frame");
  m.wire_format = r.u8("wire_format");
  m.compression = r.u8("compression");
  m.channels = r.u8("channels");
}
void get(ByteReader& r, TileAssign& m) { get_tile_head(r, m); }
void get(ByteReader& r, TileResult& m) {
  get_tile_head(r, m);
  m.wire_format = r.u8("wire_format");
  m.compression = r.u8("compression");
  m.channels = r.u8("channels");
  m.raw_size = r.u32("raw_size");
  m.render_us = r.u32("render_us");
  m.primary_rays = r.u64("primary_rays");
  m.shadow_rays = r.u64("shadow_rays");
  m.reflection_rays = r.u64("reflection_rays");
  m.pixels = get_blob(r, kMaxTilePixels, "pixels");
}
void get(ByteReader& r, Heartbeat& m) {
  m.seq = r.u64("seq");
  m.sent_us = r.u64("sent_us");
}
void get(ByteReader& r, HeartbeatAck& m) {
  m.seq = r.u64("seq");
  m.sent_us = r.u64("sent_us");
}
void get(ByteReader& r, ErrorMessage& m) {
  const std::uint16_t code = r.u16("code");
  if (code < static_cast<std::uint16_t>(ErrorCode::Protocol) || code > static_cast<std::uint16_t>(ErrorCode::Timeout))
    r.fail("code", "unknown error code " + std::to_string(code));
  m.code = static_cast<ErrorCode>(code);
  m.text = r.str(kMaxText, "text");
}
void get(ByteReader& r, Goodbye& m) { m.reason = r.str(kMaxText, "reason"); }
void get(ByteReader& r, ProbeRequest& m) {
  m.bytes = r.u32("bytes");
  if (m.bytes > kMaxProbe)
    r.fail("bytes", "asks for " + std::to_string(m.bytes) + " bytes, over the limit " + std::to_string(kMaxProbe));
}
void get(ByteReader& r, ProbeData& m) { m.bytes = get_blob(r, kMaxProbe, "bytes"); }
void get(ByteReader& r, FrameEnd& m) { m.sequence = r.u32("sequence"); }
void get(ByteReader& r, MarkGrid& m) {
  for (double& v : m.lo) v = r.f64("lo");
  for (double& v : m.hi) v = r.f64("hi");
  for (std::uint32_t& v : m.dims) v = r.u32("dims");
}
void get(ByteReader& r, TileMarks& m) {
  m.sequence = r.u32("sequence");
  m.tile = r.u32("tile");
  m.shaded = get_bool(r, "shaded");
  const std::uint32_t counts[2] = {r.u32("path count"), r.u32("shadow count")};
  const std::uint32_t packed_size = r.u32("packed size");
  if (!r.ok()) return;
  if (counts[0] > kMaxMarkVoxels || counts[1] > kMaxMarkVoxels) {
    r.fail("path count", "voxel counts " + std::to_string(counts[0]) + " and " + std::to_string(counts[1]) +
                             " exceed the limit " + std::to_string(kMaxMarkVoxels));
    return;
  }
  const std::span<const std::uint8_t> packed = r.take(packed_size, "packed voxels");
  if (!r.ok()) return;
  // At most 5 bytes a voxel unpacked (and deflate expands at most ~1032:1): a stream that
  // inflates further is refused, not followed.
  const std::uint64_t limit =
      std::min<std::uint64_t>(5ull * (std::uint64_t{counts[0]} + counts[1]), 1032ull * packed_size + 64);
  std::vector<std::uint8_t> raw(static_cast<std::size_t>(limit) + 1);
  uLongf raw_size = static_cast<uLongf>(raw.size());
  const int rc = uncompress(raw.data(), &raw_size, packed.data(), static_cast<uLong>(packed.size()));
  if (rc != Z_OK || raw_size > limit) {
    r.fail("packed voxels", rc == Z_OK || rc == Z_BUF_ERROR ? "unpacks to more bytes than the counts allow"
                                                           : "not a zlib stream (zlib error " + std::to_string(rc) + ")");
    return;
  }
  std::size_t pos = 0;
  for (int list = 0; list < 2; ++list) {
    std::vector<std::uint32_t>& out = list == 0 ? m.path : m.shadow;
    out.reserve(counts[list]);
    std::uint64_t value = 0;
    for (std::uint32_t i = 0; i < counts[list]; ++i) {
      std::uint64_t d = 0;
      for (int shift = 0;; shift += 7) {
        if (pos >= raw_size || shift > 28) {
          r.fail("packed voxels", pos >= raw_size ? "fewer voxels than counted" : "varint longer than 5 bytes");
          return;
        }
        const std::uint8_t byte = raw[pos++];
        d |= static_cast<std::uint64_t>(byte & 0x7f) << shift;
        if ((byte & 0x80) == 0) break;
      }
      value += d;
      if (value > 0xffffffffu) {
        r.fail("packed voxels", "voxel index over 32 bits");
        return;
      }
      out.push_back(static_cast<std::uint32_t>(value));
    }
  }
  if (pos != raw_size) r.fail("packed voxels", std::to_string(raw_size - pos) + " bytes beyond the counted voxels");
}

// What a field must satisfy beyond its bytes; "" when the message is valid.
template <class T>
std::string validate(const T&) {
  return {};
}
std::string validate(const Hello& m) {
  if (m.protocol_version != kVersion)
    return "protocol_version " + std::to_string(m.protocol_version) + ", this build speaks " + std::to_string(kVersion);
  return {};
}
std::string validate_size(std::uint32_t width, std::uint32_t height) {
  if (width == 0) return "width is 0";
  if (height == 0) return "height is 0";
  return {};
}
std::string validate(const TileAssign& m) { return validate_size(m.width, m.height); }
std::string validate(const MarkGrid& m) {
  const bool off = m.dims[0] == 0 && m.dims[1] == 0 && m.dims[2] == 0;
  std::uint64_t voxels = 1;
  for (int k = 0; k < 3; ++k) {
    if (off) break;
    if (m.dims[k] == 0) return "dims[" + std::to_string(k) + "] is 0";
    voxels *= m.dims[k];
    if (voxels > kMaxMarkVoxels) return "more than " + std::to_string(kMaxMarkVoxels) + " voxels";
    if (!std::isfinite(m.lo[k]) || !std::isfinite(m.hi[k]) || !(m.lo[k] < m.hi[k]))
      return "bounds on axis " + std::to_string(k) + " are not a finite interval";
  }
  return {};
}
std::string validate(const TileMarks& m) {
  for (const auto* list : {&m.path, &m.shadow}) {
    for (std::size_t i = 1; i < list->size(); ++i) {
      if ((*list)[i] <= (*list)[i - 1]) return "voxels do not ascend";
    }
  }
  return {};
}
std::string validate(const TileResult& m) { return validate_size(m.width, m.height); }
std::string validate(const SceneChunk& m) {
  if (m.offset > std::numeric_limits<std::uint64_t>::max() - m.bytes.size())
    return "offset " + std::to_string(m.offset) + " + " + std::to_string(m.bytes.size()) + " bytes overflows";
  return {};
}

// Decodes the payload of Message's alternative `I` (type I + 1).
template <std::size_t I>
PayloadResult decode_as(std::span<const std::uint8_t> payload) {
  PayloadResult result;
  const char* name = kTypeNames[I];
  ByteReader r(payload);
  std::variant_alternative_t<I, Message> m;
  get(r, m);
  r.finish("payload");
  if (!r.ok()) {
    result.error = std::string(name) + ": " + r.error();
    return result;
  }
  if (std::string problem = validate(m); !problem.empty()) {
    result.error = std::string(name) + ": " + problem;
    return result;
  }
  result.status = DecodeStatus::Complete;
  result.message = std::move(m);
  return result;
}

using PayloadDecoder = PayloadResult (*)(std::span<const std::uint8_t>);
template <std::size_t... I>
constexpr std::array<PayloadDecoder, sizeof...(I)> make_decoders(std::index_sequence<I...>) {
  return {&decode_as<I>...};
}
constexpr auto kDecoders = make_decoders(std::make_index_sequence<std::variant_size_v<Message>>());

}  // namespace

MessageType type_of(const Message& m) { return static_cast<MessageType>(m.index() + 1); }

std::string type_name(std::uint16_t type) {
  if (!known_type(type)) return "unknown type " + std::to_string(type);
  return kTypeNames[type - 1];
}

std::uint32_t max_payload(std::uint16_t type) { return known_type(type) ? kMaxPayloads[type - 1] : 0; }

std::uint32_t crc32(std::span<const std::uint8_t> bytes) {
  // zlib takes uInt lengths; feed large spans in pieces.
  uLong crc = ::crc32(0L, Z_NULL, 0);
  const std::uint8_t* p = bytes.data();
  std::size_t left = bytes.size();
  while (left > 0) {
    const uInt n = static_cast<uInt>(std::min<std::size_t>(left, 1u << 30));
    crc = ::crc32(crc, p, n);
    p += n;
    left -= n;
  }
  return static_cast<std::uint32_t>(crc);
}

// magic u32 | version u16 | type u16 | payload length u32 | crc32(payload) u32 | payload
void encode_to(const Message& m, std::vector<std::uint8_t>& out) {
  const std::size_t start = out.size();
  const auto type = static_cast<std::uint16_t>(type_of(m));
  ByteWriter w(out);
  w.u32(kMagic);
  w.u16(kVersion);
  w.u16(type);
  w.u32(0);  // payload length, patched below
  w.u32(0);  // CRC, patched below
  std::visit([&w](const auto& msg) { put(w, msg); }, m);
  const std::size_t length = out.size() - start - kHeaderSize;
  RTC_CHECK(length <= max_payload(type), "encoded payload over its type's limit");
  w.patch_u32(start + 8, static_cast<std::uint32_t>(length));
  w.patch_u32(start + 12, crc32(std::span<const std::uint8_t>(out).subspan(start + kHeaderSize)));
}

std::vector<std::uint8_t> encode(const Message& m) {
  std::vector<std::uint8_t> out;
  encode_to(m, out);
  return out;
}

HeaderResult parse_header(std::span<const std::uint8_t> bytes) {
  HeaderResult result;
  if (bytes.size() < kHeaderSize) return result;
  ByteReader r(bytes.first(kHeaderSize));
  const std::uint32_t magic = r.u32("magic");
  result.header.version = r.u16("version");
  result.header.type = r.u16("type");
  result.header.payload_length = r.u32("payload length");
  result.header.crc = r.u32("crc");
  result.status = DecodeStatus::Bad;
  if (magic != kMagic) {
    result.error = "bad magic " + hex32(magic) + " (not an rtc peer?)";
  } else if (result.header.version != kVersion) {
    result.error =
        "protocol version " + std::to_string(result.header.version) + ", this build speaks " + std::to_string(kVersion);
  } else if (!known_type(result.header.type)) {
    result.error = "unknown message type " + std::to_string(result.header.type);
  } else if (result.header.payload_length > max_payload(result.header.type)) {
    result.error = type_name(result.header.type) + " payload of " + std::to_string(result.header.payload_length) +
                   " bytes exceeds its limit of " + std::to_string(max_payload(result.header.type));
  } else {
    result.status = DecodeStatus::Complete;
  }
  return result;
}

PayloadResult decode_payload(const Header& header, std::span<const std::uint8_t> payload) {
  PayloadResult result;
  if (!known_type(header.type)) {
    result.error = "unknown message type " + std::to_string(header.type);
    return result;
  }
  const std::string name = type_name(header.type);
  if (payload.size() != header.payload_length) {
    result.error = name + ": payload of " + std::to_string(payload.size()) + " bytes, the header says " +
                   std::to_string(header.payload_length);
    return result;
  }
  if (payload.size() > max_payload(header.type)) {
    result.error = name + " payload of " + std::to_string(payload.size()) + " bytes exceeds its limit of " +
                   std::to_string(max_payload(header.type));
    return result;
  }
  const std::uint32_t crc = crc32(payload);
  if (crc != header.crc) {
    result.error = name + ": CRC mismatch (header " + hex32(header.crc) + ", payload " + hex32(crc) + ")";
    return result;
  }
  try {
    return kDecoders[header.type - 1](payload);
  } catch (const std::bad_alloc&) {
    // Payloads are bounded by max_payload(), so this is the machine running out, not the peer lying.
    result = PayloadResult{};
    result.error = name + ": out of memory decoding " + std::to_string(payload.size()) + " bytes";
    return result;
  }
}

DecodeResult decode(std::span<const std::uint8_t> bytes) {
  DecodeResult result;
  HeaderResult header = parse_header(bytes);
  if (header.status != DecodeStatus::Complete) {
    result.status = header.status;
    result.error = std::move(header.error);
    return result;
  }
  const std::size_t total = kHeaderSize + header.header.payload_length;
  if (bytes.size() < total) return result;  // NeedMore
  PayloadResult payload = decode_payload(header.header, bytes.subspan(kHeaderSize, header.header.payload_length));
  result.status = payload.status;
  result.error = std::move(payload.error);
  if (payload.status == DecodeStatus::Complete) {
    result.message = std::move(payload.message);
    result.consumed = total;
  }
  return result;
}

}  // namespace rtc::protocol
