#pragma once
// Helpers of the reliability tests: running the built `hmap` tool (HMAP_BIN_PATH, or $HMAP_BIN)
// as a child process that can be killed, and reading files whole.

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

extern char** environ;

namespace hmap::test {

inline std::string hmap_bin() {
  const char* bin = std::getenv("HMAP_BIN");
  return bin != nullptr && *bin != '\0' ? bin : HMAP_BIN_PATH;
}

inline std::string read_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// `hmap ARGS...` started in the background, its stdout and stderr into `log` (or /dev/null).
class Child {
 public:
  explicit Child(const std::vector<std::string>& args, const std::string& log = "/dev/null") {
    std::vector<std::string> argv_s = {hmap_bin()};
    argv_s.insert(argv_s.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : argv_s) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    if (posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
  }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;
  ~Child() {
    if (pid_ > 0 && !reaped_) {
      ::kill(pid_, SIGKILL);
      (void)wait();
    }
  }

  [[nodiscard]] bool started() const { return pid_ > 0; }
  /// True once the child has ended (without blocking).
  bool finished() {
    if (reaped_) return true;
    const pid_t r = ::waitpid(pid_, &status_, WNOHANG);
    if (r == pid_) reaped_ = true;
    return reaped_;
  }
  void kill() { ::kill(pid_, SIGKILL); }
  /// Waits for the end; the exit code, or -signal when killed.
  int wait() {
    if (!reaped_) {
      while (::waitpid(pid_, &status_, 0) < 0 && errno == EINTR) {
      }
      reaped_ = true;
    }
    return WIFEXITED(status_) ? WEXITSTATUS(status_) : -WTERMSIG(status_);
  }

 private:
  pid_t pid_ = -1;
  int status_ = 0;
  bool reaped_ = false;
};

/// Runs `hmap ARGS...` to its end; returns the exit code and puts its output into `out`.
inline int run_hmap(const std::vector<std::string>& args, const std::filesystem::path& log, std::string& out) {
  Child child(args, log.string());
  if (!child.started()) return -1000;
  const int code = child.wait();
  out = read_bytes(log);
  return code;
}

}  // namespace hmap::test
