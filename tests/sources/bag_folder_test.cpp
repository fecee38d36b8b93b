// A ROS 2 bag folder whose recorder died before writing metadata.yaml: its files are
// read in rosbag2's numbering (NAME_2 before NAME_10), and recovered() says how.
#include "container.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>

namespace mobmap::sources {
namespace {

namespace fs = std::filesystem;

// An MCAP file with no record but its header and the end of its data section.
void writeEmptyMcap(const fs::path& path) {
  std::string out("\x89MCAP0\r\n", 8);
  const auto record = [&](char op, const std::string& content) {
    out.push_back(op);
    for (int i = 0; i < 8; ++i) out.push_back(static_cast<char>((content.size() >> (8 * i)) & 0xff));
    out += content;
  };
  record(0x01, std::string(8, '\0'));  // profile and library: two empty strings
  record(0x0F, std::string(4, '\0'));
  std::ofstream(path, std::ios::binary) << out;
}

TEST(BagFolder, WithoutMetadataItsFilesAreReadInTheirNumbersOrder) {
  const fs::path dir = fs::temp_directory_path() / ("mobmap-bag-folder-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  for (const char* name : {"run_10.mcap", "run_2.mcap", "run_0.mcap", "run_1.mcap", "notes.txt"}) writeEmptyMcap(dir / name);
  ASSERT_TRUE(isBagFolderWithoutMetadata(dir.string()));
  const auto folder = openBagFolder(dir.string());
  std::vector<std::string> names;
  for (const std::string& f : folder->files()) names.push_back(fs::path(f).filename().string());
  EXPECT_EQ(names, (std::vector<std::string>{"run_0.mcap", "run_1.mcap", "run_2.mcap", "run_10.mcap"}));
  EXPECT_FALSE(folder->scan([](const RawMessage&) {}));
  EXPECT_NE(folder->recovered().find("no metadata.yaml (its recorder did not finish): its 4 bag files read in order"), std::string::npos)
      << folder->recovered();
  // With metadata.yaml (and a folder without bag files) there is nothing to say.
  std::ofstream(dir / "metadata.yaml") << "rosbag2_bagfile_information:\n  relative_file_paths:\n    - run_1.mcap\n";
  EXPECT_FALSE(isBagFolderWithoutMetadata(dir.string()));
  EXPECT_EQ(openBagFolder(dir.string())->recovered(), "");
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mobmap::sources
