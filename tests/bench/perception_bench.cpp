// The per-frame pipeline (a) against a reference built from stock PCL classes
// configured as the paper's original code (b), on the same VGA frames, in one run.
// Prints per-frame times and the medians of (a), (b) and (b)/(a). Release builds only.
//
//   perception_bench [SHARED_DATA_DIR] [--all] [--ours-only] [--repeat N] [--config FILE] [--voxel M] [--dump FILE]
//
// (a) runs N times per frame (default 3) and its median is reported; (b) runs once.
// --config FILE changes (a)'s parameters (for experiments; the reference is fixed);
// --voxel M then rescales them to M-metre voxels as `mobmap build --voxel` does.
// The allocator is set up as in `mobmap` (apps/src/main.cpp), so large buffers are
// reused instead of being mapped and faulted in afresh for every frame.
//
// --dump FILE writes, per frame, digests of (a)'s output (points, normals, labels,
// segment features: every bit) and each segment's features in text, so that a speed
// change can be checked to leave the results as they were: run both builds, diff.
//
// Without --all, every 50th frame of 7scenes-redkitchen is used (the reference takes
// seconds per frame); all other VGA frames of the data folder are always used.
#include "io/dataset.hpp"
#include "io/config.hpp"
#include "io/frame_source.hpp"
#include "mobmap/sources/pcd.hpp"

#include "mobmap/perception/pipeline.hpp"
#include "mobmap/perception/stages.hpp"
#include "kernels/simd.hpp"  // private: names the instruction set the kernels run on

#include <pcl/features/normal_3d.h>
#include <pcl/filters/extract_indices.h>
#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/filters/uniform_sampling.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/region_growing_rgb.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <malloc.h>
#include <map>
#include <string>
#include <vector>

using namespace mobmap;
using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;

namespace {

double ms(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double, std::milli>(b - a).count(); }
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

struct Input {
  std::string name;
  std::vector<Eigen::Vector3f> organized;  // width x height, NaN = invalid
  int width = 0, height = 0;
};

Input fromDepth(const std::string& name, const perception::DepthImage& d, const perception::PinholeIntrinsics& k) {
  Input in{name, {}, d.width, d.height};
  in.organized.resize(d.depth_m.size(), Eigen::Vector3f::Constant(NAN));
  for (int v = 0; v < d.height; ++v) {
    for (int u = 0; u < d.width; ++u) {
      const float z = d.at(u, v);
      if (z > 0) in.organized[static_cast<std::size_t>(v) * d.width + u] = perception::backProject(k, u, v, z).cast<float>();
    }
  }
  return in;
}

// FNV-1a over raw bytes: a digest that changes when any bit of the output does.
class Digest {
 public:
  template <typename T>
  void add(const T& value) {
    unsigned char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    for (unsigned char b : bytes) h_ = (h_ ^ b) * 0x100000001b3ULL;
  }
  [[nodiscard]] std::uint64_t value() const { return h_; }

 private:
  std::uint64_t h_ = 0xcbf29ce484222325ULL;
};

void dumpResult(std::FILE* f, const std::string& name, const perception::FrameResult& r) {
  Digest points, normals, labels, features;
  for (const auto& p : r.points) points.add(p.x()), points.add(p.y()), points.add(p.z());
  for (std::size_t i = 0; i < r.normals.size(); ++i) {
    normals.add(r.normals[i].x()), normals.add(r.normals[i].y()), normals.add(r.normals[i].z());
    normals.add(r.curvature[i]);
  }
  for (int l : r.segment_of_point) labels.add(l);
  for (const auto& s : r.segments) {
    features.add(s.slope_deg), features.add(s.roughness), features.add(s.mobility), features.add(s.area_m2);
  }
  std::fprintf(f, "%s: %zu points, %zu segments; points %016llx normals %016llx labels %016llx features %016llx\n",
               name.c_str(), r.points.size(), r.segments.size(), static_cast<unsigned long long>(points.value()),
               static_cast<unsigned long long>(normals.value()), static_cast<unsigned long long>(labels.value()),
               static_cast<unsigned long long>(features.value()));
  for (const auto& s : r.segments) {
    std::fprintf(f, "  %3d %6zu %s%s slope %.6f roughness %.6f mobility %.6f\n", s.id, s.points.size(),
                 s.is_ground ? "g" : "-", s.is_rough ? "r" : "-", s.slope_deg, s.roughness, s.mobility);
  }
}

// (b): the paper's original configuration of stock PCL classes.
double reference(const Input& in, double max_range, std::vector<double>& stage_ms) {
  const auto t0 = Clock::now();
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  for (const auto& p : in.organized) {
    if (p.allFinite() && p.norm() <= max_range && p.norm() >= 0.3) cloud->push_back({p.x(), p.y(), p.z()});
  }
  pcl::PointCloud<pcl::PointXYZ>::Ptr reduced(new pcl::PointCloud<pcl::PointXYZ>);
  pcl::UniformSampling<pcl::PointXYZ> us;
  us.setInputCloud(cloud);
  us.setRadiusSearch(0.01);
  us.filter(*reduced);
  const auto t1 = Clock::now();
  pcl::PointCloud<pcl::PointXYZ>::Ptr clean(new pcl::PointCloud<pcl::PointXYZ>);
  pcl::StatisticalOutlierRemoval<pcl::PointXYZ> sor;
  sor.setInputCloud(reduced);
  sor.setMeanK(50);
  sor.setStddevMulThresh(1.0);
  sor.filter(*clean);
  const auto t2 = Clock::now();
  pcl::PointCloud<pcl::Normal>::Ptr normals(new pcl::PointCloud<pcl::Normal>);
  pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> ne;
  pcl::search::KdTree<pcl::PointXYZ>::Ptr tree(new pcl::search::KdTree<pcl::PointXYZ>);
  ne.setInputCloud(clean);
  ne.setSearchMethod(tree);
  ne.setRadiusSearch(0.06);
  ne.setViewPoint(0, 0, 0);
  ne.compute(*normals);
  const auto t3 = Clock::now();
  pcl::SACSegmentation<pcl::PointXYZ> sac;
  sac.setModelType(pcl::SACMODEL_PLANE);
  sac.setMethodType(pcl::SAC_RANSAC);
  sac.setDistanceThreshold(0.02);
  sac.setInputCloud(clean);
  pcl::PointIndices::Ptr ground(new pcl::PointIndices);
  pcl::ModelCoefficients coeff;
  sac.segment(*ground, coeff);
  const auto t4 = Clock::now();
  // RGB-N colours (eq. 5) on the non-ground points, then RegionGrowingRGB.
  std::vector<Eigen::Vector3f> n3;
  for (const auto& n : normals->points) n3.emplace_back(std::isfinite(n.normal_x) ? Eigen::Vector3f(n.normal_x, n.normal_y, n.normal_z) : Eigen::Vector3f::Zero());
  const auto colours = perception::normalColours(n3);
  std::vector<bool> is_ground(clean->size(), false);
  for (int i : ground->indices) is_ground[static_cast<std::size_t>(i)] = true;
  pcl::PointCloud<pcl::PointXYZRGB>::Ptr rgb(new pcl::PointCloud<pcl::PointXYZRGB>);
  for (std::size_t i = 0; i < clean->size(); ++i) {
    if (is_ground[i]) continue;
    pcl::PointXYZRGB q;
    q.x = (*clean)[i].x;
    q.y = (*clean)[i].y;
    q.z = (*clean)[i].z;
    q.r = colours[i][0];
    q.g = colours[i][1];
    q.b = colours[i][2];
    rgb->push_back(q);
  }
  std::vector<pcl::PointIndices> clusters;
  if (rgb->size() > 50) {
    pcl::RegionGrowingRGB<pcl::PointXYZRGB> rg;
    pcl::search::KdTree<pcl::PointXYZRGB>::Ptr rtree(new pcl::search::KdTree<pcl::PointXYZRGB>);
    rg.setInputCloud(rgb);
    rg.setSearchMethod(rtree);
    rg.setDistanceThreshold(0.025f);
    rg.setPointColorThreshold(6);
    rg.setRegionColorThreshold(5);
    rg.setMinClusterSize(50);
    rg.extract(clusters);
  }
  const auto t5 = Clock::now();
  // Per segment: least-squares plane and CGAL Delaunay areas.
  std::vector<Eigen::Vector3f> pts;
  for (const auto& p : rgb->points) pts.emplace_back(p.x, p.y, p.z);
  for (const auto& c : clusters) {
    const std::vector<int> idx(c.indices.begin(), c.indices.end());
    (void)perception::delaunayRoughness(pts, idx, perception::leastSquaresPlane(pts, idx), 0.05,
                                        perception::Triangulator::kCgal);
  }
  const auto t6 = Clock::now();
  stage_ms = {ms(t0, t1), ms(t1, t2), ms(t2, t3), ms(t3, t4), ms(t4, t5), ms(t5, t6)};
  return ms(t0, t6);
}

}  // namespace

int main(int argc, char** argv) {
#ifndef NDEBUG
  std::fprintf(stderr, "warning: this is not a Release build; the numbers mean little\n");
#endif
  std::string data = "../shared/data";
  bool all = false, ours_only = false;
  int repeat = 3;
  std::string config_path, dump_path;
  double voxel = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--all") all = true;
    else if (a == "--ours-only") ours_only = true;
    else if (a == "--repeat" && i + 1 < argc) repeat = std::max(1, std::atoi(argv[++i]));
    else if (a == "--config" && i + 1 < argc) config_path = argv[++i];
    else if (a == "--voxel" && i + 1 < argc) voxel = std::atof(argv[++i]);
    else if (a == "--dump" && i + 1 < argc) dump_path = argv[++i];
    else data = a;
  }
  mallopt(M_MMAP_THRESHOLD, 256 << 20);  // as apps/src/main.cpp
  mallopt(M_TRIM_THRESHOLD, 512 << 20);
  if (!fs::exists(data)) {
    std::fprintf(stderr, "no data folder at %s (pass the path to shared/data)\n", data.c_str());
    return 1;
  }
  std::vector<Input> inputs;
  for (const auto& name : {"five_people.pcd", "milk_cartoon_all_small_clorox.pcd", "table_scene_mug_stereo_textured.pcd"}) {
    const auto f = sources::loadPcd(data + "/pcl-kinect/" + name);
    if (f.width == 640 && f.height == 480) inputs.push_back({name, f.points, f.width, f.height});
  }
  for (const auto& e : fs::directory_iterator(data + "/pcl-kinect/grabber_sequences")) {
    const auto f = sources::loadPcd(e.path().string());
    if (f.width == 640 && f.height == 480) inputs.push_back({e.path().filename().string(), f.points, f.width, f.height});
  }
  {
    const app::SevenScenesDirectory d(data + "/7scenes-redkitchen");
    for (std::size_t i = 0; i < d.frameNumbers().size(); i += all ? 1 : 50) {
      const int n = d.frameNumbers()[i];
      inputs.push_back(fromDepth("redkitchen " + std::to_string(n), d.readDepth(n), d.intrinsics()));
    }
    const app::SevenScenesDirectory l(data + "/3dmatch-lounge/seq-01");
    for (int n : l.frameNumbers()) inputs.push_back(fromDepth("lounge " + std::to_string(n), l.readDepth(n), l.intrinsics()));
  }
  for (int n : {1, 2}) {
    const auto d = app::readDepthPng(data + "/realsense-person/depth_image_" + std::to_string(n) + ".png");
    const auto k = app::readIntrinsicsFile(data + "/realsense-person/camera-intrinsics.txt", d.width, d.height);
    inputs.push_back(fromDepth("realsense " + std::to_string(n), d, k));
  }
  app::Config config;
  if (!config_path.empty()) config = app::loadConfig(config_path);
  if (voxel != 0) config.perception = perception::scaledToVoxel(config.perception, voxel);
  const perception::FramePipeline pipeline(config.perception, app::makeModel(config));  // 3 m range, one thread
  std::FILE* dump = nullptr;
  if (!dump_path.empty() && !(dump = std::fopen(dump_path.c_str(), "w"))) {
    std::fprintf(stderr, "cannot write %s\n", dump_path.c_str());
    return 1;
  }
  std::printf("(a)'s vector kernels on this CPU: %s\n", perception::toString(perception::bestSimd()));
  std::printf("%-40s %10s %10s %8s\n", "frame (VGA)", "(a) ms", "(b) ms", "(b)/(a)");
  std::vector<double> a_all, b_all, ratio;
  std::vector<std::vector<double>> b_stages(6);
  std::map<std::string, std::vector<double>> a_stages;
  for (const auto& in : inputs) {
    std::vector<double> runs;
    std::map<std::string, std::vector<double>> run_stages;
    for (int rep = 0; rep < repeat; ++rep) {
      const auto t0 = Clock::now();
      const auto r = pipeline.processOrganized(in.organized, in.width, in.height);
      runs.push_back(ms(t0, Clock::now()));
      for (const auto& s : r.stages) run_stages[s.name].push_back(s.milliseconds);
      if (dump && rep == 0) dumpResult(dump, in.name, r);
    }
    const double a = median(runs);
    for (const auto& [name, v] : run_stages) a_stages[name].push_back(median(v));
    std::vector<double> st;
    const double b = ours_only ? 0.0 : reference(in, 3.0, st);
    for (std::size_t i = 0; i < st.size(); ++i) b_stages[i].push_back(st[i]);
    a_all.push_back(a);
    b_all.push_back(b);
    ratio.push_back(b / a);
    std::printf("%-40s %10.1f %10.1f %8.1f\n", in.name.c_str(), a, b, b / a);
    std::fflush(stdout);
  }
  std::printf("\nmedians over %zu frames: (a) %.1f ms, (b) %.1f ms, per-frame ratio (b)/(a) %.1f\n", inputs.size(), median(a_all),
              median(b_all), median(ratio));
  std::printf("(a) per stage:");
  for (const auto& [name, v] : a_stages) std::printf(" %s %.1f", name.c_str(), median(v));
  const char* names[] = {"uniform sampling", "SOR k=50", "normals r=6cm", "RANSAC ground", "RGB-N + RegionGrowingRGB", "Delaunay"};
  std::printf("\n(b) per stage:");
  for (int i = 0; i < 6; ++i) std::printf(" %s %.1f", names[i], median(b_stages[static_cast<std::size_t>(i)]));
  std::printf("\n");
  if (dump) std::fclose(dump);
  return 0;
}
