// libFuzzer target: a scene bundle as a worker receives it (a wire Bundle, or, when the input is
// not one, files given as "path<TAB>data" lines). Building, hashing and unpacking it into the
// cache must succeed or throw BundleError, and unpacking never writes outside the cache.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "common/bundle/bundle.h"
#include "common/protocol/convert.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rayfarm;
  namespace fs = std::filesystem;
  const std::string input(reinterpret_cast<const char*>(data), size);
  (void)is_bundle_hash(input);
  try {
    Bundle bundle;
    wire::Bundle message;
    if (message.ParseFromString(input)) {
      bundle = protocol::bundle_from_wire(message);
    } else {
      std::vector<BundleFile> files;
      size_t start = 0;
      while (start < input.size()) {
        size_t end = input.find('\n', start);
        if (end == std::string::npos) end = input.size();
        const std::string line = input.substr(start, end - start);
        const size_t tab = line.find('\t');
        files.push_back({line.substr(0, tab), tab == std::string::npos ? "" : line.substr(tab + 1)});
        start = end + 1;
      }
      bundle = make_bundle(std::move(files));
    }
    for (const BundleFile& f : bundle.files) check_bundle_path(f.path);
    const std::string hash = bundle_hash(bundle);
    fuzz::require(is_bundle_hash(hash), "bundle_hash is not a bundle hash");
    const fs::path cache = fuzz::scratch_dir() / "cache";
    const fs::path root = unpack_bundle(bundle, cache, hash);
    fuzz::require(root == cache / hash, "unpacked elsewhere than cache/hash");
    // The root holds exactly the bundle's files with their bytes, and the cache nothing else.
    size_t count = 0;
    for (const auto& entry : fs::recursive_directory_iterator(root)) {
      fuzz::require(!entry.is_symlink(), "a symbolic link was unpacked");
      if (entry.is_regular_file()) ++count;
    }
    fuzz::require(count == bundle.files.size(), "unpacked file count");
    for (const BundleFile& f : bundle.files) {
      std::ifstream in(root / f.path, std::ios::binary);
      const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      fuzz::require(in.good() || in.eof(), "a bundle file was not unpacked");
      fuzz::require(bytes == f.data, "an unpacked file differs from the bundle's");
    }
    size_t entries = 0;
    for (const auto& entry : fs::directory_iterator(cache)) entries += entry.path() != root;
    fuzz::require(entries == 0, "unpacking left something else in the cache");
    fs::remove_all(root);
    // A wrong hash is refused.
    try {
      (void)unpack_bundle(bundle, cache, std::string(64, '0'));
      fuzz::require(hash == std::string(64, '0'), "a bundle unpacked under a wrong hash");
    } catch (const BundleError&) {
    }
  } catch (const BundleError&) {
  }
  return 0;
}
