#pragma once
// --frames A-B[:STEP], as `rayfarm render` and `rayfarm submit` both check it before any work:
// the list itself, then against the scene's animation (docs/scene-format.md, "Animation").
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <system_error>

#include <fmt/format.h>

#include "cli/scene_option.h"
#include "common/protocol/convert.h"
#include "common/scene/frames.h"
#include "common/scene/parser.h"

namespace rayfarm::cli {

/// The frames `text` names: in the animation of `source`'s scene, or, for a list of scene files
/// (SceneArgs::is_list), frames whose files all exist and are still scenes of one film size (each
/// is loaded). Throws std::invalid_argument naming the option, the frame and the file when the
/// list is malformed or reversed, the scene is a still, a frame lies beyond its animation, a
/// frame's file is missing, animated or of another size, and when `reference` is set (one
/// reference image cannot measure a sequence); a broken file is its SceneError.
inline FrameList check_frames_option(const std::string& text, const SceneArgs& source,
                                     bool reference) {
  std::string why;
  const auto frames = parse_frame_list(text, &why);
  if (!frames) throw std::invalid_argument("--frames: " + why);
  if (reference) {
    throw std::invalid_argument(
        "--reference is one image; it cannot measure a sequence (render a frame with --frame N "
        "and its reference)");
  }
  if (source.is_list()) {
    std::optional<FilmSize> film;
    RenderSettings render;
    std::filesystem::path first;
    for (int64_t i = 0; i < frames->count(); ++i) {
      const int64_t frame = frames->at(i);
      const std::filesystem::path file = source.file_at(frame);
      std::error_code ec;
      if (!std::filesystem::is_regular_file(file, ec)) {
        throw std::invalid_argument(fmt::format("--frames {}: frame {}'s scene {} does not exist",
                                                text, frame, file.string()));
      }
      const Scene scene = source.load(SceneImages::kCheckOnly, frame);
      if (!film) {
        film = scene.film;
        render = scene.render;
        first = file;
      } else if (scene.film.width != film->width || scene.film.height != film->height) {
        throw std::invalid_argument(fmt::format(
            "--frames {}: {} is {}x{} but {} is {}x{}: the frames of a sequence share one film",
            text, file.string(), scene.film.width, scene.film.height, first.string(), film->width,
            film->height));
      } else if (!protocol::same_settings(scene.render, render)) {
        throw std::invalid_argument(fmt::format(
            "--frames {}: {}'s render settings differ from {}'s: the frames of a sequence share "
            "one set (the farm renders every frame with the first's)",
            text, file.string(), first.string()));
      }
    }
    return *frames;
  }
  const std::optional<FrameRange> animation = load_scene_animation(source.scene);
  if (!animation) {
    throw std::invalid_argument("--frames " + text + ": " + source.scene +
                                " is a still scene (it has no animation)");
  }
  if (!animation->contains(frames->first) || !animation->contains(frames->last)) {
    throw std::invalid_argument(
        fmt::format("--frames {}: beyond the scene's animation, frames {}-{}", text,
                    animation->first, animation->last));
  }
  return *frames;
}

}  // namespace rayfarm::cli
