#pragma once
// The server of `hmap view`: the page (web/), three.js from Debian's libjs-three, and the map data
// the page asks for (hmap/view), over HTTP on one address. It serves nothing else: static files
// come from a fixed list (the page) or from the three.js folder through a checked relative path,
// and every other request is refused.
//
//   GET /, /index.html, /viewer.js, /viewer.css     the page (web_root)
//   GET /three/<path>.js                            three.js modules (three_root)
//   GET /api/map                                    MapScene::summary_json() with "version", "progress"
//   GET /api/tile?a=A&b=B&level=L                   box records (map_scene.hpp), octet-stream
//   GET /api/grid                                   the grid image's bytes, octet-stream
//   GET /api/column?x=X&y=Y                         column_json()
//   GET /api/status                                 {"version": V, "progress": "..."}: which map is served
//   GET /api/events                                 server-sent events: the same object at each new map
//   anything else                                   404; a malformed query 400; other methods 405

#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>

#include "hmap/view/map_scene.hpp"

namespace hmap::serve {

struct ServerOptions {
  std::string bind = "127.0.0.1";        ///< address to listen on
  int port = 8080;                       ///< 0: a free port chosen by the system
  std::filesystem::path web_root;        ///< holds index.html, viewer.js, viewer.css
  std::filesystem::path three_root;      ///< Debian's libjs-three: /usr/share/javascript/three
};

/// The file a static request names, or nullopt when the request is not one the server serves:
/// only the page's files, and three.js files (".js") under three_root by a relative path of
/// plain segments (letters, digits, '_', '-', '.'; no "." or ".." segment) that stays inside
/// three_root once symbolic links are resolved. `path` is the decoded request path.
[[nodiscard]] std::optional<std::filesystem::path> static_file(std::string_view path, const ServerOptions& options);

class ViewServer {
 public:
  /// Checks that the page and three.js are where `options` says (throws hmap::Error naming the
  /// missing file).
  ViewServer(std::shared_ptr<const view::MapScene> scene, ServerOptions options);
  ~ViewServer();
  ViewServer(const ViewServer&) = delete;
  ViewServer& operator=(const ViewServer&) = delete;

  /// Binds the address and port; throws hmap::Error with the reason ("address already in use")
  /// when it cannot.
  void bind();
  /// Serves until stop() (from another thread or a signal handler's thread). bind() first.
  void run();
  void stop();
  /// The port bound (the chosen one when options.port is 0); 0 before bind().
  [[nodiscard]] int port() const { return port_; }
  /// "http://ADDRESS:PORT/".
  [[nodiscard]] std::string url() const;
  /// Replaces the map served (a live view) and tells the pages listening to /api/events, with a
  /// line of progress ("scan 12 of 80"); requests in flight keep the map they started with.
  void set_scene(std::shared_ptr<const view::MapScene> scene, std::string progress = {});

 private:
  [[nodiscard]] std::shared_ptr<const view::MapScene> scene() const;
  /// {"version": V, "progress": "..."} of the map served.
  [[nodiscard]] std::string status_json() const;
  [[nodiscard]] std::string status_json_locked() const;  ///< scene_mutex_ held

  struct Http;  // cpp-httplib, kept out of this header
  std::unique_ptr<Http> http_;
  ServerOptions options_;
  int port_ = 0;
  mutable std::mutex scene_mutex_;
  std::condition_variable scene_changed_;
  std::shared_ptr<const view::MapScene> scene_;
  std::uint64_t version_ = 1;
  std::string progress_;
  bool stopping_ = false;
};

}  // namespace hmap::serve
