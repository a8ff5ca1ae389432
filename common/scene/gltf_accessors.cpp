#include "common/scene/gltf_accessors.h"

#include "common/limits.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>

#include "common/scene/scene_files.h"

namespace rayfarm::gltf {

static_assert(std::endian::native == std::endian::little,
              "glTF buffers are little-endian and are read as they lie in memory");

void Source::fail(const std::string& where, const std::string& what) const {
  throw SceneError(display + ": " + where + ": " + what);
}

void Source::warn(const std::string& where, const std::string& what) const {
  warnings->push_back(display + ": " + where + ": " + what);
}

namespace {

/// Bytes of one component, or 0 for a type the format does not define.
size_t component_bytes(int type) {
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return 2;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return 4;
    default:
      return 0;
  }
}

int type_components(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR:
      return 1;
    case TINYGLTF_TYPE_VEC2:
      return 2;
    case TINYGLTF_TYPE_VEC3:
      return 3;
    case TINYGLTF_TYPE_VEC4:
      return 4;
    default:
      return 0;  // matrices are never vertex attributes or indices here
  }
}

/// A checked accessor: element i's component c lies at data + i * stride + c * size.
struct View {
  const uint8_t* data = nullptr;  ///< null: no buffer view, every element is zero
  size_t count = 0;
  size_t stride = 0;
  size_t size = 0;  ///< of one component
  int component_type = 0;
  int components = 0;
  bool normalized = false;
  /// A sparse accessor's substitutions: for element i, its row in `values` (kNotSubstituted
  /// where the base element stands); empty when the accessor is not sparse.
  std::vector<uint32_t> sparse_row;
  const uint8_t* values = nullptr;  ///< tightly packed elements of the same type
};
constexpr uint32_t kNotSubstituted = UINT32_MAX;

/// Element i's first byte, or null where it is zero (no buffer view, no substitution).
const uint8_t* element(const View& v, size_t i) {
  if (!v.sparse_row.empty() && v.sparse_row[i] != kNotSubstituted)
    return v.values + size_t{v.sparse_row[i]} * v.size * static_cast<size_t>(v.components);
  return v.data == nullptr ? nullptr : v.data + i * v.stride;
}

std::string accessor_name(int index) { return "accessors[" + std::to_string(index) + "]"; }

const tinygltf::Accessor& accessor_at(const Source& src, int index, const std::string& where) {
  const auto& accessors = src.model->accessors;
  if (index < 0 || static_cast<size_t>(index) >= accessors.size()) {
    src.fail(where, "accessor " + std::to_string(index) + " does not exist (the file has " +
                        std::to_string(accessors.size()) + ")");
  }
  return accessors[static_cast<size_t>(index)];
}

/// Checks a buffer view against its buffer; returns its first byte and sets `length`.
const uint8_t* view_span(const Source& src, int index, const std::string& where, size_t& length) {
  const auto& views = src.model->bufferViews;
  const std::string name = "bufferViews[" + std::to_string(index) + "]";
  if (index < 0 || static_cast<size_t>(index) >= views.size())
    src.fail(where, name + " does not exist (the file has " + std::to_string(views.size()) + ")");
  const tinygltf::BufferView& view = views[static_cast<size_t>(index)];
  const auto& buffers = src.model->buffers;
  if (view.buffer < 0 || static_cast<size_t>(view.buffer) >= buffers.size())
    src.fail(name, "buffer " + std::to_string(view.buffer) + " does not exist");
  const std::vector<unsigned char>& data = buffers[static_cast<size_t>(view.buffer)].data;
  // Sums in 64 bits of values each below 2^53: no overflow.
  if (view.byteOffset > data.size() || view.byteLength > data.size() - view.byteOffset) {
    src.fail(name, "bytes " + std::to_string(view.byteOffset) + " to " +
                       std::to_string(uint64_t(view.byteOffset) + view.byteLength) +
                       " lie outside buffer " + std::to_string(view.buffer) + " of " +
                       std::to_string(data.size()) + " bytes");
  }
  length = view.byteLength;
  return data.data() + view.byteOffset;
}

/// Reads a sparse accessor's indices and values into `v` (whose type and count are set), each
/// checked against its buffer view and the accessor's count.
void read_sparse(const Source& src, const tinygltf::Accessor& a, const std::string& name, View& v) {
  const std::string at = name + "/sparse";
  const auto count = static_cast<size_t>(std::max(a.sparse.count, 0));
  if (a.sparse.count < 1 || count > v.count)
    src.fail(at + "/count", std::to_string(a.sparse.count) + " must lie in [1, " +
                                std::to_string(v.count) + "], the accessor's count");
  // Both arrays are tightly packed in their buffer views, after their offsets.
  auto packed = [&](int view, int offset, size_t element_bytes, const std::string& what) {
    size_t length = 0;
    const uint8_t* base = view_span(src, view, at + "/" + what, length);
    if (offset < 0 || static_cast<size_t>(offset) > length ||
        count > (length - static_cast<size_t>(offset)) / element_bytes) {
      src.fail(at + "/" + what, std::to_string(count) + " elements of " +
                                    std::to_string(element_bytes) + " bytes do not fit in " +
                                    "bufferViews[" + std::to_string(view) + "] after byte " +
                                    std::to_string(offset));
    }
    return base + offset;
  };
  const int index_type = a.sparse.indices.componentType;
  const size_t index_size = index_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE    ? 1
                            : index_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ? 2
                            : index_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT   ? 4
                                                                                   : 0;
  if (index_size == 0)
    src.fail(at + "/indices/componentType", "must be an unsigned byte, short or int");
  const uint8_t* indices =
      packed(a.sparse.indices.bufferView, a.sparse.indices.byteOffset, index_size, "indices");
  v.values = packed(a.sparse.values.bufferView, a.sparse.values.byteOffset,
                    v.size * static_cast<size_t>(v.components), "values");
  v.sparse_row.assign(v.count, kNotSubstituted);
  uint64_t previous = 0;
  for (size_t k = 0; k < count; ++k) {
    uint32_t index = 0;
    std::memcpy(&index, indices + k * index_size, index_size);  // little-endian
    if (index >= v.count || (k > 0 && index <= previous))
      src.fail(at + "/indices", "index " + std::to_string(k) + " is " + std::to_string(index) +
                                    ": indices must increase and stay below the count " +
                                    std::to_string(v.count));
    previous = index;
    v.sparse_row[index] = static_cast<uint32_t>(k);
  }
}

View checked_view(const Source& src, int index, const std::string& where) {
  const tinygltf::Accessor& a = accessor_at(src, index, where);
  const std::string name = accessor_name(index);
  View v;
  v.component_type = a.componentType;
  v.size = component_bytes(a.componentType);
  if (v.size == 0) src.fail(name, "unknown componentType " + std::to_string(a.componentType));
  v.components = type_components(a.type);
  if (v.components == 0) src.fail(name, "a matrix or unknown type where a vector was expected");
  v.count = a.count;
  // Before anything is allocated for it: an accessor without a buffer view costs no bytes of
  // the file, whatever count it declares.
  if (v.count > kMaxGltfAccessorElements)
    src.fail(name, "count " + std::to_string(v.count) + " exceeds the limit of " +
                       std::to_string(kMaxGltfAccessorElements) + " elements");
  v.normalized = a.normalized;
  const size_t element = v.size * static_cast<size_t>(v.components);
  v.stride = element;
  if (a.sparse.isSparse) read_sparse(src, a, name, v);
  if (a.bufferView < 0) return v;  // all zeros but the substitutions, as the specification says
  size_t length = 0;
  const uint8_t* base = view_span(src, a.bufferView, name, length);
  const auto& bv = src.model->bufferViews[static_cast<size_t>(a.bufferView)];
  if (bv.byteStride != 0) {
    if (bv.byteStride < element || bv.byteStride > 252)
      src.fail(name, "byteStride " + std::to_string(bv.byteStride) + " of its buffer view is " +
                         "outside [" + std::to_string(element) + ", 252]");
    v.stride = bv.byteStride;
  }
  if (a.byteOffset > length)
    src.fail(name, "byteOffset " + std::to_string(a.byteOffset) + " lies past its buffer view");
  if (v.count > 0) {
    const size_t room = length - a.byteOffset;
    // Last element's end: (count - 1) * stride + element, checked without overflow.
    if (element > room || (v.count - 1) > (room - element) / v.stride) {
      src.fail(name, std::to_string(v.count) + " elements of " + std::to_string(element) +
                         " bytes (stride " + std::to_string(v.stride) + ") do not fit in the " +
                         std::to_string(room) + " bytes its buffer view holds after its offset");
    }
  }
  v.data = base + a.byteOffset;
  return v;
}

/// Component c of element i as a float: normalized integers to [0, 1] or [-1, 1].
float component(const View& v, size_t i, int c) {
  const uint8_t* first = element(v, i);
  if (first == nullptr) return 0.f;
  const uint8_t* p = first + static_cast<size_t>(c) * v.size;
  switch (v.component_type) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: {
      float f;
      std::memcpy(&f, p, 4);
      return f;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return v.normalized ? float(*p) / 255.f : float(*p);
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      const auto b = static_cast<int8_t>(*p);
      return v.normalized ? std::max(float(b) / 127.f, -1.f) : float(b);
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      uint16_t s;
      std::memcpy(&s, p, 2);
      return v.normalized ? float(s) / 65535.f : float(s);
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      int16_t s;
      std::memcpy(&s, p, 2);
      return v.normalized ? std::max(float(s) / 32767.f, -1.f) : float(s);
    }
    default: {  // unsigned int
      uint32_t u;
      std::memcpy(&u, p, 4);
      return float(u);
    }
  }
}

}  // namespace

size_t accessor_count(const Source& src, int index, const std::string& where) {
  return accessor_at(src, index, where).count;
}

std::vector<float> read_floats(const Source& src, int accessor, int components,
                               const std::string& where) {
  const View v = checked_view(src, accessor, where);
  const std::string name = accessor_name(accessor);
  if (v.components != components) {
    src.fail(name, "has " + std::to_string(v.components) + " components per element, " + where +
                       " needs " + std::to_string(components));
  }
  std::vector<float> out;
  out.reserve(v.count * static_cast<size_t>(components));
  for (size_t i = 0; i < v.count; ++i) {
    for (int c = 0; c < components; ++c) {
      const float x = component(v, i, c);
      if (!std::isfinite(x) || std::fabs(x) > 1e30f)
        src.fail(name, "element " + std::to_string(i) + " is not finite or exceeds 1e30");
      out.push_back(x);
    }
  }
  return out;
}

std::vector<Vec3> read_vec3(const Source& src, int accessor, const std::string& where) {
  const std::vector<float> f = read_floats(src, accessor, 3, where);
  std::vector<Vec3> out(f.size() / 3);
  for (size_t i = 0; i < out.size(); ++i) out[i] = {f[3 * i], f[3 * i + 1], f[3 * i + 2]};
  return out;
}

std::vector<Vec2> read_vec2(const Source& src, int accessor, const std::string& where) {
  const std::vector<float> f = read_floats(src, accessor, 2, where);
  std::vector<Vec2> out(f.size() / 2);
  for (size_t i = 0; i < out.size(); ++i) out[i] = {f[2 * i], f[2 * i + 1]};
  return out;
}

std::vector<Vec4> read_vec4(const Source& src, int accessor, const std::string& where) {
  const std::vector<float> f = read_floats(src, accessor, 4, where);
  std::vector<Vec4> out(f.size() / 4);
  for (size_t i = 0; i < out.size(); ++i)
    out[i] = {f[4 * i], f[4 * i + 1], f[4 * i + 2], f[4 * i + 3]};
  return out;
}

std::vector<Vec3> read_colours(const Source& src, int accessor, size_t vertex_count,
                               const std::string& where, bool& alpha) {
  const tinygltf::Accessor& a = accessor_at(src, accessor, where);
  if (a.count != vertex_count)
    src.fail(where, std::to_string(a.count) + " elements, but POSITION has " +
                        std::to_string(vertex_count));
  if (a.type != TINYGLTF_TYPE_VEC3 && a.type != TINYGLTF_TYPE_VEC4)
    src.fail(where, "must be a VEC3 or VEC4 accessor");
  const int components = a.type == TINYGLTF_TYPE_VEC4 ? 4 : 3;
  const std::vector<float> f = read_floats(src, accessor, components, where);
  const auto unit = [](float v) { return std::clamp(v, 0.f, 1.f); };
  std::vector<Vec3> out(vertex_count);
  alpha = false;
  for (size_t i = 0; i < vertex_count; ++i) {
    const float* c = &f[i * size_t(components)];
    out[i] = Vec3(unit(c[0]), unit(c[1]), unit(c[2]));
    alpha |= components == 4 && c[3] < 1.f;
  }
  return out;
}

std::vector<uint32_t> read_indices(const Source& src, int accessor, size_t vertex_count,
                                   const std::string& where) {
  const View v = checked_view(src, accessor, where);
  const std::string name = accessor_name(accessor);
  if (v.components != 1) src.fail(name, "indices must be scalars");
  if (v.component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
      v.component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
      v.component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
    src.fail(name, "indices must be unsigned bytes, shorts or ints");
  }
  std::vector<uint32_t> out(v.count);
  for (size_t i = 0; i < v.count; ++i) {
    uint32_t index = 0;
    if (const uint8_t* p = element(v, i); p != nullptr) {
      if (v.size == 1) {
        index = *p;
      } else if (v.size == 2) {
        uint16_t s;
        std::memcpy(&s, p, 2);
        index = s;
      } else {
        std::memcpy(&index, p, 4);
      }
    }
    if (index >= vertex_count) {
      src.fail(name, "index " + std::to_string(i) + " is " + std::to_string(index) + ", past the " +
                         std::to_string(vertex_count) + " vertices of " + where);
    }
    out[i] = index;
  }
  return out;
}

std::vector<uint8_t> buffer_view_bytes(const Source& src, int index, const std::string& where) {
  size_t length = 0;
  const uint8_t* p = view_span(src, index, where, length);
  return std::vector<uint8_t>(p, p + length);
}

}  // namespace rayfarm::gltf
