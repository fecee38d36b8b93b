// Readers and writers of single files: PNG, PCD, pose, gravity and intrinsics files,
// atomic writes, hostile files.
#include "io_support.hpp"

namespace mobmap::app {
namespace {

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
TEST(Picture, FramePictureShowsTheColourImageInGreyAndDepthShaded) {
  EXPECT_EQ(greyOf({255, 0, 0}), (Rgb{76, 76, 76}));
  EXPECT_EQ(greyOf({0, 255, 0}), (Rgb{150, 150, 150}));
  EXPECT_EQ(greyOf({0, 0, 255}), (Rgb{29, 29, 29}));
  EXPECT_EQ(greyOf({255, 255, 255}), (Rgb{255, 255, 255}));
  EXPECT_EQ(greyOf({192, 0, 0}), (Rgb{57, 57, 57}));  // a stereo camera's fill where it measured nothing
  const ImageRgb colour{2, 1, {{192, 0, 0}, {10, 200, 30}}};
  const std::vector<float> depth{1.0f, 0.0f};
  const ImageRgb c = framePicture(2, 1, &colour, depth);
  EXPECT_EQ(c.pixels[0], greyOf(colour.pixels[0]));
  EXPECT_EQ(c.pixels[1], greyOf(colour.pixels[1]));
  // Without a colour image of the frame's size: depth, nearer lighter, black where none.
  const ImageRgb small{1, 1, {{255, 0, 0}}};
  const ImageRgb d = framePicture(2, 1, &small, depth);
  EXPECT_EQ(d.pixels[0], (Rgb{210, 210, 210}));
  EXPECT_EQ(d.pixels[1], (Rgb{0, 0, 0}));
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
    const std::string e = errorOf([&] { (void)sources::loadPcd(path); });
    const std::string checked = errorOf([&] { sources::checkPcdComplete(path); });
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
  EXPECT_NE(errorOf([&] { (void)sources::loadPcd(dir.file("c.pcd")); })
                .find("c.pcd: PCD header declares 10000000 points of 3 values, but its 167000 bytes of ASCII data hold at most 27833"),
            std::string::npos);
  // binary_compressed whose uncompressed size says 4 GB (100 points of 12 bytes are 1200).
  std::string sizes = {10, 0, 0, 0, 0, 0, 0, static_cast<char>(0xF0)};
  writeBytes(dir.file("d.pcd"), pcdHeader("100", "binary_compressed") + sizes + std::string(10, '\0'));
  EXPECT_EQ(both(dir.file("d.pcd")), dir.file("d.pcd") + ": PCD compressed data says it holds 4026531840 bytes, but 100 "
                                     "points of 12 bytes are 1200 (corrupt file)");
  // A COUNT of 10^9 on one field: 8 GB asked of PCL's header reader for two points
  // (std::bad_alloc, naming no file, under a memory limit), in every data format.
  for (const char* format : {"ascii", "binary", "binary_compressed"}) {
    std::string header = pcdHeader("2", format);
    header.replace(header.find("COUNT 1 1 1"), 11, "COUNT 1 1 1000000000");
    writeBytes(dir.file("f.pcd"), header + std::string(100, '\0'));
    EXPECT_EQ(both(dir.file("f.pcd")), dir.file("f.pcd") + ": PCD header declares field 3 of SIZE 4 and COUNT 1000000000; a "
                                       "point of depth data is a few numbers")
        << format;
  }
  // Compressed data that could not hold what the header declares (LZF shrinks 264 bytes to 3 at best).
  writeBytes(dir.file("g.pcd"), pcdHeader("1000000", "binary_compressed") + sizes + std::string(100, '\0'));
  EXPECT_EQ(both(dir.file("g.pcd")), dir.file("g.pcd") + ": PCD header declares 1000000 points of 12 bytes, more than its 108 "
                                     "bytes of compressed data can hold");
  // The same file honest: 20000 ASCII points load.
  writeBytes(dir.file("e.pcd"), pcdHeader("20000", "ascii") + lines);
  EXPECT_EQ(sources::loadPcd(dir.file("e.pcd")).points.size(), 20000u);
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
    const Frame f = sources::loadPcd(dir.file(name));
    ASSERT_EQ(f.points.size(), points.size()) << name;
    for (std::size_t i = 0; i < points.size(); ++i) {
      EXPECT_EQ(f.points[i], points[i].cast<float>()) << name << " point " << i;
    }
  }
  // Coordinates that are not floats are refused by name.
  std::string ints = ascii;
  ints.replace(ints.find("TYPE F F F"), 10, "TYPE I I I");
  writeBytes(dir.file("ints.pcd"), ints);
  EXPECT_NE(errorOf([&] { (void)sources::loadPcd(dir.file("ints.pcd")); }).find("ints.pcd: PCD field x is not a 4- or 8-byte float"),
            std::string::npos)
      << errorOf([&] { (void)sources::loadPcd(dir.file("ints.pcd")); });
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
  EXPECT_THROW(parseVector3("0,0,0", "--gravity"), util::ValueError);
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

}  // namespace
}  // namespace mobmap::app
