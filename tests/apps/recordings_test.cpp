// Real recordings, right answers: the input mistakes labs make with their own cameras
// (a range that cuts away the floor, depth in another unit), reproduced on the
// simulated corridor, whose geometry is exact, and caught.
#include "io/dataset.hpp"
#include "io/depth_checks.hpp"
#include "io/frame_source.hpp"
#include "mobmap/sources/pcd.hpp"
#include "io/io_error.hpp"
#include "io/png_io.hpp"

#include "mobmap/perception/pipeline.hpp"
#include "mobmap/sim/corridor_scene.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <unistd.h>

namespace mobmap::app {
namespace {

namespace fs = std::filesystem;

// A frame of the noise-free corridor from a camera `pitch_deg` below the horizon.
sim::RenderedFrame corridorFrame(double pitch_deg, int frame = 60) {
  sim::CorridorParams p;
  p.pitch_down_deg = pitch_deg;
  p.bob_m = 0.0;
  return sim::CorridorScene(p).render(frame);
}

Eigen::Vector3f gravityInCamera(const sim::RenderedFrame& f) {
  return (f.T_world_camera.linear().transpose() * Eigen::Vector3d(0, 0, -1)).cast<float>();
}

// The counts against a brute-force pass over the pixels; the sampled percentiles within
// a few percent of the exact ones.
TEST(RangeReport, CountsWhatTheRangeTookAndWhereThePointsLay) {
  const sim::RenderedFrame f = corridorFrame(35.0);
  const sim::CorridorParams params;
  const perception::PinholeIntrinsics& k = params.intrinsics;
  // The range limits at the 20th and 80th percentiles of the frame's ranges.
  std::vector<double> ranges;
  std::vector<Eigen::Vector3f> points;
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const float z = f.depth.depth_m[static_cast<std::size_t>(v) * k.width + u];
      if (!(z > 0.f)) continue;
      // As the pipeline back-projects (float, reciprocal focal lengths), so that a point
      // on a range limit falls on the same side.
      const float inv_fx = static_cast<float>(1.0 / k.fx), inv_fy = static_cast<float>(1.0 / k.fy);
      points.emplace_back((static_cast<float>(u) - static_cast<float>(k.cx)) * inv_fx * z,
                          ((static_cast<float>(v) - static_cast<float>(k.cy)) * inv_fy) * z, z);
      ranges.push_back(points.back().norm());
    }
  }
  std::sort(ranges.begin(), ranges.end());
  perception::PerceptionParams pp;
  pp.min_range_m = ranges[ranges.size() / 5];
  pp.max_range_m = ranges[ranges.size() * 4 / 5];
  const perception::FramePipeline pipeline(pp, gp::MobilityModel{});
  const perception::FrameResult r = pipeline.process(f.depth, k, gravityInCamera(f));
  std::size_t beyond = 0, nearer = 0;
  for (const Eigen::Vector3f& q : points) {
    const float r2 = q.squaredNorm();
    beyond += r2 > static_cast<float>(pp.max_range_m * pp.max_range_m);
    nearer += r2 < static_cast<float>(pp.min_range_m * pp.min_range_m);
  }
  const std::size_t valid = points.size();
  EXPECT_EQ(r.range.valid_points, valid);
  EXPECT_EQ(r.range.beyond_max_range, beyond);
  EXPECT_EQ(r.range.nearer_than_min_range, nearer);
  ASSERT_GT(beyond, 1000u);
  ASSERT_GT(nearer, 1000u);
  EXPECT_EQ(r.stages.front().points_in, valid);
  EXPECT_NEAR(r.range.median_range_m, ranges[ranges.size() / 2], 0.03 * ranges[ranges.size() / 2]);
  EXPECT_NEAR(r.range.range_p95_m, ranges[ranges.size() * 95 / 100], 0.03 * ranges[ranges.size() * 95 / 100]);
  EXPECT_TRUE(r.range.down_from_gravity);
  // The floor is the lowest surface: the camera height below the camera.
  ASSERT_TRUE(r.range.lowest.has_value());
  EXPECT_NEAR(r.range.lowest->below_camera_m, params.camera_height_m, 0.02);
}

// The office case: a camera 1.35 m up looking level sees the floor only from 3.4 m on
// (its lower field of view is 21.5 degrees), so the default 3 m range drops all of it and
// leaves a box top or nothing as "ground". The warning says so and names the range that
// keeps it, which then finds the floor 1.35 m below.
TEST(RangeChecks, AFloorBeyondTheRangeIsFoundAndTheSuggestedRangeKeepsIt) {
  const sim::RenderedFrame f = corridorFrame(0.0);
  const sim::CorridorParams params;
  perception::PerceptionParams pp;  // max_range_m 3
  const perception::FrameResult r =
      perception::FramePipeline(pp, gp::MobilityModel{}).process(f.depth, params.intrinsics, gravityInCamera(f));
  ASSERT_TRUE(r.range.lowest.has_value());
  EXPECT_NEAR(r.range.lowest->below_camera_m, params.camera_height_m, 0.03);
  EXPECT_GT(r.range.lowest->share_beyond, 0.99);
  const std::optional<double> ground = r.ground_plane ? std::optional<double>((*r.ground_plane)(3)) : std::nullopt;
  if (ground) {
    EXPECT_LT(*ground, 1.0);  // not the floor
  }
  const auto problem = floorCutProblem(r.range, ground);
  ASSERT_TRUE(problem.has_value());
  EXPECT_NE(problem->find("1.35 m below the camera (along gravity)"), std::string::npos) << *problem;
  const double suggested = rangeToSuggest(r.range.lowest->range_p95_m);
  EXPECT_NE(problem->find("`max_range_m` " + std::to_string(static_cast<int>(suggested)) +
                          (suggested == std::floor(suggested) ? " " : ".5 ")),
            std::string::npos)
      << *problem;
  EXPECT_GE(suggested, 3.5);
  pp.max_range_m = suggested;
  const perception::FrameResult kept =
      perception::FramePipeline(pp, gp::MobilityModel{}).process(f.depth, params.intrinsics, gravityInCamera(f));
  ASSERT_TRUE(kept.ground_plane.has_value());
  EXPECT_NEAR((*kept.ground_plane)(3), params.camera_height_m, 0.03);
  EXPECT_FALSE(floorCutProblem(kept.range, (*kept.ground_plane)(3)).has_value());
  // Pitched down as a walking head is, the floor is near and nothing is said.
  const sim::RenderedFrame walking = corridorFrame(35.0);
  const perception::FrameResult w = perception::FramePipeline(perception::PerceptionParams{}, gp::MobilityModel{})
                                        .process(walking.depth, params.intrinsics, gravityInCamera(walking));
  EXPECT_FALSE(floorCutProblem(w.range, w.ground_plane ? std::optional<double>((*w.ground_plane)(3)) : std::nullopt));
  EXPECT_FALSE(rangeCutProblem(w.range));
  // Most of the level view lies beyond 1.5 m: that is said too, with the range that keeps it.
  pp.max_range_m = 1.5;
  const perception::FrameResult cut =
      perception::FramePipeline(pp, gp::MobilityModel{}).process(f.depth, params.intrinsics, gravityInCamera(f));
  ASSERT_GT(cut.range.shareBeyond(), 0.5);
  const auto most = rangeCutProblem(cut.range);
  ASSERT_TRUE(most.has_value());
  EXPECT_NE(most->find("beyond `max_range_m` 1.5 m"), std::string::npos) << *most;
}

struct TempDir {
  TempDir() : path(fs::temp_directory_path() / ("mobmap_recordings_" + std::to_string(::getpid()))) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() { fs::remove_all(path); }
  fs::path path;
};

// A 16-bit depth PNG of the corridor written in `units_per_m`.
std::string writeDepthIn(const TempDir& dir, const sim::RenderedFrame& f, double units_per_m) {
  Image16 img{f.depth.width, f.depth.height, {}};
  for (float z : f.depth.depth_m) {
    const double v = std::round(static_cast<double>(z) * units_per_m);
    img.pixels.push_back(z > 0.f && v < 65535 ? static_cast<std::uint16_t>(v) : 0);
  }
  const std::string path = (dir.path / ("d" + std::to_string(static_cast<int>(units_per_m)) + ".png")).string();
  writePng16(path, img);
  writeIntrinsicsFile((dir.path / "camera-intrinsics.txt").string(), sim::CorridorParams{}.intrinsics);
  return path;
}

// Depth written in tenths of a millimetre and read as millimetres lies 10 times too far:
// the check names the unit that fits, and read in it the floor is found.
TEST(DepthUnit, DepthInAnotherUnitIsCaughtAndTheSuggestedScaleReadsIt) {
  const TempDir dir;
  // Pitched 60 degrees down: every depth within 6.5 m fits the 16-bit PNG at 10000 per metre.
  const sim::RenderedFrame f = corridorFrame(60.0);
  const std::string png = writeDepthIn(dir, f, 10000.0);
  Frame frame = loadSingleFrame(png, -1, "");
  EXPECT_EQ(frame.depth_unit.units_per_m, 1000.0);
  const perception::FramePipeline pipeline(perception::PerceptionParams{}, gp::MobilityModel{});
  const perception::FrameResult wrong = perceiveFrame(pipeline, frame, gravityInCamera(f));
  EXPECT_GT(wrong.range.median_range_m, kPlausibleMedianMax);
  const auto problem = depthUnitProblem(wrong.range, frame.depth_unit);
  ASSERT_TRUE(problem.has_value());
  // 10000 puts the median at 1.65 m, 5000 at 3.3 m: both are named, the nearer to 2 m first.
  EXPECT_NE(problem->find("; `depth_scale` 10000 (tenths of a millimetre) puts the median at 1.6"), std::string::npos) << *problem;
  EXPECT_NE(problem->find(", 5000 (TUM's unit) puts the median at 3.29 m"), std::string::npos) << *problem;
  EXPECT_FALSE(wrong.ground_plane.has_value());
  rescaleDepth(frame, 10000.0);
  const perception::FrameResult right = perceiveFrame(pipeline, frame, gravityInCamera(f));
  EXPECT_FALSE(depthUnitProblem(right.range, frame.depth_unit).has_value());
  ASSERT_TRUE(right.ground_plane.has_value());
  EXPECT_NEAR((*right.ground_plane)(3), sim::CorridorParams{}.camera_height_m, 0.02);
  // Read 10 times too near (a millimetre PNG taken for tenths): caught from the other side.
  Frame near = loadSingleFrame(writeDepthIn(dir, f, 1000.0), -1, "");
  rescaleDepth(near, 10000.0);
  const perception::FrameResult too_near = perceiveFrame(pipeline, near, gravityInCamera(f));
  EXPECT_LT(too_near.range.median_range_m, kPlausibleMedianMin);
  const auto other = depthUnitProblem(too_near.range, near.depth_unit);
  ASSERT_TRUE(other.has_value());
  EXPECT_NE(other->find("`depth_scale` 1000 (millimetres)"), std::string::npos) << *other;
  EXPECT_THROW(rescaleDepth(near, 0.0), util::FieldError);
}

// A single depth PNG is a sequence of one frame without a pose: the same interface as a
// directory, and the frame it gives is the file's depth at its camera.
TEST(FrameSource, ASingleFileIsASequenceOfOneFrame) {
  const TempDir dir;
  const sim::RenderedFrame f = corridorFrame(30.0);
  const std::string png = writeDepthIn(dir, f, 1000.0);
  const auto seq = openSequence(png, {"", 0.05, "", {}, ""});
  EXPECT_EQ(seq->frames(), std::vector<int>{0});
  EXPECT_FALSE(seq->posed());
  EXPECT_TRUE(seq->hasDepth());
  EXPECT_EQ(seq->intrinsics().fx, sim::CorridorParams{}.intrinsics.fx);
  const Frame one = seq->load(0);
  EXPECT_FALSE(one.T_world_camera.has_value());
  ASSERT_TRUE(one.depth.has_value());
  const perception::DepthImage file = readDepthPng(png);
  EXPECT_EQ(one.depth->depth_m, file.depth_m);
  for (std::size_t i = 0; i < file.depth_m.size(); i += 101) {
    if (f.depth.depth_m[i] > 0.f && f.depth.depth_m[i] < 60.f) {
      EXPECT_NEAR(file.depth_m[i], f.depth.depth_m[i], 5e-4f);
    }
  }
  // analyze's loader goes through the same sequence; a frame number other than 0 is refused.
  const Frame loaded = loadSingleFrame(png, -1, "");
  EXPECT_EQ(loaded.depth->depth_m, one.depth->depth_m);
  EXPECT_NE(loaded.note.find("camera-intrinsics.txt"), std::string::npos) << loaded.note;
  try {
    (void)loadSingleFrame(png, 3, "");
    ADD_FAILURE() << "frame 3 of a single file was loaded";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("is a single frame"), std::string::npos) << e.what();
  }
  // A missing file is named as missing, before any question of its camera.
  const std::string missing = (dir.path / "none.png").string();
  try {
    (void)loadSingleFrame(missing, -1, "");
    ADD_FAILURE() << "a missing PNG was loaded";
  } catch (const IoError& e) {
    EXPECT_EQ(std::string(e.what()), missing + ": no such file");
  }
}

// Camera files as labs have them: ROS 1 and ROS 2 camera_info dumps, a ROS calibration
// file and OpenCV's calibration YAML all give the camera the plain 3x3 text gives.
TEST(CameraFiles, RosAndOpenCvYamlGiveTheSameCameraAsTheMatrixText) {
  const TempDir dir;
  const perception::PinholeIntrinsics want{640, 480, 585.5, 586.25, 320.125, 240.0625};
  const auto write = [&](const std::string& name, const std::string& text) {
    const std::string path = (dir.path / name).string();
    std::ofstream(path) << text;
    return path;
  };
  const std::vector<std::string> files = {
      write("k.txt", "585.5 0 320.125\n0 586.25 240.0625\n0 0 1\n"),
      write("ros1.yaml", "header:\n  seq: 12\n  stamp: {secs: 1, nsecs: 2}\n  frame_id: \"camera_depth_optical_frame\"\n"
                         "height: 480\nwidth: 640\ndistortion_model: \"plumb_bob\"\nD: [0.0, 0.0, 0.0, 0.0, 0.0]\n"
                         "K: [585.5, 0.0, 320.125, 0.0, 586.25, 240.0625, 0.0, 0.0, 1.0]\n"
                         "R: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]\n"
                         "P: [585.5, 0.0, 320.125, 0.0, 0.0, 586.25, 240.0625, 0.0, 0.0, 0.0, 1.0, 0.0]\nbinning_x: 0\n"),
      write("ros2.yaml", "header:\n  frame_id: depth\nheight: 0\nwidth: 0\nd: []\n"
                         "k:\n- 585.5\n- 0.0\n- 320.125\n- 0.0\n- 586.25\n- 240.0625\n- 0.0\n- 0.0\n- 1.0\n"),
      write("ost.yaml", "image_width: 640\nimage_height: 480\ncamera_name: depth\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
                        "  data: [585.5, 0, 320.125, 0, 586.25, 240.0625, 0, 0, 1]\ndistortion_model: plumb_bob\n"
                        "distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0, 0, 0, 0, 0]\n"),
      write("opencv.yml", "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: !!opencv-matrix\n"
                          "   rows: 3\n   cols: 3\n   dt: d\n   data: [ 5.8550000000000000e+02, 0., 3.2012500000000000e+02, 0.,\n"
                          "       5.8625000000000000e+02, 2.4006250000000000e+02, 0., 0., 1. ]\n"
                          "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n"
                          "   data: [ 0., 0., 0., 0., 0. ]\n"),
  };
  for (const std::string& f : files) {
    SCOPED_TRACE(f);
    EXPECT_EQ(readIntrinsicsFile(f, 640, 480), want);
    EXPECT_EQ(parseIntrinsics(f, 640, 480), want);
  }
  // What is wrong is named, with the file.
  const auto refused = [&](const std::string& name, const std::string& text, const std::string& message) {
    const std::string path = write(name, text);
    try {
      readIntrinsicsFile(path, 640, 480);
      ADD_FAILURE() << "accepted " << name;
    } catch (const IoError& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  };
  refused("hd.yaml", "image_width: 1280\nimage_height: 720\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
                     "  data: [900, 0, 640, 0, 900, 360, 0, 0, 1]\n",
          "is for 1280x720 images, but the depth frames are 640x480");
  refused("eight.yaml", "K: [1, 0, 2, 0, 1, 2, 0, 0]\n", "\"K\" must hold 9 numbers");
  refused("skew.yaml", "K: [585, 3, 320, 0, 585, 240, 0, 0, 1]\n", "not a pinhole camera matrix");
  refused("text.yaml", "K: [585, 0, 320, 0, five, 240, 0, 0, 1]\n", "\"K\" entry 4 is not a finite number");
  refused("4x4.yaml", "camera_matrix:\n  rows: 4\n  cols: 4\n  data: [1]\n", "\"camera_matrix\" must be 3x3");
  refused("none.yaml", "%YAML:1.0\n---\ndistortion_coefficients: [0, 0]\n", "has no camera matrix");
  refused("broken.yaml", "K: [585, 0, 320\n", "not valid YAML");
  // A camera known by its field of view: fx = fy = (w / 2) / tan(fov / 2), centred.
  const perception::PinholeIntrinsics fov = parseIntrinsics("fov:57", 640, 480);
  EXPECT_NEAR(fov.fx, 320.0 / std::tan(28.5 * M_PI / 180.0), 1e-9);
  EXPECT_EQ(fov.fx, fov.fy);
  EXPECT_EQ(fov.cx, 319.5);
  EXPECT_EQ(fov.cy, 239.5);
  EXPECT_THROW(parseIntrinsics("fov:180", 640, 480), util::FieldError);
  EXPECT_THROW(parseIntrinsics("fov:wide", 640, 480), util::FieldError);
}

// Looking straight down at the stairs (no gravity given): the largest plane is the floor
// seen from above, 90 degrees from the image's up axis, with the treads parallel to it
// at their heights. That is no wall, and --gravity 0,1,0 would be wrong: nothing is said.
// A wall seen head-on above a floor still gets the note (Cli.WithoutGravity...).
TEST(GroundNote, ALookStraightDownAtStairsIsNotTakenForAWall) {
  sim::CorridorParams p;
  p.frames = 300;
  p.pitch_down_deg = 90.0;
  p.bob_m = 0.0;
  const sim::CorridorScene scene(p);
  const perception::PerceptionParams pp;
  const perception::FramePipeline pipeline(pp, gp::MobilityModel{});
  for (const int frame : {264, 272, 280}) {  // the camera above treads 2 to 4 (x 6.6-7.0 m)
    SCOPED_TRACE(frame);
    const sim::RenderedFrame f = scene.render(frame);
    const perception::FrameResult r = pipeline.process(f.depth, p.intrinsics, std::nullopt);
    ASSERT_TRUE(r.ground_plane.has_value());
    EXPECT_GT(perception::imageUpTiltDeg(*r.ground_plane), 80.0);  // what set the note off
    EXPECT_EQ(groundChoiceNote(r, pp.ground_upright_prior_deg), "");
    // Given gravity, the ground is the floor 1.35 m below.
    const perception::FrameResult g = pipeline.process(f.depth, p.intrinsics, gravityInCamera(f));
    ASSERT_TRUE(g.ground_plane.has_value());
    EXPECT_NEAR((*g.ground_plane)(3), p.camera_height_m, 0.02);
  }
}

// An organized cloud of the corridor frame in camera coordinates, moved by T (cloud =
// T * camera).
std::vector<Eigen::Vector3f> organizedCloud(const sim::RenderedFrame& f, const Eigen::Isometry3d& T) {
  const perception::PinholeIntrinsics k = sim::CorridorParams{}.intrinsics;
  std::vector<Eigen::Vector3f> cloud(static_cast<std::size_t>(k.width) * static_cast<std::size_t>(k.height),
                                     Eigen::Vector3f::Constant(std::nanf("")));
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * static_cast<std::size_t>(k.width) + static_cast<std::size_t>(u);
      const float z = f.depth.depth_m[i];
      if (z > 0.f) cloud[i] = (T * perception::backProject(k, u, v, z)).cast<float>();
    }
  }
  return cloud;
}

// `cloud` with `share` of its measured points moved to one another's pixels.
std::vector<Eigen::Vector3f> shuffledPoints(std::vector<Eigen::Vector3f> cloud, double share) {
  std::mt19937 rng(5);
  std::vector<std::size_t> measured;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (cloud[i].allFinite()) measured.push_back(i);
  }
  std::shuffle(measured.begin(), measured.end(), rng);
  measured.resize(static_cast<std::size_t>(share * static_cast<double>(measured.size())));
  std::vector<Eigen::Vector3f> moved;
  for (const std::size_t i : measured) moved.push_back(cloud[i]);
  std::rotate(moved.begin(), moved.begin() + 1, moved.end());  // each to another's pixel
  for (std::size_t j = 0; j < measured.size(); ++j) cloud[measured[j]] = moved[j];
  return cloud;
}

// A Kinect v2 driver's frame: the camera's turned a quarter about the optical axis (x down).
Eigen::Isometry3d quarterTurn() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

// The pixel grid tells where each point's ray goes: the camera's intrinsics and its pose
// in the cloud's frame come back from a cloud in any frame.
TEST(OrganizedCamera, TheCameraOfACloudInAnotherFrameIsRecovered) {
  const sim::RenderedFrame f = corridorFrame(35.0);
  const perception::PinholeIntrinsics k = sim::CorridorParams{}.intrinsics;
  // A Kinect v2 driver's frame: x down, y left (a quarter turn about the optical axis);
  // a robot's base frame: turned and 1.2 m off; and the camera frame itself.
  const Eigen::Isometry3d quarter = quarterTurn();
  Eigen::Isometry3d robot = Eigen::Isometry3d::Identity();
  robot.linear() = (Eigen::AngleAxisd(-M_PI / 2, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(-M_PI / 2 - 0.6, Eigen::Vector3d::UnitX()))
                       .toRotationMatrix();
  robot.translation() = Eigen::Vector3d(0.1, -0.05, 1.2);
  for (const Eigen::Isometry3d& T : {Eigen::Isometry3d(Eigen::Isometry3d::Identity()), quarter, robot}) {
    SCOPED_TRACE(T.matrix());
    const auto fit = perception::fitOrganizedCamera(organizedCloud(f, T), k.width, k.height);
    ASSERT_TRUE(fit.has_value());
    EXPECT_LT(fit->rms_px, 0.01);
    EXPECT_LT(std::abs(fit->skew), 1e-5);
    EXPECT_NEAR(fit->intrinsics.fx, k.fx, 0.01);
    EXPECT_NEAR(fit->intrinsics.fy, k.fy, 0.01);
    EXPECT_NEAR(fit->intrinsics.cx, k.cx, 0.01);
    EXPECT_NEAR(fit->intrinsics.cy, k.cy, 0.01);
    EXPECT_LT((fit->T_cloud_camera.linear() - T.linear()).norm(), 1e-5);
    EXPECT_LT((fit->T_cloud_camera.translation() - T.translation()).norm(), 1e-4);
  }
  // Points moved to one another's pixels are no camera's image: with half of them moved,
  // the robust fit finds the camera of the other half and says how few they are; with
  // three quarters moved, it finds none or one with fewer still.
  const std::vector<Eigen::Vector3f> half = shuffledPoints(organizedCloud(f, Eigen::Isometry3d::Identity()), 0.5);
  const auto bad = perception::fitOrganizedCamera(half, k.width, k.height);
  ASSERT_TRUE(bad.has_value());
  EXPECT_NEAR(bad->inlier_share, 0.5, 0.01);
  EXPECT_LT(bad->rms_px, 0.01);  // over the points that are still a pinhole image
  EXPECT_NEAR(bad->intrinsics.fx, k.fx, 0.01);
  const std::vector<Eigen::Vector3f> most = shuffledPoints(organizedCloud(f, Eigen::Isometry3d::Identity()), 0.75);
  const auto worse = perception::fitOrganizedCamera(most, k.width, k.height);
  EXPECT_TRUE(!worse.has_value() || worse->inlier_share < sources::kMinCameraInlierShare) << worse->inlier_share;
}

// An organized binary PCD (x y z floats, NaN where there is no point).
std::string writeOrganizedPcd(const TempDir& dir, const std::string& name, const std::vector<Eigen::Vector3f>& cloud, int w, int h) {
  const std::string path = (dir.path / name).string();
  std::ofstream out(path, std::ios::binary);
  out << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH " << w << "\nHEIGHT " << h
      << "\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << cloud.size() << "\nDATA binary\n";
  out.write(reinterpret_cast<const char*>(cloud.data()), static_cast<std::streamsize>(cloud.size() * sizeof(Eigen::Vector3f)));
  return path;
}

// The corridor frame as an organized PCD, its points moved by T.
std::string writeFramePcd(const TempDir& dir, const std::string& name, const sim::RenderedFrame& f, const Eigen::Isometry3d& T) {
  const perception::PinholeIntrinsics k = sim::CorridorParams{}.intrinsics;
  return writeOrganizedPcd(dir, name, organizedCloud(f, T), k.width, k.height);
}

// A Kinect v2 cloud whose points are its camera frame turned a quarter (x down) was scored
// upside down. Fitted from its pixel grid, it is scored in its camera's frame and gives the
// camera-frame cloud's segments, reported in its own frame (normals and centroids turned).
TEST(OrganizedCamera, ACloudInATurnedFrameScoresAsInItsCameraFrame) {
  const TempDir dir;
  const sim::RenderedFrame f = corridorFrame(35.0);
  const Eigen::Isometry3d quarter = quarterTurn();
  const std::string plain = writeFramePcd(dir, "camera.pcd", f, Eigen::Isometry3d::Identity());
  const std::string turned = writeFramePcd(dir, "turned.pcd", f, quarter);
  const perception::FramePipeline pipeline(perception::PerceptionParams{}, gp::MobilityModel{});
  Frame a = sources::loadPcd(plain);
  EXPECT_FALSE(a.T_cloud_camera.has_value());
  EXPECT_EQ(a.note, "");
  Frame b = sources::loadPcd(turned);
  ASSERT_TRUE(b.T_cloud_camera.has_value());
  EXPECT_LT((b.T_cloud_camera->linear() - quarter.linear()).norm(), 1e-5);
  EXPECT_NE(b.note.find("turned 90.0 degrees"), std::string::npos) << b.note;
  perception::FrameResult ra = perceiveFrame(pipeline, a, std::nullopt);  // no gravity: the image's up axis decides
  perception::FrameResult rb = perceiveFrame(pipeline, b, std::nullopt);
  toInputFrame(ra, a);
  toInputFrame(rb, b);
  ASSERT_TRUE(ra.ground_plane.has_value());
  ASSERT_TRUE(rb.ground_plane.has_value());
  ASSERT_EQ(ra.segments.size(), rb.segments.size());
  ASSERT_GT(ra.segments.size(), 5u);
  const Eigen::Matrix3f R = quarter.linear().cast<float>();
  for (std::size_t i = 0; i < ra.segments.size(); ++i) {
    SCOPED_TRACE(i);
    const auto& sa = ra.segments[i];
    const auto& sb = rb.segments[i];
    EXPECT_NEAR(sa.points.size(), sb.points.size(), 0.02 * sa.points.size() + 5);
    EXPECT_NEAR(sa.slope_deg, sb.slope_deg, 0.5);
    EXPECT_NEAR(sa.mobility, sb.mobility, 0.05);
    EXPECT_LT((R * sa.normal - sb.normal).norm(), 0.01);
    EXPECT_LT((R * sa.centroid - sb.centroid).norm(), 0.01);
  }
  EXPECT_NEAR((*ra.ground_plane)(3), (*rb.ground_plane)(3), 0.005);
  // Points a shuffle took off their rays: no camera's; said, and scored as they are.
  const std::vector<Eigen::Vector3f> shuffled = shuffledPoints(organizedCloud(f, quarter), 0.5);
  const perception::PinholeIntrinsics k = sim::CorridorParams{}.intrinsics;
  const Frame c = sources::loadPcd(writeOrganizedPcd(dir, "shuffled.pcd", shuffled, k.width, k.height));
  EXPECT_FALSE(c.T_cloud_camera.has_value());
  EXPECT_NE(c.note.find("its frame cannot be recovered"), std::string::npos) << c.note;
}

// A driver stores "no measurement" as a placeholder (the origin of its frame, a fixed
// point) or NaN, and real clouds have points off their rays (mixed pixels at edges). A
// Kinect v2 staircase cloud with its holes stored so was scored upside down: the fit
// counted them. The camera is found from the measured points on their rays, the
// placeholders and stray points are left out, and the frame scores as the clean one.
TEST(OrganizedCamera, PlaceholdersAndStrayPointsDoNotHideTheCamera) {
  const TempDir dir;
  const sim::RenderedFrame f = corridorFrame(35.0);
  const perception::PinholeIntrinsics k = sim::CorridorParams{}.intrinsics;
  const Eigen::Isometry3d quarter = quarterTurn();
  const std::vector<Eigen::Vector3f> clean = organizedCloud(f, quarter);
  const perception::FramePipeline pipeline(perception::PerceptionParams{}, gp::MobilityModel{});
  Frame reference = sources::loadPcd(writeOrganizedPcd(dir, "clean.pcd", clean, k.width, k.height));
  perception::FrameResult want = perceiveFrame(pipeline, reference, std::nullopt);
  ASSERT_TRUE(want.ground_plane.has_value());
  std::vector<std::size_t> measured;
  for (std::size_t i = 0; i < clean.size(); ++i) {
    if (clean[i].allFinite()) measured.push_back(i);
  }
  for (const double holes : {0.05, 0.2}) {
    for (const Eigen::Vector3f& placeholder : {Eigen::Vector3f(0.f, 0.f, 0.f), Eigen::Vector3f(0.f, 0.f, 8.f)}) {
      SCOPED_TRACE(std::to_string(holes) + " placeholder z " + std::to_string(placeholder.z()));
      std::mt19937 rng(11);
      std::vector<std::size_t> order = measured;
      std::shuffle(order.begin(), order.end(), rng);
      std::vector<Eigen::Vector3f> cloud = clean;
      const auto n_holes = static_cast<std::size_t>(holes * static_cast<double>(measured.size()));
      const std::size_t n_nan = n_holes / 4, n_placeholders = n_holes - n_nan;
      const std::size_t n_stray = measured.size() / 50;  // 2 %: moved 5 cm across their rays
      std::size_t next = 0;
      for (std::size_t j = 0; j < n_nan; ++j) cloud[order[next++]] = Eigen::Vector3f::Constant(std::nanf(""));
      for (std::size_t j = 0; j < n_placeholders; ++j) cloud[order[next++]] = placeholder;
      const Eigen::Vector3f across = (quarter.linear() * Eigen::Vector3d(0.05, 0.0, 0.0)).cast<float>();
      for (std::size_t j = 0; j < n_stray; ++j) cloud[order[next++]] += across;
      const auto fit = perception::fitOrganizedCamera(cloud, k.width, k.height);
      ASSERT_TRUE(fit.has_value());
      EXPECT_EQ(fit->unmeasured, clean.size() - measured.size() + n_holes);
      EXPECT_NEAR(fit->inlier_share, 1.0 - static_cast<double>(n_stray) / static_cast<double>(measured.size() - n_holes), 0.01);
      EXPECT_LT(fit->rms_px, 0.01);
      EXPECT_NEAR(fit->intrinsics.fx, k.fx, 0.01);
      EXPECT_NEAR(fit->intrinsics.cy, k.cy, 0.01);
      EXPECT_LT((fit->T_cloud_camera.linear() - quarter.linear()).norm(), 1e-5);
      Frame got = sources::loadPcd(writeOrganizedPcd(dir, "holes.pcd", cloud, k.width, k.height));
      ASSERT_TRUE(got.T_cloud_camera.has_value()) << got.note;
      EXPECT_LT((got.T_cloud_camera->linear() - quarter.linear()).norm(), 1e-5);
      EXPECT_NE(got.note.find(std::to_string(n_placeholders) + " pixels hold a placeholder"), std::string::npos) << got.note;
      EXPECT_NE(got.note.find(std::to_string(n_stray) + " of its " + std::to_string(measured.size() - n_holes) + " measured points"),
                std::string::npos)
          << got.note;
      std::size_t left = 0;
      for (const Eigen::Vector3f& p : got.points) left += p.allFinite();
      EXPECT_EQ(left, measured.size() - n_holes - n_stray);
      // Scored right side up: the floor is the ground, at the clean frame's distance.
      const perception::FrameResult r = perceiveFrame(pipeline, got, std::nullopt);
      ASSERT_TRUE(r.ground_plane.has_value());
      EXPECT_NEAR((*r.ground_plane)(3), (*want.ground_plane)(3), 0.005);
      EXPECT_LT(((*r.ground_plane).head<3>() - (*want.ground_plane).head<3>()).norm(), 0.01);
    }
  }
}

// A robot's camera 0.6 m up, pitched 3.4 degrees up, without gravity: measured along
// the camera's +y axis the far floor lies lower than the near floor, so the "lowest
// surface" was the far floor beyond the range and a note said the floor was cut away
// while the ground taken was the floor. Measured along the ground found, the lowest
// surface is the floor the ground is, and nothing is said.
TEST(RangeChecks, APitchedRobotCameraGetsNoFalseFloorNote) {
  sim::CorridorParams params;
  params.camera_height_m = 0.6;
  params.pitch_down_deg = -3.4;
  params.bob_m = 0.0;
  const sim::RenderedFrame f = sim::CorridorScene(params).render(60);
  const perception::FrameResult r =
      perception::FramePipeline(perception::PerceptionParams{}, gp::MobilityModel{}).process(f.depth, params.intrinsics, std::nullopt);
  ASSERT_TRUE(r.ground_plane.has_value());
  EXPECT_NEAR((*r.ground_plane)(3), 0.6, 0.03);  // the floor
  EXPECT_FALSE(r.range.down_from_gravity);
  EXPECT_TRUE(r.range.down_from_ground);
  ASSERT_TRUE(r.range.lowest.has_value());
  EXPECT_NEAR(r.range.lowest->below_camera_m, 0.6, 0.03);
  const auto note = floorCutProblem(r.range, (*r.ground_plane)(3));
  EXPECT_FALSE(note.has_value()) << *note;
  // Along the camera's +y the far floor is up to D sin(3.4 deg) lower: the old reading.
  double deepest = 0;
  const perception::PinholeIntrinsics& k = params.intrinsics;
  for (int v = 0; v < k.height; v += 4) {
    for (int u = 0; u < k.width; u += 4) {
      const float z = f.depth.at(u, v);
      if (z > 0.f) deepest = std::max(deepest, perception::backProject(k, u, v, z).y());
    }
  }
  EXPECT_GT(deepest, 0.6 + 0.15);  // what made the false note
}

// The output of `mobmap ARGS` (stdout and stderr) and its exit code.
std::pair<int, std::string> mobmap(const std::string& args) {
  const std::string cmd = std::string(MOBMAP_EXE) + " " + args + " 2>&1";
  std::string out;
  FILE* pipe = ::popen(cmd.c_str(), "r");
  if (!pipe) return {-1, "popen failed"};
  char buf[4096];
  while (std::fgets(buf, sizeof buf, pipe)) out += buf;
  const int status = ::pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

// SUN RGB-D stores depth PNGs as millimetres rotated left by 3 bits. Read as millimetres
// they lie 8 times too far; the median alone pointed at 10000 per metre, 20 % off. The
// stored values' low bits point at the right reading; a build of such frames alone
// writes no map; --depth-format sunrgbd decodes them to the map of the plain frames.
TEST(DepthUnit, SunRgbdDepthIsRecognisedByItsLowBitsAndDecoded) {
  const TempDir dir;
  const std::string seq = (dir.path / "seq").string(), sun = (dir.path / "sun").string();
  ASSERT_EQ(mobmap("simulate --out " + seq + " --frames 2 --noise none --quiet").first, 0);
  fs::create_directories(sun);
  for (const auto& e : fs::directory_iterator(seq)) {
    const std::string name = e.path().filename().string();
    if (name.size() > 10 && name.substr(name.size() - 10) == ".depth.png") {
      Image16 img = readPng16(e.path().string());
      for (std::uint16_t& v : img.pixels) v = static_cast<std::uint16_t>((v << 3) | (v >> 13));
      writePng16((fs::path(sun) / name).string(), img);
    } else {
      fs::copy(e.path(), fs::path(sun) / name);
    }
  }
  const auto [analyzed, warned] = mobmap("analyze " + sun + " --frame 1");
  EXPECT_EQ(analyzed, 0) << warned;
  EXPECT_NE(warned.find("% of its values are multiples of 8 (their 3 low bits are zero): --depth-scale 8000 puts the median at"),
            std::string::npos)
      << warned;
  EXPECT_NE(warned.find("--depth-format sunrgbd decodes SUN RGB-D's depth PNGs"), std::string::npos) << warned;
  EXPECT_EQ(warned.find("--depth-scale 10000"), std::string::npos) << warned;
  const auto [fixed, quiet] = mobmap("analyze " + sun + " --frame 1 --depth-format sunrgbd");
  EXPECT_EQ(fixed, 0) << quiet;
  EXPECT_EQ(quiet.find("another unit"), std::string::npos) << quiet;
  // Every frame in another unit: no map, and the diagnosis; also when a range long enough
  // for the misread depth would have left something to map.
  const std::string wrong = (dir.path / "wrong.ot").string();
  for (const std::string range : {"", " --max-range 30 --resolution 0.1 --voxel 0.05"}) {
    const auto [refused, why] = mobmap("build " + sun + " --out " + wrong + range + " --quiet");
    EXPECT_EQ(refused, 1) << why;
    EXPECT_NE(why.find("--depth-format sunrgbd decodes"), std::string::npos) << why;
    EXPECT_NE(why.find("no map written"), std::string::npos) << why;
    if (!range.empty()) {
      EXPECT_NE(why.find("every frame fused reads as depth in another unit"), std::string::npos) << why;
    }
    EXPECT_FALSE(fs::exists(wrong));
  }
  // Decoded, the frames give the plain frames' map, byte for byte.
  const std::string plain_map = (dir.path / "plain.ot").string(), sun_map = (dir.path / "decoded.ot").string();
  ASSERT_EQ(mobmap("build " + seq + " --out " + plain_map + " --quiet").first, 0);
  const auto [built, said] = mobmap("build " + sun + " --out " + sun_map + " --depth-format sunrgbd --quiet");
  ASSERT_EQ(built, 0) << said;
  const auto bytes = [](const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  const std::string plain_bytes = bytes(plain_map), decoded_bytes = bytes(sun_map);
  EXPECT_GT(plain_bytes.size(), 1000u);
  EXPECT_TRUE(plain_bytes == decoded_bytes) << plain_bytes.size() << " vs " << decoded_bytes.size() << " bytes";
  std::ifstream meta_in((dir.path / "decoded.json").string());
  const nlohmann::json meta = nlohmann::json::parse(meta_in);
  EXPECT_EQ(meta["depth_format"], "sunrgbd") << meta.dump();
  // Not for inputs whose depth is not 16-bit values, nor an unknown name.
  EXPECT_EQ(mobmap("build " + seq + " --out " + (dir.path / "x.ot").string() + " --depth-format nonsense --quiet").first, 2);
}

// `build` maps a turned cloud in its points' frame as it maps the camera-frame cloud in
// the camera's: gravity comes from the same floor, so the heights of the walkable levels
// and the mobility of the surfaces agree; `analyze` reports in the cloud's frame.
TEST(OrganizedCamera, BuildAndAnalyzeTakeACloudInATurnedFrame) {
  const TempDir dir;
  const sim::RenderedFrame f = corridorFrame(35.0);
  const Eigen::Isometry3d quarter = quarterTurn();
  const std::string plain = writeFramePcd(dir, "camera.pcd", f, Eigen::Isometry3d::Identity());
  const std::string turned = writeFramePcd(dir, "turned.pcd", f, quarter);
  const auto info = [&](const std::string& pcd, const std::string& name) {
    const auto [code, out] = mobmap("build " + pcd + " --out " + (dir.path / name).string() + " --quiet");
    EXPECT_EQ(code, 0) << out;
    const auto [icode, iout] = mobmap("info " + (dir.path / name).string() + " --json");
    EXPECT_EQ(icode, 0) << iout;
    return std::make_pair(out, nlohmann::json::parse(iout));
  };
  const auto [plain_out, a] = info(plain, "a.ot");
  const auto [turned_out, b] = info(turned, "b.ot");
  EXPECT_NE(turned_out.find("its points are not in its camera's frame"), std::string::npos) << turned_out;
  ASSERT_EQ(a["walkable_levels"].size(), b["walkable_levels"].size()) << a["walkable_levels"] << b["walkable_levels"];
  for (std::size_t i = 0; i < a["walkable_levels"].size(); ++i) {
    EXPECT_NEAR(a["walkable_levels"][i]["z_m"].get<double>(), b["walkable_levels"][i]["z_m"].get<double>(), 0.005);
    EXPECT_NEAR(a["walkable_levels"][i]["share"].get<double>(), b["walkable_levels"][i]["share"].get<double>(), 0.03);
  }
  const double sa = a["surface_leaves"].get<double>(), sb = b["surface_leaves"].get<double>();
  EXPECT_NEAR(sa, sb, 0.03 * sa);
  // analyze --json: normals and the ground plane in the cloud's frame, the camera's pose in it.
  const auto [code, out] = mobmap("analyze " + turned + " --json");
  ASSERT_EQ(code, 0) << out;
  const nlohmann::json j = nlohmann::json::parse(out.substr(out.find('{')));
  ASSERT_TRUE(j.contains("T_cloud_camera"));
  EXPECT_NEAR(j["T_cloud_camera"][0][1].get<double>(), -1.0, 1e-5);
  // The ground's normal points up: in the camera frame mostly -y, in the cloud's mostly +x
  // (the cloud's x is the camera's -y turned a quarter: R (0,-1,0) = (1,0,0)).
  EXPECT_GT(j["ground_plane"][0].get<double>(), 0.7) << j["ground_plane"];
  EXPECT_NEAR(j["ground_distance_m"].get<double>(), sim::CorridorParams{}.camera_height_m, 0.02);
}

// A .pcd sequence whose clouds are in a turned frame, with the poses of that frame: the
// camera's pose in it is fitted once, and the map is the camera-frame sequence's.
TEST(OrganizedCamera, APcdSequenceInATurnedFrameMapsAsInTheCameraFrame) {
  const TempDir dir;
  sim::CorridorParams p;
  p.bob_m = 0.0;
  const sim::CorridorScene scene(p);
  const Eigen::Isometry3d quarter = quarterTurn();
  fs::create_directories(dir.path / "camera");
  fs::create_directories(dir.path / "turned");
  std::ofstream camera_poses(dir.path / "camera.txt"), turned_poses(dir.path / "turned.txt");
  camera_poses.precision(17);
  turned_poses.precision(17);
  const auto tum = [](std::ofstream& out, int i, const Eigen::Isometry3d& T) {
    const Eigen::Quaterniond q(T.linear());
    out << i << " " << T.translation().x() << " " << T.translation().y() << " " << T.translation().z() << " " << q.x() << " "
        << q.y() << " " << q.z() << " " << q.w() << "\n";
  };
  for (int i = 0; i < 3; ++i) {
    const sim::RenderedFrame f = scene.render(20 * i);
    const std::string name = "frame-" + std::to_string(i) + ".pcd";
    writeOrganizedPcd(dir, "camera/" + name, organizedCloud(f, Eigen::Isometry3d::Identity()), p.intrinsics.width, p.intrinsics.height);
    writeOrganizedPcd(dir, "turned/" + name, organizedCloud(f, quarter), p.intrinsics.width, p.intrinsics.height);
    tum(camera_poses, i, f.T_world_camera);
    tum(turned_poses, i, f.T_world_camera * quarter.inverse());
  }
  camera_poses.close();
  turned_poses.close();
  const auto build = [&](const std::string& name) {
    const auto [code, out] = mobmap("build " + (dir.path / name).string() + " --poses " + (dir.path / (name + ".txt")).string() +
                                    " --gravity 0,0,-1 --out " + (dir.path / (name + ".ot")).string() + " --quiet");
    EXPECT_EQ(code, 0) << out;
    const auto [icode, iout] = mobmap("info " + (dir.path / (name + ".ot")).string() + " --json");
    EXPECT_EQ(icode, 0) << iout;
    return nlohmann::json::parse(iout);
  };
  const nlohmann::json a = build("camera"), b = build("turned");
  ASSERT_FALSE(a["walkable_levels"].empty());
  ASSERT_EQ(a["walkable_levels"].size(), b["walkable_levels"].size()) << a["walkable_levels"] << b["walkable_levels"];
  for (std::size_t i = 0; i < a["walkable_levels"].size(); ++i) {
    EXPECT_NEAR(a["walkable_levels"][i]["z_m"].get<double>(), b["walkable_levels"][i]["z_m"].get<double>(), 0.005);
  }
  // The floor lies exactly on a voxel boundary (z = 0), where the last bit of a turned
  // point's height picks the voxel above or below: compare the columns the surfaces cover.
  const auto columns = [&](const std::string& name) {
    const std::string pcd = (dir.path / (name + ".pcd")).string();
    EXPECT_EQ(mobmap("export " + (dir.path / (name + ".ot")).string() + " --pcd " + pcd).first, 0);
    std::ifstream in(pcd);
    std::string line;
    while (std::getline(in, line) && line.rfind("DATA", 0) != 0) {
    }
    std::set<std::pair<long, long>> cells;
    double x = 0, y = 0;
    while (in >> x >> y && std::getline(in, line)) cells.insert({std::lround(x / 0.02), std::lround(y / 0.02)});
    return cells;
  };
  const auto ca = columns("camera"), cb = columns("turned");
  std::size_t common = 0;
  for (const auto& c : ca) common += cb.count(c);
  ASSERT_GT(ca.size(), 10000u);
  EXPECT_GT(static_cast<double>(common), 0.995 * static_cast<double>(std::max(ca.size(), cb.size())))
      << ca.size() << " and " << cb.size() << " columns, " << common << " in both";
}

// A quad of two triangles, counter-clockwise seen from the side its normal faces.
void addQuad(std::vector<sim::Triangle>& tris, const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
             const Eigen::Vector3d& d, int id) {
  tris.push_back({a, b, c, id});
  tris.push_back({a, c, d, id});
}

// One office frame: a camera 1.1 m up, pitched 8 degrees down, sees the floor from 1.8 m
// to 5 m away and a box 0.45 m high 1.3-1.9 m ahead. With Kinect noise the far floor's
// depths fall on disparity steps several centimetres apart: 2 cm voxels leave it striped.
// Written as a single 16-bit depth PNG (millimetres); returns its path.
std::string farFloorFrame(const fs::path& dir) {
  std::vector<sim::Triangle> tris;
  addQuad(tris, {-5, -1, 0}, {5, -1, 0}, {5, 7, 0}, {-5, 7, 0}, 1);                       // floor z = 0
  addQuad(tris, {-5, 7, 0}, {5, 7, 0}, {5, 7, 3}, {-5, 7, 3}, 2);                         // end wall
  const double x0 = -0.35, x1 = 0.35, y0 = 1.3, y1 = 1.9, h = 0.45;
  addQuad(tris, {x0, y0, h}, {x1, y0, h}, {x1, y1, h}, {x0, y1, h}, 3);                   // box top
  addQuad(tris, {x0, y0, 0}, {x0, y0, h}, {x1, y0, h}, {x1, y0, 0}, 4);                   // its front
  addQuad(tris, {x0, y0, 0}, {x0, y1, 0}, {x0, y1, h}, {x0, y0, h}, 4);                   // its sides
  addQuad(tris, {x1, y0, 0}, {x1, y0, h}, {x1, y1, h}, {x1, y1, 0}, 4);
  const double pitch = 8.0 * M_PI / 180.0;
  const Eigen::Vector3d fwd(0, std::cos(pitch), -std::sin(pitch)), right(1, 0, 0);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = right;
  T.linear().col(1) = fwd.cross(right);
  T.linear().col(2) = fwd;
  T.translation() = Eigen::Vector3d(0, 0, 1.1);
  const perception::PinholeIntrinsics k{320, 240, 292.5, 292.5, 160.0, 120.0};
  sim::RayCastResult rc = sim::castRays(tris, k, T);
  sim::applyKinectNoise(rc.depth, rc.incidence_cos, sim::KinectNoiseParams{}, k.fx, 7, 0);
  Image16 img{k.width, k.height, {}};
  for (const float z : rc.depth.depth_m) img.pixels.push_back(z > 0.f ? static_cast<std::uint16_t>(std::lround(z * 1000.f)) : 0);
  const std::string path = (dir / "office.depth.png").string();
  writePng16(path, img);
  return path;
}

// At 2 cm the striped far floor holds most of the walkable surface but few whole soles,
// and the box top many: `reach` starts on the floor (the level `info` lists first), says
// why so few soles stand there and what helps; at 4 cm the floor carries them. Gravity
// comes from that far floor, and `build` says how far and how much of it there was.
TEST(SparseFloor, AFarFloorSeenOnceIsTheStartLevelAndItsGapsAreExplained) {
  const TempDir dir;
  const std::string png = farFloorFrame(dir.path);
  // The floor's nearest pixel (the bottom row's middle) lies 1.1 m / sin(8 deg + atan(119.5 / 292.5)) away.
  const double nearest_floor = 1.1 / std::sin(8.0 * M_PI / 180.0 + std::atan(119.5 / 292.5));
  double reached_at_2cm = 0;
  for (const std::string res : {"0.02", "0.04"}) {
    SCOPED_TRACE(res);
    const std::string map = (dir.path / ("m" + res + ".ot")).string();
    const auto [built, said] =
        mobmap("build " + png + " --intrinsics 292.5,292.5,160,120 --max-range 5 --out " + map + " --resolution " + res + " --quiet");
    ASSERT_EQ(built, 0) << said;
    double near = 0, median = 0, lo = 0, hi = 0;
    const auto at = said.find("note: gravity (down) comes from the frame's ground plane, seen only ");
    ASSERT_NE(at, std::string::npos) << said;
    ASSERT_EQ(std::sscanf(said.c_str() + at, "note: gravity (down) comes from the frame's ground plane, seen only %lf m from the "
                                             "camera or farther (median %lf m;",
                          &near, &median),
              2)
        << said;
    const auto ninety = said.find("90 % of them ", at);
    ASSERT_NE(ninety, std::string::npos) << said;
    ASSERT_EQ(std::sscanf(said.c_str() + ninety, "90 %% of them %lf-%lf m", &lo, &hi), 2) << said;
    EXPECT_EQ(lo, near);
    EXPECT_GE(near, nearest_floor - 0.05);
    EXPECT_LT(near, nearest_floor + 0.5);
    EXPECT_GT(median, near);
    EXPECT_GT(hi, 4.0);
    EXPECT_LE(hi, 5.0);
    std::ifstream meta(dir.path / ("m" + res + ".json"));
    const auto mj = nlohmann::json::parse(meta);
    EXPECT_NE(mj.dump().find("the frame's ground plane (its largest plane; "), std::string::npos) << mj.dump();
    // info's largest walkable level is the floor, 1.1 m below the camera; reach starts on
    // it, and measures it the same way.
    const auto [informed, info] = mobmap("info --json " + map);
    ASSERT_EQ(informed, 0) << info;
    nlohmann::json largest;
    const auto ij = nlohmann::json::parse(info);
    for (const auto& l : ij["walkable_levels"]) {
      if (largest.is_null() || l["share"].get<double>() > largest["share"].get<double>()) largest = l;
    }
    ASSERT_FALSE(largest.is_null()) << info;
    EXPECT_NEAR(largest["z_m"].get<double>(), -1.1, 0.03);
    EXPECT_GT(largest["share"].get<double>(), 0.8);
    const auto [reached, out] = mobmap("reach --json " + map);
    ASSERT_EQ(reached, 0) << out;
    const auto rj = nlohmann::json::parse(out.substr(out.find('{')));
    EXPECT_NEAR(rj["start"]["place"][2].get<double>(), -1.1, 0.05) << rj.dump();
    EXPECT_DOUBLE_EQ(rj["start"]["level"]["z_m"].get<double>(), largest["z_m"].get<double>());
    EXPECT_DOUBLE_EQ(rj["start"]["level"]["walkable_share"].get<double>(), largest["share"].get<double>());
    const double carried = rj["start"]["level"]["standable_near"].get<double>() / rj["start"]["level"]["walkable_near"].get<double>();
    if (res == "0.02") {
      EXPECT_LT(carried, 0.3) << rj.dump();
      ASSERT_TRUE(rj["start"]["note"].is_string()) << rj.dump();
      EXPECT_NE(rj["start"]["note"].get<std::string>().find("a coarser --resolution (0.04 m, twice this map's)"), std::string::npos)
          << rj.dump();
      reached_at_2cm = rj["reachable"]["area_m2"].get<double>();
      const auto [text_code, text] = mobmap("reach " + map);
      EXPECT_NE(text.find("note: the start level (z = -1.0"), std::string::npos) << text;
    } else {
      EXPECT_GT(carried, 0.5) << rj.dump();
      EXPECT_TRUE(rj["start"]["note"].is_null()) << rj.dump();
      EXPECT_GT(rj["reachable"]["area_m2"].get<double>(), 4 * reached_at_2cm) << rj.dump();
    }
  }
}

}  // namespace
}  // namespace mobmap::app
