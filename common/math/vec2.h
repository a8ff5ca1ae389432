#pragma once
// Two-component float vector: texture coordinates.

namespace rayfarm {

struct Vec2 {
  float x = 0.f, y = 0.f;

  constexpr Vec2() = default;
  constexpr Vec2(float x_, float y_) : x(x_), y(y_) {}
  constexpr bool operator==(const Vec2&) const = default;
};

constexpr Vec2 operator+(const Vec2& a, const Vec2& b) { return {a.x + b.x, a.y + b.y}; }
constexpr Vec2 operator-(const Vec2& a, const Vec2& b) { return {a.x - b.x, a.y - b.y}; }
constexpr Vec2 operator*(const Vec2& a, float s) { return {a.x * s, a.y * s}; }

}  // namespace rayfarm
