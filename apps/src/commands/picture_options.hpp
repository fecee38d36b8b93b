#pragma once
// The options every picture command shares: a picture's file name (its extension picks
// PNG, SVG or PDF) and the colour scale.

#include "pictures/picture.hpp"

#include <CLI/CLI.hpp>

#include <string>

namespace mobmap::app {

/// Checks that an option names a picture: ".png", ".svg" or ".pdf".
inline CLI::Validator pictureFile() {
  return CLI::Validator(
      [](std::string& path) -> std::string {
        try {
          pictureFormat(path);
        } catch (const std::exception& e) {
          return e.what();
        }
        return {};
      },
      "PICTURE");
}

/// `--colours viridis|red-green` into `scale` (viridis by default); another name is a
/// usage error listing the two.
inline CLI::Option* addColoursOption(CLI::App& cmd, ColourScale& scale) {
  return cmd
      .add_option_function<std::string>(
          "--colours", [&scale](const std::string& name) { scale = *mapping::colourScaleNamed(name); },
          "Mobility colours: viridis (dark purple 0, teal 0.5, yellow 1; readable with the common "
          "colour-vision deficiencies) or red-green (red 0, yellow 0.5, green 1, the paper's)")
      ->check(CLI::IsMember({"viridis", "red-green"}))
      ->default_str("viridis");
}

}  // namespace mobmap::app
