#include "mobmap/util/plugin.hpp"

#include <dlfcn.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#ifndef MOBMAP_PLUGIN_INSTALL_DIR
#define MOBMAP_PLUGIN_INSTALL_DIR ""
#endif
#ifndef MOBMAP_PLUGIN_BUILD_DIR
#define MOBMAP_PLUGIN_BUILD_DIR ""
#endif

namespace mobmap::util {
namespace {

// The folder of the program or shared library this function was linked into.
std::string ownFolder() {
  Dl_info info{};
  if (dladdr(reinterpret_cast<void*>(&ownFolder), &info) == 0 || info.dli_fname == nullptr) return {};
  std::string path = info.dli_fname;
  const auto slash = path.rfind('/');
  return slash == std::string::npos ? std::string(".") : path.substr(0, slash);
}

std::vector<std::string> folders() {
  std::vector<std::string> out;
  if (const char* env = std::getenv("MOBMAP_PLUGIN_DIR"); env != nullptr && *env != '\0') out.emplace_back(env);
  if (const std::string own = ownFolder(); !own.empty()) {
    std::error_code ec;
    out.push_back(std::filesystem::absolute(own + "/../lib/mobmap", ec).lexically_normal().string());
  }
  for (const char* dir : {MOBMAP_PLUGIN_INSTALL_DIR, MOBMAP_PLUGIN_BUILD_DIR}) {
    if (*dir != '\0' && std::find(out.begin(), out.end(), dir) == out.end()) out.emplace_back(dir);
  }
  return out;
}

void* open(const std::string& name) {
  static std::mutex mutex;
  static std::map<std::string, void*> opened;
  const std::lock_guard<std::mutex> lock(mutex);
  if (const auto it = opened.find(name); it != opened.end()) return it->second;
  const std::string file = "libmobmap_" + name + ".so";
  std::string tried, last_error;
  for (const std::string& dir : folders()) {
    const std::string path = dir + "/" + file;
    if (void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL)) {
      opened[name] = handle;
      return handle;
    }
    const char* e = dlerror();
    // A file that exists but cannot be loaded (a library it needs is missing) says so.
    if (e != nullptr && std::string(e).find("No such file") == std::string::npos) last_error = e;
    tried += (tried.empty() ? "" : ", ") + dir;
  }
  throw std::runtime_error("mobmap's " + name + " adapter (" + file + ") " +
                           (last_error.empty() ? "is not installed: looked in " + tried
                                               : "cannot be loaded: " + last_error));
}

}  // namespace

void* pluginSymbol(const std::string& name, const char* symbol) {
  void* handle = open(name);
  dlerror();
  void* found = dlsym(handle, symbol);
  if (found == nullptr) {
    throw std::runtime_error("mobmap's " + name + " adapter (libmobmap_" + name + ".so) has no " + symbol +
                             ": it belongs to another version of mobmap");
  }
  return found;
}

}  // namespace mobmap::util
