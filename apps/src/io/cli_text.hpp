#pragma once
// The library names the fields a caller sets (`max_step_m`, `depth_topic`); on the command
// line they are flags. Every library message the tool shows goes through cliText.

#include <exception>
#include <optional>
#include <string>
#include <string_view>

namespace mobmap::app {

/// The flag that sets a library field (`max_step_m` -> "--max-step"), or nullopt for a
/// field no flag sets (a configuration file's key keeps the library's name).
std::optional<std::string> flagOf(std::string_view field);

/// `message` with each field it names spelled as its flag.
std::string cliText(std::string_view message);

/// An error's message as the command line shows it: a util::FieldError as "--flag
/// problem" (without the struct that holds the field), anything else as cliText(what()).
std::string cliText(const std::exception& e);

}  // namespace mobmap::app
