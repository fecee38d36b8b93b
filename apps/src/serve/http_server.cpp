#include "serve/http_server.hpp"

#include <httplib.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <functional>
#include <list>
#include <map>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

namespace mobmap::app::serve {
namespace {

using Clock = std::chrono::steady_clock;

Clock::time_point after(double seconds) {
  return Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
}

// Waits until `sock` is ready for `events` or `deadline` passes; true when ready (a
// socket shut down by stop() is ready: its reads end at once).
bool waitFor(int sock, short events, Clock::time_point deadline) {
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) return false;
    pollfd p{sock, events, 0};
    const int n = ::poll(&p, 1, static_cast<int>(std::min<long long>(left, 1 << 30)));
    if (n > 0) return true;
    if (n == 0) return false;
    if (errno != EINTR) return false;
  }
}

std::string addressOf(const sockaddr_storage& a) {
  char text[INET6_ADDRSTRLEN] = "";
  if (a.ss_family == AF_INET) {
    ::inet_ntop(AF_INET, &reinterpret_cast<const sockaddr_in&>(a).sin_addr, text, sizeof text);
  } else if (a.ss_family == AF_INET6) {
    ::inet_ntop(AF_INET6, &reinterpret_cast<const sockaddr_in6&>(a).sin6_addr, text, sizeof text);
  }
  return text;
}

int portOf(const sockaddr_storage& a) {
  if (a.ss_family == AF_INET) return ntohs(reinterpret_cast<const sockaddr_in&>(a).sin_port);
  if (a.ss_family == AF_INET6) return ntohs(reinterpret_cast<const sockaddr_in6&>(a).sin6_port);
  return -1;
}

// One request's reads and its answer's writes over a socket, each with a deadline for
// the whole (httplib's own stream has a timeout per read, which a client sending a byte
// a second never reaches). Reads are buffered: httplib reads a request's head a byte at
// a time.
class DeadlineStream : public httplib::Stream {
 public:
  DeadlineStream(int sock, double read_s, double write_s) : sock_(sock), read_by_(after(read_s)), write_s_(write_s) {}

  bool is_readable() const override { return begin_ < end_ || waitFor(sock_, POLLIN, read_by_); }
  bool is_writable() const override { return waitFor(sock_, POLLOUT, writeDeadline()); }

  ssize_t read(char* ptr, size_t size) override {
    if (begin_ == end_) {
      if (!waitFor(sock_, POLLIN, read_by_)) return -1;
      // A body is read in large pieces: straight into the caller's buffer.
      const bool direct = size >= sizeof buffer_;
      ssize_t n;
      do {
        n = ::recv(sock_, direct ? ptr : buffer_, direct ? size : sizeof buffer_, 0);
      } while (n < 0 && errno == EINTR);
      if (direct) return n;
      if (n <= 0) return n;
      begin_ = 0, end_ = static_cast<std::size_t>(n);
    }
    const std::size_t n = std::min(size, end_ - begin_);
    std::memcpy(ptr, buffer_ + begin_, n);
    begin_ += n;
    return static_cast<ssize_t>(n);
  }

  ssize_t write(const char* ptr, size_t size) override {
    const Clock::time_point by = writeDeadline();
    std::size_t sent = 0;
    while (sent < size) {
      if (!waitFor(sock_, POLLOUT, by)) return sent > 0 ? static_cast<ssize_t>(sent) : -1;
      const ssize_t n = ::send(sock_, ptr + sent, size - sent, MSG_NOSIGNAL);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) return sent > 0 ? static_cast<ssize_t>(sent) : -1;
      sent += static_cast<std::size_t>(n);
    }
    return static_cast<ssize_t>(sent);
  }

  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage a{};
    socklen_t len = sizeof a;
    if (::getpeername(sock_, reinterpret_cast<sockaddr*>(&a), &len) == 0) ip = addressOf(a), port = portOf(a);
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage a{};
    socklen_t len = sizeof a;
    if (::getsockname(sock_, reinterpret_cast<sockaddr*>(&a), &len) == 0) ip = addressOf(a), port = portOf(a);
  }
  socket_t socket() const override { return sock_; }

 private:
  // The answer's deadline runs from its first byte: the time the handler took is not the client's.
  Clock::time_point writeDeadline() const {
    if (!write_by_) write_by_ = after(write_s_);
    return *write_by_;
  }
  int sock_;
  Clock::time_point read_by_;
  double write_s_;
  mutable std::optional<Clock::time_point> write_by_;
  char buffer_[4096];
  std::size_t begin_ = 0, end_ = 0;
};

// Set on a thread that must refuse the connection it is handed (every worker is busy).
thread_local bool t_refuse_all_busy = false;

// A fixed set of workers, one connection each: a connection that finds every worker
// taken is refused at once on the accepting thread (503), rather than waiting behind
// slow clients for as long as they hold the workers. A connection counts from its accept
// to the end of its last request, so whether it is taken does not depend on how soon a
// worker thread is scheduled.
class WorkerPool : public httplib::TaskQueue {
 public:
  explicit WorkerPool(std::size_t n) : most_(n) {
    for (std::size_t i = 0; i < n; ++i) threads_.emplace_back([this] { work(); });
  }
  void enqueue(std::function<void()> fn) override {
    {
      std::unique_lock<std::mutex> lock(mutex_);
      if (taken_ < most_) {
        ++taken_;
        jobs_.push_back(std::move(fn));
        ready_.notify_one();
        return;
      }
    }
    t_refuse_all_busy = true;
    fn();
    t_refuse_all_busy = false;
  }
  void shutdown() override {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
    }
    ready_.notify_all();
    for (std::thread& t : threads_) t.join();
  }

 private:
  void work() {
    for (;;) {
      std::function<void()> fn;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        ready_.wait(lock, [this] { return stopping_ || !jobs_.empty(); });
        if (jobs_.empty()) return;  // stopping
        fn = std::move(jobs_.front());
        jobs_.pop_front();
      }
      fn();
      const std::lock_guard<std::mutex> lock(mutex_);
      --taken_;
    }
  }
  const std::size_t most_;
  std::vector<std::thread> threads_;
  std::list<std::function<void()>> jobs_;
  std::size_t taken_ = 0;  // connections accepted and not yet done with
  bool stopping_ = false;
  std::mutex mutex_;
  std::condition_variable ready_;
};

// Writes a whole 503 answer without waiting (the refusing thread must not block), then
// reads what the client already sent, so that closing does not reset the connection
// before the answer is read.
void refuse(int sock, const std::string& message) {
  const std::string body = errorBody(message);
  const std::string answer = "HTTP/1.1 503 Service Unavailable\r\nContent-Type: application/json\r\nRetry-After: 1\r\n"
                             "Connection: close\r\nContent-Length: " +
                             std::to_string(body.size()) + "\r\n\r\n" + body;
  const ssize_t sent = ::send(sock, answer.data(), answer.size(), MSG_DONTWAIT | MSG_NOSIGNAL);
  (void)sent;
  ::shutdown(sock, SHUT_WR);
  char sink[4096];
  for (int i = 0; i < 16 && ::recv(sock, sink, sizeof sink, MSG_DONTWAIT) > 0; ++i) {
  }
}

// httplib's server with the connections under our rules (docs/RELIABILITY.md): a bounded
// pool and no queue, a bound per client address, a deadline for each request's arrival
// and its answer's departure, an admission limit for large bodies, and a stop that ends
// every connection at once (httplib's own stop() does nothing until listening has begun,
// and waits for every client to finish).
class GuardedServer : public httplib::Server {
 public:
  explicit GuardedServer(const Limits& limits) : limits_(limits) {
    new_task_queue = [this] { return new WorkerPool(limits_.max_connections); };
  }

  void stopAll() {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
      for (const auto& [sock, client] : open_) ::shutdown(sock, SHUT_RDWR);
    }
    stop();
    const socket_t sock = svr_sock_.exchange(INVALID_SOCKET);
    if (sock == INVALID_SOCKET) return;
    ::shutdown(sock, SHUT_RDWR);
    ::close(sock);
  }

  // Pre-routing: a large body takes one of max_large_bodies places until its answer has
  // gone, or is refused before it is read.
  bool admitBody(const httplib::Request& req) {
    const bool chunked = req.get_header_value("Transfer-Encoding").find("chunked") != std::string::npos;
    const std::size_t length = req.get_header_value<std::uint64_t>("Content-Length");
    if (!chunked && length <= limits_.large_body_bytes) return true;
    const std::lock_guard<std::mutex> lock(mutex_);
    if (large_bodies_ >= limits_.max_large_bodies) {
      t_body_refused = true;  // unread, it would be taken for the next request
      return false;
    }
    ++large_bodies_;
    t_holds_large_body = true;
    return true;
  }

 private:
  static thread_local bool t_holds_large_body;
  static thread_local bool t_body_refused;

  void releaseBody() {
    if (!t_holds_large_body) return;
    t_holds_large_body = false;
    const std::lock_guard<std::mutex> lock(mutex_);
    --large_bodies_;
  }

  bool process_and_close_socket(socket_t sock) override {
    const auto close = [sock] {
      ::shutdown(sock, SHUT_RDWR);
      ::close(sock);
    };
    if (t_refuse_all_busy) {
      refuse(sock, "the server is answering " + std::to_string(limits_.max_connections) +
                       " connections, its most (try again shortly)");
      close();
      return false;
    }
    sockaddr_storage peer{};
    socklen_t len = sizeof peer;
    const std::string client = ::getpeername(sock, reinterpret_cast<sockaddr*>(&peer), &len) == 0 ? addressOf(peer) : "";
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      if (stopping_) {
        close();
        return false;
      }
      if (per_client_[client] >= limits_.max_connections_per_client()) {
        refuse(sock, "this address has " + std::to_string(limits_.max_connections_per_client()) +
                         " connections open, the most one client may have");
        close();
        return false;
      }
      ++per_client_[client];
      open_.emplace(sock, client);
    }
    bool ok = true;
    for (std::size_t left = keep_alive_max_count_; left > 0 && ok; --left) {
      // An idle connection waits at most keep_alive_idle_s for its next request.
      if (!waitFor(sock, POLLIN, after(limits_.keep_alive_idle_s))) break;
      DeadlineStream stream(sock, limits_.request_read_s, limits_.answer_write_s);
      t_body_refused = false;
      bool closed = false;
      ok = process_request(stream, left == 1, closed, [](httplib::Request&) {});
      releaseBody();
      if (closed || t_body_refused) break;
    }
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      open_.erase(sock);
      if (--per_client_[client] == 0) per_client_.erase(client);
    }
    close();
    return ok;
  }

  const Limits limits_;
  std::mutex mutex_;
  bool stopping_ = false;
  std::map<socket_t, std::string> open_;  // connections being served, by socket, with their client
  std::map<std::string, std::size_t> per_client_;
  std::size_t large_bodies_ = 0;
};

thread_local bool GuardedServer::t_holds_large_body = false;
thread_local bool GuardedServer::t_body_refused = false;

}  // namespace

struct HttpServer::Impl {
  const Api& api;
  GuardedServer server;
  explicit Impl(const Api& a) : api(a), server(a.limits()) {}
};

HttpServer::HttpServer(const Api& api) : impl_(std::make_unique<Impl>(api)) {
  GuardedServer& s = impl_->server;
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
  s.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    if (!impl_->server.admitBody(req)) {
      res.status = 503;
      res.set_header("Retry-After", "1");
      res.set_content(errorBody("the server is reading " + std::to_string(impl_->api.limits().max_large_bodies) +
                                " request bodies over " + std::to_string(impl_->api.limits().large_body_bytes >> 20) +
                                " MiB, its most at once (try again shortly)"),
                      "application/json");
      return httplib::Server::HandlerResponse::Handled;
    }
    // httplib acts on two request headers in ways that do not fit this API, so they are
    // adjusted before it reads them (the request is this thread's own; httplib hands
    // handlers a const view of it). A body sent as a form (curl -d's default type) is
    // parsed by httplib as one, and refused past 8 KB: the API reads JSON whatever the
    // type says. Brotli at httplib's setting (its slowest) takes seconds for a large
    // voxel page: gzip is offered when the client takes it, else nothing.
    auto& headers = const_cast<httplib::Headers&>(req.headers);
    const auto type = headers.find("Content-Type");
    if (type != headers.end() && type->second.find("x-www-form-urlencoded") != std::string::npos) {
      type->second = "application/json";
    }
    const auto encoding = headers.find("Accept-Encoding");
    if (encoding != headers.end() && encoding->second.find("br") != std::string::npos) {
      const bool gzip = encoding->second.find("gzip") != std::string::npos;
      headers.erase(encoding);
      if (gzip) headers.emplace("Accept-Encoding", "gzip");
    }
    return httplib::Server::HandlerResponse::Unhandled;
  });
  const auto answer = [this](const httplib::Request& req, httplib::Response& res) {
    std::multimap<std::string, std::string> params(req.params.begin(), req.params.end());
    const Response r = impl_->api.handle(req.method, req.path, params, req.body);
    res.status = r.status;
    if (r.status == 503) res.set_header("Retry-After", "1");
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
  impl_->api.stopWork();
  impl_->server.stopAll();
}

}  // namespace mobmap::app::serve
