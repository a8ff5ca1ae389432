#pragma once
// Scattering at a path vertex: a variant with one alternative per BSDF kind, each in its own
// header, dispatched by std::visit (a switch on the variant's index, no virtual call). Built per
// vertex from the hit's material. Adding a kind: its header here and one line in `Bsdf`.
#include <cassert>
#include <type_traits>
#include <variant>

#include "common/scene/scene.h"
#include "worker/bsdfs/bsdf_sample.h"
#include "worker/bsdfs/dielectric.h"
#include "worker/bsdfs/diffuse.h"
#include "worker/bsdfs/metallic_roughness.h"
#include "worker/bsdfs/mirror.h"
#include "worker/bsdfs/phong.h"
#include "worker/bsdfs/plastic.h"
#include "worker/bsdfs/rough_conductor.h"
#include "worker/bsdfs/rough_dielectric.h"
#include "worker/bsdfs/thin_dielectric.h"
#include "worker/textures/texture_lookup.h"

namespace rayfarm {

namespace detail {
// The first of Kinds built from material parameters P (member `type`; none if no kind is).
template <class P, class... Kinds>
struct BsdfKindFor {};
template <class P, class K, class... Rest>
struct BsdfKindFor<P, K, Rest...>
    : std::conditional_t<std::is_same_v<P, typename K::Params>, std::type_identity<K>,
                         BsdfKindFor<P, Rest...>> {};
}  // namespace detail

/// A BSDF that knows the kinds `Kinds`. Each kind has `Params` (the material struct it is built
/// from), `is_specular()` (every lobe a Dirac delta: per instance, since a rough kind with
/// roughness 0 is smooth) and eval / pdf / sample as documented below. A BSDF that is not specular
/// may still draw some samples from a Dirac lobe (a smooth coat over a diffuse base): those carry
/// `BsdfSample::specular`, and eval / pdf leave the Dirac lobes out.
template <class... Kinds>
class BsdfOf {
 public:
  /// True when this BSDF knows m's kind.
  static bool supports(const Material& m) {
    return std::visit(
        [](const auto& params) {
          return requires {
            typename detail::BsdfKindFor<std::decay_t<decltype(params)>, Kinds...>::type;
          };
        },
        m.kind);
  }

  /// The BSDF of material m, whose kind it must know (supports(m)), with its textured
  /// parameters read through `tex` (the default lookup serves untextured materials only).
  explicit BsdfOf(const Material& m, const TextureLookup& tex = {})
      : kind_(std::visit(
            [&tex](const auto& params) -> std::variant<Kinds...> {
              using P = std::decay_t<decltype(params)>;
              if constexpr (requires { typename detail::BsdfKindFor<P, Kinds...>::type; }) {
                using K = typename detail::BsdfKindFor<P, Kinds...>::type;
                if (tex.has_textures())
                  return std::variant<Kinds...>(std::in_place_type<K>,
                                                resolve_textures(params, tex));
                return std::variant<Kinds...>(std::in_place_type<K>, params);
              } else {
                assert(!"material kind unknown to this BSDF");
                __builtin_unreachable();
              }
            },
            m.kind)) {}

  /// True when every lobe is a Dirac delta (light sampling cannot help).
  bool is_specular() const {
    return std::visit([](const auto& k) { return k.is_specular(); }, kind_);
  }
  /// f(wo, wi) * |cos(wi)|; zero for specular kinds.
  Vec3 eval(const Vec3& wo, const Vec3& wi) const {
    return std::visit([&](const auto& k) { return k.eval(wo, wi); }, kind_);
  }
  /// Solid-angle density with which sample() draws wi given wo; zero for specular kinds.
  float pdf(const Vec3& wo, const Vec3& wi) const {
    return std::visit([&](const auto& k) { return k.pdf(wo, wi); }, kind_);
  }
  /// Draws wi from three uniform numbers; false when no direction carries energy.
  bool sample(const Vec3& wo, float u_lobe, float u1, float u2, BsdfSample& out) const {
    return std::visit([&](const auto& k) { return k.sample(wo, u_lobe, u1, u2, out); }, kind_);
  }

 private:
  std::variant<Kinds...> kind_;
};

/// Every BSDF kind: the one the renderer uses.
using Bsdf = BsdfOf<DiffuseBsdf, PhongBsdf, MirrorBsdf, DielectricBsdf, RoughConductorBsdf,
                    RoughDielectricBsdf, ThinDielectricBsdf, PlasticBsdf, MetallicRoughnessBsdf>;

/// Diffuse only: for measuring what the other kinds cost a diffuse scene (bench/diffuse_only.sh).
using DiffuseOnlyBsdf = BsdfOf<DiffuseBsdf>;

}  // namespace rayfarm
