#include "common/bundle/bundle.h"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <fstream>
#include <iterator>
#include <set>
#include <system_error>
#include <utility>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "common/scene/mitsuba_loader.h"
#include "common/scene/parser.h"
#include "common/util/atomic_file.h"

namespace rayfarm {
namespace fs = std::filesystem;
namespace {

void append_u64le(std::string& out, uint64_t v) {
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xff));
}

/// Closes a file descriptor when it goes out of scope.
struct Fd {
  int fd = -1;
  explicit Fd(int f) : fd(f) {}
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  Fd(Fd&& other) noexcept : fd(std::exchange(other.fd, -1)) {}
  Fd& operator=(Fd&& other) noexcept {
    std::swap(fd, other.fd);
    return *this;
  }
};

std::string errno_text(int err) { return std::error_code(err, std::generic_category()).message(); }

/// Why `name` in the folder `dir` could not be opened: a symbolic link (with its target) or the
/// system's cause.
std::string open_failure(int dir, const std::string& name, int err) {
  struct stat st {};
  if (::fstatat(dir, name.c_str(), &st, AT_SYMLINK_NOFOLLOW) == 0 && S_ISLNK(st.st_mode)) {
    std::string target(4096, '\0');
    const ssize_t n = ::readlinkat(dir, name.c_str(), target.data(), target.size());
    target.resize(n > 0 ? static_cast<size_t>(n) : 0);
    return "is a symbolic link" + (target.empty() ? std::string() : " to " + target) +
           "; rayfarm packs only regular files inside the scene's folder, so that no link can "
           "carry another file to the master: replace the link with a copy of what it points to";
  }
  return "cannot read it for the scene bundle: " + errno_text(err);
}

/// Reads the file `rel` of the folder `root` without following a symbolic link anywhere below
/// `root`: each folder on the way and the file are opened with O_NOFOLLOW, so the file read is the
/// regular file that lies inside `root` under that name, whatever links the folder holds.
std::string read_inside(const fs::path& root, const fs::path& rel) {
  const fs::path shown = root / rel;
  if (rel.empty() || rel.is_absolute() || *rel.begin() == "..") {
    throw BundleError(shown.string() + ": lies outside the scene's folder " + root.string());
  }
  Fd dir(::open(root.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (dir.fd < 0) {
    throw BundleError(root.string() + ": cannot open the scene's folder: " + errno_text(errno));
  }
  fs::path walked = root;
  const auto last = std::prev(rel.end());
  for (auto it = rel.begin(); it != rel.end(); ++it) {
    const std::string name = it->string();
    walked /= name;
    const int flags = O_RDONLY | O_NOFOLLOW | O_CLOEXEC | (it == last ? O_NONBLOCK : O_DIRECTORY);
    Fd next(::openat(dir.fd, name.c_str(), flags));
    if (next.fd < 0) {
      const int err = errno;
      std::string why = walked.string() + ": " + open_failure(dir.fd, name, err);
      if (it != last) why += " (it is on the path of " + shown.string() + ")";
      throw BundleError(why);
    }
    dir = std::move(next);
  }
  struct stat st {};
  if (::fstat(dir.fd, &st) != 0) {
    throw BundleError(shown.string() + ": cannot read it for the scene bundle: " +
                      errno_text(errno));
  }
  if (!S_ISREG(st.st_mode)) {
    throw BundleError(shown.string() +
                      ": is not a regular file; rayfarm packs only regular files inside the "
                      "scene's folder");
  }
  std::string data;
  data.reserve(static_cast<size_t>(st.st_size));
  char buf[1 << 16];
  while (true) {
    const ssize_t n = ::read(dir.fd, buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      throw BundleError(shown.string() + ": read error while packing the scene bundle: " +
                        errno_text(errno));
    }
    if (n == 0) break;
    data.append(buf, static_cast<size_t>(n));
  }
  return data;
}

void write_file(const fs::path& path, const std::string& data) {
  // A failure here is the unpacking side's storage (a full disk), not the bundle's fault: the
  // system error says which, and is_storage_error() recognises it.
  write_bytes(path, data);
}

/// Deepest folder containing both `a` and `b` (both absolute and lexically normal).
fs::path common_ancestor(const fs::path& a, const fs::path& b) {
  fs::path out;
  auto ia = a.begin(), ib = b.begin();
  for (; ia != a.end() && ib != b.end() && *ia == *ib; ++ia, ++ib) out /= *ia;
  return out;
}

std::string unique_suffix() {
  static std::atomic<uint64_t> counter{0};
  return std::to_string(::getpid()) + "-" + std::to_string(counter.fetch_add(1));
}

}  // namespace

uint64_t Bundle::data_bytes() const {
  uint64_t n = 0;
  for (const auto& f : files) n += f.data.size();
  return n;
}

void check_bundle_path(std::string_view path) {
  const std::string quoted = "bundle path '" + std::string(path) + "'";
  if (path.empty()) throw BundleError("empty bundle path");
  if (path.size() > 4096) throw BundleError(quoted + " is too long");
  if (path.front() == '/') throw BundleError(quoted + " is absolute");
  if (path.find('\\') != std::string_view::npos || path.find('\0') != std::string_view::npos) {
    throw BundleError(quoted + " contains a backslash or NUL");
  }
  size_t start = 0;
  while (start <= path.size()) {
    const size_t end = std::min(path.find('/', start), path.size());
    const std::string_view part = path.substr(start, end - start);
    if (part.empty()) throw BundleError(quoted + " has an empty component");
    if (part == "..") throw BundleError(quoted + " contains '..'");
    if (part == ".") throw BundleError(quoted + " contains '.'");
    start = end + 1;
  }
}

bool is_bundle_hash(std::string_view hash) {
  return hash.size() == 64 && std::all_of(hash.begin(), hash.end(), [](char c) {
           return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
         });
}

Bundle make_bundle(std::vector<BundleFile> files) {
  std::sort(files.begin(), files.end(),
            [](const BundleFile& a, const BundleFile& b) { return a.path < b.path; });
  for (size_t i = 0; i < files.size(); ++i) {
    check_bundle_path(files[i].path);
    if (i > 0 && files[i].path == files[i - 1].path) {
      throw BundleError("bundle path '" + files[i].path + "' appears twice");
    }
  }
  return Bundle{std::move(files)};
}

std::string canonical_bytes(const Bundle& bundle) {
  std::string out;
  out.reserve(bundle.data_bytes() + bundle.files.size() * 64);
  for (const auto& f : bundle.files) {
    append_u64le(out, f.path.size());
    out += f.path;
    append_u64le(out, f.data.size());
    out += f.data;
  }
  return out;
}

std::string bundle_hash(const Bundle& bundle) { return sha256_hex(canonical_bytes(bundle)); }

namespace {

/// Packs `scene_file` with the files its loaded `scene` references.
/// The files a loaded scene needs: the scene file itself, then every file it references.
std::vector<fs::path> scene_sources(const fs::path& scene_file, const Scene& scene) {
  const fs::path scene_abs = fs::absolute(scene_file).lexically_normal();
  std::vector<fs::path> sources{scene_abs};
  for (const auto& ref : scene.referenced) {
    if (ref.is_absolute()) {
      throw BundleError(scene_file.string() + ": references the absolute path " + ref.string() +
                        "; a bundled scene must reference its files by relative paths");
    }
    sources.push_back((scene_abs.parent_path() / ref).lexically_normal());
  }
  return sources;
}

/// Packs `sources` under their deepest common folder; the bundle's scene is `scene_file` (which
/// may be a pattern naming the files of a list).
PackedScene pack_sources(const fs::path& scene_file, const std::vector<fs::path>& sources) {
  const fs::path scene_abs = fs::absolute(scene_file).lexically_normal();
  fs::path root = scene_abs.parent_path();
  for (const auto& s : sources) root = common_ancestor(root, s.parent_path());

  std::vector<BundleFile> files;
  std::set<std::string> packed_paths;
  for (const auto& s : sources) {
    const std::string rel = s.lexically_relative(root).generic_string();
    if (!packed_paths.insert(rel).second) continue;  // referenced twice
    files.push_back({rel, read_inside(root, s.lexically_relative(root))});
  }
  PackedScene packed;
  packed.scene_path = scene_abs.lexically_relative(root).generic_string();
  packed.bundle = make_bundle(std::move(files));
  packed.hash = bundle_hash(packed.bundle);
  return packed;
}

PackedScene pack_loaded(const fs::path& scene_file, const Scene& scene) {
  return pack_sources(scene_file, scene_sources(scene_file, scene));
}

/// Adds `text` to the bundle as the file `stem` + `suffix` (with '_'s before the suffix while
/// that name is taken) and makes it the bundle's scene: a small scene file that names the real
/// one and says what the command line said.
void add_wrapper(PackedScene& packed, const std::string& stem, const std::string& suffix,
                 const std::string& text) {
  std::string wrapper = stem + suffix;
  std::vector<BundleFile> files = packed.bundle.files;
  while (std::any_of(files.begin(), files.end(),
                     [&](const BundleFile& f) { return f.path == wrapper; })) {
    wrapper.insert(wrapper.size() - suffix.size(), "_");
  }
  files.push_back({wrapper, text});
  packed.scene_path = wrapper;
  packed.bundle = make_bundle(std::move(files));
  packed.hash = bundle_hash(packed.bundle);
}

}  // namespace

PackedScene pack_scene(const fs::path& scene_file, const fs::path& scene_root) {
  return pack_loaded(scene_file,
                     load_scene(scene_file, {}, SceneImages::kCheckOnly, {}, scene_root));
}

PackedScene pack_gltf_scene(const fs::path& gltf_file, const std::string& camera,
                            const std::string& environment) {
  GltfOptions options;
  options.camera = camera;
  options.environment = environment;
  // The camera and the environment's image exist; an animated file keeps its frames in the
  // wrapper (below). The bundle holds what this scene read: the file, its buffers and images,
  // the environment's image.
  const Scene scene = load_scene(gltf_file, {}, SceneImages::kCheckOnly, options);
  PackedScene packed = pack_loaded(gltf_file, scene);
  const auto quoted = [](const std::string& text) {  // as a JSON string
    std::string out = "\"";
    for (const unsigned char c : text) {
      if (c == '"' || c == '\\') {
        out += '\\';
        out += static_cast<char>(c);
      } else if (c < 0x20) {
        static const char* hex = "0123456789abcdef";
        out += "\\u00";
        out += hex[c >> 4];
        out += hex[c & 15];
      } else {
        out += static_cast<char>(c);
      }
    }
    return out + "\"";
  };
  const fs::path gltf(packed.scene_path);
  // Posed as the file rendered directly: an animated file over its own frames (kGltfFps from
  // frame 1), any other at time 0 (an animation of one key still poses its nodes).
  const std::string animation =
      scene.animation ? ", \"animation\": {\"frames\": [" + std::to_string(scene.animation->first) +
                            ", " + std::to_string(scene.animation->last) +
                            "], \"fps\": " + std::to_string(int(kGltfFps)) + "}"
                      : "";
  // The environment as the JSON scene's light that says the same (gltf_scene.cpp reads it so).
  const std::string lights =
      environment.empty() ? ""
      : environment == "uniform"
          ? ", \"lights\": [{\"type\": \"constant\", \"radiance\": [1, 1, 1]}]"
          : ", \"lights\": [{\"type\": \"environment\", \"file\": " + quoted(environment) + "}]";
  const std::string json = "{\"gltf\": {\"file\": " + quoted(gltf.filename().generic_string()) +
                           (camera.empty() ? "" : ", \"camera\": " + quoted(camera)) +
                           (scene.animation ? "" : ", \"time\": 0") + "}" + animation + lights +
                           "}\n";
  add_wrapper(packed, (gltf.parent_path() / gltf.filename()).generic_string(), ".camera.json",
              json);
  return packed;
}

PackedScene pack_mitsuba_scene(const fs::path& xml_file, const fs::path& scene_root,
                               const std::map<std::string, std::string>& parameters) {
  // The parameters may name files (an include, a mesh): the bundle holds what they name.
  PackedScene packed = pack_loaded(
      xml_file, load_mitsuba_scene(xml_file, {}, SceneImages::kCheckOnly, scene_root, parameters));
  if (parameters.empty()) return packed;
  if (fs::path(packed.scene_path).filename().string().find('$') != std::string::npos)
    throw BundleError(xml_file.string() + ": -D needs a scene file name without '$'");
  auto escape = [](const std::string& text) {
    std::string out;
    for (const char c : text) {
      switch (c) {
        case '&':
          out += "&amp;";
          break;
        case '<':
          out += "&lt;";
          break;
        case '>':
          out += "&gt;";
          break;
        case '"':
          out += "&quot;";
          break;
        default:
          out += c;
      }
    }
    return out;
  };
  const fs::path scene(packed.scene_path);
  std::string xml = "<scene version=\"3.0.0\">\n";
  for (const auto& [name, value] : parameters)
    xml += "  <default name=\"" + escape(name) + "\" value=\"" + escape(value) + "\"/>\n";
  xml += "  <include filename=\"" + escape(scene.filename().generic_string()) + "\"/>\n</scene>\n";
  add_wrapper(packed, (scene.parent_path() / scene.stem()).generic_string(), ".defines.xml", xml);
  return packed;
}

fs::path unpack_bundle(const Bundle& bundle, const fs::path& cache_dir,
                       const std::string& expected_hash) {
  if (!is_bundle_hash(expected_hash)) {
    throw BundleError("'" + expected_hash + "' is not a bundle hash (64 lowercase hex digits)");
  }
  const fs::path final_dir = cache_dir / expected_hash;
  std::error_code ec;
  if (fs::is_directory(final_dir, ec)) return final_dir;

  for (const auto& f : bundle.files) check_bundle_path(f.path);
  const std::string actual = bundle_hash(bundle);
  if (actual != expected_hash) {
    throw BundleError("bundle hash mismatch: expected " + expected_hash + ", contents hash to " +
                      actual);
  }

  const fs::path temp = cache_dir / (".tmp-" + expected_hash.substr(0, 16) + "-" + unique_suffix());
  try {
    fs::create_directories(temp);
    for (const auto& f : bundle.files) {
      const fs::path target = temp / fs::path(f.path);
      fs::create_directories(target.parent_path());
      write_file(target, f.data);
    }
    fs::rename(temp, final_dir, ec);
    if (ec) {
      // Another process unpacked the same bundle first: keep theirs.
      fs::remove_all(temp);
      if (!fs::is_directory(final_dir)) {
        throw BundleError("cannot move unpacked bundle into " + final_dir.string() + ": " +
                          ec.message());
      }
    }
  } catch (const fs::filesystem_error& e) {
    fs::remove_all(temp, ec);
    throw BundleError(std::string("cannot unpack bundle into ") + cache_dir.string() + ": " +
                      e.what());
  } catch (...) {
    fs::remove_all(temp, ec);
    throw;
  }
  return final_dir;
}

PackedScene pack_scene_list(const fs::path& pattern, const std::vector<fs::path>& files) {
  std::vector<fs::path> sources;
  for (const fs::path& file : files) {
    // One scene at a time: only the names of what it references are kept.
    const Scene scene = load_scene(file, {}, SceneImages::kCheckOnly);
    for (fs::path& s : scene_sources(file, scene)) sources.push_back(std::move(s));
  }
  return pack_sources(pattern, sources);
}

}  // namespace rayfarm
