// libFuzzer target: arbitrary bytes as a .ot file must give a map or a MapIoError,
// never a crash, hang or unbounded allocation; a map that loads must open and answer
// the questions every command asks (a point, a snap, a sole, the surface columns).
#include "scratch_file.hpp"

#include "mobmap/mapping/footholds.hpp"
#include "mobmap/mapping/mobility_map.hpp"

#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const mobmap::fuzz::ScratchFile scratch("map.ot");
  const std::string& path = scratch.write(data, size);
  std::unique_ptr<mobmap::mapping::MobilityOcTree> tree;
  try {
    tree = mobmap::mapping::loadMobilityMap(path);
  } catch (const mobmap::mapping::MapIoError&) {
    return 0;
  }
  // Opening may not throw for a tree the reader accepted.
  mobmap::mapping::MobilityMap map = mobmap::mapping::openMap(std::move(tree), mobmap::mapping::MapMetadata{});
  (void)map.query(Eigen::Vector3d::Zero());
  (void)map.snapDown(Eigen::Vector3d(0.01, 0.01, 1.0), 2.0);
  mobmap::mapping::Foot foot;
  (void)map.footprint(foot);
  try {
    const mobmap::mapping::SurfaceColumns columns(map.tree());
    (void)columns;
  } catch (const std::length_error&) {  // a map spread over more than 2^26 columns: a documented refusal
  }
  return 0;
}
