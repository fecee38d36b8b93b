#pragma once
// `mobmap serve`'s HTTP server: the Api over loopback (or any address), on a pool of
// threads. cpp-httplib stays inside http_server.cpp.

#include "serve/api.hpp"

#include <memory>
#include <string>

namespace mobmap::app::serve {

class HttpServer {
 public:
  /// Answers with `api`, which must outlive the server.
  explicit HttpServer(const Api& api);
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  /// Binds `address`:`port` (0: a free port); returns the port. std::runtime_error naming
  /// the address when it cannot be bound.
  int bind(const std::string& address, int port);
  /// Serves until stop(); call after bind(), from a thread of its own.
  void run();
  /// Stops run() (from any thread). Requests being answered finish first.
  void stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mobmap::app::serve
