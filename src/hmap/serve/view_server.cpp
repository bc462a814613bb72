#include "hmap/serve/view_server.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <httplib.h>

#include <array>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "hmap/core/error.hpp"

namespace hmap::serve {

namespace fs = std::filesystem;

namespace {

constexpr std::array<std::string_view, 3> kPageFiles{"index.html", "viewer.js", "viewer.css"};

bool plain_segment(std::string_view s) {
  if (s.empty() || s == "." || s == "..") return false;
  for (const char c : s) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
                    c == '-' || c == '.';
    if (!ok) return false;
  }
  return true;
}

std::string_view content_type(const fs::path& file) {
  const std::string ext = file.extension().string();
  if (ext == ".html") return "text/html; charset=utf-8";
  if (ext == ".css") return "text/css; charset=utf-8";
  // Not text/javascript: Debian's cpp-httplib compresses every text/* response with Brotli at its
  // default quality (11), which took 3.8 s of the page's start for three.module.js (1.1 MB, loopback).
  // It leaves other types alone but for a few exact ones, and application/javascript with a
  // parameter is not among them; browsers take it for a module script all the same.
  return "application/javascript; charset=utf-8";
}

std::optional<std::string> read_file(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return std::nullopt;
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// A whole decimal number of the query, or nullopt (absent, empty, trailing characters).
template <typename T>
std::optional<T> query_number(const httplib::Request& req, const char* name) {
  if (!req.has_param(name)) return std::nullopt;
  const std::string v = req.get_param_value(name);
  T out{};
  const auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), out);
  if (ec != std::errc() || end != v.data() + v.size() || v.empty()) return std::nullopt;
  return out;
}

void refuse(httplib::Response& res, int status, const std::string& why) {
  res.status = status;
  res.set_content(why + "\n", "text/plain; charset=utf-8");
}

}  // namespace

std::optional<fs::path> static_file(std::string_view path, const ServerOptions& options) {
  if (path == "/") return options.web_root / "index.html";
  for (const std::string_view f : kPageFiles) {
    if (path.size() == f.size() + 1 && path[0] == '/' && path.substr(1) == f) return options.web_root / fs::path(f);
  }
  constexpr std::string_view kThree = "/three/";
  if (!path.starts_with(kThree) || !path.ends_with(".js")) return std::nullopt;
  std::string_view rel = path.substr(kThree.size());
  fs::path file = options.three_root;
  while (!rel.empty()) {
    const std::size_t slash = rel.find('/');
    const std::string_view seg = rel.substr(0, slash);
    if (!plain_segment(seg)) return std::nullopt;
    file /= fs::path(seg);
    rel = slash == std::string_view::npos ? std::string_view{} : rel.substr(slash + 1);
    if (slash != std::string_view::npos && rel.empty()) return std::nullopt;  // a trailing '/'
  }
  // Debian's build/three.module.js is a link to ../three.module.js: links are followed, the
  // target must still be inside the package's folder.
  std::error_code ec;
  const fs::path real = fs::canonical(file, ec);
  if (ec) return std::nullopt;
  const fs::path root = fs::canonical(options.three_root, ec);
  if (ec) return std::nullopt;
  const auto [r, _] = std::mismatch(root.begin(), root.end(), real.begin(), real.end());
  if (r != root.end() || !fs::is_regular_file(real, ec)) return std::nullopt;
  return real;
}

struct ViewServer::Http {
  httplib::Server server;
};

ViewServer::ViewServer(std::shared_ptr<const view::MapScene> initial_scene, ServerOptions options)
    : http_(std::make_unique<Http>()), options_(std::move(options)), scene_(std::move(initial_scene)) {
  for (const std::string_view f : kPageFiles) {
    if (!fs::is_regular_file(options_.web_root / fs::path(f))) {
      throw Error("view: the page's " + std::string(f) + " is not in " + options_.web_root.string());
    }
  }
  if (!fs::is_regular_file(options_.three_root / "build" / "three.module.js")) {
    throw Error("view: three.js is not in " + options_.three_root.string() + " (Debian: apt-get install libjs-three)");
  }
  if (options_.port < 0 || options_.port > 65535) throw Error("view: port " + std::to_string(options_.port) + " is not in 0..65535");

  httplib::Server& s = http_->server;
  // cpp-httplib's default adds SO_REUSEPORT, with which a second server binds a port already
  // served and the two share its connections: only SO_REUSEADDR (a restart need not wait for
  // TIME_WAIT), so a port in use is refused.
  s.set_socket_options([](socket_t sock) {
    const int one = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  });
  // Headers and body go in two writes: with Nagle's algorithm the body waited for the client's
  // delayed ACK, 40 ms a tile (196 tiles of a million HVoxels: 2.7 s, now well under one).
  s.set_tcp_nodelay(true);
  s.set_payload_max_length(4096);
  s.set_keep_alive_max_count(100);
  s.set_default_headers({{"X-Content-Type-Options", "nosniff"}, {"Cache-Control", "no-store"}});

  s.Get("/api/map", [this](const httplib::Request&, httplib::Response& res) {
    // The map with its version and progress, taken together: a page that asked /api/status first
    // could get a newer map than that status told, and label it with the older progress.
    std::shared_ptr<const view::MapScene> served;
    std::string status;
    {
      const std::lock_guard lock(scene_mutex_);
      served = scene_;
      status = status_json_locked();
    }
    const std::string summary = served->summary_json();  // a JSON object with members
    res.set_content(status.substr(0, status.size() - 1) + "," + summary.substr(1), "application/json");
  });
  s.Get("/api/tile", [this](const httplib::Request& req, httplib::Response& res) {
    const auto a = query_number<std::int32_t>(req, "a");
    const auto b = query_number<std::int32_t>(req, "b");
    const auto level = query_number<int>(req, "level");
    if (!a || !b || !level || *level < 0 || *level >= view::kLevels) {
      return refuse(res, 400, "tile: a, b (integers) and level (0.." + std::to_string(view::kLevels - 1) + ") expected");
    }
    const std::vector<std::uint8_t> bytes = view::encode_boxes(scene()->tile_boxes({*a, *b}, *level));
    res.set_content(reinterpret_cast<const char*>(bytes.data()), bytes.size(), "application/octet-stream");
  });
  s.Get("/api/grid", [this](const httplib::Request&, httplib::Response& res) {
    const auto keep = scene();
    const std::vector<std::uint8_t>& cells = keep->grid_image().cells;
    res.set_content(reinterpret_cast<const char*>(cells.data()), cells.size(), "application/octet-stream");
  });
  s.Get("/api/column", [this](const httplib::Request& req, httplib::Response& res) {
    const auto x = query_number<double>(req, "x");
    const auto y = query_number<double>(req, "y");
    if (!x || !y || !std::isfinite(*x) || !std::isfinite(*y) || std::abs(*x) > 1e9 || std::abs(*y) > 1e9) {
      return refuse(res, 400, "column: x and y (finite numbers, metres) expected");
    }
    try {
      res.set_content(view::column_json(scene()->column(*x, *y)), "application/json");
    } catch (const Error& e) {  // beyond the map's ±2^30 cells
      refuse(res, 400, one_line(e.what()));
    }
  });
  s.Get("/api/status", [this](const httplib::Request&, httplib::Response& res) {
    res.set_content(status_json(), "application/json");
  });
  // One event per new map; a comment every 10 s keeps proxies and the browser from closing it.
  s.Get("/api/events", [this](const httplib::Request&, httplib::Response& res) {
    auto sent = std::make_shared<std::uint64_t>(0);
    res.set_chunked_content_provider("text/event-stream", [this, sent](std::size_t, httplib::DataSink& sink) {
      std::unique_lock lock(scene_mutex_);
      scene_changed_.wait_for(lock, std::chrono::seconds(10), [&] { return stopping_ || version_ != *sent; });
      if (stopping_) return false;
      std::string chunk = ": still here\n\n";
      if (version_ != *sent) {
        *sent = version_;
        lock.unlock();
        chunk = "data: " + status_json() + "\n\n";
      } else {
        lock.unlock();
      }
      return sink.write(chunk.data(), chunk.size());
    });
  });
  s.Get(R"(/.*)", [this](const httplib::Request& req, httplib::Response& res) {
    const std::optional<fs::path> file = static_file(req.path, options_);
    if (!file) return refuse(res, 404, "not found");
    const std::optional<std::string> body = read_file(*file);
    if (!body) return refuse(res, 404, "not found");
    res.set_content(*body, std::string(content_type(*file)));
  });
  const auto not_allowed = [](const httplib::Request&, httplib::Response& res) {
    refuse(res, 405, "only GET is served");
  };
  s.Post(R"(/.*)", not_allowed);
  s.Put(R"(/.*)", not_allowed);
  s.Delete(R"(/.*)", not_allowed);
  s.Patch(R"(/.*)", not_allowed);
  s.Options(R"(/.*)", not_allowed);
  s.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
    std::string what = "internal error";
    try {
      std::rethrow_exception(ep);
    } catch (const std::exception& e) {
      what = e.what();
    } catch (...) {
    }
    refuse(res, 500, one_line(what));
  });
}

ViewServer::~ViewServer() { stop(); }

void ViewServer::bind() {
  httplib::Server& s = http_->server;
  const int port = options_.port == 0 ? s.bind_to_any_port(options_.bind) : (s.bind_to_port(options_.bind, options_.port) ? options_.port : -1);
  if (port > 0) {
    port_ = port;
    return;
  }
  // cpp-httplib says only that it failed: bind a socket of our own to learn why.
  std::string why = "cannot listen there";
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(options_.port));
  if (::inet_pton(AF_INET, options_.bind.c_str(), &addr.sin_addr) != 1) {
    why = "not an IPv4 address";
  } else if (const int fd = ::socket(AF_INET, SOCK_STREAM, 0); fd >= 0) {
    const int one = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) why = std::strerror(errno);
    ::close(fd);
  }
  throw Error("view: cannot listen on " + options_.bind + ":" + std::to_string(options_.port) + ": " + why);
}

void ViewServer::run() {
  if (port_ == 0) throw Error("view: run() before bind()");
  http_->server.listen_after_bind();
}

void ViewServer::stop() {
  {
    const std::lock_guard lock(scene_mutex_);
    stopping_ = true;
  }
  scene_changed_.notify_all();  // the event streams end
  if (http_) http_->server.stop();
}

std::string ViewServer::url() const { return "http://" + options_.bind + ":" + std::to_string(port_) + "/"; }

void ViewServer::set_scene(std::shared_ptr<const view::MapScene> scene, std::string progress) {
  {
    const std::lock_guard lock(scene_mutex_);
    scene_ = std::move(scene);
    progress_ = std::move(progress);
    ++version_;
  }
  scene_changed_.notify_all();
}

std::string ViewServer::status_json() const {
  const std::lock_guard lock(scene_mutex_);
  return status_json_locked();
}

std::string ViewServer::status_json_locked() const {
  return nlohmann::json{{"version", version_}, {"progress", progress_}}.dump();
}

std::shared_ptr<const view::MapScene> ViewServer::scene() const {
  const std::lock_guard lock(scene_mutex_);
  return scene_;
}

}  // namespace hmap::serve
