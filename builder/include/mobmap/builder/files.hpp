#pragma once
// Small file helpers: atomic writes (temporary file + rename), sets of files written all
// or nothing, inputs kept from being written over.

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace mobmap::builder {

/// Calls `write(temporary_path)` and then renames the temporary file over `path`, so
/// `path` is either the old file or the complete new one, never half written. The
/// temporary file is removed if `write` throws. The folder must exist: IoError naming it
/// if not (a mistyped path is not made into a tree of new folders). Temporaries of
/// `path` that a killed process left behind are removed first.
void writeAtomically(const std::string& path, const std::function<void(const std::string&)>& write);

/// One file of a set written together: `write(temporary_path)` writes it there.
struct PendingFile {
  std::string path;
  std::function<void(const std::string& temporary_path)> write;
};

/// Writes a set of files that belong together (a map's .ot, .bt, octovis .ot and .json)
/// all or nothing: every file goes to a temporary beside its path first, and only when
/// all are written are they renamed into place, in the given order. If a write fails
/// (disk full), every temporary is removed, the files on disk stay as they were, and the
/// error names the file that failed. Creates missing parent directories (a map's folder,
/// as `build --out` names it). Temporaries of these files that a killed process left
/// behind are removed first.
void writeFilesTogether(const std::vector<PendingFile>& files);

/// Checks before a long job that `path` could be written: creates its directory and a
/// probe file beside it (removed again). IoError naming the path and the reason if not.
void checkWritable(const std::string& path);

/// A file a command reads or writes, with what it is for the error message: a field in
/// backquotes ("`out`"), a front's option ("--png") or a role ("the map").
struct NamedPath {
  std::string name;
  std::string path;
};

/// Before a command writes anything: IoError if an output's folder does not exist;
/// util::ValueError if an output is one of the inputs, or the same file as another output, naming both. Files are compared as the files they
/// resolve to (another spelling, a symbolic or a hard link is the same file). Empty
/// paths (options not given) are left out.
void refuseToOverwriteInputs(const std::vector<NamedPath>& outputs, const std::vector<NamedPath>& inputs);

/// writeAtomically() for text.
void writeTextFileAtomically(const std::string& path, const std::string& text);

}  // namespace mobmap::builder
