#pragma once
// --res WxH, --width and --height: the film size of `rayfarm render` and `rayfarm submit`, over the
// scene's. One of --width and --height alone keeps the scene's aspect ratio.
#include <cmath>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>

#include <CLI/CLI.hpp>

#include "common/scene/scene.h"

namespace rayfarm::cli {

/// Largest side accepted from the command line (the master has its own pixel limit).
inline constexpr uint32_t kMaxFilmSide = 65536;

struct FilmArgs {
  std::string res;
  uint32_t width = 0, height = 0;

  bool given() const { return !res.empty() || width != 0 || height != 0; }

  /// The film to render given the scene's; nullopt when no option was given. Throws
  /// std::invalid_argument naming the option on a bad value.
  std::optional<FilmSize> resolve(const FilmSize& scene) const {
    if (!given()) return std::nullopt;
    if (!res.empty()) {
      if (width || height) throw std::invalid_argument("give --res or --width/--height, not both");
      const size_t x = res.find_first_of("xX");
      size_t end_w = 0, end_h = 0;
      unsigned long w = 0, h = 0;
      try {
        if (x == std::string::npos) throw std::invalid_argument("no x");
        w = std::stoul(res.substr(0, x), &end_w);
        h = std::stoul(res.substr(x + 1), &end_h);
      } catch (const std::exception&) {
        end_w = 0;
      }
      if (end_w == 0 || end_w != x || end_h != res.size() - x - 1 || res[0] == '-' ||
          res[x + 1] == '-') {
        throw std::invalid_argument("--res " + res + ": expected WIDTHxHEIGHT, e.g. 1280x720");
      }
      return checked(w, h, "--res " + res);
    }
    if (width && height) return checked(width, height, "--width/--height");
    if (scene.width == 0 || scene.height == 0) throw std::invalid_argument("the scene's film is empty");
    if (width) {
      return checked(width, std::max(1.0, std::round(double(width) * scene.height / scene.width)),
                     "--width");
    }
    return checked(std::max(1.0, std::round(double(height) * scene.width / scene.height)), height,
                   "--height");
  }

 private:
  static FilmSize checked(double w, double h, const std::string& what) {
    if (!(w >= 1 && h >= 1 && w <= kMaxFilmSide && h <= kMaxFilmSide)) {
      throw std::invalid_argument(what + ": each side must be in [1, " +
                                  std::to_string(kMaxFilmSide) + "] pixels");
    }
    return FilmSize{static_cast<uint32_t>(w), static_cast<uint32_t>(h)};
  }
};

inline void add_film_options(CLI::App* cmd, FilmArgs& args) {
  cmd->add_option("--res", args.res, "Film size WIDTHxHEIGHT, over the scene's (e.g. 1280x720)");
  cmd->add_option("--width", args.width,
                  "Film width in pixels (alone: the height follows the scene's aspect)");
  cmd->add_option("--height", args.height,
                  "Film height in pixels (alone: the width follows the scene's aspect)");
}

}  // namespace rayfarm::cli
