#include "serve/viewer_assets.hpp"

namespace mobmap::app::serve {
namespace {

// Generated at build time from apps/viewer/ and the three.js of Debian's libjs-three.
constexpr char kPage[] =
#include "viewer_index_html.inc"
    ;
constexpr char kViewerJs[] =
#include "viewer_js.inc"
    ;
constexpr char kThree[] =
#include "three_min_js.inc"
    ;
constexpr char kOrbit[] =
#include "orbit_controls_js.inc"
    ;

const ViewerAsset kAssets[] = {
    {kPage, sizeof kPage - 1, "text/html; charset=utf-8"},
    {kViewerJs, sizeof kViewerJs - 1, "text/javascript; charset=utf-8"},
    {kThree, sizeof kThree - 1, "text/javascript; charset=utf-8"},
    {kOrbit, sizeof kOrbit - 1, "text/javascript; charset=utf-8"},
};

}  // namespace

const ViewerAsset* findViewerAsset(const std::string& path) {
  if (path == "/" || path == "/index.html") return &kAssets[0];
  if (path == "/viewer.js") return &kAssets[1];
  if (path == "/three.min.js") return &kAssets[2];
  if (path == "/OrbitControls.js") return &kAssets[3];
  return nullptr;
}

}  // namespace mobmap::app::serve
