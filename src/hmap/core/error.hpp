#pragma once
// The one exception type of hmap: a message that names what was wrong and, for input, where.

#include <stdexcept>
#include <string>

namespace hmap {

/// Thrown for anything the caller or the input can cause: bad parameters, malformed files,
/// impossible poses. `what()` is a complete one-line message ready to show a user.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
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
