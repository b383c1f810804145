// Little-endian byte writing and bounds-checked reading for wire formats (protocol messages,
// serialized scenes, tile pixels). The reader never throws: it fails stickily, so decoders of
// untrusted bytes can check once at the end and be fuzzed byte by byte.
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace rtc {

static_assert(std::endian::native == std::endian::little, "rtc's wire formats assume a little-endian host");

/// Appends little-endian values to a byte vector. Not thread-safe.
class ByteWriter {
 public:
  ByteWriter() = default;
  explicit ByteWriter(std::vector<std::uint8_t>& out) : out_(&out) {}

  void u8(std::uint8_t v) { out().push_back(v); }
  void u16(std::uint16_t v) { raw(&v, sizeof v); }
  void u32(std::uint32_t v) { raw(&v, sizeof v); }
  void u64(std::uint64_t v) { raw(&v, sizeof v); }
  void i32(std::int32_t v) { raw(&v, sizeof v); }
  void f32(float v) { raw(&v, sizeof v); }
  void f64(double v) { raw(&v, sizeof v); }
  /// u32 length, then the bytes.
  void str(std::string_view s) {
    u32(static_cast<std::uint32_t>(s.size()));
    raw(s.data(), s.size());
  }
  /// u32 length, then the bytes.
  void blob(std::span<const std::uint8_t> b) {
    u32(static_cast<std::uint32_t>(b.size()));
    raw(b.data(), b.size());
  }
  /// The bytes as they are (no length).
  void raw(const void* data, std::size_t n) {
    if (n == 0) return;
    const auto* p = static_cast<const std::uint8_t*>(data);
    out().insert(out().end(), p, p + n);
  }
  /// Overwrites 4 bytes at `offset` (already written), e.g. a length known only later.
  void patch_u32(std::size_t offset, std::uint32_t v) { std::memcpy(out().data() + offset, &v, sizeof v); }

  [[nodiscard]] std::size_t size() const { return out_ ? out_->size() : own_.size(); }
  /// The bytes written (owned storage only; with an external vector read that instead).
  [[nodiscard]] std::vector<std::uint8_t> take() { return std::move(own_); }

 private:
  std::vector<std::uint8_t>& out() { return out_ ? *out_ : own_; }
  std::vector<std::uint8_t>* out_ = nullptr;
  std::vector<std::uint8_t> own_;
};

/// Reads little-endian values from a byte span. Every read checks the bounds; the first failure
/// records a reason ("truncated at byte 17 reading u32 'width'") and every later read returns
/// zero / empty. Never throws, never reads out of bounds. Not thread-safe.
class ByteReader {
 public:
  explicit ByteReader(std::span<const std::uint8_t> bytes) : bytes_(bytes) {}

  std::uint8_t u8(const char* what = "u8") { return scalar<std::uint8_t>(what); }
  std::uint16_t u16(const char* what = "u16") { return scalar<std::uint16_t>(what); }
  std::uint32_t u32(const char* what = "u32") { return scalar<std::uint32_t>(what); }
  std::uint64_t u64(const char* what = "u64") { return scalar<std::uint64_t>(what); }
  std::int32_t i32(const char* what = "i32") { return scalar<std::int32_t>(what); }
  float f32(const char* what = "f32") { return scalar<float>(what); }
  double f64(const char* what = "f64") { return scalar<double>(what); }

  /// A u32-length-prefixed string of at most `max_len` bytes.
  std::string str(std::size_t max_len, const char* what = "string") {
    const std::uint32_t n = u32(what);
    if (!ok_) return {};
    if (n > max_len) return fail(what, "length " + std::to_string(n) + " exceeds the limit " + std::to_string(max_len)), std::string();
    const std::span<const std::uint8_t> b = take(n, what);
    return std::string(reinterpret_cast<const char*>(b.data()), b.size());
  }
  /// A u32-length-prefixed byte string of at most `max_len` bytes (a view into the input).
  std::span<const std::uint8_t> blob(std::size_t max_len, const char* what = "bytes") {
    const std::uint32_t n = u32(what);
    if (!ok_) return {};
    if (n > max_len) return fail(what, "length " + std::to_string(n) + " exceeds the limit " + std::to_string(max_len)), std::span<const std::uint8_t>();
    return take(n, what);
  }
  /// The next `n` bytes as they are (a view into the input).
  std::span<const std::uint8_t> take(std::size_t n, const char* what = "bytes") {
    if (!ok_) return {};
    if (n > remaining()) return fail(what, "needs " + std::to_string(n) + " bytes, " + std::to_string(remaining()) + " left"), std::span<const std::uint8_t>();
    const std::span<const std::uint8_t> b = bytes_.subspan(pos_, n);
    pos_ += n;
    return b;
  }

  /// Records a failure found by the caller's own validation (e.g. a count too large for the
  /// bytes left); keeps the first reason.
  void fail(const char* what, const std::string& reason) {
    if (!ok_) return;
    ok_ = false;
    error_ = std::string(what) + " at byte " + std::to_string(pos_) + ": " + reason;
  }

  [[nodiscard]] bool ok() const { return ok_; }
  [[nodiscard]] const std::string& error() const { return error_; }
  [[nodiscard]] std::size_t position() const { return pos_; }
  [[nodiscard]] std::size_t remaining() const { return bytes_.size() - pos_; }
  /// True when every byte was consumed and nothing failed; otherwise records "N trailing bytes".
  bool finish(const char* what = "message") {
    if (ok_ && remaining() != 0) fail(what, std::to_string(remaining()) + " trailing bytes");
    return ok_;
  }

 private:
  template <class T>
  T scalar(const char* what) {
    if (!ok_) return T{};
    if (sizeof(T) > remaining()) {
      fail(what, "truncated: needs " + std::to_string(sizeof(T)) + " bytes, " + std::to_string(remaining()) + " left");
      return T{};
    }
    T v;
    std::memcpy(&v, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }

  std::span<const std::uint8_t> bytes_;
  std::size_t pos_ = 0;
  bool ok_ = true;
  std::string error_;
};

}  // namespace rtc
