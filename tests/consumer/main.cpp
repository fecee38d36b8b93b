// A downstream project: links mobmap::mapping (and through it gp and perception).
#include <mobmap/gp/mobility_model.hpp>
#include <mobmap/mapping/gravity.hpp>

#include <cmath>
#include <cstdio>

int main() {
  // 7-Scenes redkitchen gravity: the map's z axis must come out pointing up.
  const Eigen::Vector3d g(-0.0089, 0.9044, 0.4265);
  const Eigen::Matrix3d r = mobmap::mapping::gravityAlignment(g);
  const Eigen::Vector3d down = r * g.normalized();
  const double score = mobmap::gp::MobilityModel().predict(5.0, 1.1).mobility;
  std::printf("down in map frame: %.6f %.6f %.6f, flat-ground score %.3f\n", down.x(), down.y(), down.z(), score);
  return (std::abs(down.z() + 1.0) < 1e-9 && score > 0.9) ? 0 : 1;
}
