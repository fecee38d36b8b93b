#pragma once
// Progress for long jobs: a rewritten status line on a terminal, plain log lines
// (every 10 %) otherwise, nothing with --quiet.

#include "io/cli_text.hpp"

#include <chrono>
#include <cstdio>
#include <string>

#include <unistd.h>

namespace mobmap::app {

class Progress {
 public:
  /// Rates and the ETA count from `start` (default: now); pass the job's own start when
  /// work done before the first update belongs to it.
  Progress(std::string label, int total, bool quiet,
           std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now())
      : label_(std::move(label)), total_(total), quiet_(quiet), tty_(::isatty(2) == 1), start_(start) {}

  /// Writes `line` (and a newline) to stderr over the status line on a terminal, which
  /// the next update() draws again below it; shown with --quiet too. The fields the
  /// library names in it are spelled as flags.
  static void message(const std::string& line) {
    std::fprintf(stderr, "%s%s\n", ::isatty(2) == 1 ? "\r\x1b[K" : "", cliText(line).c_str());
  }

  void update(int done, const std::string& extra = "") {
    if (quiet_ || total_ <= 0) return;
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    const double rate = secs > 0 ? done / secs : 0.0;
    const double eta = rate > 0 ? (total_ - done) / rate : 0.0;
    if (tty_) {
      std::fprintf(stderr, "\r%s %d/%d frames  %.1f fps  ETA %.0f s %s\x1b[K", label_.c_str(), done,
                   total_, rate, eta, extra.c_str());
      if (done >= total_) std::fprintf(stderr, "\n");
    } else {
      const int decile = done * 10 / total_;
      if (decile > last_decile_ || done >= total_) {
        last_decile_ = decile;
        std::fprintf(stderr, "%s %d/%d frames (%.1f fps) %s\n", label_.c_str(), done, total_, rate, extra.c_str());
      }
    }
  }

 private:
  std::string label_;
  int total_;
  bool quiet_;
  bool tty_;
  int last_decile_ = -1;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace mobmap::app
