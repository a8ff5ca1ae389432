// What a unit's result costs on the wire: renders the first pass of a scene's units as a farm job
// cuts them (tiles of --tile, passes of default_pass_spp, or --pass-spp), and prints the bytes of
// the sums per unit as 16-byte fixed-point values and as the packed form the wire carries
// (protocol::pack_fixed), and the time to pack and unpack them both ways (the 16-byte form as the
// wire had it before: low then high 64 bits, little-endian).
#include <algorithm>
#include <chrono>
#include <iostream>
#include <vector>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include "common/image/film.h"
#include "common/image/fixed.h"
#include "common/protocol/convert.h"
#include "common/scene/motion.h"
#include "common/scene/parser.h"
#include "renderer/renderer.h"

namespace {

std::string pack_raw(const std::vector<rayfarm::Fixed>& values) {
  std::string out(values.size() * 16, '\0');
  char* p = out.data();
  for (const rayfarm::Fixed v : values) {
    const uint64_t lo = rayfarm::fixed_lo(v), hi = static_cast<uint64_t>(rayfarm::fixed_hi(v));
    for (int i = 0; i < 8; ++i) p[i] = static_cast<char>((lo >> (8 * i)) & 0xff);
    for (int i = 0; i < 8; ++i) p[8 + i] = static_cast<char>((hi >> (8 * i)) & 0xff);
    p += 16;
  }
  return out;
}

std::vector<rayfarm::Fixed> unpack_raw(const std::string& bytes, size_t count) {
  if (bytes.size() != count * 16) throw std::runtime_error("size");
  std::vector<rayfarm::Fixed> out(count);
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  for (size_t k = 0; k < count; ++k, p += 16) {
    uint64_t lo = 0, hi = 0;
    for (int i = 0; i < 8; ++i) lo |= uint64_t{p[i]} << (8 * i);
    for (int i = 0; i < 8; ++i) hi |= uint64_t{p[8 + i]} << (8 * i);
    out[k] = rayfarm::fixed_from_parts(lo, static_cast<int64_t>(hi));
  }
  return out;
}

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"result_size_bench: bytes and packing time of a unit's sums on the wire"};
  std::string scene_path;
  uint32_t tile = 64, spp = 256, units = 8;
  std::optional<uint32_t> pass_spp;
  app.add_option("scene", scene_path, "Scene file")->required();
  app.add_option("--tile", tile, "Tile size")->capture_default_str();
  app.add_option("--spp", spp, "The job's samples per pixel (sets the default pass)")
      ->capture_default_str();
  app.add_option("--pass-spp", pass_spp, "Samples per pass (default: default_pass_spp)");
  app.add_option("--units", units, "Units rendered (the first tiles of pass 0)")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    rayfarm::Scene scene = rayfarm::load_scene(scene_path);
    rayfarm::add_motion(scene, scene.render);  // a scene's own shutter blurs what moves
    rayfarm::RenderSettings settings = scene.render;
    settings.spp = spp;
    const rayfarm::Renderer renderer(scene, settings);
    const uint32_t per_pass = pass_spp.value_or(rayfarm::default_pass_spp(tile, spp));
    const std::vector<rayfarm::TileRect> tiles = rayfarm::split_tiles(scene.film, tile);
    uint64_t raw = 0, packed = 0;
    double pack_s = 0, unpack_s = 0, raw_pack_s = 0, raw_unpack_s = 0;
    const uint32_t n = std::min<uint32_t>(units, static_cast<uint32_t>(tiles.size()));
    constexpr int kRepeats = 20;  // each unit's sums packed and unpacked this many times
    for (uint32_t u = 0; u < n; ++u) {
      const rayfarm::TileResult r = renderer.render(tiles[u], {0, per_pass});
      for (const auto* values : {&r.sum, &r.sum_sq}) {
        auto t = std::chrono::steady_clock::now();
        std::string bytes;
        for (int i = 0; i < kRepeats; ++i) bytes = rayfarm::protocol::pack_fixed(*values);
        pack_s += seconds_since(t) / kRepeats;
        t = std::chrono::steady_clock::now();
        std::vector<rayfarm::Fixed> back;
        for (int i = 0; i < kRepeats; ++i)
          back = rayfarm::protocol::unpack_fixed(bytes, values->size());
        unpack_s += seconds_since(t) / kRepeats;
        if (back != *values) throw std::runtime_error("packing is not exact");
        packed += bytes.size();
        t = std::chrono::steady_clock::now();
        std::string raw_bytes;
        for (int i = 0; i < kRepeats; ++i) raw_bytes = pack_raw(*values);
        raw_pack_s += seconds_since(t) / kRepeats;
        t = std::chrono::steady_clock::now();
        for (int i = 0; i < kRepeats; ++i) back = unpack_raw(raw_bytes, values->size());
        raw_unpack_s += seconds_since(t) / kRepeats;
        if (back != *values) throw std::runtime_error("the 16-byte form is not exact");
        raw += raw_bytes.size();
      }
    }
    std::cout << fmt::format(
        "{}: {} units of {}x{} px, {} spp each: sums {:.0f} KB a unit as 16-byte values, {:.0f} "
        "KB packed ({:.2f}x smaller, {:.1f} bytes a value); a unit's sums packed in {:.3f} ms "
        "(16-byte: {:.3f}), unpacked in {:.3f} ms (16-byte: {:.3f})\n",
        scene_path, n, tile, tile, per_pass, raw / 1e3 / n, packed / 1e3 / n,
        double(raw) / double(packed), double(packed) / (double(raw) / 16), pack_s * 1e3 / n,
        raw_pack_s * 1e3 / n, unpack_s * 1e3 / n, raw_unpack_s * 1e3 / n);
  } catch (const std::exception& e) {
    std::cerr << "result_size_bench: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
