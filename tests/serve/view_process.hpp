#pragma once
// Starts `hmap view` as a child process for the tests and reads the URL it prints.

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace hmap::test {

inline std::string hmap_bin() {
  const char* bin = std::getenv("HMAP_BIN");
  return bin != nullptr && *bin != '\0' ? bin : HMAP_BIN_PATH;
}

/// `hmap COMMAND ARGS...` (view, or map --view) running; stops it (SIGTERM) when destroyed.
class ViewProcess {
 public:
  explicit ViewProcess(const std::vector<std::string>& args, const std::string& command = "view") {
    int out[2];
    if (::pipe(out) != 0) return;
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(out[1], 1);
      ::dup2(out[1], 2);
      ::close(out[0]);
      ::close(out[1]);
      std::vector<std::string> argv_s{hmap_bin(), command};
      argv_s.insert(argv_s.end(), args.begin(), args.end());
      std::vector<char*> argv;
      for (std::string& a : argv_s) argv.push_back(a.data());
      argv.push_back(nullptr);
      ::execv(argv[0], argv.data());
      ::_exit(127);
    }
    ::close(out[1]);
    out_ = ::fdopen(out[0], "r");
    // Lines until the URL, or the end (an error).
    char line[4096];
    while (out_ != nullptr && std::fgets(line, sizeof line, out_) != nullptr) {
      output_ += line;
      const std::string s(line);
      if (const std::size_t at = s.find("open http://"); at != std::string::npos) {
        url_ = s.substr(at + 5, s.find(' ', at + 5) - (at + 5));
        break;
      }
    }
  }
  ~ViewProcess() { stop(); }
  ViewProcess(const ViewProcess&) = delete;
  ViewProcess& operator=(const ViewProcess&) = delete;

  /// "http://127.0.0.1:PORT/", empty when it did not start.
  [[nodiscard]] const std::string& url() const { return url_; }
  [[nodiscard]] const std::string& output() const { return output_; }
  /// CPU seconds (user + system) the process has used so far (Linux /proc); 0 when not running.
  [[nodiscard]] double cpu_seconds() const {
    if (pid_ <= 0) return 0.0;
    FILE* f = std::fopen(("/proc/" + std::to_string(pid_) + "/stat").c_str(), "r");
    if (f == nullptr) return 0.0;
    char buf[1024] = {};
    const std::size_t n = std::fread(buf, 1, sizeof buf - 1, f);
    std::fclose(f);
    const std::string stat(buf, n);
    const std::size_t close = stat.rfind(')');
    if (close == std::string::npos) return 0.0;
    // Fields after "pid (comm) ": state is the 1st, utime the 12th, stime the 13th.
    unsigned long utime = 0, stime = 0;
    if (std::sscanf(stat.c_str() + close + 2, "%*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %lu %lu", &utime, &stime) != 2) return 0.0;
    return static_cast<double>(utime + stime) / static_cast<double>(::sysconf(_SC_CLK_TCK));
  }
  /// SIGTERM, then the exit code (-1 when killed otherwise).
  int stop() {
    if (pid_ <= 0) return exit_code_;
    ::kill(pid_, SIGTERM);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    pid_ = -1;
    if (out_ != nullptr) {
      char buf[4096];
      while (std::fgets(buf, sizeof buf, out_) != nullptr) output_ += buf;
      std::fclose(out_);
      out_ = nullptr;
    }
    exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return exit_code_;
  }

 private:
  pid_t pid_ = -1;
  FILE* out_ = nullptr;
  std::string url_;
  std::string output_;
  int exit_code_ = -1;
};

}  // namespace hmap::test
