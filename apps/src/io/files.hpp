#pragma once
// Small file helpers for the commands: the library's atomic writes and input checks
// (mobmap/builder/files.hpp), whole-file reads and numbers in text (mobmap/sources/text.hpp).

#include "mobmap/builder/files.hpp"
#include "mobmap/sources/text.hpp"

namespace mobmap::app {

using builder::checkWritable;
using builder::NamedPath;
using builder::PendingFile;
using builder::refuseToOverwriteInputs;
using builder::writeAtomically;
using builder::writeFilesTogether;
using builder::writeTextFileAtomically;
using sources::parseFiniteNumber;
using sources::readTextFile;
using sources::splitNumbers;

}  // namespace mobmap::app
