#include "mobmap/sim/tum_pose.hpp"

#include <ios>

namespace mobmap::sim {

void writeTumPoseLine(std::ostream& out, double t, const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.linear());
  const auto flags = out.flags();
  const auto precision = out.precision(9);
  out << std::fixed << t << " " << T.translation().x() << " " << T.translation().y() << " " << T.translation().z() << " "
      << q.x() << " " << q.y() << " " << q.z() << " " << q.w() << "\n";
  out.flags(flags);
  out.precision(precision);
}

}  // namespace mobmap::sim
