#pragma once
// Four-component float vector: an RGBA value (textures return colour and alpha together).
namespace rayfarm {

/// RGBA, or any four floats.
struct Vec4 {
  float x = 0.f, y = 0.f, z = 0.f, w = 0.f;

  constexpr Vec4() = default;
  constexpr Vec4(float x_, float y_, float z_, float w_) : x(x_), y(y_), z(z_), w(w_) {}

  constexpr float operator[](int i) const { return i == 0 ? x : (i == 1 ? y : (i == 2 ? z : w)); }
  constexpr bool operator==(const Vec4&) const = default;
};

constexpr Vec4 operator+(const Vec4& a, const Vec4& b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z, a.w + b.w};
}
constexpr Vec4 operator*(float s, const Vec4& a) { return {s * a.x, s * a.y, s * a.z, s * a.w}; }

}  // namespace rayfarm
