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

  /// The film to render given the scene's; nullopt when no option was given. The options' values
  /// were checked when parsed (add_film_options); throws std::invalid_argument when the scene's
  /// film is empty or --width/--height alone makes a side too long.
  std::optional<FilmSize> resolve(const FilmSize& scene) const {
    if (!given()) return std::nullopt;
    if (!res.empty()) {
      const auto wh = parse_res(res);
      if (!wh) throw std::invalid_argument(res_problem(res));
      return *wh;
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

  /// "WIDTHxHEIGHT" (or X), each side a number in [1, kMaxFilmSide]; nullopt otherwise.
  static std::optional<FilmSize> parse_res(const std::string& text) {
    const size_t x = text.find_first_of("xX");
    if (x == std::string::npos || x == 0 || x + 1 == text.size()) return std::nullopt;
    const auto side = [](const std::string& t) -> std::optional<uint32_t> {
      if (t.empty() || t.size() > 6) return std::nullopt;
      uint32_t v = 0;
      for (const char c : t) {
        if (c < '0' || c > '9') return std::nullopt;
        v = v * 10 + static_cast<uint32_t>(c - '0');
      }
      if (v < 1 || v > kMaxFilmSide) return std::nullopt;
      return v;
    };
    const auto w = side(text.substr(0, x)), h = side(text.substr(x + 1));
    if (!w || !h) return std::nullopt;
    return FilmSize{*w, *h};
  }
  /// Why parse_res refuses `text`.
  static std::string res_problem(const std::string& text) {
    return "expected WIDTHxHEIGHT, e.g. 1280x720, each side in [1, " +
           std::to_string(kMaxFilmSide) + "] pixels, got '" + text + "'";
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

/// --res, --width and --height; a malformed or out-of-range value, or --res with --width or
/// --height, is a usage error (exit 2) when the command line is parsed.
inline void add_film_options(CLI::App* cmd, FilmArgs& args) {
  CLI::Option* res =
      cmd->add_option("--res", args.res, "Film size WIDTHxHEIGHT, over the scene's (e.g. 1280x720)")
          ->check([](const std::string& v) {
            return FilmArgs::parse_res(v) ? std::string() : FilmArgs::res_problem(v);
          });
  cmd->add_option("--width", args.width,
                  "Film width in pixels (alone: the height follows the scene's aspect)")
      ->check(CLI::Range(1u, kMaxFilmSide))
      ->excludes(res);
  cmd->add_option("--height", args.height,
                  "Film height in pixels (alone: the width follows the scene's aspect)")
      ->check(CLI::Range(1u, kMaxFilmSide))
      ->excludes(res);
}

}  // namespace rayfarm::cli
