#pragma once
// The one exception type of hmap: a message that names what was wrong and, for input, where.

#include <algorithm>
#include <stdexcept>
#include <string>
#include <string_view>

namespace hmap {

/// `text` with every control character, and every byte that is not part of a valid UTF-8
/// character, written as \xNN: messages quote what the input held, and a newline, a terminal
/// escape or a stray byte from a file must not break the one-line message or drive the user's
/// terminal. Valid UTF-8 (file names, units) is kept as it is. At most about 1 KiB is kept.
[[nodiscard]] inline std::string one_line(std::string_view text) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  // A quoted token can be a whole file without a line break: the message keeps its start (file,
  // position, problem) and says how much was cut.
  constexpr std::size_t kMaxLength = 1024;
  std::string out;
  out.reserve(std::min(text.size(), kMaxLength + 64));
  std::size_t i = 0;
  while (i < text.size()) {
    if (out.size() >= kMaxLength) {
      out += " [" + std::to_string(text.size() - i) + " more bytes cut]";
      break;
    }
    const auto u = static_cast<unsigned char>(text[i]);
    // Length of the UTF-8 character starting here (0: not a valid start or a C1 control).
    std::size_t n = 0;
    if (u >= 0x20 && u < 0x7F) n = 1;
    else if (u >= 0xC2 && u <= 0xDF) n = 2;
    else if (u >= 0xE0 && u <= 0xEF) n = 3;
    else if (u >= 0xF0 && u <= 0xF4) n = 4;
    bool valid = n > 0 && i + n <= text.size();
    for (std::size_t k = 1; valid && k < n; ++k) valid = (static_cast<unsigned char>(text[i + k]) & 0xC0) == 0x80;
    if (valid && n >= 2) {
      const auto u1 = static_cast<unsigned char>(text[i + 1]);
      if (u == 0xC2 && u1 < 0xA0) valid = false;                // U+0080..U+009F: C1 controls
      if (u == 0xE0 && u1 < 0xA0) valid = false;                // overlong
      if (u == 0xED && u1 >= 0xA0) valid = false;               // surrogates
      if (u == 0xF0 && u1 < 0x90) valid = false;                // overlong
      if (u == 0xF4 && u1 >= 0x90) valid = false;               // beyond U+10FFFF
    }
    if (valid) {
      out.append(text.substr(i, n));
      i += n;
    } else {
      out += "\\x";
      out += kHex[u >> 4];
      out += kHex[u & 0xF];
      ++i;
    }
  }
  return out;
}

/// Thrown for anything the caller or the input can cause: bad parameters, malformed files,
/// impossible poses. `what()` is a complete one-line message ready to show a user.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(one_line(message)) {}
};

/// An error in an input: `source` names the file (or stream), `position` says where in it
/// ("line 12", "byte 4096"), `problem` says what was expected.
class InputError : public Error {
 public:
  InputError(const std::string& source, const std::string& position, const std::string& problem)
      : Error(source + (position.empty() ? "" : ": " + position) + ": " + problem),
        source_(source) {}
  [[nodiscard]] const std::string& source() const { return source_; }

 private:
  std::string source_;
};

}  // namespace hmap
