#include "common/scene/mtl_loader.h"

#include <charconv>
#include <optional>
#include <set>
#include <string_view>

#include "common/limits.h"
#include "common/scene/scene_files.h"

namespace rayfarm {
namespace fs = std::filesystem;
using scene_text::Where;

namespace {

/// Reads one MTL file's materials, every line checked as it is read.
class MtlReader {
 public:
  explicit MtlReader(std::string display) : display_(std::move(display)) {}

  void read(const std::string& text) {
    scene_text::for_each_line(
        text, display_, [this](const Where& at, std::string_view line) { statement(at, line); });
  }

  std::vector<MtlMaterial> materials;
  std::vector<Where> defined_at;
  std::vector<std::string> warnings;

 private:
  void statement(const Where& at, std::string_view line) {
    const std::vector<std::string_view> words = scene_text::split_words(line);
    const std::string_view keyword = words.empty() ? std::string_view{} : words[0];
    if (keyword == "newmtl") {
      const std::string_view name = scene_text::rest_after_keyword(line, "newmtl");
      if (name.empty()) at.fail("newmtl without a material name");
      materials.emplace_back().name = std::string(name);
      defined_at.push_back(at);
      has_d_ = false;
      has_tr_ = false;
    } else if (keyword == "Kd" || keyword == "Ks" || keyword == "Ke" || keyword == "Tf" ||
               keyword == "Kt") {
      scene_text::check_numbers(at, words, 3, 3, "3 numbers (r g b)");
      MtlMaterial* m = current();
      if (!m) return;
      float* rgb = keyword == "Kd"   ? m->diffuse
                   : keyword == "Ks" ? m->specular
                   : keyword == "Ke" ? m->emission
                                     : m->transmittance;
      for (int i = 0; i < 3; ++i) rgb[i] = number(words[size_t(i) + 1]);
    } else if (keyword == "Ni" || keyword == "Ns" || keyword == "d" || keyword == "Tr") {
      scene_text::check_numbers(at, words, 1, 1, "1 number");
      MtlMaterial* m = current();
      if (!m) return;
      const float value = number(words[1]);
      if (keyword == "Ni") {
        m->ior = value;
      } else if (keyword == "Ns") {
        m->shininess = value;
      } else if (keyword == "d") {
        m->dissolve = value;  // d wins over Tr
        has_d_ = true;
      } else {
        if (!has_d_) m->dissolve = 1.f - value;
        has_tr_ = true;
      }
    } else if (keyword == "illum") {
      int model = -1;
      bool ok = words.size() == 2;
      if (ok) {
        const char* end = words[1].data() + words[1].size();
        ok = std::from_chars(words[1].data(), end, model).ptr == end && model >= 0 && model <= 10;
      }
      if (!ok) at.fail("illum: expected an integer from 0 to 10");
      if (MtlMaterial* m = current()) m->illum = model;
    } else if (!keyword.empty() && keyword.front() != '#' && keyword != "Ka" &&
               warned_.insert(std::string(keyword)).second) {
      warnings.push_back(at.message("statement " + scene_text::in_quotes(keyword) +
                                    " is not supported and is ignored"));
    }
  }

  /// The material being defined; statements before the first newmtl belong to none.
  MtlMaterial* current() { return materials.empty() ? nullptr : &materials.back(); }
  static float number(std::string_view word) {
    return static_cast<float>(*scene_text::parse_number(word));
  }

  std::string display_;
  std::set<std::string> warned_;
  bool has_d_ = false;
  bool has_tr_ = false;
};

/// Loads one MTL file into the library; a name defined before keeps its first definition.
void load_mtl(const fs::path& scene_dir, const fs::path& relative, MtlLibrary* library) {
  const std::string display = (scene_dir / relative).string();
  MtlReader reader(display);
  reader.read(read_text_file(scene_dir / relative, kMaxMtlFileBytes, display));
  library->warnings.insert(library->warnings.end(), reader.warnings.begin(), reader.warnings.end());
  if (reader.materials.empty()) throw SceneError(display + ": cannot read the materials");
  library->files.push_back(relative);
  for (size_t i = 0; i < reader.materials.size(); ++i) {
    const Where& where = reader.defined_at[i];
    const std::string& name = reader.materials[i].name;
    if (library->index.count(name) != 0) {
      library->warnings.push_back(where.message("material " + scene_text::in_quotes(name) +
                                                " is defined again; the first one is used"));
      continue;
    }
    library->index[name] = static_cast<int>(library->materials.size());
    library->materials.push_back(std::move(reader.materials[i]));
    library->defined_at.push_back(where);
  }
}

}  // namespace

MtlLibrary load_mtllibs(const fs::path& scene_dir, const fs::path& obj,
                        const std::vector<MtlLibLine>& mtllibs) {
  MtlLibrary library;
  std::set<fs::path> loaded;
  for (const auto& [where, names] : mtllibs) {
    for (const std::string& name : names) {
      std::string why;
      const auto relative = resolve_scene_path(obj.parent_path(), name, &why);
      if (!relative) where.fail("mtllib " + scene_text::in_quotes(name) + ": " + why);
      if (!fs::exists(scene_dir / *relative)) {
        where.fail("mtllib " + scene_text::in_quotes(name) + ": file not found (looked for " +
                   (scene_dir / *relative).string() + ")");
      }
      if (loaded.insert(*relative).second) load_mtl(scene_dir, *relative, &library);
    }
  }
  return library;
}

}  // namespace rayfarm
