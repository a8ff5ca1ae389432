#pragma once
// --camera, --environment, --scene-root and -D: how `rayfarm render` and `rayfarm submit` read a
// scene file (docs/gltf.md for cameras, docs/mitsuba.md for Mitsuba XML's root and $name
// parameters).
#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "common/bundle/bundle.h"
#include "common/scene/frame_files.h"
#include "common/scene/mitsuba_loader.h"
#include "common/scene/motion.h"
#include "common/scene/parser.h"
#include "common/util/utf8.h"

namespace rayfarm::cli {

struct SceneArgs {
  std::string scene;
  std::string camera;
  std::string environment;  ///< --environment: "uniform" or an image file
  std::string root;
  std::vector<std::string> defines;

  /// -D NAME=VALUE pairs; a malformed one is a usage error (CLI::ValidationError, exit 2).
  XmlParameters parameters() const {
    XmlParameters out;
    for (const std::string& d : defines) {
      const size_t eq = d.find('=');
      bool ok = eq != std::string::npos && eq > 0;
      for (size_t i = 0; ok && i < eq; ++i)
        ok = std::isalnum(static_cast<unsigned char>(d[i])) != 0 || d[i] == '_';
      if (!ok)
        throw CLI::ValidationError("-D " + d +
                                   ": expected NAME=VALUE, NAME of letters, digits and _");
      // A value travels to the farm inside an XML attribute: nothing there may change it.
      for (size_t i = eq + 1; ok && i < d.size(); ++i)
        ok = d[i] != '$' && static_cast<unsigned char>(d[i]) >= 0x20;
      if (!ok)
        throw CLI::ValidationError("-D " + d + ": a value may not hold '$' or control characters");
      out[d.substr(0, eq)] = d.substr(eq + 1);
    }
    return out;
  }

  /// An option that does not apply to the scene's format is a usage error (docs/cli.md): throws
  /// CLI::ValidationError (exit 2). So is a malformed -D.
  void check() const {
    if (!camera.empty() && !is_gltf_path(scene))
      throw CLI::ValidationError(
          "--camera chooses among a glTF file's cameras; a JSON scene names "
          "its glTF camera in \"gltf\" (docs/gltf.md)");
    if (!environment.empty() && !is_gltf_path(scene))
      throw CLI::ValidationError(
          "--environment lights a glTF file; a JSON scene adds a \"constant\" or "
          "\"environment\" light to its \"lights\" (docs/scene-format.md)");
    if (!environment.empty()) (void)gltf_environment();
    if (is_list() && (!camera.empty() || !environment.empty() || is_mitsuba_path(scene)))
      throw CLI::ValidationError(scene +
                                  ": a list of scene files, one per frame, holds JSON scenes "
                                  "(or glTF files rendered through their own cameras)");
    if ((!root.empty() || !defines.empty()) && !is_mitsuba_path(scene))
      throw CLI::ValidationError("--scene-root and -D apply to Mitsuba XML scenes (.xml), not to " +
                                 scene);
    if (is_mitsuba_path(scene)) (void)parameters();
  }

  /// --environment as GltfOptions::environment: "uniform", or the image's path relative to the
  /// glTF file's folder, which must hold it (the image travels with the file to the farm).
  std::string gltf_environment() const {
    if (environment.empty() || environment == "uniform") return environment;
    namespace fs = std::filesystem;
    const fs::path folder = fs::path(scene).parent_path();
    const fs::path relative = fs::weakly_canonical(environment)
                                  .lexically_relative(fs::weakly_canonical(
                                      folder.empty() ? fs::current_path() : fs::absolute(folder)));
    const std::string text = relative.generic_string();
    if (text.empty() || text == "." || *relative.begin() == "..")
      throw CLI::ValidationError("--environment " + environment +
                                 ": the image must lie in the glTF file's folder (" +
                                 (folder.empty() ? std::string(".") : folder.string()) +
                                 ") or below it, as seen from here (it travels with the file); "
                                 "or give \"uniform\"");
    // The farm's scene names it in JSON, which holds UTF-8 only.
    if (invalid_utf8_at(text) != std::string::npos)
      throw CLI::ValidationError("--environment " + environment + ": the path is not UTF-8");
    return text;
  }

  /// A list of scene files, one still scene per frame: the file name holds a frame pattern
  /// ("shots/frame_####.json", "frame_%04d.json"; docs/farm.md, "Frame sequences").
  bool is_list() const { return is_scene_list(scene); }
  /// The scene file of `frame` in a list.
  std::filesystem::path file_at(int64_t frame) const {
    try {
      return frame_scene_file(scene, frame);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("scene " + scene + ": " + e.what());
    }
  }

  /// The scene at `frame` (an animated scene's first when nullopt; a list's file of that frame).
  /// A frame of a still scene, or one outside an animated scene's frames, is a SceneError naming
  /// the scene.
  Scene load(SceneImages images, std::optional<int64_t> at = std::nullopt) const {
    check();
    if (is_list()) {
      if (!at) {
        throw CLI::ValidationError(scene +
                                    " is a list of scene files, one per frame: name the frames "
                                    "(--frames A-B[:STEP] or --frame N)");
      }
      const std::filesystem::path file = file_at(*at);
      Scene s = load_scene(file, {}, images);
      if (s.animation) {
        throw std::invalid_argument(file.string() +
                                    " is animated: the files of a list are still scenes, one "
                                    "per frame");
      }
      s.frame = *at;
      return s;
    }
    if (is_mitsuba_path(scene) && !at) {
      return load_mitsuba_scene(scene, {}, images, root, parameters());
    }
    GltfOptions gltf;
    gltf.camera = camera;
    gltf.environment = gltf_environment();
    return load_scene(scene, {}, images, gltf, {}, at);
  }

  /// Finds what moves within the open shutter of `settings` in a scene that load() gave
  /// (add_motion(), common/scene/motion.h); a list's frames are stills.
  void add_motion(Scene& s, const RenderSettings& settings) const {
    if (is_list() || is_mitsuba_path(scene)) return;
    GltfOptions gltf;
    gltf.camera = camera;
    gltf.environment = gltf_environment();
    rayfarm::add_motion(s, settings, gltf);
  }

  PackedScene pack() const {
    check();
    if (is_list()) {
      throw CLI::ValidationError(scene +
                                  " is a list of scene files, one per frame: name the frames "
                                  "(--frames A-B[:STEP] or --frame N)");
    }
    if (is_mitsuba_path(scene)) return pack_mitsuba_scene(scene, root, parameters());
    return camera.empty() && environment.empty()
               ? pack_scene(scene)
               : pack_gltf_scene(scene, camera, gltf_environment());
  }
};

/// --res, --width and --height resize the film; a film that is a crop of a larger image (a
/// Mitsuba hdrfilm's crop_*) cannot be resized so. Throws std::invalid_argument.
inline void check_uncropped(const Scene& scene) {
  if (scene.camera.full_width != 0)
    throw std::invalid_argument(
        "--res, --width and --height cannot resize a cropped film; change the scene's crop "
        "(hdrfilm crop_width, crop_height) or its width and height");
}

inline void add_scene_options(CLI::App* cmd, SceneArgs& args) {
  cmd->add_option("--camera", args.camera,
                  "glTF scenes: the camera (its or its node's name, or its index) to render "
                  "through; default: the first in the scene");
  cmd->add_option("--environment", args.environment,
                  "glTF scenes: light the file from every direction, \"uniform\" (radiance 1) "
                  "or an equirectangular image (.hdr, .exr) in the file's folder");
  cmd->add_option("--scene-root", args.root,
                  "Mitsuba XML scenes: the folder the scene may read files from (default: the "
                  "scene's own folder)");
  cmd->add_option(
      "-D,--define", args.defines,
      "Mitsuba XML scenes: NAME=VALUE, the value of $NAME (over the scene's <default>)");
}

}  // namespace rayfarm::cli
