#include "master/limits.h"

#include <algorithm>

#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "common/scene/scene.h"

namespace rayfarm::master {
namespace {

using Json = nlohmann::json;

/// Arrays and objects nested deeper than this are not read (the scene parser refuses them).
constexpr int kMaxNesting = 64;
/// The tile size a job gets when it does not choose one (docs/protocol.md).
constexpr uint64_t kDefaultTile = 64;
/// Fields and framing of a UnitResult besides its sums.
constexpr uint64_t kResultOverheadBytes = 4096;

struct TooDeep {};

/// The scene file's JSON, or null when it is not valid JSON (the parser will say why).
Json parse_scene_json(const std::string& text) {
  const Json::parser_callback_t limit = [](int depth, Json::parse_event_t event, Json&) {
    const bool opens =
        event == Json::parse_event_t::object_start || event == Json::parse_event_t::array_start;
    if (opens && depth >= kMaxNesting) throw TooDeep{};
    return true;
  };
  try {
    return Json::parse(text, limit, /*allow_exceptions=*/true, /*ignore_comments=*/true);
  } catch (...) {
    return nullptr;
  }
}

/// `object[key]` when it is a non-negative integer.
std::optional<uint64_t> unsigned_field(const Json& object, const char* key) {
  if (!object.is_object()) return std::nullopt;
  auto it = object.find(key);
  if (it == object.end() || !it->is_number_unsigned()) return std::nullopt;
  return it->get<uint64_t>();
}

std::string mib(uint64_t bytes) { return fmt::format("{:.1f} MiB", bytes / 1048576.0); }

}  // namespace

uint64_t unit_result_bytes(uint64_t tile_width, uint64_t tile_height) {
  return 2 * tile_width * tile_height * 3 * 16 + kResultOverheadBytes;
}

SubmissionFigures bundle_figures(const wire::SubmitJob& request) {
  SubmissionFigures f;
  for (const auto& file : request.bundle().files()) {
    f.bundle_bytes += file.data().size();
    ++f.bundle_files;
  }
  return f;
}

SubmissionFigures figures_of(const wire::SubmitJob& request) {
  SubmissionFigures f;
  const std::string* scene_text = nullptr;
  for (const auto& file : request.bundle().files()) {
    f.bundle_bytes += file.data().size();
    ++f.bundle_files;
    if (file.path() == request.scene_path()) scene_text = &file.data();
  }
  const wire::JobOverrides& o = request.overrides();
  if (o.tile_size() != 0) f.tile_size = o.tile_size();
  if (o.has_spp()) f.spp = o.spp();
  if (!scene_text) return f;
  const Json scene = parse_scene_json(*scene_text);
  if (!scene.is_object()) return f;
  if (auto film = scene.find("film"); film != scene.end()) {
    f.width = unsigned_field(*film, "width");
    f.height = unsigned_field(*film, "height");
  }
  if (o.width() != 0 && o.height() != 0) {  // the job's film replaces the scene's
    f.width = o.width();
    f.height = o.height();
  }
  if (!f.spp) {
    auto render = scene.find("render");
    if (render == scene.end()) {
      f.spp = RenderSettings{}.spp;  // the scene format's default
    } else if (render->is_object() && !render->contains("spp")) {
      f.spp = RenderSettings{}.spp;
    } else {
      f.spp = unsigned_field(*render, "spp");
    }
  }
  return f;
}

std::optional<std::string> check_queue(size_t jobs_waiting, const Limits& limits) {
  if (jobs_waiting < limits.max_queued_jobs) return std::nullopt;
  return fmt::format(
      "the master's queue is full: {} jobs are queued or running, the limit is {} "
      "(--max-queued-jobs); submit again when some have finished",
      jobs_waiting, limits.max_queued_jobs);
}

std::optional<std::string> check_figures(const SubmissionFigures& f, const Limits& limits) {
  if (f.bundle_bytes > limits.max_bundle_bytes) {
    return fmt::format(
        "the scene bundle is {} ({} bytes), over the master's limit of {} (--max-bundle-mb)",
        mib(f.bundle_bytes), f.bundle_bytes, mib(limits.max_bundle_bytes));
  }
  if (f.bundle_files > limits.max_bundle_files) {
    return fmt::format(
        "the scene bundle has {} files, over the master's limit of {} files (--max-bundle-files)",
        f.bundle_files, limits.max_bundle_files);
  }
  if (f.width && f.height) {
    const double pixels = static_cast<double>(*f.width) * static_cast<double>(*f.height);
    if (pixels > static_cast<double>(limits.max_image_pixels)) {
      return fmt::format(
          "the image is {}x{} = {:.0f} pixels, over the master's limit of {} pixels "
          "(--max-image-pixels)",
          *f.width, *f.height, pixels, limits.max_image_pixels);
    }
    const uint64_t tile_w = std::min(f.tile_size, *f.width);
    const uint64_t tile_h = std::min(f.tile_size, *f.height);
    const uint64_t result = unit_result_bytes(tile_w, tile_h);
    if (result > static_cast<uint64_t>(limits.max_message_bytes)) {
      return fmt::format(
          "a tile of {}x{} pixels makes results of {}, over the master's message limit of {} "
          "(--max-message-mb); use smaller tiles (--tile)",
          tile_w, tile_h, mib(result), mib(static_cast<uint64_t>(limits.max_message_bytes)));
    }
  }
  if (f.spp && *f.spp > limits.max_spp) {
    return fmt::format("{} samples per pixel is over the master's limit of {} spp (--max-spp)",
                       *f.spp, limits.max_spp);
  }
  return std::nullopt;
}

std::optional<std::string> check_submission(const wire::SubmitJob& request, size_t jobs_waiting,
                                            const Limits& limits) {
  if (auto refusal = check_queue(jobs_waiting, limits)) return refusal;
  return check_figures(figures_of(request), limits);
}

}  // namespace rayfarm::master
