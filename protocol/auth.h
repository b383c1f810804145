// Shared-token authentication and content hashes: the token is never sent; a worker proves it
// with HMAC-SHA256 over the master's random nonce, compared in constant time (OpenSSL).
#pragma once

#include <filesystem>
#include <span>
#include <string>
#include <string_view>

#include "protocol/message.h"

namespace rtc::protocol {

/// SHA-256 of `bytes` (scene content hashes).
[[nodiscard]] Digest sha256(std::span<const std::uint8_t> bytes);
/// HMAC-SHA256(key = token, message = "rtc-auth-v1" || nonce). An empty token gives a proof
/// too (a master without a token accepts any proof).
[[nodiscard]] Digest auth_proof(std::string_view token, const Nonce& nonce);
/// Constant-time comparison (CRYPTO_memcmp): the time does not depend on where they differ.
[[nodiscard]] bool equal_constant_time(const Digest& a, const Digest& b);
/// 32 bytes from OpenSSL's CSPRNG (RAND_bytes); throws rtc::Error if it fails.
[[nodiscard]] Nonce random_nonce();
/// Lowercase hex.
[[nodiscard]] std::string to_hex(std::span<const std::uint8_t> bytes);

/// Reads a token file: the whole file with trailing whitespace (newlines) removed. Throws
/// rtc::Error naming the file for a missing/unreadable file, an empty token, a token over
/// 4096 bytes, or one containing a NUL byte.
[[nodiscard]] std::string read_token_file(const std::filesystem::path& path);

/// Tokens shorter than this many bytes are weak: anyone who records one handshake (the nonce
/// and the proof, in clear without TLS) can try guesses offline at HMAC speed.
inline constexpr std::size_t kMinStrongToken = 16;
/// A warning for a token from `path` shorter than kMinStrongToken bytes ("" for a longer one):
/// the programs log it and go on, since a short token still keeps out a peer that lacks it.
[[nodiscard]] std::string weak_token_warning(const std::string& token, const std::string& path);
/// read_token_file, and weak_token_warning's warning in the log where there is one: what
/// rtc-master and rtc-worker do with --token-file.
[[nodiscard]] std::string read_token_file_warning_if_weak(const std::string& path);

}  // namespace rtc::protocol
