// Readers and writers of the apps layer: round trips, hostile files, real data.
#include "io/dataset.hpp"
#include "io/ground_truth.hpp"
#include "io/files.hpp"
#include "io/frame_source.hpp"
#include "io/pcd.hpp"
#include "io/io_error.hpp"
#include "io/map_files.hpp"
#include "pictures/canvas.hpp"
#include "io/png_io.hpp"
#include "io/simulation_writer.hpp"
#include "pictures/top_view.hpp"

#include <Eigen/SVD>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>

#include <unistd.h>

namespace mobmap::app {
namespace {

namespace fs = std::filesystem;
constexpr double kDeg = 3.14159265358979323846 / 180.0;

class TempDir {
 public:
  TempDir() {
    path_ = fs::temp_directory_path() /
            ("mobmap-test-" + std::to_string(::getpid()) + "-" + std::to_string(counter_++));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  [[nodiscard]] std::string file(const std::string& name) const { return (path_ / name).string(); }
  [[nodiscard]] std::string str() const { return path_.string(); }

 private:
  static inline int counter_ = 0;
  fs::path path_;
};

void writeBytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const IoError& e) {
    return e.what();
  }
  return "no error";
}

TEST(Png, SixteenBitRoundTripIsExact) {
  TempDir dir;
  Image16 img{37, 11, {}};
  std::mt19937 rng(3);
  for (int i = 0; i < 37 * 11; ++i) img.pixels.push_back(static_cast<std::uint16_t>(rng()));
  writePng16(dir.file("a.png"), img);
  const Image16 back = readPng16(dir.file("a.png"));
  EXPECT_EQ(back.width, 37);
  EXPECT_EQ(back.height, 11);
  EXPECT_EQ(back.pixels, img.pixels);
}

TEST(Png, RgbRoundTripIsExact) {
  TempDir dir;
  ImageRgb img{5, 4, {}};
  for (int i = 0; i < 20; ++i) img.pixels.push_back({static_cast<std::uint8_t>(i), static_cast<std::uint8_t>(3 * i), 200});
  writePngRgb(dir.file("c.png"), img);
  EXPECT_EQ(readPngRgb(dir.file("c.png")).pixels, img.pixels);
}

// Overlays show their frame in grey (BT.601 luma) under the mobility colours.
TEST(Canvas, FramePictureShowsTheColourImageInGreyAndDepthShaded) {
  EXPECT_EQ(greyOf({255, 0, 0}), (Rgb{76, 76, 76}));
  EXPECT_EQ(greyOf({0, 255, 0}), (Rgb{150, 150, 150}));
  EXPECT_EQ(greyOf({0, 0, 255}), (Rgb{29, 29, 29}));
  EXPECT_EQ(greyOf({255, 255, 255}), (Rgb{255, 255, 255}));
  EXPECT_EQ(greyOf({192, 0, 0}), (Rgb{57, 57, 57}));  // a stereo camera's fill where it measured nothing
  const ImageRgb colour{2, 1, {{192, 0, 0}, {10, 200, 30}}};
  const std::vector<float> depth{1.0f, 0.0f};
  const Canvas c = framePicture(2, 1, &colour, depth);
  EXPECT_EQ(c.get(0, 0), greyOf(colour.pixels[0]));
  EXPECT_EQ(c.get(1, 0), greyOf(colour.pixels[1]));
  // Without a colour image of the frame's size: depth, nearer lighter, black where none.
  const ImageRgb small{1, 1, {{255, 0, 0}}};
  const Canvas d = framePicture(2, 1, &small, depth);
  EXPECT_EQ(d.get(0, 0), (Rgb{210, 210, 210}));
  EXPECT_EQ(d.get(1, 0), (Rgb{0, 0, 0}));
}

TEST(Png, HostileFilesGiveErrorsNamingTheFile) {
  TempDir dir;
  EXPECT_NE(errorOf([&] { readPng16(dir.file("missing.png")); }).find("missing.png: cannot open"), std::string::npos);
  writeBytes(dir.file("text.png"), "this is not a png at all");
  EXPECT_NE(errorOf([&] { readPng16(dir.file("text.png")); }).find("text.png: not a PNG"), std::string::npos);
  // A valid 16-bit PNG cut in half.
  Image16 img{64, 64, std::vector<std::uint16_t>(64 * 64, 1234)};
  for (std::size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = static_cast<std::uint16_t>(i * 7919);
  writePng16(dir.file("full.png"), img);
  const std::string bytes = readTextFile(dir.file("full.png"));
  writeBytes(dir.file("cut.png"), bytes.substr(0, bytes.size() / 2));
  EXPECT_NE(errorOf([&] { readPng16(dir.file("cut.png")); }).find("cut.png: corrupt or truncated"), std::string::npos);
  // An 8-bit colour PNG where depth is expected.
  writePngRgb(dir.file("rgb.png"), ImageRgb{2, 2, std::vector<std::array<std::uint8_t, 3>>(4)});
  EXPECT_NE(errorOf([&] { readPng16(dir.file("rgb.png")); }).find("not a 16-bit greyscale PNG"), std::string::npos);
}

// A PNG's chunk with its CRC (the bitwise form of the polynomial PNG uses).
std::string pngChunk(const std::string& type, const std::string& data) {
  const std::string body = type + data;
  std::uint32_t crc = 0xFFFFFFFFu;
  for (unsigned char c : body) {
    crc ^= c;
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  crc ^= 0xFFFFFFFFu;
  const auto be32 = [](std::uint32_t v) {
    return std::string{static_cast<char>(v >> 24), static_cast<char>(v >> 16), static_cast<char>(v >> 8), static_cast<char>(v)};
  };
  return be32(static_cast<std::uint32_t>(data.size())) + body + be32(crc);
}

// The header of a 16-bit grey PNG of the given size: what the decoder reads first.
std::string pngHeaderOfSize(std::uint32_t width, std::uint32_t height) {
  std::string ihdr;
  for (std::uint32_t v : {width, height}) {
    for (int shift : {24, 16, 8, 0}) ihdr.push_back(static_cast<char>(v >> shift));
  }
  ihdr += std::string{16, 0, 0, 0, 0};  // bit depth 16, grey, deflate, no filter, no interlace
  return std::string("\x89PNG\r\n\x1a\n", 8) + pngChunk("IHDR", ihdr) + pngChunk("IDAT", "") + pngChunk("IEND", "");
}

TEST(Png, AFrameLargerThanTheLimitIsNamedAsSuchBeforeAnyPixelIsAllocated) {
  TempDir dir;
  // 16384 x 16384 (512 MB of 16-bit pixels) used to be decoded until memory ran out;
  // 100000 x 1 was reported as a corrupt file.
  for (const auto& [w, h] : {std::pair<std::uint32_t, std::uint32_t>{16384, 16384}, {100000, 1}, {1, 20000}, {4097, 4097}}) {
    const std::string path = dir.file("big.png");
    writeBytes(path, pngHeaderOfSize(w, h));
    EXPECT_EQ(errorOf([&] { checkPngComplete(path); }), "no error");  // a whole file: only decoding finds it
    const std::string e = errorOf([&] { readPng16(path); });
    EXPECT_EQ(e, path + ": the image is " + std::to_string(w) + "x" + std::to_string(h) +
                     " pixels, larger than mobmap reads (at most 16384 pixels a side and 16777216 pixels in all)");
    EXPECT_EQ(errorOf([&] { readPngRgb(path); }), e);
  }
  // At the limit the header passes and the missing pixels are what is reported.
  writeBytes(dir.file("edge.png"), pngHeaderOfSize(16384, 1024));
  EXPECT_NE(errorOf([&] { readPng16(dir.file("edge.png")); }).find("corrupt or truncated"), std::string::npos);
}

const char* kPcdHeader = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH %W\nHEIGHT 1\n"
                         "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS %W\nDATA %D\n";

std::string pcdHeader(const std::string& width, const std::string& data) {
  std::string h = kPcdHeader;
  for (std::size_t at; (at = h.find("%W")) != std::string::npos;) h.replace(at, 2, width);
  h.replace(h.find("%D"), 2, data);
  return h;
}

TEST(Pcd, DeclaredSizesAreCheckedAgainstTheFileAndTheFrameLimitBeforeAnythingIsAllocated) {
  TempDir dir;
  std::string lines;
  for (int i = 0; i < 20000; ++i) lines += std::to_string(i % 100) + " " + std::to_string(i / 100) + " 1\n";
  const auto both = [&](const std::string& path) {
    const std::string e = errorOf([&] { (void)loadPcd(path); });
    const std::string checked = errorOf([&] { checkPcdComplete(path); });
    EXPECT_EQ(checked, e) << "the check before a run and the loader disagree";
    return e;
  };
  // A billion points declared over 20000 lines; 4e9 binary points; both used to end in
  // std::bad_alloc after gigabytes, inside PCL's header reader.
  writeBytes(dir.file("a.pcd"), pcdHeader("1000000000", "ascii") + lines);
  EXPECT_EQ(both(dir.file("a.pcd")), dir.file("a.pcd") + ": PCD header declares 1000000000 points (WIDTH 1000000000, HEIGHT 1), "
                                     "more than mobmap reads in one frame (16777216)");
  writeBytes(dir.file("b.pcd"), pcdHeader("4000000000", "binary") + std::string(1200, '\0'));
  EXPECT_NE(both(dir.file("b.pcd")).find("b.pcd: PCD header declares 4000000000 points"), std::string::npos);
  // Within the limit, more ASCII points than the data can hold (2 bytes a value at least).
  writeBytes(dir.file("c.pcd"), pcdHeader("10000000", "ascii") + lines);
  EXPECT_NE(errorOf([&] { (void)loadPcd(dir.file("c.pcd")); })
                .find("c.pcd: PCD header declares 10000000 points of 3 values, but its 167000 bytes of ASCII data hold at most 27833"),
            std::string::npos);
  // binary_compressed whose uncompressed size says 4 GB (100 points of 12 bytes are 1200).
  std::string sizes = {10, 0, 0, 0, 0, 0, 0, static_cast<char>(0xF0)};
  writeBytes(dir.file("d.pcd"), pcdHeader("100", "binary_compressed") + sizes + std::string(10, '\0'));
  EXPECT_EQ(both(dir.file("d.pcd")), dir.file("d.pcd") + ": PCD compressed data says it holds 4026531840 bytes, but 100 "
                                     "points of 12 bytes are 1200 (corrupt file)");
  // The same file honest: 20000 ASCII points load.
  writeBytes(dir.file("e.pcd"), pcdHeader("20000", "ascii") + lines);
  EXPECT_EQ(loadPcd(dir.file("e.pcd")).points.size(), 20000u);
}

TEST(Pcd, EightByteCoordinatesAreReadAsWritten) {
  // PCL writes and reads SIZE 8 TYPE F; they used to load as zeros without a word.
  TempDir dir;
  const std::vector<Eigen::Vector3d> points = {{1.5, -2.25, 3.0}, {0.125, 0.5, -1.0}, {12.75, 0.0, 4.5}};
  std::string ascii = "VERSION 0.7\nFIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 3\nHEIGHT 1\n"
                      "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n";
  std::string binary = "VERSION 0.7\nFIELDS x y z intensity\nSIZE 8 8 8 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 3\nHEIGHT 1\n"
                       "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA binary\n";
  for (const auto& p : points) {
    char line[96];
    std::snprintf(line, sizeof line, "%.17g %.17g %.17g\n", p.x(), p.y(), p.z());
    ascii += line;
    binary.append(reinterpret_cast<const char*>(p.data()), 24);
    const float intensity = 7.0f;
    binary.append(reinterpret_cast<const char*>(&intensity), 4);
  }
  writeBytes(dir.file("ascii.pcd"), ascii);
  writeBytes(dir.file("binary.pcd"), binary);
  for (const std::string name : {"ascii.pcd", "binary.pcd"}) {
    const Frame f = loadPcd(dir.file(name));
    ASSERT_EQ(f.points.size(), points.size()) << name;
    for (std::size_t i = 0; i < points.size(); ++i) {
      EXPECT_EQ(f.points[i], points[i].cast<float>()) << name << " point " << i;
    }
  }
  // Coordinates that are not floats are refused by name.
  std::string ints = ascii;
  ints.replace(ints.find("TYPE F F F"), 10, "TYPE I I I");
  writeBytes(dir.file("ints.pcd"), ints);
  EXPECT_NE(errorOf([&] { (void)loadPcd(dir.file("ints.pcd")); }).find("ints.pcd: PCD field x is not a 4- or 8-byte float"),
            std::string::npos)
      << errorOf([&] { (void)loadPcd(dir.file("ints.pcd")); });
}

// The cheap check `build` runs on every frame before a long run: whole files pass, files
// cut anywhere (a recorder killed mid-write) fail, and so does whatever readPng16 refuses
// to open.
TEST(Png, CompletenessCheckFindsEveryCutWithoutDecoding) {
  TempDir dir;
  Image16 img{64, 64, std::vector<std::uint16_t>(64 * 64)};
  for (std::size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = static_cast<std::uint16_t>(i * 7919);
  writePng16(dir.file("full.png"), img);
  EXPECT_EQ(errorOf([&] { checkPngComplete(dir.file("full.png")); }), "no error");
  const std::string bytes = readTextFile(dir.file("full.png"));
  ASSERT_GT(bytes.size(), 100u);
  int cuts = 0;
  for (std::size_t keep = 8; keep < bytes.size(); keep += 1 + keep / 4, ++cuts) {
    writeBytes(dir.file("cut.png"), bytes.substr(0, keep));
    EXPECT_EQ(errorOf([&] { checkPngComplete(dir.file("cut.png")); }),
              dir.file("cut.png") + ": truncated PNG: " + std::to_string(keep) + " bytes, and no complete IEND chunk at its end");
    // ...and each is a file the decoder refuses too.
    EXPECT_NE(errorOf([&] { readPng16(dir.file("cut.png")); }), "no error") << keep;
  }
  EXPECT_GT(cuts, 10);
  writeBytes(dir.file("cut.png"), bytes.substr(0, bytes.size() - 1));  // only the CRC's last byte missing
  EXPECT_NE(errorOf([&] { checkPngComplete(dir.file("cut.png")); }), "no error");
  EXPECT_NE(errorOf([&] { checkPngComplete(dir.file("missing.png")); }).find("missing.png: cannot open"), std::string::npos);
  writeBytes(dir.file("text.png"), "this is not a png at all");
  EXPECT_NE(errorOf([&] { checkPngComplete(dir.file("text.png")); }).find("text.png: not a PNG"), std::string::npos);
}

TEST(DepthPng, MillimetresWithZeroAndMaxMeaningNoMeasurement) {
  TempDir dir;
  Image16 img{4, 1, {0, 1000, 65535, 1500}};
  writePng16(dir.file("d.png"), img);
  const auto d = readDepthPng(dir.file("d.png"));
  EXPECT_EQ(d.depth_m[0], 0.f);
  EXPECT_FLOAT_EQ(d.depth_m[1], 1.0f);
  EXPECT_EQ(d.depth_m[2], 0.f);
  EXPECT_FLOAT_EQ(d.depth_m[3], 1.5f);
}

TEST(PoseFile, RoundTripAndValidation) {
  TempDir dir;
  Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
  t.topLeftCorner<3, 3>() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  t.topRightCorner<3, 1>() = Eigen::Vector3d(1.5, -2.25, 0.125);
  writePoseFile(dir.file("p.txt"), t);
  EXPECT_LT((readPoseFile(dir.file("p.txt")) - t).cwiseAbs().maxCoeff(), 1e-15);

  writeBytes(dir.file("nan.txt"), "1 0 0 0\n0 1 0 nan\n0 0 1 0\n0 0 0 1\n");
  EXPECT_NE(errorOf([&] { readPoseFile(dir.file("nan.txt")); }).find("nan.txt: line 2"), std::string::npos);
  writeBytes(dir.file("short.txt"), "1 0 0 0\n0 1 0\n0 0 1 0\n0 0 0 1\n");
  EXPECT_NE(errorOf([&] { readPoseFile(dir.file("short.txt")); }).find("line 2: expected 4 numbers, found 3"), std::string::npos);
  writeBytes(dir.file("three.txt"), "1 0 0 0\n0 1 0 0\n0 0 1 0\n");
  EXPECT_NE(errorOf([&] { readPoseFile(dir.file("three.txt")); }).find("expected 4 rows"), std::string::npos);
  writeBytes(dir.file("scaled.txt"), "2 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
  EXPECT_NE(errorOf([&] { readPoseFile(dir.file("scaled.txt")); }).find("not a rigid transform"), std::string::npos);
  writeBytes(dir.file("mirror.txt"), "-1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
  EXPECT_NE(errorOf([&] { readPoseFile(dir.file("mirror.txt")); }).find("reflection"), std::string::npos);
}

// A direction file is normalised without squaring its components (which overflows to
// infinity above ~1e154 and turned a valid direction into zero; found by fuzz_poses).
TEST(GravityFile, HugeAndOrdinaryDirectionsAreNormalisedAndZeroIsAnError) {
  TempDir dir;
  writeBytes(dir.file("g.txt"), "0 -3 4\n");
  EXPECT_LT((readGravityFile(dir.file("g.txt")) - Eigen::Vector3d(0, -0.6, 0.8)).norm(), 1e-15);
  writeBytes(dir.file("huge.txt"), "0 0 9e158\n");
  EXPECT_LT((readGravityFile(dir.file("huge.txt")) - Eigen::Vector3d(0, 0, 1)).norm(), 1e-15);
  writeBytes(dir.file("zero.txt"), "0 0 0\n");
  EXPECT_NE(errorOf([&] { readGravityFile(dir.file("zero.txt")); }).find("zero.txt: gravity direction is the zero vector"),
            std::string::npos);
  // --gravity: the same, with components beyond a float's range.
  EXPECT_LT((parseVector3("0,1e39,0", "--gravity") - Eigen::Vector3f(0, 1, 0)).norm(), 1e-7f);
  EXPECT_LT((parseVector3("3,0,-4", "--gravity") - Eigen::Vector3f(0.6f, 0, -0.8f)).norm(), 1e-7f);
  EXPECT_THROW(parseVector3("0,0,0", "--gravity"), UsageError);
}

TEST(IntrinsicsFile, RoundTripAndValidation) {
  TempDir dir;
  const perception::PinholeIntrinsics k{640, 480, 570.342, 571.5, 320.25, 239.75};
  writeIntrinsicsFile(dir.file("k.txt"), k);
  EXPECT_EQ(readIntrinsicsFile(dir.file("k.txt"), 640, 480), k);
  writeBytes(dir.file("bad.txt"), "585 0 320\n0 -585 240\n0 0 1\n");
  EXPECT_NE(errorOf([&] { readIntrinsicsFile(dir.file("bad.txt"), 640, 480); }).find("fy"), std::string::npos);
}

TEST(AtomicWrite, FailedWriteLeavesTheOldFileAndNoTemporary) {
  TempDir dir;
  writeTextFileAtomically(dir.file("m.txt"), "old");
  EXPECT_THROW(writeAtomically(dir.file("m.txt"),
                               [](const std::string& tmp) {
                                 std::ofstream(tmp) << "half";
                                 throw std::runtime_error("killed mid-write");
                               }),
               std::runtime_error);
  EXPECT_EQ(readTextFile(dir.file("m.txt")), "old");
  int files = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir.str())) ++files;
  EXPECT_EQ(files, 1);
}

// A map's files are written as a set: one that fails (disk full) leaves every file of the
// set as it was, removes the temporaries, and the error names the file by its own name.
TEST(AtomicWrite, AFileSetIsReplacedAllOrNothing) {
  TempDir dir;
  for (const char* name : {"m.ot", "m.bt", "m.json"}) writeTextFileAtomically(dir.file(name), std::string("old ") + name);
  const auto text = [](const std::string& content) {
    return [content](const std::string& tmp) { writeTextFileAtomically(tmp, content); };
  };
  const std::string error = errorOf([&] {
    writeFilesTogether({{dir.file("m.ot"), text("new ot")},
                        {dir.file("m.bt"), text("new bt")},
                        {dir.file("m.octovis.ot"), text("new octovis")},
                        {dir.file("m.json"),
                         [](const std::string& tmp) {
                           std::ofstream(tmp) << "{\"half";
                           throw IoError(tmp, "write failed (disk full?)");
                         }}});
  });
  EXPECT_EQ(error, dir.file("m.json") + ": write failed (disk full?); no file of the set was changed");
  for (const char* name : {"m.ot", "m.bt", "m.json"}) EXPECT_EQ(readTextFile(dir.file(name)), std::string("old ") + name);
  EXPECT_FALSE(fs::exists(dir.file("m.octovis.ot")));  // a new file of the set is not created either
  int files = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir.str())) ++files;
  EXPECT_EQ(files, 3);
  // When every write succeeds, all are replaced and nothing else is left.
  writeFilesTogether({{dir.file("m.ot"), text("new ot")}, {dir.file("sub/m.json"), text("new json")}});
  EXPECT_EQ(readTextFile(dir.file("m.ot")), "new ot");
  EXPECT_EQ(readTextFile(dir.file("sub/m.json")), "new json");
  files = 0;
  for ([[maybe_unused]] const auto& e : fs::recursive_directory_iterator(dir.str())) ++files;
  EXPECT_EQ(files, 5);  // m.ot, m.bt, m.json, sub, sub/m.json
}

// Writes a short noise-free corridor and reads it back through the dataset reader.
class WrittenCorridor : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir();
    sim::CorridorParams p;
    p.frames = 40;
    p.noise = sim::NoiseModel::kNone;
    scene_ = new sim::CorridorScene(p);
    // Only a few frames are needed: write the whole sequence's metadata, then the frames.
    writeSimulation(*scene_, dir_->str(), 2, [](int) {});
  }
  static void TearDownTestSuite() {
    delete scene_;
    delete dir_;
  }
  static inline TempDir* dir_ = nullptr;
  static inline sim::CorridorScene* scene_ = nullptr;
};

TEST_F(WrittenCorridor, SevenScenesReaderRoundTrip) {
  const SevenScenesDirectory d(dir_->str());
  ASSERT_EQ(d.frameNumbers().size(), 40u);
  EXPECT_EQ(d.intrinsics(), scene_->params().intrinsics);
  ASSERT_TRUE(d.gravityDown().has_value());
  EXPECT_NEAR((*d.gravityDown() - scene_->gravityDown()).norm(), 0.0, 1e-15);
  for (int f : {0, 17, 39}) {
    const auto r = scene_->render(f);
    const auto depth = d.readDepth(f);
    for (std::size_t i = 0; i < depth.depth_m.size(); ++i) {
      if (r.exact_depth.depth_m[i] > 0 && r.exact_depth.depth_m[i] < 65.0f) {
        ASSERT_NEAR(depth.depth_m[i], r.exact_depth.depth_m[i], 0.5e-3 + 1e-6);  // millimetre rounding
      } else {
        ASSERT_EQ(depth.depth_m[i], 0.f);
      }
    }
    EXPECT_LT((d.readPose(f) - r.T_world_camera.matrix()).cwiseAbs().maxCoeff(), 1e-15);
    EXPECT_EQ(readPng16(d.labelsPath(f)).pixels, r.labels);
  }
}

TEST_F(WrittenCorridor, BackProjectedRampsRecoverTheirSlopeWithinATenthOfADegree) {
  const SevenScenesDirectory d(dir_->str());
  const Eigen::Vector3d up = -*d.gravityDown();
  std::map<int, std::vector<Eigen::Vector3d>> points;  // ramp id -> world points
  for (int f : {0, 20, 39}) {
    const auto depth = d.readDepth(f);
    const Eigen::Matrix4d pose = d.readPose(f);
    const Eigen::Affine3d T(pose);
    const auto labels = readPng16(d.labelsPath(f)).pixels;
    const auto& k = d.intrinsics();
    for (int v = 0; v < k.height; ++v) {
      for (int u = 0; u < k.width; ++u) {
        const auto i = static_cast<std::size_t>(v * k.width + u);
        const int id = labels[i];
        if (id == 0 || depth.depth_m[i] <= 0 || scene_->surface(id).kind != sim::SurfaceKind::kRamp) continue;
        points[id].push_back(T * perception::backProject(k, u, v, depth.depth_m[i]));
      }
    }
  }
  ASSERT_GE(points.size(), 4u);
  for (const auto& [id, pts] : points) {
    if (pts.size() < 2000) continue;  // only well-observed ramps
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& p : pts) mean += p;
    mean /= static_cast<double>(pts.size());
    Eigen::MatrixXd a(pts.size(), 3);
    for (std::size_t i = 0; i < pts.size(); ++i) a.row(static_cast<Eigen::Index>(i)) = (pts[i] - mean).transpose();
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeThinV);
    const Eigen::Vector3d n = svd.matrixV().col(2);
    const double slope = std::acos(std::min(1.0, std::abs(n.dot(up)))) / kDeg;
    EXPECT_NEAR(slope, scene_->surface(id).slope_deg, 0.1) << scene_->surface(id).name << " from " << pts.size() << " points";
  }
}

TEST_F(WrittenCorridor, GroundTruthJsonListsEverySurface) {
  const auto j = nlohmann::json::parse(readTextFile(dir_->file("ground_truth.json")));
  ASSERT_EQ(j["surfaces"].size(), scene_->surfaces().size());
  for (const auto& s : j["surfaces"]) {
    const auto& truth = scene_->surface(s["id"].get<int>());
    EXPECT_EQ(s["name"], truth.name);
    EXPECT_DOUBLE_EQ(s["slope_deg"].get<double>(), truth.slope_deg);
    EXPECT_DOUBLE_EQ(s["roughness"].get<double>(), truth.roughness);
    EXPECT_DOUBLE_EQ(s["expected_mobility"].get<double>(), truth.expected_mobility);
  }
  EXPECT_EQ(j["moving_obstacle"]["start_frame"].get<int>(), scene_->movingObstacle().start_frame);
  // pixels_seen: the label images' pixel counts, summed over every frame written.
  std::map<int, long long> counted;
  const SevenScenesDirectory d(dir_->str());
  for (int f : d.frameNumbers()) {
    for (const std::uint16_t id : readPng16(d.labelsPath(f)).pixels) {
      if (id != 0) ++counted[id];
    }
  }
  int never = 0;
  for (const auto& s : j["surfaces"]) {
    const int id = s["id"].get<int>();
    EXPECT_EQ(s["pixels_seen"].get<long long>(), counted.count(id) ? counted[id] : 0) << s["name"];
    never += counted.count(id) == 0;
  }
  EXPECT_GT(never, 0);  // the ramps' backs face away from the walk
  EXPECT_GT(counted[1], 1000000);  // the floor
}

// evaluateMap on a hand-made map: a floor (answer 1) meets a wall (answer 0) at x = 1.005;
// a back face at y = 1 that no frame showed stands on the floor.
TEST(Evaluate, EdgeVoxelsAreScoredApartAndFacesNeverInViewTakeNoVoxels) {
  const std::string truth_json = R"({"format": "mobmap-ground-truth", "gravity_down_world": [0, 0, -1], "surfaces": [
    {"id": 1, "name": "floor", "kind": "floor", "slope_deg": 0, "roughness": 1, "expected_mobility": 1, "pixels_seen": 100,
     "geometry": {"type": "polygons", "polygons": [[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]]}},
    {"id": 2, "name": "wall", "kind": "wall", "slope_deg": 90, "roughness": 1, "expected_mobility": 0, "pixels_seen": 100,
     "geometry": {"type": "polygons", "polygons": [[[1.005, 0, 0], [1.005, 1, 0], [1.005, 1, 1], [1.005, 0, 1]]]}},
    {"id": 3, "name": "back", "kind": "ramp_side", "slope_deg": 90, "roughness": 1, "expected_mobility": 0, "pixels_seen": 0,
     "geometry": {"type": "polygons", "polygons": [[[0, 1, 0], [1, 1, 0], [1, 1, 0.2], [0, 1, 0.2]]]}}]})";
  TempDir dir;
  const std::string with_views = dir.file("truth.json");
  const std::string without_views = dir.file("truth-old.json");
  writeTextFileAtomically(with_views, truth_json);
  std::string old = truth_json;
  for (std::size_t at; (at = old.find(", \"pixels_seen\": ")) != std::string::npos;) old.erase(at, old.find(',', at + 1) - at);
  writeTextFileAtomically(without_views, old);

  auto tree = std::make_unique<mapping::MobilityOcTree>(0.02);
  const auto surface = [&](double x, double y, double z, double mobility) {
    const octomap::OcTreeKey key = tree->coordToKey(x, y, z);
    for (int i = 0; i < 3; ++i) tree->updateNode(key, true)->fuse(mobility, 0.01, 1e4);
  };
  surface(0.51, 0.51, 0.01, 1.0);  // floor
  surface(0.31, 0.51, 0.01, 0.8);  // floor, off by 0.2
  surface(1.01, 0.51, 0.51, 0.0);  // wall
  surface(0.99, 0.51, 0.01, 0.0);  // the corner: 1 cm from the floor, 1.5 cm from the wall
  surface(0.51, 0.99, 0.03, 1.0);  // floor noise 1 cm from the back face, 3 cm above the floor
  const mapping::MobilityMap map(std::move(tree), mapping::MapParams{}, Eigen::Matrix3d::Identity());

  // The evaluation points into the ground truth: both must outlive the checks.
  const GroundTruth truth = loadGroundTruth(with_views);
  const Evaluation ev = evaluateMap(map, truth, 3, 0.04);
  ASSERT_EQ(ev.surfaces.size(), 3u);
  EXPECT_FALSE(ev.surfaces[2].surface->seen);
  EXPECT_EQ(ev.surfaces[0].voxels, 3);  // with the voxel beside the back face
  EXPECT_NEAR(ev.surfaces[0].mean_abs_error, 0.2 / 3, 0.005);
  EXPECT_EQ(ev.surfaces[1].voxels, 1);
  EXPECT_NEAR(ev.surfaces[1].mean_abs_error, 0.0, 0.005);
  EXPECT_EQ(ev.surfaces[2].voxels, 0);
  EXPECT_EQ(ev.edge_voxels, 1);
  EXPECT_NEAR(ev.edge_mean_abs_error, 1.0, 0.005);      // the nearest surface (the floor) says 1
  EXPECT_NEAR(ev.edge_mean_abs_error_any, 0.0, 0.005);  // the wall it also touches says 0
  // All five count in the confusion; only the corner is on the wrong side.
  EXPECT_EQ(ev.true_traversable + ev.true_untraversable, 4);
  EXPECT_EQ(ev.false_untraversable, 1);

  // Without pixels_seen every surface counts as seen: the back face takes its voxel.
  const GroundTruth truth_all = loadGroundTruth(without_views);
  const Evaluation all = evaluateMap(map, truth_all, 3, 0.04);
  EXPECT_TRUE(all.surfaces[2].surface->seen);
  EXPECT_EQ(all.surfaces[2].voxels, 1);
  EXPECT_NEAR(all.surfaces[2].mean_abs_error, 1.0, 0.005);
  EXPECT_EQ(all.surfaces[0].voxels, 2);
}

TEST(SevenScenesDirectory, MismatchedInputsNameTheFile) {
  TempDir dir;
  EXPECT_NE(errorOf([&] { SevenScenesDirectory{dir.str()}; }).find("no frame-NNNNNN.depth.png"), std::string::npos);
  writePng16(dir.file("frame-000000.depth.png"), Image16{8, 6, std::vector<std::uint16_t>(48, 1000)});
  const std::string no_k = errorOf([&] { SevenScenesDirectory{dir.str()}; });
  EXPECT_NE(no_k.find("no camera-intrinsics.txt here or in the parent directory: pass --intrinsics"), std::string::npos)
      << no_k;
  // Microsoft's 7-Scenes download has no camera-intrinsics.txt: --intrinsics stands in.
  {
    const SevenScenesDirectory given(dir.str(), "5,6,3.5,2.5");
    EXPECT_EQ(given.intrinsics().width, 8);
    EXPECT_EQ(given.intrinsics().height, 6);
    EXPECT_EQ(given.intrinsics().fy, 6.0);
    EXPECT_EQ(given.intrinsics().cx, 3.5);
  }
  writeIntrinsicsFile(dir.file("camera-intrinsics.txt"), {8, 6, 5, 5, 4, 3});
  // ... and wins over the file.
  EXPECT_EQ(SevenScenesDirectory(dir.str(), "7,7,4,3").intrinsics().fx, 7.0);
  writePng16(dir.file("frame-000001.depth.png"), Image16{9, 6, std::vector<std::uint16_t>(54, 1000)});
  const SevenScenesDirectory d(dir.str());
  EXPECT_NO_THROW((void)d.readDepth(0));
  EXPECT_NE(errorOf([&] { (void)d.readDepth(1); }).find("frame-000001.depth.png: depth image is 9x6"), std::string::npos);
  EXPECT_NE(errorOf([&] { (void)d.readPose(0); }).find("frame-000000.pose.txt: no such file"), std::string::npos);
  // A scene folder of the 7-Scenes / 3DMatch downloads: its sequences are sub-folders.
  TempDir scene;
  std::filesystem::create_directories(scene.file("seq-02"));
  std::filesystem::create_directories(scene.file("seq-01"));
  std::filesystem::create_directories(scene.file("empty"));
  for (const char* f : {"seq-02/frame-000000.depth.png", "seq-02/frame-000001.depth.png", "seq-01/frame-000000.depth.png"})
    writePng16(scene.file(f), Image16{8, 6, std::vector<std::uint16_t>(48, 1000)});
  const std::string parent = errorOf([&] { SevenScenesDirectory{scene.str()}; });
  EXPECT_NE(parent.find(scene.str() + ": no frame-NNNNNN.depth.png files here, but these sub-folders have them: "
                                      "seq-01 (1 frame), seq-02 (2 frames); pass one sequence folder, such as " +
                        scene.file("seq-01")),
            std::string::npos)
      << parent;
}

// The top view's grid against the voxels it was drawn from: every occupied column gets
// a cell of its own and shows its highest voxel, whatever the camera path adds.
TEST(TopView, EveryColumnHasItsOwnCellWhereverTheCameraIs) {
  const double res = 0.02;
  mapping::MobilityOcTree tree(res);
  const auto put = [&](double x, double y, double z, double mobility) {
    mapping::MobilityOcTreeNode* n = tree.updateNode(octomap::point3d(x, y, z), true);
    if (mobility >= 0) n->fuse(mobility, 0.01, 100.0);
  };
  // A floor of 12 x 8 columns (voxel centres at odd multiples of 1 cm), a box top on
  // 3 of them 30 cm higher, and one floor voxel never scored.
  for (int i = 0; i < 12; ++i) {
    for (int j = 0; j < 8; ++j) put((i + 0.5) * res, (j + 0.5) * res, -0.01, i == 11 && j == 7 ? -1.0 : 1.0);
  }
  for (int i = 2; i < 5; ++i) put((i + 0.5) * res, 0.5 * res, 0.29, 0.0);
  // A region far from the floor where 2 x 2 x 2 equal voxels are pruned into one leaf.
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j)
      for (int k = 0; k < 2; ++k) put(0.8 + (i + 0.5) * res, 0.8 + (j + 0.5) * res, (k + 0.5) * res, 0.5);
  tree.prune();
  // Camera positions on a column edge (the origin: the case that drew empty lines),
  // inside a column, and far outside the surfaces.
  for (const Eigen::Vector2d& camera : {Eigen::Vector2d(0, 0), Eigen::Vector2d(0.013, 0.007), Eigen::Vector2d(-0.517, 1.309)}) {
    SCOPED_TRACE(camera.transpose());
    const TopView v = computeTopView(tree, {camera});
    const auto cellOf = [&](double x, double y) {
      return std::make_pair(static_cast<int>(std::floor((x - v.x0) / res + 0.5)),
                            static_cast<int>(std::floor((y - v.y0) / res + 0.5)));
    };
    int filled = 0;
    for (int cy = 0; cy < v.rows; ++cy)
      for (int cx = 0; cx < v.columns; ++cx) filled += !v.empty(cx, cy);
    EXPECT_EQ(filled, 12 * 8 + 4);
    for (int i = 0; i < 12; ++i) {
      for (int j = 0; j < 8; ++j) {
        const auto [cx, cy] = cellOf((i + 0.5) * res, (j + 0.5) * res);
        ASSERT_TRUE(cx >= 0 && cy >= 0 && cx < v.columns && cy < v.rows);
        const bool box = j == 0 && i >= 2 && i < 5;
        EXPECT_NEAR(v.top[v.cell(cx, cy)], box ? 0.3 : 0.0, 1e-9) << i << " " << j;
        const Rgb want = box ? mobilityColour(0.0) : (i == 11 && j == 7 ? kUnknownGrey : mobilityColour(1.0));
        EXPECT_EQ(v.colour[v.cell(cx, cy)], want) << i << " " << j;
      }
    }
    for (const double x : {0.81, 0.83}) {
      for (const double y : {0.81, 0.83}) {
        const auto [cx, cy] = cellOf(x, y);
        EXPECT_EQ(v.colour[v.cell(cx, cy)], mobilityColour(0.5));
      }
    }
    const auto [kx, ky] = cellOf(camera.x(), camera.y());  // the path is inside the picture
    EXPECT_TRUE(kx >= 0 && ky >= 0 && kx < v.columns && ky < v.rows);
  }
  EXPECT_THROW(computeTopView(mapping::MobilityOcTree(res)), std::invalid_argument);
}

// `export --max-z`: the top view cut at a height shows what lies under the cut (the floor
// under a table), and a pruned block straddling the cut shows its highest voxel below it.
TEST(TopView, ACutShowsTheHighestSurfaceBelowIt) {
  const double res = 0.02;
  mapping::MobilityOcTree tree(res);
  const auto put = [&](double x, double y, double z, double mobility) {
    tree.updateNode(octomap::point3d(x, y, z), true)->fuse(mobility, 0.01, 100.0);
  };
  for (int i = 0; i < 6; ++i) put((i + 0.5) * res, 0.5 * res, -0.01, 1.0);  // floor, tops at z = 0
  for (int i = 0; i < 3; ++i) put((i + 0.5) * res, 0.5 * res, 0.71, 0.0);   // a table over half of it, tops at 0.72
  // A 2 x 2 x 2 block of equal voxels, pruned into one leaf spanning z = 0.64 .. 0.68.
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j)
      for (int k = 0; k < 2; ++k) put(0.4 + (i + 0.5) * res, 0.4 + (j + 0.5) * res, 0.64 + (k + 0.5) * res, 0.5);
  tree.prune();
  int pruned = 0;
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it) pruned += it.getSize() > 1.5 * res;
  ASSERT_EQ(pruned, 1);
  const auto topAt = [](const TopView& v, double x, double y) {
    const int cx = static_cast<int>(std::floor((x - v.x0) / v.resolution + 0.5));
    const int cy = static_cast<int>(std::floor((y - v.y0) / v.resolution + 0.5));
    return std::make_pair(v.top[v.cell(cx, cy)], v.colour[v.cell(cx, cy)]);
  };
  const TopView all = computeTopView(tree);
  EXPECT_NEAR(topAt(all, 0.01, 0.01).first, 0.72, 1e-9);
  EXPECT_EQ(topAt(all, 0.01, 0.01).second, mobilityColour(0.0));
  EXPECT_NEAR(topAt(all, 0.41, 0.41).first, 0.68, 1e-9);
  // Between the floor and the table: the floor everywhere, the block whole.
  const TopView under = computeTopView(tree, {}, 0, 0.70);
  EXPECT_EQ(under.columns, all.columns);  // the same grid, so cuts line up
  EXPECT_EQ(under.rows, all.rows);
  for (int i = 0; i < 6; ++i) {
    EXPECT_NEAR(topAt(under, (i + 0.5) * res, 0.01).first, 0.0, 1e-9) << i;
    EXPECT_EQ(topAt(under, (i + 0.5) * res, 0.01).second, mobilityColour(1.0)) << i;
  }
  EXPECT_NEAR(topAt(under, 0.41, 0.41).first, 0.68, 1e-9);
  // Through the block: its lower voxels (top 0.66) are below the cut, its upper ones not.
  const TopView through = computeTopView(tree, {}, 0, 0.67);
  EXPECT_NEAR(topAt(through, 0.41, 0.41).first, 0.66, 1e-9);
  EXPECT_NEAR(topAt(through, 0.43, 0.43).first, 0.66, 1e-9);
  EXPECT_EQ(topAt(through, 0.41, 0.41).second, mobilityColour(0.5));
  // A cut inside its lowest voxel leaves nothing of the block; one on a top face keeps it.
  EXPECT_TRUE(std::isinf(topAt(computeTopView(tree, {}, 0, 0.65), 0.41, 0.41).first));
  EXPECT_NEAR(topAt(computeTopView(tree, {}, 0, 0.66), 0.41, 0.41).first, 0.66, 1e-9);
  // Below everything: an empty grid of the same size.
  const TopView none = computeTopView(tree, {}, 0, -0.5);
  EXPECT_EQ(none.columns, all.columns);
  EXPECT_TRUE(std::all_of(none.top.begin(), none.top.end(), [](double z) { return std::isinf(z); }));
  EXPECT_THROW(computeTopView(tree, {}, 0, std::nan("")), std::invalid_argument);
}

// A map with more columns than the picture may have: cells of k x k columns, each
// showing the highest of its voxels, and a far camera path shrinks the map instead of
// asking for a grid of millions of cells.
TEST(TopView, LargeMapsGetCellsOfSeveralColumnsShowingTheHighest) {
  const double res = 0.02;
  mapping::MobilityOcTree tree(res);
  for (int i = 0; i < 150; ++i) {
    for (int j = 0; j < 50; ++j) tree.updateNode(octomap::point3d((i + 0.5) * res, (j + 0.5) * res, -0.01), true)->fuse(1.0, 0.01, 100.0);
  }
  tree.updateNode(octomap::point3d(77.5 * res, 23.5 * res, 0.29), true)->fuse(0.0, 0.01, 100.0);
  const TopView v = computeTopView(tree, {}, 40);
  EXPECT_EQ(v.columns_per_cell, 4);  // 150 columns in at most 40 cells
  EXPECT_DOUBLE_EQ(v.resolution, 4 * res);
  EXPECT_EQ(v.columns, 38);
  EXPECT_EQ(v.rows, 13);
  for (int cy = 0; cy < v.rows; ++cy) {
    for (int cx = 0; cx < v.columns; ++cx) {
      const bool box = cx == 77 / 4 && cy == 23 / 4;
      EXPECT_NEAR(v.top[v.cell(cx, cy)], box ? 0.3 : 0.0, 1e-9) << cx << " " << cy;
      EXPECT_EQ(v.colour[v.cell(cx, cy)], box ? mobilityColour(0.0) : mobilityColour(1.0)) << cx << " " << cy;
    }
  }
  // Cell centres where the camera path is drawn: the box's cell holds the box's column.
  EXPECT_LE(std::abs(v.x0 + 19 * v.resolution - 77.5 * res), v.resolution / 2);
  EXPECT_LE(std::abs(v.y0 + 5 * v.resolution - 23.5 * res), v.resolution / 2);
  // One column per cell when it fits.
  const TopView fine = computeTopView(tree, {}, 150);
  EXPECT_EQ(fine.columns_per_cell, 1);
  EXPECT_EQ(fine.columns, 150);
  // Each cell names the voxel it shows (reach colours cells by it): an occupied voxel
  // whose top face is the cell's top, in one of the cell's columns; also when the floor
  // is pruned into blocks.
  const auto checkTopKeys = [](const mapping::MobilityOcTree& t, const TopView& view) {
    int checked = 0;
    for (int cy = 0; cy < view.rows; ++cy) {
      for (int cx = 0; cx < view.columns; ++cx) {
        if (view.empty(cx, cy)) continue;
        const octomap::OcTreeKey k = view.top_key[view.cell(cx, cy)];
        const auto* n = t.search(k);
        ASSERT_TRUE(n && t.isNodeOccupied(n)) << cx << " " << cy;
        const octomap::point3d c = t.keyToCoord(k);
        EXPECT_NEAR(c.z() + t.getResolution() / 2, view.top[view.cell(cx, cy)], 1e-6) << cx << " " << cy;
        EXPECT_LE(std::abs(c.x() - (view.x0 + cx * view.resolution)), view.resolution / 2 + 1e-6) << cx << " " << cy;
        EXPECT_LE(std::abs(c.y() - (view.y0 + cy * view.resolution)), view.resolution / 2 + 1e-6) << cx << " " << cy;
        ++checked;
      }
    }
    EXPECT_EQ(checked, view.columns * view.rows);  // the map fills its grid
  };
  checkTopKeys(tree, v);
  checkTopKeys(tree, fine);
  mapping::MobilityOcTree pruned(tree);
  for (int i = 0; i < 150; ++i) {  // a floor two voxels thick, all alike, prunes into 2 x 2 x 2 blocks and larger
    for (int j = 0; j < 50; ++j) {
      for (const float z : {-0.01f, -0.03f}) pruned.setNodeValue(octomap::point3d((i + 0.5) * res, (j + 0.5) * res, z), 1.0f)->setMobility(1.0, 100.0, 1);
    }
  }
  pruned.updateInnerOccupancy();
  pruned.prune();
  ASSERT_LT(pruned.getNumLeafNodes(), tree.getNumLeafNodes() / 3);
  checkTopKeys(pruned, computeTopView(pruned, {}, 40));
  checkTopKeys(pruned, computeTopView(pruned, {}, 150));
  // A camera 10 km away (500,001 columns from the first): 501 columns per cell, and the
  // map is still drawn.
  const TopView far = computeTopView(tree, {Eigen::Vector2d(1e4, 0.0)}, 1000);
  EXPECT_EQ(far.columns_per_cell, 501);
  EXPECT_LE(far.columns, 1000);
  EXPECT_NEAR(far.top[far.cell(0, 0)], 0.3, 1e-9);  // the whole map in one cell: the box is its highest
  EXPECT_THROW(computeTopView(tree, {Eigen::Vector2d(std::nan(""), 0.0)}, 1000), std::invalid_argument);
}

TEST(RealData, SevenScenesRedkitchenReadsWithGravityAndRigidPoses) {
  const std::string dir = std::string(MOBMAP_SHARED_DATA_DIR) + "/7scenes-redkitchen";
  if (!fs::exists(dir)) GTEST_SKIP() << "shared data not found at " << dir;
  const SevenScenesDirectory d(dir);
  EXPECT_EQ(d.frameNumbers().size(), 1000u);
  EXPECT_EQ(d.intrinsics(), (perception::PinholeIntrinsics{640, 480, 585, 585, 320, 240}));
  ASSERT_TRUE(d.gravityDown().has_value());
  EXPECT_NEAR(d.gravityDown()->norm(), 1.0, 1e-12);
  const auto depth = d.readDepth(50);
  int valid = 0;
  for (float z : depth.depth_m) valid += (z > 0.3f && z < 10.f);
  EXPECT_GT(valid, 100000);
  (void)d.readPose(50);  // throws if not rigid
}

TEST(RealData, ThreeDMatchLoungeFindsIntrinsicsInTheParentDirectory) {
  const std::string dir = std::string(MOBMAP_SHARED_DATA_DIR) + "/3dmatch-lounge/seq-01";
  if (!fs::exists(dir)) GTEST_SKIP() << "shared data not found at " << dir;
  const SevenScenesDirectory d(dir);
  EXPECT_EQ(d.frameNumbers().size(), 5u);
  EXPECT_NEAR(d.intrinsics().fx, 570.342205, 1e-9);  // the file's value (the data README rounds it)
  EXPECT_FALSE(d.gravityDown().has_value());
}

}  // namespace
}  // namespace mobmap::app
