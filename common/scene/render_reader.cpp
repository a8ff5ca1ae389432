#include "common/scene/render_reader.h"

#include <fmt/format.h>

#include <cmath>

#include "common/limits.h"

namespace rayfarm {

using namespace scene_json;  // NOLINT(google-build-using-namespace): the JSON readers

void read_render_settings(const Node& n, RenderSettings& r) {
  n.allow_keys({"spp", "max_depth", "integrator", "seed", "sampler", "roulette", "roulette_depth",
                "shutter", "motion_steps"});
  if (auto spp = n.find("spp")) r.spp = static_cast<uint32_t>(read_integer(*spp, 1, kMaxSpp));
  if (auto d = n.find("max_depth")) {
    if (d->json().is_string()) {
      if (read_string(*d) != "unlimited")
        d->fail("max_depth must be a number or \"unlimited\", got " + as_written(d->json()));
      r.max_depth = kUnlimitedDepth;
    } else {
      r.max_depth = static_cast<uint32_t>(read_integer(*d, 0, kMaxDepth));
    }
  }
  if (auto s = n.find("sampler")) {
    const auto type = parse_sampler(read_string(*s));
    if (!type)
      s->fail("unknown sampler " + as_written(s->json()) + "; expected sobol or independent");
    r.sampler = *type;
  }
  if (auto s = n.find("roulette")) {
    const auto type = parse_roulette(read_string(*s));
    if (!type)
      s->fail("unknown roulette " + as_written(s->json()) + "; expected root, throughput or update");
    r.roulette = *type;
  }
  if (auto d = n.find("roulette_depth"))
    r.roulette_depth = static_cast<uint32_t>(read_integer(*d, 0, kMaxRouletteDepth));
  if (auto i = n.find("integrator")) {
    const auto type = parse_integrator(read_string(*i));
    if (!type)
      i->fail("unknown integrator " + as_written(i->json()) + "; expected naive, nee or mis");
    r.integrator = *type;
  }
  if (auto seed = n.find("seed")) r.seed = read_unsigned(*seed);
  if (auto sh = n.find("shutter")) {
    if (sh->array().size() != 2)
      sh->fail("expected [OPEN, CLOSE] in frames after the frame, got an array of " +
               std::to_string(sh->array().size()) + " values");
    float ends[2];
    for (size_t i = 0; i < 2; ++i) {
      const Node end = sh->child(i);
      const double v = read_number(end);
      if (!(std::fabs(v) <= kMaxShutterFrames))
        end.fail(fmt::format("a shutter end must be within +-{:g} frames of the frame, got {:g}",
                             kMaxShutterFrames, v));
      ends[i] = static_cast<float>(v);
    }
    if (ends[1] < ends[0])
      sh->fail(fmt::format("the shutter closes ({:g}) before it opens ({:g})", ends[1], ends[0]));
    r.shutter_open = ends[0];
    r.shutter_close = ends[1];
  }
  if (auto k = n.find("motion_steps"))
    r.motion_steps = static_cast<uint32_t>(read_integer(*k, kMinMotionSteps, kMaxMotionSteps));
}

}  // namespace rayfarm
