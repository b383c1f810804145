// Walking text formats (OBJ, MTL, NFF, ASCII PLY) token by token,
// with line numbers for messages.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace rtc {

/// Walks `text` token by token. Tokens are separated by blanks (space, tab, CR, VT, FF) and
/// newlines; with comments enabled, '#' starts a comment up to the end of the line. Every
/// error it throws reads "<file>:<line>: <message>". Does not own `text`.
class TextCursor {
 public:
  /// `first_line` numbers the first line of `text` (for text that starts inside a file).
  TextCursor(std::string_view text, std::string file, bool hash_comments = true,
             std::uint64_t first_line = 1);

  /// Next token, crossing line ends; empty at the end of the text.
  std::string_view next_token();
  /// The token next_token() would return, without consuming it.
  std::string_view peek_token();
  /// Next token on the current line (the line of the last token); empty when the line ends.
  std::string_view next_token_on_line();
  /// True when the current line holds another token.
  [[nodiscard]] bool more_on_line();
  /// Skips the rest of the current line.
  void skip_line();
  /// The rest of the current line without leading and trailing blanks (names with spaces).
  std::string_view rest_of_line();

  /// Next token (crossing lines) as a finite float; `what` names it in the message.
  float next_float(std::string_view what);
  /// Next token on the current line as a finite float.
  float next_float_on_line(std::string_view what);
  /// Next token (crossing lines) as an integer.
  std::int64_t next_int(std::string_view what);

  /// Line of the last token returned (1-based; 0 before the first).
  [[nodiscard]] std::uint64_t line() const { return token_line_; }
  [[nodiscard]] const std::string& file() const { return file_; }
  /// Byte offset just past the last token.
  [[nodiscard]] std::size_t offset() const { return pos_; }
  [[noreturn]] void fail(std::string_view message) const;

 private:
  void skip_blanks();
  std::string_view next_token_on_line_unchecked();

  std::string_view text_;
  std::string file_;
  std::size_t pos_ = 0;
  std::uint64_t line_ = 1;        // line of pos_
  std::uint64_t token_line_ = 0;  // line of the last token
  bool hash_comments_;
};

/// Parses a whole token as a float (a leading '+' allowed). Returns false for garbage,
/// overflow (1e999), NaN and infinity.
[[nodiscard]] bool parse_finite_float(std::string_view token, float& out);
/// Parses a whole token as a signed 64-bit integer (a leading '+' allowed).
[[nodiscard]] bool parse_int(std::string_view token, std::int64_t& out);

/// `token` quoted for messages, cut to 40 characters, non-printable bytes as '?'.
[[nodiscard]] std::string quoted(std::string_view token);

}  // namespace rtc
