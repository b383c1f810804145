// Shared-token authentication and content hashes on OpenSSL: SHA-256, HMAC-SHA256 proofs,
// constant-time comparison, CSPRNG nonces, and token files.
#include "protocol/auth.h"

#include <openssl/crypto.h>
#include <openssl/err.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <openssl/rand.h>
#include <spdlog/spdlog.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <system_error>

#include "common/base/error.h"
#include "common/base/log.h"

namespace rtc::protocol {
namespace {

/// Domain separation: a proof for this protocol can never be a MAC of anything else.
constexpr std::string_view kAuthContext = "rtc-auth-v1";
constexpr std::size_t kMaxToken = 4096;
/// Token files are read up to this many bytes; anything longer is rejected without reading on.
constexpr std::size_t kMaxTokenFile = 64 * 1024;

std::string openssl_error() {
  const unsigned long code = ERR_get_error();
  if (code == 0) return "no OpenSSL error queued";
  char buffer[256];
  ERR_error_string_n(code, buffer, sizeof buffer);
  return buffer;
}

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f'; }

}  // namespace

Digest sha256(std::span<const std::uint8_t> bytes) {
  Digest out{};
  unsigned int length = 0;
  // EVP_Digest only fails on allocation or a broken provider: our failure, not the input's.
  const int ok = EVP_Digest(bytes.data(), bytes.size(), out.data(), &length, EVP_sha256(), nullptr);
  RTC_CHECK(ok == 1 && length == out.size(), "EVP_Digest(SHA-256) failed");
  return out;
}

Digest auth_proof(std::string_view token, const Nonce& nonce) {
  RTC_CHECK(token.size() <= 0x7fffffff, "auth_proof: token longer than HMAC's int key length");
  std::array<std::uint8_t, kAuthContext.size() + sizeof(Nonce)> message{};
  std::memcpy(message.data(), kAuthContext.data(), kAuthContext.size());
  std::memcpy(message.data() + kAuthContext.size(), nonce.data(), nonce.size());
  // A non-null key pointer even for the empty token: some OpenSSL versions reject (nullptr, 0).
  static const unsigned char kNoKey = 0;
  const void* key = token.empty() ? static_cast<const void*>(&kNoKey) : static_cast<const void*>(token.data());
  Digest out{};
  unsigned int length = 0;
  const unsigned char* mac =
      HMAC(EVP_sha256(), key, static_cast<int>(token.size()), message.data(), message.size(), out.data(), &length);
  RTC_CHECK(mac != nullptr && length == out.size(), "HMAC-SHA256 failed");
  return out;
}

bool equal_constant_time(const Digest& a, const Digest& b) { return CRYPTO_memcmp(a.data(), b.data(), a.size()) == 0; }

Nonce random_nonce() {
  Nonce out{};
  if (RAND_bytes(out.data(), static_cast<int>(out.size())) != 1)
    throw Error("random_nonce: RAND_bytes failed: " + openssl_error());
  return out;
}

std::string to_hex(std::span<const std::uint8_t> bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out;
  out.reserve(bytes.size() * 2);
  for (const std::uint8_t b : bytes) {
    out += kDigits[b >> 4];
    out += kDigits[b & 0xf];
  }
  return out;
}

std::string read_token_file(const std::filesystem::path& path) {
  const std::string where = path.string();
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw_at(where, 0, "cannot read token file: it is a directory");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw_at(where, 0, std::string("cannot read token file: ") + std::strerror(errno));
  std::string token(kMaxTokenFile + 1, '\0');
  in.read(token.data(), static_cast<std::streamsize>(token.size()));
  if (in.bad()) throw_at(where, 0, "cannot read token file: read error");
  token.resize(static_cast<std::size_t>(in.gcount()));
  if (token.size() > kMaxTokenFile)
    throw_at(where, 0,
             "token file over " + std::to_string(kMaxTokenFile) + " bytes (a token is at most " +
                 std::to_string(kMaxToken) + ")");
  while (!token.empty() && is_space(token.back())) token.pop_back();
  if (token.empty()) throw_at(where, 0, "token file is empty (or only whitespace)");
  if (token.size() > kMaxToken)
    throw_at(where, 0,
             "token of " + std::to_string(token.size()) + " bytes, over the limit of " + std::to_string(kMaxToken));
  if (token.find('\0') != std::string::npos)
    throw_at(where, 0, "token contains a NUL byte at offset " + std::to_string(token.find('\0')));
  return token;
}

std::string read_token_file_warning_if_weak(const std::string& path) {
  std::string token = read_token_file(path);
  if (const std::string warning = weak_token_warning(token, path); !warning.empty()) spdlog::warn("{}", warning);
  return token;
}

std::string weak_token_warning(const std::string& token, const std::string& path) {
  if (token.size() >= kMinStrongToken) return {};
  return "--token-file " + path + ": the token is " + counted(token.size(), "byte", "bytes") +
         "; anyone who records one handshake can guess a short token offline. Use " + std::to_string(kMinStrongToken) +
         " or more random bytes, e.g. head -c 32 /dev/urandom | od -An -tx1 | tr -d ' \\n' > " + path;
}

}  // namespace rtc::protocol
