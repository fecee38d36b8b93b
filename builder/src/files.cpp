#include "mobmap/builder/files.hpp"

#include "mobmap/sources/io_error.hpp"
#include "mobmap/util/field_error.hpp"

#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace mobmap::builder {

using sources::IoError;

namespace {

namespace fs = std::filesystem;

// The path as the file it names: absolute, links and "." / ".." resolved as far as the
// file system has them.
fs::path resolved(const std::string& path) {
  std::error_code ec;
  fs::path p = fs::weakly_canonical(fs::absolute(path, ec), ec);
  return ec ? fs::absolute(path, ec).lexically_normal() : p;
}

bool sameFile(const std::string& a, const std::string& b) {
  std::error_code ec;
  if (fs::exists(a, ec) && fs::exists(b, ec)) return fs::equivalent(a, b, ec) && !ec;
  return resolved(a) == resolved(b);
}

// IoError naming `path` when the folder it goes in does not exist; `what` names the
// folder in the message ("--png's folder").
void requireParentDirectory(const std::string& path, const std::string& what = "the folder") {
  const fs::path parent = fs::path(path).parent_path();
  std::error_code ec;
  if (parent.empty() || fs::is_directory(parent, ec)) return;
  throw IoError(path, what + " " + parent.string() + " does not exist (create it first)");
}

}  // namespace

void refuseToOverwriteInputs(const std::vector<NamedPath>& outputs, const std::vector<NamedPath>& inputs) {
  for (std::size_t i = 0; i < outputs.size(); ++i) {
    const NamedPath& out = outputs[i];
    if (out.path.empty()) continue;
    requireParentDirectory(out.path, out.name + "'s folder");
    for (const NamedPath& in : inputs) {
      if (in.path.empty()) continue;
      if (sameFile(out.path, in.path)) {
        throw util::ValueError(out.name + " " + out.path + " is " + in.name + " " + in.path +
                         ", which this command reads; choose another path");
      }
    }
    for (std::size_t k = 0; k < i; ++k) {
      if (!outputs[k].path.empty() && sameFile(out.path, outputs[k].path)) {
        throw util::ValueError(out.name + " " + out.path + " and " + outputs[k].name + " " + outputs[k].path +
                         " are the same file; give each output its own path");
      }
    }
  }
}

namespace {

// Creates the directory a file will go in; IoError naming the file if it cannot.
void createParentDirectory(const std::string& path) {
  const std::filesystem::path target(path);
  if (!target.has_parent_path()) return;
  std::error_code ec;
  std::filesystem::create_directories(target.parent_path(), ec);
  if (ec) throw IoError(path, "cannot create directory " + target.parent_path().string() + ": " + ec.message());
}

}  // namespace

namespace {

// Removes the temporaries of `path` (path.new.PID..., path.tmp.PID...) whose process is
// gone: a save killed between writing and renaming leaves one, and nothing else would
// ever remove it. Those of a process still running are left alone.
void removeStaleTemporaries(const std::string& path) {
  const std::filesystem::path target(path);
  const std::filesystem::path dir = target.has_parent_path() ? target.parent_path() : std::filesystem::path(".");
  const std::string base = target.filename().string();
  std::error_code ec;
  for (std::filesystem::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    for (const char* tag : {".new.", ".tmp."}) {
      const std::string prefix = base + tag;
      if (name.size() <= prefix.size() || name.compare(0, prefix.size(), prefix) != 0) continue;
      const std::size_t digits = name.find_first_not_of("0123456789", prefix.size());
      const std::string pid_text = name.substr(prefix.size(), digits == std::string::npos ? std::string::npos : digits - prefix.size());
      if (pid_text.empty() || pid_text.size() > 9) continue;
      const pid_t pid = static_cast<pid_t>(std::stol(pid_text));
      if (pid == ::getpid() || ::kill(pid, 0) == 0 || errno != ESRCH) continue;  // running, or not ours to judge
      std::error_code ignored;
      std::filesystem::remove(it->path(), ignored);
    }
  }
}

// Whether the folders of the files written must exist, or are created.
enum class Folders { kMustExist, kCreate };

// Writes each file to path + suffix + PID, then renames them all into place in order;
// on a failed write every temporary is removed and the error names the file itself.
void replaceFiles(const std::vector<PendingFile>& files, const std::string& suffix, Folders folders) {
  std::error_code ec;
  for (const PendingFile& f : files) {
    if (folders == Folders::kMustExist) requireParentDirectory(f.path);
    removeStaleTemporaries(f.path);
  }
  std::vector<std::string> temporaries;
  const auto discard = [&](std::size_t from) {
    for (std::size_t i = from; i < temporaries.size(); ++i) std::filesystem::remove(temporaries[i], ec);
  };
  for (const PendingFile& f : files) {
    if (folders == Folders::kCreate) createParentDirectory(f.path);
    temporaries.push_back(f.path + suffix + std::to_string(::getpid()));
    const std::string& tmp = temporaries.back();
    try {
      f.write(tmp);
    } catch (const std::exception& e) {
      discard(0);
      // The user knows the file by its own name, not by the temporary's a writer may give.
      std::string reason;
      if (const auto* io = dynamic_cast<const IoError*>(&e)) {
        reason = io->reason();
      } else {
        const std::string what = e.what();
        reason = what.rfind(tmp + ": ", 0) == 0 ? what.substr(tmp.size() + 2) : what;
      }
      throw IoError(f.path, reason + (files.size() > 1 ? "; no file of the set was changed" : ""));
    } catch (...) {
      discard(0);
      throw;
    }
  }
  for (std::size_t i = 0; i < files.size(); ++i) {
    if (std::rename(temporaries[i].c_str(), files[i].path.c_str()) != 0) {
      const std::string reason = std::strerror(errno);
      discard(i);
      throw IoError(files[i].path, "cannot rename the temporary file into place: " + reason +
                                       (i > 0 ? " (the files before it in the set were replaced)" : ""));
    }
  }
}

}  // namespace

void writeAtomically(const std::string& path, const std::function<void(const std::string&)>& write) {
  replaceFiles({{path, write}}, ".tmp.", Folders::kMustExist);
}

void writeFilesTogether(const std::vector<PendingFile>& files) {
  // Not ".tmp.PID", which the writers' own atomic saves use inside: a temporary left
  // behind by a killed run then says which of the two left it.
  replaceFiles(files, ".new.", Folders::kCreate);
}

void checkWritable(const std::string& path) {
  const std::filesystem::path target(path);
  std::error_code ec;
  createParentDirectory(path);
  if (std::filesystem::is_directory(target, ec)) throw IoError(path, "is a directory");
  const std::string probe = path + ".probe." + std::to_string(::getpid());
  {
    std::ofstream out(probe, std::ios::binary);
    if (!out) throw IoError(path, std::string("cannot write there: ") + std::strerror(errno));
  }
  std::filesystem::remove(probe, ec);
}

void writeTextFileAtomically(const std::string& path, const std::string& text) {
  writeAtomically(path, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    if (!out) throw IoError(path, std::string("cannot write: ") + std::strerror(errno));
    out << text;
    out.flush();
    if (!out) throw IoError(path, "write failed (disk full?)");
  });
}

}  // namespace mobmap::builder
