// TextCursor and the number parsers shared by the text loaders.
#include "common/scene/text_cursor.h"

#include <charconv>
#include <cmath>
#include <system_error>

#include "common/base/error.h"

namespace rtc {

namespace {

bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }
bool is_space(char c) { return is_blank(c) || c == '\n'; }

}  // namespace

bool parse_finite_float(std::string_view token, float& out) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  if (token.empty()) return false;
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, out);
  return ec == std::errc() && ptr == end && std::isfinite(out);
}

bool parse_int(std::string_view token, std::int64_t& out) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  if (token.empty()) return false;
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, out);
  return ec == std::errc() && ptr == end;
}

std::string quoted(std::string_view token) {
  std::string out = "\"";
  const std::size_t n = token.size() < 40 ? token.size() : 40;
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<unsigned char>(token[i]);
    out += (c >= 0x20 && c < 0x7f) ? static_cast<char>(c) : '?';
  }
  if (token.size() > n) out += "...";
  out += '"';
  return out;
}

TextCursor::TextCursor(std::string_view text, std::string file, bool hash_comments,
                       std::uint64_t first_line)
    : text_(text), file_(std::move(file)), line_(first_line), hash_comments_(hash_comments) {}

void TextCursor::skip_blanks() {
  while (pos_ < text_.size() && is_blank(text_[pos_])) ++pos_;
  if (hash_comments_ && pos_ < text_.size() && text_[pos_] == '#') {
    while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
  }
}

std::string_view TextCursor::next_token() {
  for (;;) {
    skip_blanks();
    if (pos_ >= text_.size()) return {};
    if (text_[pos_] != '\n') break;
    ++pos_;
    ++line_;
  }
  return next_token_on_line_unchecked();
}

std::string_view TextCursor::peek_token() {
  const std::size_t pos = pos_;
  const std::uint64_t line = line_, token_line = token_line_;
  const std::string_view token = next_token();
  pos_ = pos;
  line_ = line;
  token_line_ = token_line;
  return token;
}

std::string_view TextCursor::next_token_on_line() {
  skip_blanks();
  if (pos_ >= text_.size() || text_[pos_] == '\n') return {};
  return next_token_on_line_unchecked();
}

std::string_view TextCursor::next_token_on_line_unchecked() {
  const std::size_t begin = pos_;
  while (pos_ < text_.size() && !is_space(text_[pos_])) ++pos_;
  token_line_ = line_;
  return text_.substr(begin, pos_ - begin);
}

bool TextCursor::more_on_line() {
  skip_blanks();
  return pos_ < text_.size() && text_[pos_] != '\n';
}

void TextCursor::skip_line() {
  while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
}

std::string_view TextCursor::rest_of_line() {
  while (pos_ < text_.size() && is_blank(text_[pos_])) ++pos_;
  const std::size_t begin = pos_;
  while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
  std::size_t end = pos_;
  while (end > begin && is_blank(text_[end - 1])) --end;
  token_line_ = line_;
  return text_.substr(begin, end - begin);
}

float TextCursor::next_float(std::string_view what) {
  const std::string_view token = next_token();
  // At the end of the file the message names the last line with a token.
  if (token.empty()) fail("unexpected end of file, expected " + std::string(what));
  float value = 0.0f;
  if (!parse_finite_float(token, value)) {
    fail("bad " + std::string(what) + " " + quoted(token) + " (expected a finite number)");
  }
  return value;
}

float TextCursor::next_float_on_line(std::string_view what) {
  const std::string_view token = next_token_on_line();
  if (token.empty()) {
    token_line_ = line_;
    fail("line ends early, expected " + std::string(what));
  }
  float value = 0.0f;
  if (!parse_finite_float(token, value)) {
    fail("bad " + std::string(what) + " " + quoted(token) + " (expected a finite number)");
  }
  return value;
}

std::int64_t TextCursor::next_int(std::string_view what) {
  const std::string_view token = next_token();
  // At the end of the file the message names the last line with a token.
  if (token.empty()) fail("unexpected end of file, expected " + std::string(what));
  std::int64_t value = 0;
  if (!parse_int(token, value))
    fail("bad " + std::string(what) + " " + quoted(token) + " (expected an integer)");
  return value;
}

void TextCursor::fail(std::string_view message) const {
  throw_at(file_, token_line_ == 0 ? line_ : token_line_, message);
}

}  // namespace rtc
