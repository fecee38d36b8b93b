#pragma once
/// @file field_error.hpp
/// How the library names what its caller set. A library error about a value names the
/// field that holds it as the library's structs spell it, in backquotes (`max_step_m`,
/// `intrinsics`, `depth_topic`), never a command-line flag: the same library serves the
/// command line, Python, the HTTP API and the ROS nodes, each with its own spelling. A
/// front respells the names in a message it shows (respellFields): the CLI writes its
/// flags, Python its keywords, the API its JSON keys.

#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

namespace mobmap::util {

/// "`name`": a field as library messages name it.
[[nodiscard]] std::string fieldName(std::string_view name);

/// Values the caller gave that the library cannot take, its message naming the fields
/// involved in backquotes ("`out` m.ot is `poses` m.ot, which ...").
class ValueError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// A value the caller gave that the library cannot take: "`field` problem", for example
/// "`max_pose_gap_s` must be a finite number of seconds >= 0, got -1"; with `where` (the
/// struct that holds the field), "where: `field` problem".
class FieldError : public ValueError {
 public:
  FieldError(const std::string& field, const std::string& problem, const std::string& where = {})
      : ValueError((where.empty() ? std::string() : where + ": ") + named(field, problem)),
        field_(field),
        problem_(problem) {}
  /// The field, without backquotes.
  [[nodiscard]] const std::string& field() const { return field_; }
  /// What is wrong with its value, without the field's name.
  [[nodiscard]] const std::string& problem() const { return problem_; }
  /// "`field` problem" ("`field`: problem" when the problem starts with a colon).
  [[nodiscard]] static std::string named(const std::string& field, const std::string& problem) {
    return fieldName(field) + (problem.rfind(':', 0) == 0 ? "" : " ") + problem;
  }

 private:
  std::string field_;
  std::string problem_;
};

/// A front's spelling of a field: its flag, keyword or key, or nullopt to keep the
/// library's `name`.
using FieldSpelling = std::function<std::optional<std::string>(std::string_view field)>;

/// `message` with every `name` in it (a run of letters, digits and underscores between
/// backquotes) replaced by `spelling(name)` when that gives one; everything else as it is.
[[nodiscard]] std::string respellFields(std::string_view message, const FieldSpelling& spelling);

}  // namespace mobmap::util
