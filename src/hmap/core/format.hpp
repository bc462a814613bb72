#pragma once
// printf-style formatting into a std::string of the exact length: no fixed buffer to overflow or
// to cut a line short (a coordinate of 1e30 prints 35 digits with "%.4f").

#include <cstdarg>
#include <cstdio>
#include <string>

namespace hmap {

/// `fmt` with its arguments, as std::snprintf would print them, whatever their length.
[[nodiscard]] __attribute__((format(printf, 1, 2))) inline std::string format(const char* fmt, ...) {
  std::va_list args;
  va_start(args, fmt);
  std::va_list again;
  va_copy(again, args);
  char small[256];
  const int n = std::vsnprintf(small, sizeof small, fmt, args);
  va_end(args);
  std::string out;
  if (n < 0) {
    va_end(again);
    return out;  // an encoding error: nothing sensible to print
  }
  if (static_cast<std::size_t>(n) < sizeof small) {
    out.assign(small, static_cast<std::size_t>(n));
  } else {
    out.resize(static_cast<std::size_t>(n));
    std::vsnprintf(out.data(), out.size() + 1, fmt, again);  // writes n characters and the NUL
  }
  va_end(again);
  return out;
}

}  // namespace hmap
