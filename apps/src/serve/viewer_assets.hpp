#pragma once
// The files of the browser viewer `mobmap serve` hands out: its page and three.js,
// built into the executable (no network, no files to find at run time).

#include <cstddef>
#include <string>

namespace mobmap::app::serve {

struct ViewerAsset {
  const char* bytes;
  std::size_t size;
  const char* content_type;
};

/// The asset served at `path` ("/" is the page), or null.
const ViewerAsset* findViewerAsset(const std::string& path);

}  // namespace mobmap::app::serve
