// Throughput of `mobmap serve` against the in-process API: point queries and sole
// footprints over loopback HTTP in batches of 1 and 1000 (one keep-alive connection),
// beside the same questions asked of MobilityMap directly, with the JSON answers the
// server builds, and of the server's API without its sockets (to tell the JSON's cost
// from HTTP's). The HTTP times include the client's own JSON work. Medians of 5 passes.
//   serve_bench MAP.ot
// Eigen before httplib: <resolv.h>, which httplib pulls in, defines _res, a name Eigen uses.
#include "answers/answers.hpp"
#include "serve/api.hpp"
#include "serve/http_server.hpp"

#include "mobmap/mapping/mobility_map.hpp"

#include <httplib.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <functional>
#include <random>
#include <string>
#include <thread>
#include <vector>

namespace {

using namespace mobmap;
using Clock = std::chrono::steady_clock;

// Median over 5 passes of `pass`, in seconds.
double median(const std::function<void()>& pass) {
  std::vector<double> s;
  for (int i = 0; i < 5; ++i) {
    const auto t0 = Clock::now();
    pass();
    s.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
  }
  std::sort(s.begin(), s.end());
  return s[2];
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: serve_bench MAP.ot\n");
    return 2;
  }
  app::serve::ServedMap served;
  served.map = std::make_shared<const mapping::MobilityMap>(mapping::openMap(argv[1]));
  const mapping::MobilityMap& map = *served.map;
  const app::serve::MapSource source(served);
  app::serve::Limits limits;
  const app::serve::Api api(argv[1], source, limits);
  app::serve::HttpServer server(api);
  const int port = server.bind("127.0.0.1", 0);
  std::thread serving([&] { server.run(); });

  // Questions spread over the map's bounds.
  double x0, y0, z0, x1, y1, z1;
  map.tree().getMetricMin(x0, y0, z0);
  map.tree().getMetricMax(x1, y1, z1);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ux(x0, x1), uy(y0, y1), uz(z0, z1), uyaw(-3.14159, 3.14159);
  constexpr std::size_t kQuestions = 2000;
  std::vector<std::array<double, 3>> points(kQuestions);
  std::vector<std::array<double, 6>> soles(kQuestions);
  for (std::size_t i = 0; i < kQuestions; ++i) {
    points[i] = {ux(rng), uy(rng), uz(rng)};
    soles[i] = {points[i][0], points[i][1], points[i][2], uyaw(rng), 0.25, 0.12};
  }

  httplib::Client client("127.0.0.1", port);
  client.set_keep_alive(true);
  client.set_tcp_nodelay(true);
  client.set_read_timeout(300, 0);
  std::size_t answered = 0;
  // Asks about questions [0, n) over HTTP, `batch` per request.
  const auto overHttp = [&](const std::string& path, const std::string& field, std::size_t n, std::size_t batch,
                            const auto& questions) {
    for (std::size_t first = 0; first < n; first += batch) {
      nlohmann::json rows = nlohmann::json::array();
      for (std::size_t i = first; i < std::min(n, first + batch); ++i) rows.push_back(questions[i]);
      const auto res = client.Post(path.c_str(), nlohmann::json{{field, rows}}.dump(), "application/json");
      if (!res || res->status != 200) {
        std::fprintf(stderr, "serve_bench: %s failed\n", path.c_str());
        std::exit(1);
      }
      answered += nlohmann::json::parse(res->body)["answers"].size();
    }
  };
  double sink = 0;
  std::printf("%s, %zu random points and 25 x 12 cm soles in its bounds; microseconds per question (median of 5 passes)\n\n",
              argv[1], kQuestions);
  std::printf("| question | in-process API | + its JSON answer | server's API without sockets, batches of 1000 | HTTP, "
              "batches of 1000 | HTTP, batches of 1 |\n");
  std::printf("|---|---|---|---|---|---|\n");
  for (const bool feet : {false, true}) {
    const double direct = median([&] {
      for (std::size_t i = 0; i < kQuestions; ++i) {
        if (feet) {
          const auto& s = soles[i];
          sink += map.footprint({s[0], s[1], s[2], s[3], s[4], s[5]}, 0.1, 0.1).min_mobility;
        } else {
          sink += map.query({points[i][0], points[i][1], points[i][2]}).occupancy;
        }
      }
    }) / kQuestions;
    const double with_json = median([&] {
      for (std::size_t i = 0; i < kQuestions; ++i) {
        const std::string text =
            feet ? app::toJson(app::answerFoot(map, soles[i], app::InputFrame::kMap, -1, nullptr)).dump()
                 : app::toJson(app::answerPoint(map, {points[i][0], points[i][1], points[i][2]}, app::InputFrame::kMap,
                                                -1, nullptr))
                       .dump();
        sink += static_cast<double>(text.size());
      }
    }) / kQuestions;
    const std::string path = feet ? "/api/foot" : "/api/query";
    // The server's own work for a batch of 1000: the API without the socket.
    const double handled = median([&] {
      for (std::size_t first = 0; first < kQuestions; first += 1000) {
        nlohmann::json rows = nlohmann::json::array();
        for (std::size_t i = first; i < first + 1000; ++i) {
          if (feet) {
            rows.push_back(soles[i]);
          } else {
            rows.push_back(points[i]);
          }
        }
        const std::string body = nlohmann::json{{feet ? "soles" : "points", rows}}.dump();
        sink += static_cast<double>(api.handle("POST", path, {}, body).body.size());
      }
    }) / kQuestions;

    const std::string field = feet ? "soles" : "points";
    const double batched = feet ? median([&] { overHttp(path, field, kQuestions, 1000, soles); }) / kQuestions
                                : median([&] { overHttp(path, field, kQuestions, 1000, points); }) / kQuestions;
    // One question per request: fewer of them, it is slow.
    const std::size_t single_n = 500;
    const double single = feet ? median([&] { overHttp(path, field, single_n, 1, soles); }) / single_n
                               : median([&] { overHttp(path, field, single_n, 1, points); }) / single_n;
    std::printf("| %s | %.2f | %.2f (%.1fx) | %.2f (%.1fx) | %.2f (%.1fx) | %.1f (%.0fx) |\n",
                feet ? "sole (`/api/foot`)" : "point (`/api/query`)", direct * 1e6, with_json * 1e6, with_json / direct,
                handled * 1e6, handled / direct, batched * 1e6, batched / direct, single * 1e6, single / direct);
  }
  std::printf("\n(%zu answers over HTTP; checksum %.3f)\n", answered, sink);
  server.stop();
  serving.join();
  return 0;
}
