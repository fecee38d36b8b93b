// Sequences read with a correction: depth in another unit than the input's own
// (withDepthScale) and the camera mounted on the body whose poses are given
// (withExtrinsics), siblings of the depth formats (DepthFormatSequence, sequence.cpp).
#include "mobmap/sources/adjusted.hpp"

#include "mobmap/mapping/gravity.hpp"
#include "mobmap/sources/io_error.hpp"
#include "mobmap/sources/text.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

namespace mobmap::sources {

float depthRescaleFactor(const DepthUnit& from, double units_per_m) {
  if (!(units_per_m > 0) || !std::isfinite(units_per_m)) throw util::FieldError("depth_scale", "must be a positive number of units per metre");
  return static_cast<float>(from.units_per_m / units_per_m);
}

void scaleDepth(std::vector<float>& depth_m, std::vector<Eigen::Vector3f>& points, float factor) {
  for (float& z : depth_m) z *= factor;
  for (Eigen::Vector3f& p : points) p *= factor;
}

namespace {

// A sequence read in another depth unit.
class ScaledSequence : public ForwardingSequence {
 public:
  ScaledSequence(std::unique_ptr<Sequence> inner, double units_per_m, float factor)
      : ForwardingSequence(std::move(inner)), unit_{units_per_m, this->inner().depthUnit().cloud}, factor_(factor) {}
  [[nodiscard]] Frame load(int n) const override {
    Frame f = inner().load(n);
    scaleFrame(f, factor_, unit_.units_per_m);
    return f;
  }
  [[nodiscard]] DepthUnit depthUnit() const override { return unit_; }

 private:
  DepthUnit unit_;
  float factor_;
};

}  // namespace

void scaleFrame(Frame& f, float factor, double units_per_m) {
  std::vector<float> no_depth;
  scaleDepth(f.depth ? f.depth->depth_m : no_depth, f.points, factor);
  if (f.T_cloud_camera) f.T_cloud_camera->translation() *= static_cast<double>(factor);
  f.depth_unit.units_per_m = units_per_m;
}

std::unique_ptr<Sequence> withDepthScale(std::unique_ptr<Sequence> seq, double units_per_m) {
  const float factor = depthRescaleFactor(seq->depthUnit(), units_per_m);
  if (seq->depthUnit().units_per_m == units_per_m) return seq;
  return std::make_unique<ScaledSequence>(std::move(seq), units_per_m, factor);
}

void rescaleDepth(Frame& f, double units_per_m) {
  const float factor = depthRescaleFactor(f.depth_unit, units_per_m);
  if (units_per_m == f.depth_unit.units_per_m) return;
  scaleFrame(f, factor, units_per_m);
}

namespace {

Eigen::Isometry3d fromQuaternion(const std::vector<double>& v, const std::string& what) {
  const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
  if (std::abs(q.norm() - 1.0) > 1e-3) {
    throw IoError(what, "the rotation qx,qy,qz,qw is not a unit quaternion (norm " + std::to_string(q.norm()) + ")");
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q.normalized().toRotationMatrix();
  T.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
  return T;
}

Eigen::Isometry3d fromMatrix(const std::vector<double>& v, const std::string& what) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  for (std::size_t i = 0; i < v.size(); ++i) m(static_cast<int>(i / 4), static_cast<int>(i % 4)) = v[i];
  if (const auto problem = mapping::checkRigid(m)) throw IoError(what, "the transform is not rigid: " + *problem);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = mapping::nearestRotation(m.topLeftCorner<3, 3>());
  T.translation() = m.topRightCorner<3, 1>();
  return T;
}

std::vector<double> numbers(const YAML::Node& n) {
  std::vector<double> v;
  for (const auto& x : n) v.push_back(x.as<double>());
  return v;
}

Eigen::Isometry3d fromYaml(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw IoError(path, std::string("cannot be read as YAML: ") + e.what());
  }
  try {
    for (const char* key : {"T_base_camera", "extrinsics"}) {
      if (root[key]) root = root[key];
    }
    if (const YAML::Node lt = root["local_transform"]) {
      const std::vector<double> v = numbers(lt["data"] ? lt["data"] : lt);
      if (v.size() != 12 && v.size() != 16) throw IoError(path, "local_transform holds " + std::to_string(v.size()) + " values, not 12 or 16");
      return fromMatrix(v, path);
    }
    if (root["translation"] && root["rotation"]) {
      const YAML::Node t = root["translation"], r = root["rotation"];
      return fromQuaternion({t["x"].as<double>(), t["y"].as<double>(), t["z"].as<double>(), r["x"].as<double>(),
                             r["y"].as<double>(), r["z"].as<double>(), r["w"].as<double>()},
                            path);
    }
    if (root["data"]) {
      const std::vector<double> v = numbers(root["data"]);
      if (v.size() != 12 && v.size() != 16) throw IoError(path, "data holds " + std::to_string(v.size()) + " values, not 12 or 16");
      return fromMatrix(v, path);
    }
  } catch (const YAML::Exception& e) {
    throw IoError(path, std::string("its transform cannot be read: ") + e.what());
  }
  throw IoError(path, "holds no transform: expected local_transform, translation + rotation, or data (12 or 16 values)");
}

class ExtrinsicSequence : public ForwardingSequence {
 public:
  ExtrinsicSequence(std::unique_ptr<Sequence> inner, const Eigen::Isometry3d& T) : ForwardingSequence(std::move(inner)), T_(T) {}
  std::string describe() const override { return inner().describe() + ", the camera at `extrinsics` on the posed frame"; }
  Frame load(int n) const override {
    Frame f = inner().load(n);
    if (f.T_world_camera) f.T_world_camera = *f.T_world_camera * T_;
    return f;
  }
  std::optional<Eigen::Isometry3d> pose(int n) const override {
    auto p = inner().pose(n);
    if (p) p = *p * T_;
    return p;
  }

 private:
  Eigen::Isometry3d T_;
};

}  // namespace

Eigen::Isometry3d parseExtrinsics(const std::string& spec) {
  std::error_code ec;
  if (std::filesystem::is_regular_file(spec, ec)) return fromYaml(spec);
  std::vector<double> v;
  std::stringstream in(spec);
  std::string token;
  while (std::getline(in, token, ',')) {
    const auto x = parseFiniteNumber(token);
    if (!x) throw util::FieldError("extrinsics", "'" + token + "' is not a number (expected x,y,z,qx,qy,qz,qw or a YAML file)");
    v.push_back(*x);
  }
  if (v.size() != 7) {
    throw util::FieldError("extrinsics", "takes 7 numbers x,y,z,qx,qy,qz,qw (the camera's pose in the posed frame) or a YAML file; got " +
                                             std::to_string(v.size()) + (std::filesystem::exists(spec, ec) ? "" : " (and no file " + spec + ")"));
  }
  try {
    return fromQuaternion(v, "extrinsics");
  } catch (const IoError& e) {
    throw util::FieldError("extrinsics", e.reason());
  }
}

std::string extrinsicsText(const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.linear());
  char text[256];
  std::snprintf(text, sizeof text, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g", T.translation().x(), T.translation().y(),
                T.translation().z(), q.x(), q.y(), q.z(), q.w());
  return text;
}

std::unique_ptr<Sequence> withExtrinsics(std::unique_ptr<Sequence> seq, const Eigen::Isometry3d& T_base_camera) {
  return std::make_unique<ExtrinsicSequence>(std::move(seq), T_base_camera);
}

}  // namespace mobmap::sources
