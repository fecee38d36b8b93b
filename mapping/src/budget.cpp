#include "mobmap/mapping/budget.hpp"

#include <cmath>

namespace mobmap::mapping {

Budget Budget::within(double seconds, const std::atomic<bool>* stop) {
  if (!(seconds > 0) || !std::isfinite(seconds)) {
    throw std::invalid_argument("Budget::within: seconds must be finite and > 0, got " + std::to_string(seconds));
  }
  Budget b;
  const auto span = std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(seconds));
  b.deadline = std::chrono::steady_clock::now() + span;
  b.stop = stop;
  return b;
}

Budget Budget::tightenedBy(const Budget& other) const {
  Budget b = *this;
  if (other.deadline && (!b.deadline || *other.deadline < *b.deadline)) b.deadline = other.deadline;
  if (!b.stop) b.stop = other.stop;
  return b;
}

void Budget::check(const char* what) const {
  if (stopped()) throw BudgetExceeded(std::string(what) + ": stopped before it ended");
  if (exceeded()) throw BudgetExceeded(std::string(what) + ": ran out of time before it ended");
}

}  // namespace mobmap::mapping
