// rtc's wire protocol between master and workers: a fixed 16-byte header and typed payloads.
// Knows bytes, not scenes or pixels (those arrive as opaque blobs made by scene/serialize and
// image/pixel_format). Every byte is written out in protocol/protocol.md.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace rtc::protocol {

/// "RTC1" as it appears on the wire (bytes 'R' 'T' 'C' '1', read as a little-endian u32).
inline constexpr std::uint32_t kMagic = 0x31435452u;
inline constexpr std::uint16_t kVersion = 1;
/// magic u32 | version u16 | type u16 | payload length u32 | CRC-32 of the payload u32
/// (CRC-32/ISO-HDLC, zlib's crc32, the same as Python's zlib.crc32).
inline constexpr std::size_t kHeaderSize = 16;
/// No payload of any type may exceed this (the per-type limits in max_payload() are smaller).
inline constexpr std::uint32_t kMaxPayload = 64u << 20;
/// Scene chunks carry at most this many scene bytes.
inline constexpr std::uint32_t kMaxSceneChunk = 1u << 20;
/// Limits on strings in messages.
inline constexpr std::size_t kMaxName = 256;
inline constexpr std::size_t kMaxText = 4096;
/// ProbeRequest.bytes and ProbeData.bytes are at most this (16 MiB).
inline constexpr std::uint32_t kMaxProbe = 16u << 20;

using Digest = std::array<std::uint8_t, 32>;  ///< SHA-256 or HMAC-SHA256
using Nonce = std::array<std::uint8_t, 32>;

enum class MessageType : std::uint16_t {
  Challenge = 1,      ///< master -> worker, first message on a connection
  Hello = 2,          ///< worker -> master, answer to Challenge
  Auth = 3,           ///< worker -> master, right after Hello
  Welcome = 4,        ///< master -> worker, authentication passed
  SceneOffer = 5,     ///< master -> worker
  SceneRequest = 6,   ///< worker -> master, answer to SceneOffer
  SceneChunk = 7,     ///< master -> worker
  SceneReady = 8,     ///< worker -> master, scene decoded and usable
  FrameSettings = 9,  ///< master -> worker, before the first tile of a frame
  TileAssign = 10,    ///< master -> worker
  TileResult = 11,    ///< worker -> master
  Heartbeat = 12,     ///< either way
  HeartbeatAck = 13,  ///< answer to Heartbeat, echoing it
  Error = 14,         ///< either way, then the sender closes
  Goodbye = 15,       ///< either way, then the sender closes
  ProbeRequest = 16,  ///< master -> worker: send me this many bytes (link measurement)
  ProbeData = 17,     ///< worker -> master
  FrameEnd = 18,      ///< master -> worker: the frame is complete, drop its state
  MarkGrid = 19,      ///< master -> worker: record temporal-coherence marks on this grid
  TileMarks = 20,     ///< worker -> master, right before a TileResult: the voxels its rays crossed
};

struct Challenge {
  Nonce nonce{};
  bool auth_required = false;
  std::string master_build;  ///< at most kMaxName bytes
};
struct Hello {
  std::uint16_t protocol_version = kVersion;
  std::uint32_t cores = 0;    ///< hardware threads of the worker's machine
  std::uint32_t threads = 0;  ///< render threads it will use
  std::string isa;            ///< kernel ISA in use, e.g. "avx2"; at most kMaxName
  std::string build_id;       ///< e.g. "rtc 0.1.0 (g++ 12.2.0, Release)"; at most kMaxName
  std::string name;           ///< host name or --name; at most kMaxName
};
struct Auth {
  Digest proof{};  ///< auth_proof(token, challenge nonce), see protocol/auth.h
};
struct Welcome {
  std::uint32_t worker_id = 0;
  std::uint32_t heartbeat_ms = 0;       ///< the master sends a Heartbeat this often
  std::uint32_t max_outstanding = 0;    ///< tiles the master keeps assigned to this worker
};
struct SceneOffer {
  Digest hash{};            ///< SHA-256 of the serialized scene
  std::uint64_t size = 0;   ///< serialized scene bytes
  std::string name;         ///< at most kMaxName
};
struct SceneRequest {
  Digest hash{};
  bool have = false;  ///< true: the worker has this scene already, send no chunks
};
struct SceneChunk {
  Digest hash{};
  std::uint64_t offset = 0;
  std::vector<std::uint8_t> bytes;  ///< at most kMaxSceneChunk
};
struct SceneReady {
  Digest hash{};
  std::uint32_t load_ms = 0;  ///< time to decode (and, if any, transfer) on the worker
};
struct FrameSettings {
  /// The master's frame sequence number: unique per rendered frame (with --loop the same
  /// scene frame is rendered again under a new sequence number).
  std::uint32_t sequence = 0;
  std::int32_t frame = 0;  ///< scene frame (animation time)
  std::uint8_t wire_format = 0;  ///< image/pixel_format's WireFormat value
  std::uint8_t compression = 0;  ///< image/pixel_format's Compression value
  std::uint8_t channels = 0;     ///< image/pixel_format's TileChannels bits (depth, normal)
};
struct TileAssign {
  std::uint32_t sequence = 0;  ///< FrameSettings::sequence
  std::int32_t frame = 0;
  std::uint32_t tile = 0;  ///< index of the tile in its frame
  std::uint32_t x = 0, y = 0, width = 0, height = 0;
};
struct TileResult {
  std::uint32_t sequence = 0;
  std::int32_t frame = 0;
  std::uint32_t tile = 0;
  std::uint32_t x = 0, y = 0, width = 0, height = 0;
  std::uint8_t wire_format = 0;
  std::uint8_t compression = 0;
  std::uint8_t channels = 0;
  std::uint32_t raw_size = 0;    ///< pixel bytes before compression
  std::uint32_t render_us = 0;   ///< time the worker spent tracing the tile
  std::uint64_t primary_rays = 0, shadow_rays = 0, reflection_rays = 0;
  std::vector<std::uint8_t> pixels;  ///< in wire_format, compressed per `compression`
};
struct Heartbeat {
  std::uint64_t seq = 0;
  std::uint64_t sent_us = 0;  ///< sender's steady clock
};
struct HeartbeatAck {
  std::uint64_t seq = 0;
  std::uint64_t sent_us = 0;  ///< echoed from the Heartbeat
};
enum class ErrorCode : std::uint16_t {
  Protocol = 1,      ///< malformed or unexpected message
  Version = 2,       ///< protocol version mismatch
  AuthFailed = 3,    ///< wrong token
  SceneInvalid = 4,  ///< the scene bytes did not decode or hash
  Internal = 5,      ///< the sender failed (e.g. out of memory)
  Timeout = 6,       ///< a handshake step took too long; the peer may try again
};
struct ErrorMessage {
  ErrorCode code = ErrorCode::Protocol;
  std::string text;  ///< at most kMaxText
};
struct Goodbye {
  std::string reason;  ///< at most kMaxText
};
struct ProbeRequest {
  std::uint32_t bytes = 0;  ///< at most 16 MiB
};
struct ProbeData {
  std::vector<std::uint8_t> bytes;  ///< at most 16 MiB
};
struct FrameEnd {
  std::uint32_t sequence = 0;
};

/// Largest voxel count of a mark grid and of each list in TileMarks.
inline constexpr std::uint32_t kMaxMarkVoxels = 1u << 21;

/// Object-space temporal coherence (common/render/temporal.h): from now on the worker records,
/// for every tile, which voxels of this grid its rays crossed and sends them in a TileMarks
/// before the tile's TileResult. A grid with dims 0 stops the recording.
struct MarkGrid {
  double lo[3] = {0, 0, 0};
  double hi[3] = {0, 0, 0};
  std::uint32_t dims[3] = {0, 0, 0};
};
struct TileMarks {
  std::uint32_t sequence = 0;
  std::uint32_t tile = 0;
  bool shaded = false;                ///< some hit was shaded with the lights
  std::vector<std::uint32_t> path;    ///< voxels crossed by primary and reflection rays, ascending
  std::vector<std::uint32_t> shadow;  ///< voxels crossed by shadow rays, ascending
};

using Message = std::variant<Challenge, Hello, Auth, Welcome, SceneOffer, SceneRequest, SceneChunk, SceneReady,
                             FrameSettings, TileAssign, TileResult, Heartbeat, HeartbeatAck, ErrorMessage, Goodbye,
                             ProbeRequest, ProbeData, FrameEnd, MarkGrid, TileMarks>;

[[nodiscard]] MessageType type_of(const Message& m);
/// "TileResult", or "unknown type 99".
[[nodiscard]] std::string type_name(std::uint16_t type);
/// Largest payload accepted for a known type (0 for an unknown one).
[[nodiscard]] std::uint32_t max_payload(std::uint16_t type);

/// The whole message on the wire: header + payload. Throws nothing; a field beyond its limit
/// (a string too long, a chunk too big) is a caller bug (RTC_CHECK).
[[nodiscard]] std::vector<std::uint8_t> encode(const Message& m);
/// Appends the encoded message to `out` (avoids a copy for big payloads).
void encode_to(const Message& m, std::vector<std::uint8_t>& out);

struct Header {
  std::uint16_t version = 0;
  std::uint16_t type = 0;
  std::uint32_t payload_length = 0;
  std::uint32_t crc = 0;
};

enum class DecodeStatus { Complete, NeedMore, Bad };

/// Checks the first kHeaderSize bytes: magic, version, known type, length within the type's
/// limit. Bad with a reason such as "bad magic 0x00474554 (not an rtc peer?)",
/// "protocol version 2, this build speaks 1", "unknown message type 99",
/// "TileAssign payload of 99999999 bytes exceeds its limit of 28". NeedMore when fewer than
/// kHeaderSize bytes are given. Never throws.
struct HeaderResult {
  DecodeStatus status = DecodeStatus::NeedMore;
  Header header;
  std::string error;
};
[[nodiscard]] HeaderResult parse_header(std::span<const std::uint8_t> bytes);

/// Checks the payload against the header's CRC and decodes it. Bad with a reason naming the
/// message type and the field ("TileResult: pixels at byte 52: truncated ..."); never throws.
struct PayloadResult {
  DecodeStatus status = DecodeStatus::Bad;  ///< Complete or Bad
  Message message;
  std::string error;
};
[[nodiscard]] PayloadResult decode_payload(const Header& header, std::span<const std::uint8_t> payload);

/// Decodes one message from the start of `bytes` (header and payload): Complete with the
/// number of bytes it used, NeedMore when the message is not all there yet, Bad with a reason.
/// Never throws, never reads past `bytes`; for tests, fuzzers and stream readers.
struct DecodeResult {
  DecodeStatus status = DecodeStatus::NeedMore;
  Message message;
  std::size_t consumed = 0;
  std::string error;
};
[[nodiscard]] DecodeResult decode(std::span<const std::uint8_t> bytes);

/// CRC-32/ISO-HDLC (zlib's crc32).
[[nodiscard]] std::uint32_t crc32(std::span<const std::uint8_t> bytes);

}  // namespace rtc::protocol
