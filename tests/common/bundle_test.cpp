// Scene bundles: paths are checked (relative, no ".."), the hash is SHA-256 of a canonical form
// that does not depend on the order files were added, a scene packs with every file it references,
// and unpacking verifies the hash and writes atomically into <cache>/<hash>/.
#include <gtest/gtest.h>

#include <unistd.h>

#include <atomic>
#include <fstream>
#include <iterator>

#include "common/bundle/bundle.h"
#include "common/scene/parser.h"
#include "tests/support/temp_dir.h"

namespace rayfarm {
namespace {
namespace fs = std::filesystem;

using testing::read_file;
using testing::TempDir;

void write_file(const fs::path& file, const std::string& text) {
  fs::create_directories(file.parent_path());
  std::ofstream(file, std::ios::binary) << text;
}

/// The bundled Embree Cornell box with its mesh moved to meshes/, in a temporary folder.
fs::path cornell_with_mesh_folder(const fs::path& root) {
  const fs::path source = fs::path(RAYFARM_SOURCE_DIR) / "scenes" / "embree-cornell";
  write_file(root / "meshes" / "cornell_box.obj", read_file(source / "cornell_box.obj"));
  write_file(root / "meshes" / "cornell_box.mtl", read_file(source / "cornell_box.mtl"));
  std::string scene = read_file(source / "scene.json");
  const std::string from = "\"cornell_box.obj\"";
  scene.replace(scene.find(from), from.size(), "\"meshes/cornell_box.obj\"");
  write_file(root / "scene.json", scene);
  return root / "scene.json";
}

TEST(BundlePath, CleanRelativePathsAreAccepted) {
  EXPECT_NO_THROW(check_bundle_path("scene.json"));
  EXPECT_NO_THROW(check_bundle_path("meshes/box.obj"));
  EXPECT_NO_THROW(check_bundle_path("a/b/c..d"));
}

TEST(BundlePath, EscapingOrOddPathsAreRejected) {
  for (const char* bad : {"", "/etc/passwd", "..", "../x", "a/../../x", "a/..", "./a", "a/./b",
                          "a//b", "a/", "a\\b", "..\\x"}) {
    EXPECT_THROW(check_bundle_path(bad), BundleError) << bad;
  }
  EXPECT_THROW(check_bundle_path(std::string("a\0b", 3)), BundleError);
}

TEST(BundleHash, Sha256MatchesTheStandardVector) {
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_TRUE(is_bundle_hash(sha256_hex("")));
  EXPECT_FALSE(is_bundle_hash("../../etc"));
  EXPECT_FALSE(is_bundle_hash(std::string(64, 'A')));
}

TEST(BundleHash, CanonicalFormIsLengthPrefixedInPathOrder) {
  const Bundle b = make_bundle({{"b", "2"}, {"a", "xy"}});
  const std::string expected =
      std::string("\x01\0\0\0\0\0\0\0", 8) + "a" + std::string("\x02\0\0\0\0\0\0\0", 8) + "xy" +
      std::string("\x01\0\0\0\0\0\0\0", 8) + "b" + std::string("\x01\0\0\0\0\0\0\0", 8) + "2";
  EXPECT_EQ(canonical_bytes(b), expected);
}

TEST(BundleHash, IndependentOfInsertionOrderAndSensitiveToContent) {
  const Bundle a = make_bundle({{"x/one", "1"}, {"two", "22"}});
  const Bundle b = make_bundle({{"two", "22"}, {"x/one", "1"}});
  EXPECT_EQ(bundle_hash(a), bundle_hash(b));
  EXPECT_NE(bundle_hash(a), bundle_hash(make_bundle({{"x/one", "1"}, {"two", "23"}})));
  EXPECT_NE(bundle_hash(a), bundle_hash(make_bundle({{"x/onf", "1"}, {"two", "22"}})));
  // Moving a byte from a path into the data changes the hash (lengths are part of the form).
  EXPECT_NE(bundle_hash(make_bundle({{"ab", "c"}})), bundle_hash(make_bundle({{"a", "bc"}})));
}

TEST(Bundle, RepeatedOrBadPathsAreRejected) {
  EXPECT_THROW(make_bundle({{"a", "1"}, {"a", "2"}}), BundleError);
  EXPECT_THROW(make_bundle({{"../a", "1"}}), BundleError);
}

TEST(Bundle, PacksASceneWithEveryFileItReferencesAndNothingElse) {
  TempDir dir;
  const fs::path scene = cornell_with_mesh_folder(dir.path() / "box");
  // Files beside the scene that it does not reference stay home.
  write_file(dir.path() / "box" / "meshes" / "unused.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  write_file(dir.path() / "box" / "renders" / "old.exr", std::string(1 << 20, 'x'));
  const PackedScene packed = pack_scene(scene);
  EXPECT_EQ(packed.scene_path, "scene.json");
  std::vector<std::string> paths;
  for (const auto& f : packed.bundle.files) paths.push_back(f.path);
  EXPECT_EQ(paths, (std::vector<std::string>{"meshes/cornell_box.mtl", "meshes/cornell_box.obj",
                                             "scene.json"}));
  EXPECT_EQ(packed.hash, bundle_hash(packed.bundle));
  // Packing again, from another working directory, gives the same hash.
  EXPECT_EQ(pack_scene(fs::relative(scene)).hash, packed.hash);
}

/// Expects pack_scene(`scene`) to throw a BundleError whose message holds each of `parts`.
void expect_pack_error(const fs::path& scene, const std::vector<std::string>& parts) {
  try {
    const PackedScene packed = pack_scene(scene);
    std::string paths;
    for (const auto& f : packed.bundle.files) paths += " " + f.path;
    FAIL() << "packed" << paths;
  } catch (const BundleError& e) {
    for (const auto& part : parts) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  }
}

TEST(Bundle, ASymbolicLinkInTheSceneFolderIsRefusedNotFollowed) {
  TempDir dir;
  const fs::path box = dir.path() / "box";
  const fs::path scene = cornell_with_mesh_folder(box);
  // A file outside the scene's folder that the MTL parser reads without complaint.
  const fs::path mtl = box / "meshes" / "cornell_box.mtl";
  const std::string mtl_text = read_file(mtl);
  write_file(dir.path() / "private" / "passwd", mtl_text + "# root:x:0:0:root:/root:/bin/bash\n");
  fs::remove(mtl);
  fs::create_symlink(dir.path() / "private" / "passwd", mtl);
  ASSERT_NO_THROW(load_scene(scene));  // the scene loads: only packing must refuse the link
  expect_pack_error(scene, {mtl.string() + ": is a symbolic link to " +
                                (dir.path() / "private" / "passwd").string(),
                            "only regular files inside the scene's folder"});

  // A link that stays inside the folder is refused as well: what is packed is what lies there.
  write_file(box / "meshes" / "real.mtl", mtl_text);
  fs::remove(mtl);
  fs::create_symlink("real.mtl", mtl);
  expect_pack_error(scene, {mtl.string() + ": is a symbolic link to real.mtl"});

  // A linked folder on the way to a file is refused, naming the folder and the file.
  fs::remove(mtl);
  write_file(mtl, mtl_text);
  fs::rename(box / "meshes", dir.path() / "elsewhere");
  fs::create_directory_symlink(dir.path() / "elsewhere", box / "meshes");
  ASSERT_NO_THROW(load_scene(scene));
  expect_pack_error(scene, {(box / "meshes").string() + ": is a symbolic link",
                            "on the path of " + (box / "meshes" / "cornell_box.obj").string()});

  // The scene file itself as a link.
  fs::remove(box / "meshes");
  fs::rename(dir.path() / "elsewhere", box / "meshes");
  fs::rename(scene, box / "real.json");
  fs::create_symlink("real.json", scene);
  expect_pack_error(scene, {scene.string() + ": is a symbolic link"});

  // With regular files only, the scene packs, the MTL with its own content.
  fs::remove(scene);
  fs::rename(box / "real.json", scene);
  fs::remove(box / "meshes" / "real.mtl");
  const PackedScene packed = pack_scene(scene);
  ASSERT_EQ(packed.bundle.files.size(), 3u);
  EXPECT_EQ(packed.bundle.files[0].path, "meshes/cornell_box.mtl");
  EXPECT_EQ(packed.bundle.files[0].data, mtl_text);
}

TEST(Bundle, ABadSceneIsTheParsersError) {
  TempDir dir;
  write_file(dir.path() / "bad.json", "{ \"camera\": ");
  EXPECT_THROW(pack_scene(dir.path() / "bad.json"), SceneError);
}

TEST(Bundle, UnpacksIntoTheCacheAndTheSceneLoadsFromThere) {
  TempDir dir;
  const PackedScene packed = pack_scene(cornell_with_mesh_folder(dir.path() / "box"));
  const fs::path cache = dir.path() / "cache";
  const fs::path unpacked = unpack_bundle(packed.bundle, cache, packed.hash);
  EXPECT_EQ(unpacked, cache / packed.hash);
  const Scene scene = load_scene(unpacked / packed.scene_path);
  EXPECT_EQ(scene.film.width, 512u);
  EXPECT_FALSE(scene.meshes.empty());
  // Only the final folder is left: no temporary folders.
  int entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(cache)) ++entries;
  EXPECT_EQ(entries, 1);
  // A second unpack reuses the folder.
  EXPECT_EQ(unpack_bundle(packed.bundle, cache, packed.hash), unpacked);
}

TEST(Bundle, UnpackVerifiesTheHashAndLeavesNothingOnMismatch) {
  TempDir dir;
  const Bundle b = make_bundle({{"scene.json", "{}"}});
  const std::string wrong = sha256_hex("something else");
  EXPECT_THROW(unpack_bundle(b, dir.path(), wrong), BundleError);
  EXPECT_FALSE(fs::exists(dir.path() / wrong));
  EXPECT_THROW(unpack_bundle(b, dir.path(), "../escape"), BundleError);
  EXPECT_TRUE(fs::is_empty(dir.path()));
}

TEST(Bundle, UnpackRejectsEscapingPathsEvenWithAMatchingHash) {
  TempDir dir;
  Bundle evil;
  evil.files.push_back({"../evil.txt", "x"});  // built by hand, bypassing make_bundle
  const std::string hash = bundle_hash(evil);
  EXPECT_THROW(unpack_bundle(evil, dir.path() / "cache", hash), BundleError);
  EXPECT_FALSE(fs::exists(dir.path() / "evil.txt"));
  Bundle absolute;
  absolute.files.push_back({"/tmp/evil.txt", "x"});
  EXPECT_THROW(unpack_bundle(absolute, dir.path() / "cache", bundle_hash(absolute)), BundleError);
}

}  // namespace
}  // namespace rayfarm
