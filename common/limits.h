#pragma once
// Every cap and default that more than one part of rayfarm relies on, in one place: what the scene
// format accepts, what a job may ask for, and the master's default limits (its options raise or
// lower those). A value used by one file only stays in that file.
#include <cstddef>
#include <cstdint>

namespace rayfarm {

// ---- the scene format (docs/scene-format.md) ---------------------------------------------------

/// Largest scene file read, in bytes.
inline constexpr std::uintmax_t kMaxSceneFileBytes = std::uintmax_t{64} << 20;
/// Largest OBJ file read, in bytes.
inline constexpr std::uintmax_t kMaxObjFileBytes = std::uintmax_t{1} << 30;
/// Largest PLY file read, in bytes.
inline constexpr std::uintmax_t kMaxPlyFileBytes = std::uintmax_t{1} << 30;
/// Most bytes a glTF scene reads: its .gltf or .glb file and every buffer and image file it names.
inline constexpr std::uintmax_t kMaxGltfBytes = std::uintmax_t{1} << 30;
/// Most triangles a glTF file's meshes may hold: a mesh placed by several nodes is stored once
/// and counts once (its instances count towards kMaxInstancedTriangles), unless it is emissive
/// (the renderer stores its triangles once per node).
inline constexpr uint64_t kMaxGltfTriangles = uint64_t{1} << 26;
/// Most JSON objects in a glTF file's JSON (2^22: nodes, meshes, accessors and their parts).
inline constexpr uint64_t kMaxGltfJsonObjects = uint64_t{1} << 22;
/// Most JSON values (elements and members) in a glTF file's JSON.
inline constexpr uint64_t kMaxGltfJsonValues = uint64_t{1} << 24;
/// Most elements of one glTF accessor (3 x 2^26: the indices of the most triangles a file may
/// place); an accessor without a buffer view (all zeros) is held to it too.
inline constexpr uint64_t kMaxGltfAccessorElements = uint64_t{3} << 26;
/// Most vertices a glTF file's meshes may hold (a mesh used by several nodes counts once).
inline constexpr uint64_t kMaxGltfVertices = uint64_t{1} << 26;
/// Most nodes of a glTF file that are visited (each may place a mesh, a camera or a light).
inline constexpr size_t kMaxGltfNodes = size_t{1} << 20;
/// Largest texture image file read (PNG, JPEG, OpenEXR, HDR).
inline constexpr std::uintmax_t kMaxTextureFileBytes = std::uintmax_t{1} << 28;
/// Most bytes of samples that a scene's texture images may hold together, once decoded (8-bit
/// files one byte per sample, 16-bit PNG, OpenEXR and HDR four): what a worker keeps in memory.
inline constexpr uint64_t kMaxSceneTextureBytes = uint64_t{2} << 30;
/// Largest MTL file read, in bytes.
inline constexpr std::uintmax_t kMaxMtlFileBytes = std::uintmax_t{16} << 20;
/// Deepest nesting of JSON arrays and objects read.
inline constexpr int kMaxJsonNesting = 64;
/// Largest magnitude of any number in a scene, OBJ or MTL file.
inline constexpr double kMaxAbsNumber = 1e30;
/// Largest coordinate or length of geometry: every point of a scene (a quad's far corner, a
/// sphere's surface, a thin lens) then stays well inside the range that Embree traces, +-1.8e18.
inline constexpr double kMaxCoordinate = 1e17;
/// Largest side of a scene's film, in pixels.
inline constexpr int64_t kMaxFilmSide = 16384;
/// Most pixels of a scene's film (2^26).
inline constexpr int64_t kMaxFilmPixels = int64_t{1} << 26;

/// Largest side of an image texture (PNG, JPEG, OpenEXR, Radiance HDR), in pixels; checked from
/// the file's header before any pixel is allocated.
inline constexpr int64_t kMaxTextureSide = 16384;
/// Most pixels of an image texture (2^26: 256 MiB as 8-bit RGBA, 1 GiB as float RGBA).
inline constexpr int64_t kMaxTexturePixels = int64_t{1} << 26;

/// Most instances (placements of a mesh group) in one scene: each costs little memory, but the
/// master and every worker hold a record and an acceleration structure entry per instance.
inline constexpr uint64_t kMaxInstances = uint64_t{1} << 20;
/// Most triangles the instances of one scene place in the world (each instance counts its
/// group's triangles): not memory, but what the rays traverse and the area lights enumerate.
inline constexpr uint64_t kMaxInstancedTriangles = uint64_t{1} << 36;
/// Most triangles that instances of emissive groups place: those are copied into the world as
/// triangles of their own (area lights need them), so they cost memory per instance.
inline constexpr uint64_t kMaxEmissiveInstancedTriangles = uint64_t{1} << 26;

// ---- rendering
// -----------------------------------------------------------------------------------

/// Most samples per pixel a scene or a job may ask for.
inline constexpr uint32_t kMaxSpp = uint32_t{1} << 24;
/// Most scattering vertices per path a scene or a job may ask for as a number; beyond it, only
/// "unlimited" (kUnlimitedDepth).
inline constexpr uint32_t kMaxDepth = 1000000;
/// max_depth "unlimited": no cap, Russian roulette alone ends paths.
inline constexpr uint32_t kUnlimitedDepth = 0xffffffffu;
/// Samples per pixel when the scene does not say.
inline constexpr uint32_t kDefaultSpp = 64;
/// Scattering vertices per path when the scene does not say: no cap.
inline constexpr uint32_t kDefaultMaxDepth = kUnlimitedDepth;
/// Vertex from which throughput roulette may end paths when the scene does not say.
inline constexpr uint32_t kDefaultRouletteDepth = 5;
/// Most a roulette_depth may be.
inline constexpr uint32_t kMaxRouletteDepth = 1000000;
/// Most frames a shutter may reach before or after its frame (RenderSettings::shutter_open and
/// shutter_close).
inline constexpr double kMaxShutterFrames = 100.0;
/// Time steps at which a scene is loaded within an open shutter: the fewest, the most, and how
/// many when the scene does not say (docs/scene-format.md, "Motion blur").
inline constexpr uint32_t kMinMotionSteps = 2;
inline constexpr uint32_t kMaxMotionSteps = 64;
inline constexpr uint32_t kDefaultMotionSteps = 5;
/// Tile side in pixels when the job or the command line does not choose one (docs/protocol.md).
inline constexpr uint32_t kDefaultTileSize = 64;
/// Largest tile side a job may choose.
inline constexpr uint32_t kMaxTileSize = 4096;

// ---- sharing the farm (docs/farm.md, "Sharing the farm: priorities, fair shares, pausing")
/// A job's priority: higher runs first; jobs are submitted at 0 unless they say otherwise.
inline constexpr int32_t kMinPriority = -100;
inline constexpr int32_t kMaxPriority = 100;

// ---- the master's limits on submissions (master/limits.h; each has a master option)
// ---------------

/// Largest message a master socket accepts. --max-message-mb
inline constexpr int64_t kDefaultMaxMessageBytes = int64_t{1} << 30;
/// Largest scene bundle. --max-bundle-mb
inline constexpr uint64_t kDefaultMaxBundleBytes = uint64_t{256} << 20;
/// Most files in a scene bundle. --max-bundle-files
inline constexpr uint64_t kDefaultMaxBundleFiles = 4096;
/// Most pixels of a job's image: 33.5 Mpx, 8K UHD (7680x4320) fits. --max-image-pixels
inline constexpr uint64_t kDefaultMaxImagePixels = uint64_t{1} << 25;
/// Most samples per pixel of a job. --max-spp
inline constexpr uint32_t kDefaultMaxJobSpp = 1u << 16;
/// Most jobs queued or running at once. --max-queued-jobs
inline constexpr size_t kDefaultMaxQueuedJobs = 1000;

}  // namespace rayfarm
