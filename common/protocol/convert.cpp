#include "common/protocol/convert.h"

#include "common/scene/motion.h"

#include <bit>
#include <cmath>
#include <cstring>

namespace rayfarm::protocol {

wire::Integrator integrator_to_wire(IntegratorType type) {
  switch (type) {
    case IntegratorType::kNaive:
      return wire::INTEGRATOR_NAIVE;
    case IntegratorType::kNee:
      return wire::INTEGRATOR_NEE;
    case IntegratorType::kMis:
      return wire::INTEGRATOR_MIS;
  }
  return wire::INTEGRATOR_UNSPECIFIED;
}

IntegratorType integrator_from_wire(wire::Integrator value) {
  switch (value) {
    case wire::INTEGRATOR_NAIVE:
      return IntegratorType::kNaive;
    case wire::INTEGRATOR_NEE:
      return IntegratorType::kNee;
    case wire::INTEGRATOR_MIS:
      return IntegratorType::kMis;
    default:
      break;
  }
  throw ProtocolError("unknown integrator " + std::to_string(static_cast<int>(value)));
}

wire::Sampler sampler_to_wire(SamplerType type) {
  return type == SamplerType::kSobol ? wire::SAMPLER_SOBOL : wire::SAMPLER_INDEPENDENT;
}

SamplerType sampler_from_wire(wire::Sampler value) {
  if (value == wire::SAMPLER_SOBOL) return SamplerType::kSobol;
  if (value == wire::SAMPLER_INDEPENDENT) return SamplerType::kIndependent;
  throw ProtocolError("unknown sampler " + std::to_string(static_cast<int>(value)));
}

wire::Roulette roulette_to_wire(RouletteType type) {
  switch (type) {
    case RouletteType::kThroughput: return wire::ROULETTE_THROUGHPUT;
    case RouletteType::kRoot: return wire::ROULETTE_ROOT;
    case RouletteType::kUpdate: break;
  }
  return wire::ROULETTE_UPDATE;
}

RouletteType roulette_from_wire(wire::Roulette value) {
  if (value == wire::ROULETTE_ROOT) return RouletteType::kRoot;
  if (value == wire::ROULETTE_THROUGHPUT) return RouletteType::kThroughput;
  if (value == wire::ROULETTE_UPDATE) return RouletteType::kUpdate;
  throw ProtocolError("unknown roulette " + std::to_string(static_cast<int>(value)));
}

bool same_settings(const RenderSettings& a, const RenderSettings& b) {
  return settings_to_wire(a).SerializeAsString() == settings_to_wire(b).SerializeAsString();
}

wire::RenderSettings settings_to_wire(const RenderSettings& settings) {
  wire::RenderSettings out;
  out.set_spp(settings.spp);
  out.set_max_depth(settings.max_depth);
  out.set_integrator(integrator_to_wire(settings.integrator));
  out.set_seed(settings.seed);
  out.set_clamp(settings.clamp);
  out.set_sampler(sampler_to_wire(settings.sampler));
  out.set_roulette(roulette_to_wire(settings.roulette));
  out.set_roulette_depth(settings.roulette_depth);
  out.set_shutter_open(settings.shutter_open);
  out.set_shutter_close(settings.shutter_close);
  out.set_motion_steps(settings.motion_steps);
  return out;
}

RenderSettings settings_from_wire(const wire::RenderSettings& settings) {
  if (settings.spp() == 0) throw ProtocolError("render settings with 0 samples per pixel");
  RenderSettings out;
  out.spp = settings.spp();
  out.max_depth = settings.max_depth();
  out.integrator = integrator_from_wire(settings.integrator());
  out.seed = settings.seed();
  if (!(settings.clamp() >= 0.f) || !std::isfinite(settings.clamp())) {
    throw ProtocolError("render settings with a clamp that is negative or not finite");
  }
  out.clamp = settings.clamp();
  if (settings.max_depth() > kMaxDepth && settings.max_depth() != kUnlimitedDepth) {
    throw ProtocolError("render settings with max_depth " + std::to_string(settings.max_depth()) +
                        " (at most " + std::to_string(kMaxDepth) + ", or unlimited)");
  }
  out.sampler = sampler_from_wire(settings.sampler());
  out.roulette = roulette_from_wire(settings.roulette());
  if (settings.roulette_depth() > kMaxRouletteDepth) {
    throw ProtocolError("render settings with roulette_depth " +
                        std::to_string(settings.roulette_depth()));
  }
  out.roulette_depth = settings.roulette_depth();
  if (auto why = shutter_problem(settings.shutter_open(), settings.shutter_close(),
                                 settings.motion_steps()))
    throw ProtocolError("render settings with " + *why);
  out.shutter_open = settings.shutter_open();
  out.shutter_close = settings.shutter_close();
  out.motion_steps = settings.motion_steps();
  return out;
}

wire::FrameList frames_to_wire(const FrameList& frames) {
  wire::FrameList out;
  out.set_first(frames.first);
  out.set_last(frames.last);
  out.set_step(frames.step);
  return out;
}

std::optional<FrameList> frames_from_wire(const wire::FrameList& frames) {
  if (frames.step() == 0) {
    if (frames.first() != 0 || frames.last() != 0) {
      throw ProtocolError("the frames' step must be at least 1");
    }
    return std::nullopt;
  }
  const auto in_range = [](int64_t f) { return f >= -kMaxFrameNumber && f <= kMaxFrameNumber; };
  if (frames.step() < 0) throw ProtocolError("the frames' step must be at least 1");
  if (!in_range(frames.first()) || !in_range(frames.last())) {
    throw ProtocolError("frame numbers must be within +-1000000000");
  }
  if (frames.last() < frames.first()) {
    throw ProtocolError("the frames " + std::to_string(frames.first()) + "-" +
                        std::to_string(frames.last()) + " are reversed");
  }
  FrameList out{frames.first(), frames.last(), frames.step()};
  out.last = out.first + (out.last - out.first) / out.step * out.step;
  return out;
}

uint64_t frame_count(const wire::FrameList& frames) {
  if (frames.step() <= 0 || frames.last() < frames.first()) return 1;
  const uint64_t span = uint64_t(frames.last()) - uint64_t(frames.first());
  const uint64_t steps = span / uint64_t(frames.step());
  return steps == UINT64_MAX ? steps : steps + 1;  // never 0
}

wire::Rect rect_to_wire(const TileRect& rect) {
  wire::Rect out;
  out.set_x0(rect.x0);
  out.set_y0(rect.y0);
  out.set_x1(rect.x1);
  out.set_y1(rect.y1);
  return out;
}

TileRect rect_from_wire(const wire::Rect& rect) {
  constexpr uint32_t kMaxSide = 65536;
  if (rect.x1() <= rect.x0() || rect.y1() <= rect.y0() || rect.x1() - rect.x0() > kMaxSide ||
      rect.y1() - rect.y0() > kMaxSide) {
    throw ProtocolError("bad tile rectangle [" + std::to_string(rect.x0()) + "," +
                        std::to_string(rect.x1()) + ")x[" + std::to_string(rect.y0()) + "," +
                        std::to_string(rect.y1()) + ")");
  }
  return TileRect{rect.x0(), rect.y0(), rect.x1(), rect.y1()};
}

std::string pack_fixed(const std::vector<Fixed>& values) {
  std::string out;
  out.reserve(values.size() * 8);
  for (const Fixed v : values) {
    // Zigzag: the sign into bit 0, so that small negative values stay short too.
    UFixed z = (static_cast<UFixed>(v) << 1) ^ static_cast<UFixed>(v >> 127);
    while (z >= 0x80) {
      out.push_back(static_cast<char>(static_cast<uint8_t>(z & 0x7f) | 0x80));
      z >>= 7;
    }
    out.push_back(static_cast<char>(static_cast<uint8_t>(z)));
  }
  return out;
}

std::vector<Fixed> unpack_fixed(std::string_view bytes, size_t count) {
  // Each value takes at least one byte: a claim of more values than bytes allocates nothing.
  if (bytes.size() < count || bytes.size() > count * kMaxFixedWireBytes) {
    throw ProtocolError("expected " + std::to_string(count) + " fixed-point values (" +
                        std::to_string(count) + " to " +
                        std::to_string(count * kMaxFixedWireBytes) + " bytes), got " +
                        std::to_string(bytes.size()) + " bytes");
  }
  std::vector<Fixed> out(count);
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  const auto* const end = p + bytes.size();
  for (size_t k = 0; k < count; ++k) {
    // Most values take at most 8 bytes (56 bits): read 8 at once, find the last byte by its
    // clear top bit and squeeze out the flag bits, without a branch per byte.
    if constexpr (std::endian::native == std::endian::little) {
      if (end - p >= 8) {
        uint64_t w;
        std::memcpy(&w, p, 8);
        const uint64_t stops = ~w & 0x8080808080808080ull;
        if (stops != 0) {
          const int length = (std::countr_zero(stops) >> 3) + 1;  // 1 to 8 bytes
          uint64_t v =
              (length == 8 ? w : w & ((uint64_t{1} << (8 * length)) - 1)) & 0x7f7f7f7f7f7f7f7full;
          v = (v & 0x007f007f007f007full) | ((v & 0x7f007f007f007f00ull) >> 1);
          v = (v & 0x00003fff00003fffull) | ((v & 0x3fff00003fff0000ull) >> 2);
          v = (v & 0x000000000fffffffull) | ((v & 0x0fffffff00000000ull) >> 4);
          p += length;
          out[k] = static_cast<Fixed>(static_cast<int64_t>((v >> 1) ^ (uint64_t{0} - (v & 1))));
          continue;
        }
      }
    }
    // Longer values, or the last few bytes: a byte at a time.
    UFixed z = 0;
    for (int shift = 0;; shift += 7) {
      if (p == end) {
        throw ProtocolError("fixed-point value " + std::to_string(k) + " of " +
                            std::to_string(count) + " is cut short");
      }
      const unsigned char b = *p++;
      // The 19th byte holds bits 126 and 127 only, and ends the value.
      if (shift == 126 && b > 0x03) {
        throw ProtocolError("fixed-point value " + std::to_string(k) + " is wider than 128 bits");
      }
      z |= static_cast<UFixed>(b & 0x7f) << shift;
      if ((b & 0x80) == 0) break;
    }
    out[k] = static_cast<Fixed>((z >> 1) ^ (UFixed{0} - (z & 1)));
  }
  if (p != end) {
    throw ProtocolError(std::to_string(end - p) + " bytes after the " + std::to_string(count) +
                        " fixed-point values");
  }
  return out;
}

wire::UnitResult result_to_wire(const std::string& job_id, uint64_t unit_id,
                                const TileResult& result, double render_seconds) {
  wire::UnitResult out;
  out.set_job_id(job_id);
  out.set_unit_id(unit_id);
  *out.mutable_tile() = rect_to_wire(result.rect);
  out.set_sample_begin(result.samples.begin);
  out.set_sample_end(result.samples.end);
  out.set_sum(pack_fixed(result.sum));
  out.set_sum_sq(pack_fixed(result.sum_sq));
  out.set_nonfinite(result.nonfinite);
  out.set_rays(result.rays);
  out.set_render_seconds(render_seconds);
  return out;
}

TileResult result_from_wire(const wire::UnitResult& result) {
  const TileRect rect = rect_from_wire(result.tile());
  if (result.sample_end() <= result.sample_begin()) {
    throw ProtocolError("empty sample range [" + std::to_string(result.sample_begin()) + "," +
                        std::to_string(result.sample_end()) + ")");
  }
  const size_t count = size_t{rect.width()} * rect.height() * 3;
  TileResult out;
  out.rect = rect;
  out.samples = SampleRange{result.sample_begin(), result.sample_end()};
  try {
    out.sum = unpack_fixed(result.sum(), count);
    out.sum_sq = unpack_fixed(result.sum_sq(), count);
  } catch (const ProtocolError& e) {
    throw ProtocolError(std::string("unit result sums do not match its tile: ") + e.what());
  }
  out.nonfinite = result.nonfinite();
  out.rays = result.rays();
  return out;
}

void bundle_to_wire(const Bundle& bundle, wire::Bundle* out) {
  out->clear_files();
  for (const auto& f : bundle.files) {
    auto* file = out->add_files();
    file->set_path(f.path);
    file->set_data(f.data);
  }
}

Bundle bundle_from_wire(const wire::Bundle& bundle) {
  std::vector<BundleFile> files;
  files.reserve(static_cast<size_t>(bundle.files_size()));
  for (const auto& f : bundle.files()) files.push_back({f.path(), f.data()});
  return make_bundle(std::move(files));
}

const char* job_state_name(wire::JobState state) {
  switch (state) {
    case wire::JOB_QUEUED:
      return "queued";
    case wire::JOB_RUNNING:
      return "running";
    case wire::JOB_DONE:
      return "done";
    case wire::JOB_FAILED:
      return "failed";
    case wire::JOB_CANCELLED:
      return "cancelled";
    default:
      return "unknown";
  }
}

}  // namespace rayfarm::protocol
