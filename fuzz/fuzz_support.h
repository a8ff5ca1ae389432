#pragma once
// Shared by the fuzz targets: a scratch folder per process, and a check that crashes (so that
// libFuzzer reports it) when an invariant of the code under test is broken.
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace rayfarm::fuzz {

/// Aborts with `what` when `ok` is false: the fuzzer records the input as a finding.
inline void require(bool ok, const char* what) {
  if (!ok) {
    std::fprintf(stderr, "fuzz invariant broken: %s\n", what);
    std::abort();
  }
}

/// A folder of this process under the temporary directory, created on first use and removed
/// at exit.
inline const std::filesystem::path& scratch_dir() {
  static const std::filesystem::path dir = [] {
    const auto d = std::filesystem::temp_directory_path() /
                   ("rayfarm-fuzz-" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    std::atexit([] {
      std::error_code ignored;
      std::filesystem::remove_all(std::filesystem::temp_directory_path() /
                                      ("rayfarm-fuzz-" + std::to_string(::getpid())),
                                  ignored);
    });
    return d;
  }();
  return dir;
}

/// Writes `bytes` to `name` in the scratch folder and returns its path.
inline std::filesystem::path write_scratch(const std::string& name, const std::string& bytes) {
  const std::filesystem::path file = scratch_dir() / name;
  std::ofstream(file, std::ios::binary | std::ios::trunc) << bytes;
  return file;
}

}  // namespace rayfarm::fuzz
