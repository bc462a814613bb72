#pragma once
// A raw HTTP/1.1 request over a socket, for the server tests: the request line goes out byte for
// byte as written (no client normalises "../" or percent escapes away).

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <string>

namespace hmap::test {

struct HttpReply {
  int status = 0;  ///< 0: no answer
  std::string headers;  ///< the header lines, as sent
  std::string body;
};

/// The reply, read until the server closes or `timeout_s` passes without a byte (an event stream).
/// `extra_headers`: lines to add to the request, each ending in "\r\n".
inline HttpReply http_request(int port, const std::string& method, const std::string& target, int timeout_s = 5,
                              const std::string& extra_headers = {}) {
  HttpReply reply;
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return reply;
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  ::inet_pton(AF_INET, "127.0.0.1", &addr.sin_addr);
  timeval timeout{timeout_s, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(fd);
    return reply;
  }
  const std::string request = method + " " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n" +
                              (method == "GET" ? "" : "Content-Length: 0\r\n") + extra_headers + "\r\n";
  (void)::send(fd, request.data(), request.size(), MSG_NOSIGNAL);
  std::string raw;
  char buf[65536];
  for (ssize_t n; (n = ::recv(fd, buf, sizeof buf, 0)) > 0;) raw.append(buf, static_cast<std::size_t>(n));
  ::close(fd);
  if (raw.rfind("HTTP/1.1 ", 0) != 0 || raw.size() < 12) return reply;
  reply.status = std::stoi(raw.substr(9, 3));
  const std::size_t head_end = raw.find("\r\n\r\n");
  if (head_end != std::string::npos) {
    reply.headers = raw.substr(0, head_end);
    reply.body = raw.substr(head_end + 4);
  }
  return reply;
}

inline HttpReply http_get(int port, const std::string& target) { return http_request(port, "GET", target); }

}  // namespace hmap::test
