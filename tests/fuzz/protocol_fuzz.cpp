// Fuzz target: the wire protocol decoder, every message type (protocol/message.h). The input is
// read twice: as a byte stream the way a connection reads it (headers, CRCs, several messages),
// and as one payload behind a correct header whose type is the first byte, so that mutations
// reach each payload decoder instead of stopping at the CRC. Whatever decodes must encode again
// (the encoder's limits are the decoder's) and decode to the same bytes.
#include <span>
#include <string>

#include "protocol/message.h"
#include "tests/fuzz/fuzz_support.h"

namespace {

using namespace rtc::protocol;
using rtc::fuzz::check;

void expect_round_trip(const Message& m) {
  const std::vector<std::uint8_t> bytes = encode(m);
  const DecodeResult again = decode(bytes);
  check(again.status == DecodeStatus::Complete, type_name(static_cast<std::uint16_t>(type_of(m))) +
                                                    " decoded but its encoding does not: " + again.error);
  check(again.consumed == bytes.size(), "re-decode used " + std::to_string(again.consumed) + " of " +
                                            std::to_string(bytes.size()) + " bytes");
  check(encode(again.message) == bytes, type_name(static_cast<std::uint16_t>(type_of(m))) +
                                            ": encode(decode(encode(m))) differs from encode(m)");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> input(data, size);

  // As a stream: at most 64 messages, each bounded by the input.
  std::size_t at = 0;
  for (int n = 0; n < 64 && at < input.size(); ++n) {
    const DecodeResult r = decode(input.subspan(at));
    if (r.status == DecodeStatus::NeedMore) break;
    if (r.status == DecodeStatus::Bad) {
      check(!r.error.empty(), "Bad without a reason");
      break;
    }
    check(r.consumed >= kHeaderSize && r.consumed <= input.size() - at, "decode consumed bytes it was not given");
    expect_round_trip(r.message);
    at += r.consumed;
  }

  // As one payload of the type named by the first byte (0 and 21 are unknown types).
  if (size >= 1) {
    const auto type = static_cast<std::uint16_t>(data[0] % 22);
    const std::span<const std::uint8_t> payload = input.subspan(1);
    Header header;
    header.version = kVersion;
    header.type = type;
    header.payload_length = static_cast<std::uint32_t>(payload.size());
    header.crc = crc32(payload);
    const PayloadResult r = decode_payload(header, payload);
    if (r.status == DecodeStatus::Complete) {
      check(static_cast<std::uint16_t>(type_of(r.message)) == type, "decoded a different type than the header's");
      expect_round_trip(r.message);
    } else {
      check(r.status == DecodeStatus::Bad && !r.error.empty(), "payload not decoded, without a reason");
    }
  }
  return 0;
}
