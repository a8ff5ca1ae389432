// Mitsuba 3 XML: the files, includes, defaults and substitutions (docs/mitsuba.md). pugixml reads
// the bytes (it expands no entities beyond XML's five, so no document can grow in memory beyond
// its size); everything else is checked here, with the file and line in every message.
#include "common/scene/mitsuba_xml.h"

#include <algorithm>
#include <cctype>

#include <pugixml.hpp>

#include "common/limits.h"
#include "common/scene/scene_files.h"
#include "common/util/text.h"

namespace rayfarm {
namespace fs = std::filesystem;

namespace {

constexpr int kMaxIncludeDepth = 16;
constexpr size_t kMaxXmlFiles = 256;
constexpr size_t kMaxXmlElements = size_t{1} << 20;
constexpr int kMaxXmlNesting = 64;                             // elements within elements
constexpr uint64_t kMaxXmlBytes = uint64_t{256} << 20;         // all files read, together
constexpr uint64_t kMaxSubstitutedBytes = uint64_t{64} << 20;  // all substituted values

/// One file being read: its text, its lines, where it lives.
struct Source {
  std::string display;  ///< for messages
  fs::path dir;         ///< absolute folder of the file
  std::vector<size_t> newlines;

  uint32_t line_of(ptrdiff_t offset) const {
    if (offset < 0) return 0;
    return static_cast<uint32_t>(
        std::upper_bound(newlines.begin(), newlines.end(), static_cast<size_t>(offset)) -
        newlines.begin() + 1);
  }
};

bool inside(const fs::path& root, const fs::path& p) {
  const fs::path rel = p.lexically_relative(root);
  return !rel.empty() && *rel.begin() != "..";
}

bool is_identifier_char(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_';
}

class Expander {
 public:
  Expander(XmlFiles& files, XmlParameters parameters)
      : files_(files), parameters_(std::move(parameters)) {
    for (const auto& entry : parameters_)
      longest_name_ = std::max(longest_name_, entry.first.size());
  }

  /// Reads `file` (absolute), returning its root <scene> element with children expanded.
  XmlElement read_scene(const fs::path& file, const std::string& display, int depth) {
    Source source;
    source.display = display;
    source.dir = file.parent_path();
    if (++files_read_ > kMaxXmlFiles) {
      throw SceneError(display + ": the scene reads more than " + std::to_string(kMaxXmlFiles) +
                       " XML files");
    }
    const std::string text = read_text_file(file, kMaxSceneFileBytes, display);
    bytes_read_ += text.size();
    if (bytes_read_ > kMaxXmlBytes) {
      throw SceneError(display + ": the scene's XML files hold more than " +
                       std::to_string(kMaxXmlBytes >> 20) + " MiB together");
    }
    for (size_t i = 0; i < text.size(); ++i) {
      if (text[i] == '\n') source.newlines.push_back(i);
    }
    pugi::xml_document doc;
    const pugi::xml_parse_result parsed =
        doc.load_buffer(text.data(), text.size(), pugi::parse_default, pugi::encoding_utf8);
    if (!parsed) {
      throw SceneError(display + ":" + std::to_string(source.line_of(parsed.offset)) +
                       ": malformed XML: " + parsed.description());
    }
    const pugi::xml_node top = doc.document_element();
    XmlElement root = element_of(top, source);
    if (root.tag != "scene") root.fail("the file's root element must be <scene>");
    check_version(root);
    stack_.push_back(file);
    expand_children(top, root, source, depth, 1);
    stack_.pop_back();
    return root;
  }

 private:
  XmlElement element_of(const pugi::xml_node& node, const Source& source) {
    if (++elements_ > kMaxXmlElements) {
      throw SceneError(source.display + ": the scene has more than " +
                       std::to_string(kMaxXmlElements) + " XML elements");
    }
    XmlElement e;
    e.tag = node.name();
    e.file = source.display;
    e.line = source.line_of(node.offset_debug());
    for (const pugi::xml_attribute& a : node.attributes()) {
      e.attributes.emplace_back(a.name(), substitute(e, a.value()));
    }
    return e;
  }

  static void check_version(const XmlElement& scene) {
    const std::string* version = scene.find("version");
    if (version == nullptr) scene.fail("the <scene> element has no version attribute");
    const int major = std::atoi(version->c_str());
    if (major < 2 || major > 3 || !std::isdigit(static_cast<unsigned char>((*version)[0]))) {
      scene.fail("scene version \"" + printable(*version) +
                 "\": rayfarm reads Mitsuba 3 scenes of versions 2.x and 3.x (upgrade older "
                 "scenes with Mitsuba's own tools)");
    }
  }

  /// `value` with every $name replaced by its parameter's value; the longest parameter name
  /// that the text after '$' starts with wins, as in Mitsuba.
  std::string substitute(const XmlElement& at, const std::string& value) {
    if (value.find('$') == std::string::npos) return value;
    std::string out;
    for (size_t i = 0; i < value.size();) {
      if (value[i] != '$') {
        out += value[i++];
        continue;
      }
      size_t end = i + 1;
      while (end < value.size() && is_identifier_char(value[end])) ++end;
      bool replaced = false;
      for (size_t len = std::min(end - i - 1, longest_name_); len > 0 && !replaced; --len) {
        if (auto it = parameters_.find(value.substr(i + 1, len)); it != parameters_.end()) {
          out += it->second;
          i += 1 + len;
          replaced = true;
        }
      }
      if (!replaced) {
        const std::string name = value.substr(i + 1, end - i - 1);
        if (name.empty()) at.fail("a '$' with no parameter name after it");
        at.fail("$" + printable(name) + " has no value: add <default name=\"" + printable(name) +
                "\" value=\"...\"/> to the scene, or give it with -D " + printable(name) +
                "=VALUE");
      }
      if (out.size() > (size_t{1} << 20)) at.fail("substitution makes a value over 1 MiB");
    }
    substituted_ += out.size();
    if (substituted_ > kMaxSubstitutedBytes) {
      at.fail("substituted values hold more than " + std::to_string(kMaxSubstitutedBytes >> 20) +
              " MiB together");
    }
    return out;
  }

  void expand_children(const pugi::xml_node& node, XmlElement& into, const Source& source,
                       int depth, int nesting) {
    for (const pugi::xml_node& child : node.children()) {
      if (child.type() != pugi::node_element) continue;
      XmlElement e = element_of(child, source);
      if (nesting + depth > kMaxXmlNesting) {
        e.fail("elements nest more than " + std::to_string(kMaxXmlNesting) + " deep");
      }
      if (e.tag == "include") {
        include(e, into, depth);
      } else if (e.tag == "default") {
        const std::string* name = e.find("name");
        const std::string* value = e.find("value");
        if (name == nullptr || value == nullptr) e.fail("<default> needs name and value");
        parameters_.emplace(*name, *value);  // a value given from outside stays
        longest_name_ = std::max(longest_name_, name->size());
      } else if (e.tag == "path") {
        add_search_path(e, source);
      } else {
        expand_children(child, e, source, depth, nesting + 1);
        into.children.push_back(std::move(e));
      }
    }
  }

  void include(const XmlElement& e, XmlElement& into, int depth) {
    const std::string* name = e.find("filename");
    if (name == nullptr) e.fail("<include> needs a filename");
    if (depth + 1 > kMaxIncludeDepth) {
      e.fail("includes nest deeper than " + std::to_string(kMaxIncludeDepth) + " files");
    }
    const fs::path rel = resolve_mitsuba_file(files_, e, *name);
    const fs::path full = (files_.scene_dir / rel).lexically_normal();
    if (std::find(stack_.begin(), stack_.end(), full) != stack_.end()) {
      e.fail("including " + printable(*name) + " again makes a cycle");
    }
    XmlElement scene = read_scene(full, rel.generic_string(), depth + 1);
    for (XmlElement& c : scene.children) into.children.push_back(std::move(c));
  }

  void add_search_path(const XmlElement& e, const Source& source) {
    const std::string* value = e.find("value");
    if (value == nullptr || value->empty()) e.fail("<path> needs a value");
    if (value->find('\0') != std::string::npos) e.fail("a path must not hold a NUL byte");
    const fs::path given(*value);
    if (given.is_absolute()) e.fail("absolute paths are not allowed; give it relative to the file");
    const fs::path dir = (source.dir / given).lexically_normal();
    if (!inside(files_.root, dir / "x")) {
      e.fail("the folder " + printable(*value) + " lies outside " + files_.root.string() +
             ", the folder the scene may read (rayfarm's --scene-root widens it)");
    }
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) e.fail("no folder " + printable(*value));
    files_.search.insert(files_.search.begin(), dir);
  }

  XmlFiles& files_;
  XmlParameters parameters_;
  std::vector<fs::path> stack_;
  size_t elements_ = 0;
  size_t files_read_ = 0;
  size_t longest_name_ = 0;   // of the parameters: no longer text after a '$' can match one
  uint64_t bytes_read_ = 0;   // of every XML file
  uint64_t substituted_ = 0;  // bytes of every value that held a '$'
};

}  // namespace

const std::string* XmlElement::find(std::string_view name) const {
  for (const auto& [key, value] : attributes) {
    if (key == name) return &value;
  }
  return nullptr;
}

std::string XmlElement::where() const {
  std::string s = file + ":" + std::to_string(line) + ": <" + printable(tag, 64);
  for (const char* key : {"type", "name", "id"}) {
    if (const std::string* v = find(key))
      s += std::string(" ") + key + "=\"" + printable(*v, 64) + "\"";
  }
  return s + ">";
}

void XmlElement::fail(const std::string& what) const { throw SceneError(where() + ": " + what); }

fs::path resolve_mitsuba_file(XmlFiles& files, const XmlElement& at, const std::string& name) {
  if (name.empty()) at.fail("an empty file name");
  if (name.find('\0') != std::string::npos) at.fail("a file name must not hold a NUL byte");
  const fs::path given(name);
  if (given.is_absolute()) {
    at.fail("the absolute path " + printable(name) +
            " is not allowed: name files relative to the scene, so that it can travel to the farm");
  }
  bool outside = false;
  std::vector<fs::path> dirs = files.search;
  dirs.push_back(files.scene_dir);
  for (const fs::path& dir : dirs) {
    const fs::path candidate = (dir / given).lexically_normal();
    if (!inside(files.root, candidate)) {
      outside = true;
      continue;
    }
    std::error_code ec;
    if (fs::is_regular_file(candidate, ec)) {
      fs::path rel = candidate.lexically_relative(files.scene_dir);
      if (std::find(files.read.begin(), files.read.end(), rel) == files.read.end())
        files.read.push_back(rel);
      return rel;
    }
  }
  if (outside) {
    at.fail("the file " + printable(name) + " lies outside " + files.root.string() +
            ", the folder the scene may read (rayfarm's --scene-root widens it)");
  }
  std::string looked;
  for (const fs::path& dir : dirs) looked += (looked.empty() ? "" : ", ") + dir.string();
  at.fail("no file " + printable(name) + " (looked in " + printable(looked, 400) + ")");
}

XmlScene read_mitsuba_xml(const fs::path& file, const fs::path& root,
                          const XmlParameters& parameters) {
  XmlScene scene;
  const fs::path full = fs::absolute(file).lexically_normal();
  scene.files.scene_dir = full.parent_path();
  scene.files.root = root.empty() ? scene.files.scene_dir : fs::absolute(root).lexically_normal();
  if (!inside(scene.files.root, full)) {
    throw SceneError(file.string() + ": the scene file lies outside its root folder " +
                     scene.files.root.string());
  }
  Expander expander(scene.files, parameters);
  scene.root = expander.read_scene(full, file.string(), 0);
  return scene;
}

bool is_mitsuba_path(const fs::path& file) {
  std::string ext = file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".xml";
}

}  // namespace rayfarm
