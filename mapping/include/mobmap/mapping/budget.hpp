#pragma once
/// @file budget.hpp
/// How long a long computation (reachability, a footstep plan) may run, and a way for
/// another thread to stop it: a server answering many clients bounds each request's work
/// and stops it all when it shuts down. The computation checks the budget inside its
/// loops and throws BudgetExceeded when it has run out.

#include <atomic>
#include <chrono>
#include <optional>
#include <stdexcept>
#include <string>

namespace mobmap::mapping {

/// The budget ran out (its deadline passed, or its stop flag was set) before the
/// computation ended; what() says which and what was being computed.
class BudgetExceeded : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A deadline on the steady clock and a stop flag, each optional; a default Budget never
/// runs out. Cheap to copy; the flag is not owned and must outlive every copy.
struct Budget {
  std::optional<std::chrono::steady_clock::time_point> deadline;
  const std::atomic<bool>* stop = nullptr;

  /// A budget of `seconds` from now (std::invalid_argument unless > 0), stopped by `stop` too.
  [[nodiscard]] static Budget within(double seconds, const std::atomic<bool>* stop = nullptr);
  /// The earlier deadline of the two; this one's stop flag, or the other's when this has none.
  [[nodiscard]] Budget tightenedBy(const Budget& other) const;
  [[nodiscard]] bool stopped() const { return stop && stop->load(std::memory_order_relaxed); }
  [[nodiscard]] bool exceeded() const { return stopped() || (deadline && std::chrono::steady_clock::now() > *deadline); }
  /// Throws BudgetExceeded naming `what` when exceeded().
  void check(const char* what) const;
};

}  // namespace mobmap::mapping
