#include "renderer/lights/environment_light.h"

#include <algorithm>
#include <cmath>

#include "renderer/textures/texel_image.h"

namespace rayfarm {

namespace {

/// Rows of the constant environment's map: enough that the rows' sin(theta) steps make the
/// sampled density nearly uniform over the sphere (a single texel would crowd the poles).
constexpr uint32_t kConstantRows = 64;

/// Index of the interval of the normalised cdf (n + 1 entries) that u falls in, and u's
/// position within it in [0, 1).
uint32_t find_interval(const double* cdf, uint32_t n, double u, double& within) {
  const double* it = std::upper_bound(cdf, cdf + n + 1, u);
  uint32_t i = static_cast<uint32_t>(std::clamp<ptrdiff_t>(it - cdf - 1, 0, ptrdiff_t(n) - 1));
  // An empty interval is never meant: only rounding at the cdf's top end lands on one.
  while (i > 0 && !(cdf[i + 1] > cdf[i])) --i;
  const double width = cdf[i + 1] - cdf[i];
  within = width > 0.0 ? std::clamp((u - cdf[i]) / width, 0.0, std::nextafter(1.0, 0.0)) : 0.5;
  return i;
}

}  // namespace

std::optional<EnvironmentLight> EnvironmentLight::make(const Scene& scene, double scene_radius) {
  if (!scene.environment) return std::nullopt;
  const EnvironmentMap& map = *scene.environment;
  EnvironmentLight env;
  if (map.file.empty()) {
    env.width_ = 1, env.height_ = kConstantRows;
    env.constant_ = true;
    env.radiance_.assign(kConstantRows, map.scale);
  } else {
    if (!map.image) return std::nullopt;  // loaded to be checked only
    const TexelImage texels(DecodedImage(*map.image), ColourSpace::from_file);
    env.width_ = texels.width(), env.height_ = texels.height();
    env.radiance_.resize(size_t(env.width_) * env.height_);
    for (uint32_t y = 0; y < env.height_; ++y) {
      for (uint32_t x = 0; x < env.width_; ++x) {
        const Vec4 t = texels.texel(x, y);
        // Negative or non-finite texels (possible in HDR files) would make a negative density.
        const auto clean = [](float v) { return std::isfinite(v) && v > 0.f ? v : 0.f; };
        env.radiance_[size_t(y) * env.width_ + x] =
            Vec3(clean(t.x), clean(t.y), clean(t.z)) * map.scale;
      }
    }
  }
  for (int i = 0; i < 9; ++i) env.to_world_[i] = static_cast<float>(map.rotation[i]);
  env.bilinear_ = map.bilinear && !map.file.empty();

  const uint32_t w = env.width_, h = env.height_;
  env.weight_.resize(size_t(w) * h);
  env.column_cdf_.resize(size_t(w + 1) * h);
  env.row_cdf_.resize(h + 1);
  double integral = 0.0;  // of luminance over the sphere, for the power
  for (uint32_t y = 0; y < h; ++y) {
    const double theta0 = kPi * double(y) / h, theta1 = kPi * double(y + 1) / h;
    const float sin_theta = static_cast<float>(std::sin(kPi * (y + 0.5) / h));
    const double row_solid_angle = 2.0 * kPi * (std::cos(theta0) - std::cos(theta1)) / w;
    double* cdf = &env.column_cdf_[size_t(w + 1) * y];
    cdf[0] = 0.0;
    for (uint32_t x = 0; x < w; ++x) {
      const float lum = luminance(env.radiance_[size_t(y) * w + x]);
      float reach = lum;  // what a bilinear lookup in this cell may return
      if (env.bilinear_) {
        for (uint32_t yy = y > 0 ? y - 1 : 0; yy <= std::min(y + 1, h - 1); ++yy) {
          for (uint32_t dx = 0; dx < 3; ++dx) {
            const uint32_t xx = (x + w - 1 + dx) % w;
            reach = std::max(reach, luminance(env.radiance_[size_t(yy) * w + xx]));
          }
        }
      }
      const float weight = std::max(reach, 0.f) * sin_theta;
      env.weight_[size_t(y) * w + x] = weight;
      cdf[x + 1] = cdf[x] + weight;
      integral += std::max(lum, 0.f) * row_solid_angle;
    }
    env.row_cdf_[y + 1] = env.row_cdf_[y] + cdf[w];
    if (cdf[w] > 0.0) {
      for (uint32_t x = 1; x <= w; ++x) cdf[x] /= cdf[w];
    }
  }
  env.total_weight_ = env.row_cdf_[h];
  if (!(env.total_weight_ > 0.0) || !std::isfinite(env.total_weight_)) return std::nullopt;
  for (double& c : env.row_cdf_) c /= env.total_weight_;
  env.power_ = kPi * scene_radius * scene_radius * integral;
  return env;
}

Vec3 EnvironmentLight::direction(float u, float v) const {
  const float theta = v * kPi, phi = 2.f * kPi * u;
  const float s = std::sin(theta);
  const Vec3 local(s * std::sin(phi), std::cos(theta), -s * std::cos(phi));
  const auto& m = to_world_;
  return {m[0] * local.x + m[1] * local.y + m[2] * local.z,
          m[3] * local.x + m[4] * local.y + m[5] * local.z,
          m[6] * local.x + m[7] * local.y + m[8] * local.z};
}

std::array<float, 2> EnvironmentLight::uv(const Vec3& dir) const {
  const auto& m = to_world_;  // its transpose takes world to map
  const Vec3 local(m[0] * dir.x + m[3] * dir.y + m[6] * dir.z,
                   m[1] * dir.x + m[4] * dir.y + m[7] * dir.z,
                   m[2] * dir.x + m[5] * dir.y + m[8] * dir.z);
  float u = std::atan2(local.x, -local.z) * (0.5f / kPi);
  if (u < 0.f) u += 1.f;
  // theta from atan2, not acos(y): acos loses most digits near the poles, where the density's
  // 1 / sin(theta) needs them.
  const float v = std::atan2(std::sqrt(local.x * local.x + local.z * local.z), local.y) / kPi;
  return {u, v};
}

uint32_t EnvironmentLight::cell(float u, float v) const {
  // NaN (a degenerate direction) reads as 0: converting it to an integer is undefined.
  if (!(u >= 0.f)) u = 0.f;
  if (!(v >= 0.f)) v = 0.f;
  const auto x = std::min(static_cast<uint32_t>(std::min(u, 1.f) * width_), width_ - 1);
  const auto y = std::min(static_cast<uint32_t>(std::min(v, 1.f) * height_), height_ - 1);
  return y * width_ + x;
}

float EnvironmentLight::pdf_uv(uint32_t index) const {
  return static_cast<float>(double(weight_[index]) * width_ * height_ / total_weight_);
}

Vec3 EnvironmentLight::eval(const Vec3& dir) const {
  const auto [u, v] = uv(dir);
  if (!bilinear_) return radiance_[cell(u, v)];
  if (!(u >= 0.f && v >= 0.f)) return radiance_[0];  // NaN: a degenerate direction
  const float w = static_cast<float>(width_);
  float x = std::min(u, 1.f) * w - 0.5f;
  if (x < 0.f) x += w;
  const auto x0 = std::min(static_cast<uint32_t>(x), width_ - 1);
  const uint32_t x1 = x0 + 1 == width_ ? 0 : x0 + 1;
  const float fx = std::clamp(x - static_cast<float>(x0), 0.f, 1.f);
  uint32_t y0 = 0, y1 = 0;
  float fy = 0.f;
  if (height_ > 1) {
    const float y = std::min(v, 1.f) * static_cast<float>(height_ - 1);
    y0 = std::min(static_cast<uint32_t>(y), height_ - 2);
    y1 = y0 + 1;
    fy = std::clamp(y - static_cast<float>(y0), 0.f, 1.f);
  }
  const auto at = [&](uint32_t xx, uint32_t yy) { return radiance_[size_t(yy) * width_ + xx]; };
  const Vec3 top = at(x0, y0) * (1.f - fx) + at(x1, y0) * fx;
  const Vec3 bottom = at(x0, y1) * (1.f - fx) + at(x1, y1) * fx;
  return top * (1.f - fy) + bottom * fy;
}

float EnvironmentLight::pdf_direction(const Vec3& dir) const {
  const auto [u, v] = uv(dir);
  const float sin_theta = std::sin(v * kPi);
  if (!(sin_theta > 0.f)) return 0.f;
  return pdf_uv(cell(u, v)) / (2.f * kPi * kPi * sin_theta);
}

bool EnvironmentLight::sample(const Vec3& /*ref*/, float p_select, float u1, float u2,
                              LightSample& out) const {
  double dv = 0.0, du = 0.0;
  const uint32_t y = find_interval(row_cdf_.data(), height_, u2, dv);
  const uint32_t x = find_interval(&column_cdf_[size_t(width_ + 1) * y], width_, u1, du);
  const uint32_t index = y * width_ + x;
  const float density = pdf_uv(index);
  if (!(density > 0.f)) return false;
  const float u = static_cast<float>((x + du) / width_), v = static_cast<float>((y + dv) / height_);
  const float sin_theta = std::sin(v * kPi);
  if (!(sin_theta > 0.f)) return false;
  out.wi = direction(u, v);
  out.radiance = bilinear_ ? eval(out.wi) : radiance_[index];  // what eval() says of wi
  out.pdf = p_select * density / (2.f * kPi * kPi * sin_theta);
  out.delta = false;
  out.infinite = true;
  return std::isfinite(out.pdf) && out.pdf > 0.f;
}

}  // namespace rayfarm
