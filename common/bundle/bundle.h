#pragma once
// Scene bundles: a scene file and every file it references, packed so that a job needs no shared
// file system. A bundle is addressed by the SHA-256 of its canonical form (below), unpacked into a
// cache folder <cache>/<hash>/ atomically, and its paths are checked: relative, no "..".
//
// Canonical form: for each file in path order, the path's length as 8 bytes little-endian, the
// path (UTF-8, '/' separators), the data's length as 8 bytes little-endian, the data.
#include <cstdint>
#include <filesystem>
#include <map>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "common/util/sha256.h"

namespace rayfarm {

/// A bundle that cannot be built, verified or unpacked; the message names the path and cause.
class BundleError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One file of a bundle: its path relative to the bundle root and its bytes.
struct BundleFile {
  std::string path;
  std::string data;
  bool operator==(const BundleFile&) const = default;
};

/// Files sorted by path, each path unique and valid (check_bundle_path).
struct Bundle {
  std::vector<BundleFile> files;
  bool operator==(const Bundle&) const = default;
  /// Total bytes of file data.
  uint64_t data_bytes() const;
};

/// A scene ready to travel: its bundle, the scene file's path inside it, and the bundle's hash.
struct PackedScene {
  Bundle bundle;
  std::string scene_path;
  std::string hash;
};

/// Throws BundleError unless `path` is a clean relative path: not empty, not absolute, '/'
/// separators, no "." or ".." or empty components, no NUL or backslash.
void check_bundle_path(std::string_view path);
/// True when `hash` looks like a bundle hash: 64 lowercase hex digits.
bool is_bundle_hash(std::string_view hash);

/// Sorts `files` by path and checks every path; throws BundleError on a bad or repeated path.
Bundle make_bundle(std::vector<BundleFile> files);
/// The canonical byte string the hash is computed over (see the header comment).
std::string canonical_bytes(const Bundle& bundle);
/// SHA-256 of canonical_bytes(bundle), 64 lowercase hex digits.
std::string bundle_hash(const Bundle& bundle);

/// Loads `scene_file` (throws SceneError on a bad scene) and packs it with every file it
/// references. The bundle root is the deepest folder holding all of them, so the scene's relative
/// references still resolve after unpacking. Only regular files that lie inside that folder are
/// packed: no symbolic link below it is followed, the scene file's included, so that a link cannot
/// carry another file's content (e.g. /etc/passwd as an MTL) to the master. Throws BundleError
/// naming the file and the cause on a link, on anything but a regular file, or on an unreadable
/// file.
/// A Mitsuba XML scene may read files anywhere under `root` (empty: its own folder).
PackedScene pack_scene(const std::filesystem::path& scene_file,
                       const std::filesystem::path& root = {});
/// pack_scene() of a list of scene files, one per frame: every file of `files` with what each
/// references, in one bundle whose scene is `pattern` (their names with the frame pattern,
/// "shots/frame_####.json"; common/scene/frames.h). Throws SceneError or BundleError naming the
/// file.
PackedScene pack_scene_list(const std::filesystem::path& pattern,
                            const std::vector<std::filesystem::path>& files);
/// pack_scene() of a glTF file rendered through the camera named `camera` (empty: its first)
/// and lit by `environment` (GltfOptions::environment; empty: its own lights): the bundle's scene
/// is then a JSON file beside the glTF that names the file, the camera and the light
/// (docs/gltf.md).
PackedScene pack_gltf_scene(const std::filesystem::path& gltf_file, const std::string& camera,
                            const std::string& environment = "");

/// pack_scene() of a Mitsuba XML scene read under `root` with the $name values `parameters`:
/// when there are any, the bundle's scene is an XML file beside it that sets them as <default>s
/// and includes it (docs/mitsuba.md).
PackedScene pack_mitsuba_scene(const std::filesystem::path& xml_file,
                               const std::filesystem::path& root,
                               const std::map<std::string, std::string>& parameters);

/// Unpacks `bundle` into cache_dir/expected_hash/ and returns that folder. Verifies the hash
/// first (BundleError on a mismatch) and writes into a temporary folder that is renamed into
/// place, so the folder is either complete or absent. An existing folder is reused as is.
std::filesystem::path unpack_bundle(const Bundle& bundle, const std::filesystem::path& cache_dir,
                                    const std::string& expected_hash);

}  // namespace rayfarm
