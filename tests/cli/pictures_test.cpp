// Every picture command on the simulated corridor, in PNG, SVG and PDF: no two texts a
// picture draws overlap (each command logs them through MOBMAP_PICTURE_TEXTS), each
// lies within its picture, the SVG parses as XML with the picture's size, the PDF is
// whole, and the PNG has the picture's size.
#include "cli_support.hpp"

#include <cpl_minixml.h>

namespace mobmap::cli_test {
namespace {

struct Logged {
  std::string picture;
  int width = 0, height = 0;
  std::vector<std::pair<std::string, std::array<double, 4>>> texts;
};

std::vector<Logged> readLog(const std::string& path) {
  std::vector<Logged> out;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    const auto j = nlohmann::json::parse(line);
    Logged l;
    l.picture = j["picture"];
    l.width = j["width"];
    l.height = j["height"];
    for (const auto& t : j["texts"]) l.texts.emplace_back(t["text"].get<std::string>(), t["box"].get<std::array<double, 4>>());
    out.push_back(std::move(l));
  }
  return out;
}

bool overlap(const std::array<double, 4>& a, const std::array<double, 4>& b) {
  return a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3];
}

TEST(Pictures, EveryPictureCommandDrawsTextsThatNeverOverlapInPngSvgAndPdf) {
  const std::string dir = tempDir("pictures");
  ASSERT_EQ(run("simulate --out " + dir + "/seq --frames 240 --noise none --quiet").code, 0);
  const std::string map = dir + "/corridor.ot";
  ASSERT_EQ(run("build " + dir + "/seq --frames 0:239:6 --out " + map + " --quiet").code, 0);
  const std::string log = dir + "/texts.jsonl";
  const auto draw = [&](const std::string& args) {
    const Result r = runShell("MOBMAP_PICTURE_TEXTS=" + log + " " + MOBMAP_EXE + " " + args);
    EXPECT_EQ(r.code, 0) << args << "\n" << r.out;
  };
  for (const char* ext : {"png", "svg", "pdf"}) {
    const std::string e = ext;
    draw("export " + map + " --png " + dir + "/top." + e);
    draw("reach " + map + " --from 1 0 0 --png " + dir + "/reach." + e);
    draw("plan " + map + " --from 1 0 0 --to 7.05 0.9 0.68 --max-step 0.2 --png " + dir + "/plan." + e);
    draw("export " + map + " --layers " + dir + "/layers_" + e + " --layer-pictures --layer-picture-format " + e);
    draw("overlay " + map + " --frame 60 --out " + dir + "/overlay." + e);
    draw("analyze " + dir + "/seq --frame 30 --overlay " + dir + "/analyze." + e);
    draw("score --plot " + dir + "/plot." + e);
  }
  // The old scale too, on one picture of each kind of drawing.
  draw("export " + map + " --png " + dir + "/top_rg.png --colours red-green");
  // A scale of another name, or a picture of another format: usage errors naming both.
  const Result jet = run("export " + map + " --png " + dir + "/jet.png --colours jet");
  EXPECT_EQ(jet.code, 2);
  EXPECT_NE(jet.out.find("--colours: jet not in {viridis,red-green}"), std::string::npos) << jet.out;
  const Result gif = run("export " + map + " --png " + dir + "/top.gif");
  EXPECT_EQ(gif.code, 2);
  EXPECT_NE(gif.out.find(dir + "/top.gif: a picture's name must end in .png, .svg or .pdf"), std::string::npos) << gif.out;
  EXPECT_FALSE(fs::exists(dir + "/jet.png") || fs::exists(dir + "/top.gif"));
  const std::vector<Logged> pictures = readLog(log);
  ASSERT_EQ(pictures.size(), 3u * 7 + 1);
  std::size_t level_labels = 0;
  for (const Logged& p : pictures) {
    SCOPED_TRACE(p.picture);
    ASSERT_TRUE(fs::exists(p.picture));
    EXPECT_GT(p.texts.size(), 3u);  // a title or caption, and the legend at least
    for (std::size_t a = 0; a < p.texts.size(); ++a) {
      const auto& [text, box] = p.texts[a];
      EXPECT_TRUE(box[0] >= 0 && box[1] >= 0 && box[2] <= p.width && box[3] <= p.height) << "'" << text << "' outside";
      for (std::size_t b = a + 1; b < p.texts.size(); ++b) {
        EXPECT_FALSE(overlap(box, p.texts[b].second)) << "'" << text << "' and '" << p.texts[b].first << "'";
      }
      // A height label: "0.52 m".
      level_labels += text.size() == 6 && text.substr(4) == " m" && text[1] == '.';
    }
    const std::string ext = fs::path(p.picture).extension().string();
    const std::string bytes = fileBytes(p.picture);
    if (ext == ".png") {
      EXPECT_EQ(pngSize(p.picture), std::make_pair(p.width, p.height));
    } else if (ext == ".pdf") {
      EXPECT_EQ(bytes.substr(0, 5), "%PDF-");
      EXPECT_NE(bytes.find("%%EOF", bytes.size() - 16), std::string::npos) << "the PDF ends early";
    } else {
      CPLXMLNode* root = CPLParseXMLString(bytes.c_str());
      ASSERT_NE(root, nullptr) << "the SVG does not parse";
      const CPLXMLNode* svg = CPLSearchXMLNode(root, "=svg");  // "=": the XML declaration's siblings too
      ASSERT_NE(svg, nullptr);
      EXPECT_EQ(std::string(CPLGetXMLValue(svg, "width", "")), std::to_string(p.width) + "pt");
      EXPECT_EQ(std::string(CPLGetXMLValue(svg, "height", "")), std::to_string(p.height) + "pt");
      CPLDestroyXMLNode(root);
    }
  }
  // The top views label the corridor's levels (floor, treads, box tops).
  EXPECT_GE(level_labels, 3u * 4);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mobmap::cli_test
