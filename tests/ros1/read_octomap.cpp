// Reads the data of an octomap_msgs/Octomap message (binary, "OcTree") with OctoMap's own
// reader, as octomap_msgs' conversions do, and prints what it holds as JSON:
//   read_octomap FILE RESOLUTION  ->  {"occupied_voxels": N, "leaves": L}
// Occupied voxels count each voxel of a pruned block.
#include <octomap/OcTree.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: read_octomap FILE RESOLUTION\n");
    return 2;
  }
  std::ifstream in(argv[1], std::ios::binary);
  std::stringstream data;
  data << in.rdbuf();
  octomap::OcTree tree(std::atof(argv[2]));
  if (!tree.readBinaryData(data)) {
    std::fprintf(stderr, "read_octomap: OctoMap's reader refused %s\n", argv[1]);
    return 1;
  }
  unsigned long long occupied = 0, leaves = 0;
  const double res = tree.getResolution();
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) {
    ++leaves;
    if (!tree.isNodeOccupied(*it)) continue;
    const double n = std::round(it.getSize() / res);
    occupied += static_cast<unsigned long long>(n * n * n);
  }
  std::printf("{\"occupied_voxels\": %llu, \"leaves\": %llu}\n", occupied, leaves);
  return 0;
}
