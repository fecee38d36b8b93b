// What reading a recording costs per frame: Recording::load (the container's read, the
// message's decoding, the depth's conversion) against reading the same frame's 16-bit
// PNG from a 7-Scenes layout, in the same run, alternating.
//   recording_bench SEQ_DIR BAG [BAG...]
// Prints, per input, the median milliseconds per frame over every frame, and the ratio
// to the PNG's.
#include "io/dataset.hpp"

#include "mobmap/sources/recording.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: recording_bench SEQ_DIR BAG [BAG...]\n");
    return 2;
  }
  using Clock = std::chrono::steady_clock;
  const mobmap::app::SevenScenesDirectory seq(argv[1], "");
  std::vector<std::unique_ptr<mobmap::sources::Recording>> bags;
  for (int i = 2; i < argc; ++i) {
    const auto t0 = Clock::now();
    bags.push_back(mobmap::sources::Recording::open(argv[i]));
    std::printf("%s: opened (indexed) in %.1f ms, %d images, index %.1f KB\n", argv[i],
                std::chrono::duration<double, std::milli>(Clock::now() - t0).count(), bags.back()->imageCount(),
                static_cast<double>(bags.back()->memoryBytes()) / 1024.0);
  }
  std::vector<double> png_ms;
  std::vector<std::vector<double>> bag_ms(bags.size());
  const auto& numbers = seq.frameNumbers();
  for (int round = 0; round < 3; ++round) {
    for (std::size_t i = 0; i < numbers.size(); ++i) {
      auto t0 = Clock::now();
      const auto depth = seq.readDepth(numbers[i]);
      png_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
      for (std::size_t b = 0; b < bags.size(); ++b) {
        if (static_cast<int>(i) >= bags[b]->imageCount()) continue;
        t0 = Clock::now();
        const auto f = bags[b]->load(static_cast<int>(i));
        bag_ms[b].push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
        if (f.depth.width != depth.width) return 1;
      }
    }
  }
  const double png = median(png_ms);
  std::printf("\n%-48s %10s %8s\n", "input", "ms/frame", "x PNG");
  std::printf("%-48s %10.2f %8.2f\n", "7-Scenes layout (16-bit PNG)", png, 1.0);
  for (std::size_t b = 0; b < bags.size(); ++b) {
    std::printf("%-48s %10.2f %8.2f\n", argv[b + 2], median(bag_ms[b]), median(bag_ms[b]) / png);
  }
  return 0;
}
