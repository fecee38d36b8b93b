#include "serve/http_server.hpp"

#include <httplib.h>

#include <sys/socket.h>
#include <unistd.h>

#include <stdexcept>

namespace mobmap::app::serve {
namespace {

// httplib's server with a stop that also works before listening has begun: httplib's
// own stop() does nothing until then, and a listen that starts after it would never end.
// Closing the listening socket ends a listen that is running and one that has not begun.
class StoppableServer : public httplib::Server {
 public:
  void closeListeningSocket() {
    const socket_t sock = svr_sock_.exchange(INVALID_SOCKET);
    if (sock == INVALID_SOCKET) return;
    ::shutdown(sock, SHUT_RDWR);
    ::close(sock);
  }
};

}  // namespace

struct HttpServer::Impl {
  const Api& api;
  StoppableServer server;
  explicit Impl(const Api& a) : api(a) {}
};

HttpServer::HttpServer(const Api& api) : impl_(std::make_unique<Impl>(api)) {
  StoppableServer& s = impl_->server;
  s.set_payload_max_length(api.limits().max_body_bytes);
  // Answers leave at once: with Nagle's algorithm a small answer waits for the client's
  // delayed acknowledgement (40 ms) of the one before.
  s.set_tcp_nodelay(true);
  // SO_REUSEADDR only: httplib's default also sets SO_REUSEPORT, with which a second
  // server on a port in use binds too and the two share its requests.
  s.set_socket_options([](socket_t sock) {
    int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  const auto answer = [this](const httplib::Request& req, httplib::Response& res) {
    std::multimap<std::string, std::string> params(req.params.begin(), req.params.end());
    const Response r = impl_->api.handle(req.method, req.path, params, req.body);
    res.status = r.status;
    res.set_content(r.body, r.content_type.c_str());
  };
  s.Get(".*", answer);
  s.Post(".*", answer);
  s.Put(".*", answer);
  s.Patch(".*", answer);
  s.Delete(".*", answer);
  // What httplib refuses before a handler sees it (a body over the limit, a request it
  // cannot read) gets a JSON body too.
  s.set_error_handler([](const httplib::Request&, httplib::Response& res) {
    if (!res.body.empty()) return;
    std::string message = "HTTP " + std::to_string(res.status);
    if (res.status == 413) message += ": the request body is larger than this server takes";
    if (res.status == 400) message += ": the request could not be read";
    res.set_content(errorBody(message), "application/json");
  });
  s.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr) {
    res.status = 500;
    res.set_content(errorBody("internal error"), "application/json");
  });
}

HttpServer::~HttpServer() { stop(); }

int HttpServer::bind(const std::string& address, int port) {
  httplib::Server& s = impl_->server;
  if (port == 0) {
    const int bound = s.bind_to_any_port(address);
    if (bound <= 0) throw std::runtime_error("cannot listen on " + address + " (is it an address of this machine?)");
    return bound;
  }
  if (!s.bind_to_port(address, port)) {
    throw std::runtime_error("cannot listen on " + address + ":" + std::to_string(port) +
                             " (is the port in use, or the address not one of this machine's?)");
  }
  return port;
}

void HttpServer::run() { impl_->server.listen_after_bind(); }

void HttpServer::stop() {
  impl_->server.stop();
  impl_->server.closeListeningSocket();
}

}  // namespace mobmap::app::serve
