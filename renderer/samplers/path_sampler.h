#pragma once
// The random numbers of one path sample, as a function of (seed, pixel, sample index) only.
//
// Two samplers (RenderSettings::sampler):
//  - independent: every number from the sample's hashed PCG stream (rng.h), drawn in the order
//    the path asks for them;
//  - sobol: each group of numbers from its own scrambled four-dimensional Sobol' sequence
//    (sobol.h) keyed by (seed, pixel, group), indexed by the sample number. The groups are fixed:
//    the camera (pixel position x, y, lens u, v), the time within the shutter when something
//    moves (a group of its own), and per scattering vertex up to
//    kSobolVertices: the light (point u, v on Sobol' dimensions 0, 1; choice on 2) and the
//    scattering (direction u, v on 0, 1; BSDF lobe on 2; roulette on 3). Deeper vertices, where
//    stratification no longer shows, read the hashed stream as the independent sampler does.
//    A group that nothing reads (the light's, with one point light) is not computed; each
//    group's numbers depend on its own key alone, so that changes no other.
// Neither depends on the tile, the thread, the pass or the machine, so the farm's image is the
// local one bit for bit.
#include <array>
#include <cstdint>
#include <optional>

#include "common/scene/scene.h"
#include "renderer/samplers/rng.h"
#include "renderer/samplers/sobol.h"

namespace rayfarm {

class PathSampler {
 public:
  /// Vertices (the camera ray's hit is vertex 0) whose numbers come from Sobol' sequences.
  static constexpr uint32_t kSobolVertices = 64;

  // Each sampler sets up only what it reads: the Sobol' sampler its key (the stream waits for a
  // vertex past kSobolVertices, which most paths never reach), the independent one its stream.
  PathSampler(SamplerType type, uint64_t seed, uint64_t pixel, uint32_t sample)
      : seed_(seed), pixel_(pixel), index_(sample), sobol_(type == SamplerType::kSobol) {
    if (sobol_) {
      key_ = mix64(seed ^ mix64(pixel ^ 0x50b01u));
      reversed_index_ = sobol::reverse_bits(sample);
    } else {
      rng_.emplace(sample_stream(seed, pixel, sample));
    }
  }

  /// Pixel offset x, y in [0, 1)^2, then lens u, v.
  std::array<float, 4> camera() {
    if (sobol_) return sobol::sample_reversed<4>(reversed_index_, key_);
    Pcg32& rng = stream();
    return {rng.next_float(), rng.next_float(), rng.next_float(), rng.next_float()};
  }

  /// The sample's time within the shutter, in [0, 1) (motion blur). Asked for, after camera(),
  /// only when something moves, so that other scenes keep their numbers.
  float time() {
    if (sobol_) return sobol::sample_reversed<1>(reversed_index_, group_key(0))[0];
    return stream().next_float();
  }

  /// Light choice and point on the light at vertex `depth`, as 32-bit numbers (light selection
  /// through a tree reads all the choice's bits; light() the top 24 of each). The point's two
  /// numbers are Sobol' dimensions 0 and 1, the pair whose prefixes are (0, m, 2)-nets.
  std::array<uint32_t, 3> light_bits(uint32_t depth) {
    if (sobol_ && depth < kSobolVertices) {
      const std::array<uint32_t, 3> u =
          sobol::sample_bits_reversed<3>(reversed_index_, group_key(2 * depth + 1));
      return {u[2], u[0], u[1]};
    }
    Pcg32& rng = stream();
    const uint32_t choice = rng.next_u32(), u1 = rng.next_u32();
    return {choice, u1, rng.next_u32()};
  }
  /// light_bits() for a vertex whose light may read none of them (`read` false: one point,
  /// spot or directional light, LightSet::reads_numbers()): the Sobol' sampler then leaves its
  /// group out (each group has its own key, so no other number changes) and returns zeros; the
  /// hashed stream still draws them, so that the numbers after them stay where they were.
  std::array<uint32_t, 3> light_bits(uint32_t depth, bool read) {
    if (!read && sobol_ && depth < kSobolVertices) return {};
    return light_bits(depth);
  }
  /// light_bits() as floats in [0, 1).
  std::array<float, 3> light(uint32_t depth) {
    const std::array<uint32_t, 3> b = light_bits(depth);
    return {sobol::to_unit_float(b[0]), sobol::to_unit_float(b[1]), sobol::to_unit_float(b[2])};
  }

  /// BSDF lobe, direction u, v and the roulette number at vertex `depth`. The roulette number is
  /// drawn only when asked for (roulette()), so that the independent stream matches the path.
  std::array<float, 3> scatter(uint32_t depth) {
    if (sobol_ && depth < kSobolVertices) {
      // The direction on dimensions 0 and 1, as for the light.
      const std::array<float, 4> u =
          sobol::sample_reversed<4>(reversed_index_, group_key(2 * depth + 2));
      roulette_ = u[3];
      return {u[2], u[0], u[1]};
    }
    roulette_ = -1.f;
    Pcg32& rng = stream();
    return {rng.next_float(), rng.next_float(), rng.next_float()};
  }

  /// The roulette number of the vertex whose scatter() was the last called.
  float roulette() { return roulette_ >= 0.f ? roulette_ : stream().next_float(); }

 private:
  uint64_t group_key(uint32_t group) const { return mix64(key_ + group); }

  Pcg32& stream() {
    if (!rng_) rng_.emplace(sample_stream(seed_, pixel_, index_));
    return *rng_;
  }

  std::optional<Pcg32> rng_;
  uint64_t seed_, pixel_;
  uint64_t key_ = 0;
  uint32_t index_;
  uint32_t reversed_index_ = 0;  ///< the Sobol' sampler's index, bits reversed once per sample
  bool sobol_;
  float roulette_ = -1.f;
};

}  // namespace rayfarm
