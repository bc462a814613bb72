#pragma once
// Runs the built `hmap` tool (HMAP_BIN_PATH, or $HMAP_BIN) as a shell would, for the tests of
// tests/apps/: its exit code and everything it printed.

#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace hmap::test {

struct CmdResult {
  int code = -1;
  std::string out;  // stdout and stderr together
};

inline std::string hmap_bin() {
  const char* bin = std::getenv("HMAP_BIN");
  return bin != nullptr && *bin != '\0' ? bin : HMAP_BIN_PATH;
}

/// `hmap ARGS` through the shell (ARGS as typed, quoting included), stderr into stdout.
inline CmdResult run(const std::string& args) {
  CmdResult r;
  const std::string cmd = hmap_bin() + " " + args + " 2>&1";
  FILE* pipe = ::popen(cmd.c_str(), "r");
  if (pipe == nullptr) return r;
  std::array<char, 4096> buf{};
  std::size_t n = 0;
  while ((n = std::fread(buf.data(), 1, buf.size(), pipe)) > 0) r.out.append(buf.data(), n);
  const int status = ::pclose(pipe);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

/// The number of lines of `s` (its newlines).
inline std::size_t lines(const std::string& s) { return static_cast<std::size_t>(std::count(s.begin(), s.end(), '\n')); }

}  // namespace hmap::test
