#pragma once
// The XML layer of Mitsuba 3 scenes (docs/mitsuba.md): the files read with pugixml, then
// `<include>` spliced in, `<default>` and `$name` substituted and `<path>` search folders applied,
// so that the scene reader sees one tree in which every element knows its file and line.
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace rayfarm {

/// One XML element after includes and substitution.
struct XmlElement {
  std::string tag;
  std::vector<std::pair<std::string, std::string>> attributes;  ///< in file order, substituted
  std::vector<XmlElement> children;
  std::string file;  ///< as displayed in messages (the path the user gave, or the include's)
  uint32_t line = 0;

  /// The attribute's value, or null.
  const std::string* find(std::string_view name) const;
  /// "FILE:LINE: <tag type="..." name="...">": where this element is, for messages.
  std::string where() const;
  [[noreturn]] void fail(const std::string& what) const;
};

/// Paths the scene may read: its folder and any folder under `root`.
struct XmlFiles {
  std::filesystem::path root;                 ///< absolute, normal: nothing outside it is read
  std::filesystem::path scene_dir;            ///< absolute, normal: the scene file's folder
  std::vector<std::filesystem::path> search;  ///< absolute, newest first, then scene_dir
  std::vector<std::filesystem::path> read;    ///< every file read, relative to scene_dir
};

/// A parsed scene: the root <scene> element, and the files it may and did read.
struct XmlScene {
  XmlElement root;
  XmlFiles files;
};

/// Parameters given from outside (the command line's -D name=value), which <default> does not
/// override.
using XmlParameters = std::map<std::string, std::string>;

/// Reads `file` and everything it includes. `root` bounds every file the scene reads (empty:
/// the scene's folder). Throws SceneError "FILE:LINE: ..." on malformed XML, an include cycle,
/// a `$name` without a value, a path outside `root`, or a file too large.
XmlScene read_mitsuba_xml(const std::filesystem::path& file, const std::filesystem::path& root,
                          const XmlParameters& parameters);

/// Resolves a file name written in the scene as Mitsuba does: against each `<path>` folder,
/// newest first, then the scene's folder. Returns the path relative to the scene's folder (it
/// may start with ".." when `root` is above the folder) and records it as read. Fails at `at`
/// when the name is absolute, leaves `root`, or names no file.
std::filesystem::path resolve_mitsuba_file(XmlFiles& files, const XmlElement& at,
                                           const std::string& name);

/// True when `file`'s extension says Mitsuba XML (".xml", any case).
bool is_mitsuba_path(const std::filesystem::path& file);

}  // namespace rayfarm
