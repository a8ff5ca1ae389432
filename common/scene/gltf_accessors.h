#pragma once
// Reading glTF accessors safely: each accessor's buffer view, buffer, offsets, stride and count
// are checked against the bytes actually loaded before one element is read (a buffer shorter
// than declared, an offset past the end, an index past the vertices: each a SceneError naming
// the accessor). Internal to the glTF loader.
#include <cstdint>
#include <string>
#include <vector>

#include <tiny_gltf.h>

#include "common/math/vec2.h"
#include "common/math/vec3.h"
#include "common/math/vec4.h"

namespace rayfarm::gltf {

/// The file being read, for messages, and where warnings go.
struct Source {
  std::string display;  ///< the file as messages name it
  const tinygltf::Model* model = nullptr;
  std::vector<std::string>* warnings = nullptr;

  [[noreturn]] void fail(const std::string& where, const std::string& what) const;
  void warn(const std::string& where, const std::string& what) const;
};

/// An accessor's elements as numbers: `components` floats per element (normalized integers
/// mapped as the glTF specification says, plain integers converted).
std::vector<float> read_floats(const Source& src, int accessor, int components,
                               const std::string& where);
std::vector<Vec3> read_vec3(const Source& src, int accessor, const std::string& where);
std::vector<Vec2> read_vec2(const Source& src, int accessor, const std::string& where);
std::vector<Vec4> read_vec4(const Source& src, int accessor, const std::string& where);
/// A COLOR_0 accessor (VEC3 or VEC4, floats or normalized integers) of `vertex_count` elements,
/// linear RGB clamped to [0, 1]; `alpha` tells whether some element's alpha is below 1.
std::vector<Vec3> read_colours(const Source& src, int accessor, size_t vertex_count,
                               const std::string& where, bool& alpha);
/// An index accessor (unsigned byte, short or int scalars), each below `vertex_count`.
std::vector<uint32_t> read_indices(const Source& src, int accessor, size_t vertex_count,
                                   const std::string& where);
/// The number of elements of accessor `index` (checked to exist).
size_t accessor_count(const Source& src, int index, const std::string& where);

/// The bytes of buffer view `index`, checked to lie inside its buffer.
std::vector<uint8_t> buffer_view_bytes(const Source& src, int index, const std::string& where);

}  // namespace rayfarm::gltf
