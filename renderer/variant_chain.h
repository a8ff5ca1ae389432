#pragma once
// Calls f on the alternative a std::variant holds through a chain of index tests, in the
// variant's order, always inlined: GCC compiles std::visit into an out-of-line function (a
// switch, behind a test for a valueless variant) that it may leave uninlined, a call paid at
// every path vertex for each BSDF and light method. Listing the common kinds first makes their
// tests the first and best predicted. The variant must hold a value (the BSDFs and lights are
// built whole and never assigned).
#include <cstddef>
#include <variant>

namespace rayfarm {

template <size_t I = 0, class Variant, class F>
[[gnu::always_inline]] inline auto visit_chain(const Variant& v, F&& f) {
  if constexpr (I + 1 == std::variant_size_v<Variant>) {
    return f(*std::get_if<I>(&v));
  } else {
    if (v.index() == I) return f(*std::get_if<I>(&v));
    return visit_chain<I + 1>(v, f);
  }
}

}  // namespace rayfarm
