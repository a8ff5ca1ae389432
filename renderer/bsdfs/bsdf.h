#pragma once
// Scattering at a path vertex: a variant with one alternative per BSDF kind, each in its own
// header, dispatched without a virtual call (an inlined chain of index tests for a few kinds,
// std::visit for many). Built per vertex from the hit's material. Adding a kind: its header here
// and one line in `Bsdf`.
#include <cassert>
#include <type_traits>
#include <variant>

#include "common/scene/scene.h"
#include "renderer/bsdfs/bsdf_sample.h"
#include "renderer/bsdfs/dielectric.h"
#include "renderer/bsdfs/diffuse.h"
#include "renderer/bsdfs/metallic_roughness.h"
#include "renderer/bsdfs/mirror.h"
#include "renderer/bsdfs/phong.h"
#include "renderer/bsdfs/plastic.h"
#include "renderer/bsdfs/rough_conductor.h"
#include "renderer/bsdfs/rough_dielectric.h"
#include "renderer/bsdfs/thin_dielectric.h"
#include "renderer/textures/texture_lookup.h"
#include "renderer/variant_chain.h"

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
  explicit BsdfOf(const Material& m, const TextureLookup& tex = {}) : kind_(make(m, tex)) {}

  /// True when every lobe is a Dirac delta (light sampling cannot help).
  [[gnu::always_inline]] bool is_specular() const {
    return dispatch([](const auto& k) { return k.is_specular(); });
  }
  /// True when f(wo, wi) is zero for every wi on the other side of the surface from wo (the kind
  /// says so with kReflectsOnly; kinds that do not may transmit).
  [[gnu::always_inline]] bool reflects_only() const {
    return dispatch([](const auto& k) {
      using K = std::decay_t<decltype(k)>;
      if constexpr (requires { K::kReflectsOnly; }) {
        return K::kReflectsOnly;
      } else {
        return false;
      }
    });
  }
  /// f(wo, wi) * |cos(wi)|; zero for specular kinds.
  [[gnu::always_inline]] Vec3 eval(const Vec3& wo, const Vec3& wi) const {
    return dispatch([&](const auto& k) { return k.eval(wo, wi); });
  }
  /// Solid-angle density with which sample() draws wi given wo; zero for specular kinds.
  [[gnu::always_inline]] float pdf(const Vec3& wo, const Vec3& wi) const {
    return dispatch([&](const auto& k) { return k.pdf(wo, wi); });
  }
  /// Draws wi from three uniform numbers; false when no direction carries energy.
  [[gnu::always_inline]] bool sample(const Vec3& wo, float u_lobe, float u1, float u2,
                                     BsdfSample& out) const {
    return dispatch([&](const auto& k) { return k.sample(wo, u_lobe, u1, u2, out); });
  }

 private:
  // The variant alternative for material parameters `params`.
  template <class P>
  static std::variant<Kinds...> make_kind(const P& params, const TextureLookup& tex) {
    if constexpr (requires { typename detail::BsdfKindFor<P, Kinds...>::type; }) {
      using K = typename detail::BsdfKindFor<P, Kinds...>::type;
      if (tex.has_textures())
        return std::variant<Kinds...>(std::in_place_type<K>, resolve_textures(params, tex));
      return std::variant<Kinds...>(std::in_place_type<K>, params);
    } else {
      assert(!"material kind unknown to this BSDF");
      __builtin_unreachable();
    }
  }
  // Few enough kinds to test one by one, inlined (construction and every method).
  static constexpr bool kFewKinds = sizeof...(Kinds) <= 4;

  // A BSDF of few kinds tests the material's kind against each of them: GCC compiles std::visit
  // over all the material kinds into an out-of-line function (a switch) that it may leave a
  // call, a cost paid at every path vertex of scenes that use none of the other kinds.
  template <class K, class... Rest>
  static std::variant<Kinds...> make_first(const Material& m, const TextureLookup& tex) {
    if (const auto* params = std::get_if<typename K::Params>(&m.kind))
      return make_kind(*params, tex);
    if constexpr (sizeof...(Rest) > 0) {
      return make_first<Rest...>(m, tex);
    } else {
      assert(!"material kind unknown to this BSDF");
      __builtin_unreachable();
    }
  }
  static std::variant<Kinds...> make(const Material& m, const TextureLookup& tex) {
    if constexpr (kFewKinds) {
      return make_first<Kinds...>(m, tex);
    } else {
      return std::visit([&tex](const auto& params) { return make_kind(params, tex); }, m.kind);
    }
  }

  // The kind's method: a few kinds through an inlined chain of index tests (variant_chain.h);
  // the nine of `Bsdf` through std::visit as before (inlining all nine at every call site was
  // not tried).
  template <class F>
  [[gnu::always_inline]] auto dispatch(F&& f) const {
    if constexpr (kFewKinds) {
      return visit_chain(kind_, f);
    } else {
      return std::visit(f, kind_);
    }
  }

  std::variant<Kinds...> kind_;
};

/// Every BSDF kind: the one the renderer uses.
using Bsdf = BsdfOf<DiffuseBsdf, PhongBsdf, MirrorBsdf, DielectricBsdf, RoughConductorBsdf,
                    RoughDielectricBsdf, ThinDielectricBsdf, PlasticBsdf, MetallicRoughnessBsdf>;

/// The kinds without microfacets: the renderer uses it for scenes that have no other kind, whose
/// vertices then dispatch among four alternatives, inlined, instead of calling through the
/// table that std::visit over nine becomes (docs/benchmarks.md).
using BasicBsdf = BsdfOf<DiffuseBsdf, PhongBsdf, MirrorBsdf, DielectricBsdf>;

/// Diffuse only: for measuring what the other kinds cost a diffuse scene (bench/diffuse_only.sh).
using DiffuseOnlyBsdf = BsdfOf<DiffuseBsdf>;

}  // namespace rayfarm
