#pragma once
/// @file rgbn.hpp
/// Paper step 4, RGB-N: normals as colours (eq. 5), compared in YCrCb.

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <vector>

namespace mobmap::perception {

/// RGB-N colours (paper eq. 5): each normal component mapped to 0-255 with the
/// cloud's own min and max of that component.
std::vector<std::array<std::uint8_t, 3>> normalColours(const std::vector<Eigen::Vector3f>& normals);

/// ITU-R BT.601 full-range RGB -> (Y, Cr, Cb), each 0-255.
Eigen::Vector3f rgbToYCrCb(const std::array<std::uint8_t, 3>& rgb);

}  // namespace mobmap::perception
