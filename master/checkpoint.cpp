#include "master/checkpoint.h"
#include "master/metrics.h"

#include "common/util/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <system_error>

#include "common/util/log.h"
#include "common/util/read_file.h"
#include "common/util/sha256.h"

namespace rayfarm::master {
namespace fs = std::filesystem;
namespace {

static_assert(std::endian::native == std::endian::little,
              "checkpoints are written in the machine's byte order, which must be little-endian");

constexpr char kMagic[8] = {'R', 'F', 'C', 'K', 'P', 'T', '\r', '\n'};
constexpr size_t kHeaderSize = 8 + 4 + 8;
constexpr size_t kDigestSize = 32;

using Digest = Sha256Digest;

/// Appends little-endian fields to a byte string.
class Writer {
 public:
  explicit Writer(std::string& out) : out_(out) {}
  template <class T>
  void pod(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>);
    out_.append(reinterpret_cast<const char*>(&value), sizeof value);
  }
  template <class T>
  void array(const std::vector<T>& values) {
    pod(uint64_t{values.size()});
    if (!values.empty()) {
      out_.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
    }
  }
  void string(const std::string& s) {
    pod(uint64_t{s.size()});
    out_.append(s);
  }

 private:
  std::string& out_;
};

/// Reads what Writer wrote, with bounds checks naming the field.
class Reader {
 public:
  Reader(const char* data, size_t size) : data_(data), size_(size) {}
  template <class T>
  T pod(const char* field) {
    T value;
    need(sizeof value, field);
    std::memcpy(&value, data_ + pos_, sizeof value);
    pos_ += sizeof value;
    return value;
  }
  template <class T>
  std::vector<T> array(const char* field) {
    const uint64_t count = pod<uint64_t>(field);
    if (count > (size_ - pos_) / sizeof(T)) fail(field, "its length runs past the end");
    std::vector<T> values(count);
    if (count > 0) std::memcpy(values.data(), data_ + pos_, count * sizeof(T));
    pos_ += count * sizeof(T);
    return values;
  }
  std::string string(const char* field) {
    const uint64_t count = pod<uint64_t>(field);
    if (count > size_ - pos_) fail(field, "its length runs past the end");
    std::string s(data_ + pos_, count);
    pos_ += count;
    return s;
  }
  bool done() const { return pos_ == size_; }
  size_t position() const { return pos_; }
  [[noreturn]] void fail(const char* field, const std::string& why) const {
    throw CheckpointError("malformed payload at byte " + std::to_string(kHeaderSize + pos_) + " (" +
                          field + "): " + why);
  }

 private:
  const char* data_;
  size_t size_;
  size_t pos_ = 0;

  void need(size_t n, const char* field) const {
    if (n > size_ - pos_) fail(field, "it runs past the end");
  }
};

// Payload fields, in this order.
void encode_payload(const Checkpoint& c, Writer& w) {
  w.pod(c.sequence);
  w.string(c.job_id);
  w.pod(c.width);
  w.pod(c.height);
  w.pod(c.tile_size);
  w.pod(c.spp);
  w.pod(c.pass_spp);
  w.pod(c.elapsed_seconds);
  w.array(c.merged);
  w.array(c.sum);
  w.array(c.sum_sq);
  w.pod(c.nonfinite);
  w.pod(c.rays);
  w.pod(uint64_t{c.planner.tiles.size()});
  for (const PlannerState::Tile& t : c.planner.tiles) {
    w.pod(t.released);
    w.pod(uint8_t{t.open});
    w.pod(uint8_t{t.converged});
    w.pod(t.error);
    w.pod(t.budget);
  }
  w.pod(uint64_t{c.rows.size()});
  for (const ErrorRow& r : c.rows) {
    w.pod(r.time_s);
    w.pod(r.spp);
    w.pod(r.samples_per_s);
    w.pod(r.est_rel_mse);
    w.pod(r.est_rmse);
    for (const auto* o : {&r.ref_rel_mse, &r.ref_rmse, &r.ref_mae, &r.ref_max}) {
      w.pod(uint8_t{o->has_value()});
      w.pod(o->value_or(0.0));
    }
  }
  w.pod(c.rounds_recorded);
  w.pod(c.samples_recorded);
}

bool read_bool(Reader& r, const char* field) {
  const uint8_t v = r.pod<uint8_t>(field);
  if (v > 1) r.fail(field, "not 0 or 1");
  return v == 1;
}

/// Decodes a payload of `version` (1 or kCheckpointVersion).
Checkpoint decode_payload(Reader& r, uint32_t version) {
  const bool v1 = version == 1;
  Checkpoint c;
  c.sequence = r.pod<uint64_t>("sequence");
  c.job_id = r.string("job id");
  c.width = r.pod<uint32_t>("width");
  c.height = r.pod<uint32_t>("height");
  c.tile_size = r.pod<uint32_t>("tile size");
  c.spp = r.pod<uint32_t>("spp");
  c.pass_spp = r.pod<uint32_t>("pass spp");
  c.elapsed_seconds = r.pod<double>("elapsed seconds");
  c.merged = r.array<uint8_t>("merged units");
  c.sum = r.array<Fixed>("sums");
  c.sum_sq = r.array<Fixed>("sums of squares");
  // Version 1 also stored the samples per pixel, which the merged map says: checked, not kept.
  const size_t v1_pixel_spp = v1 ? r.array<uint32_t>("samples per pixel").size() : 0;
  c.nonfinite = r.pod<uint64_t>("nonfinite");
  c.rays = r.pod<uint64_t>("rays");
  const uint64_t tiles = r.pod<uint64_t>("planner tiles");
  if (tiles > (uint64_t{1} << 32)) r.fail("planner tiles", "too many");
  for (uint64_t i = 0; i < tiles; ++i) {
    PlannerState::Tile t;
    t.released = r.pod<uint32_t>("planner tile");
    if (v1) r.pod<uint32_t>("planner tile");  // merged units: what the merged map says
    t.open = read_bool(r, "planner tile");
    t.converged = read_bool(r, "planner tile");
    t.error = r.pod<double>("planner tile");
    t.budget = r.pod<double>("planner tile");
    c.planner.tiles.push_back(t);
  }
  if (v1) r.array<uint64_t>("planner pending units");  // always empty
  const uint64_t rows = r.pod<uint64_t>("error rows");
  if (rows > (uint64_t{1} << 32)) r.fail("error rows", "too many");
  for (uint64_t i = 0; i < rows; ++i) {
    ErrorRow row;
    row.time_s = r.pod<double>("error row");
    row.spp = r.pod<double>("error row");
    row.samples_per_s = r.pod<double>("error row");
    row.est_rel_mse = r.pod<double>("error row");
    row.est_rmse = r.pod<double>("error row");
    for (auto* o : {&row.ref_rel_mse, &row.ref_rmse, &row.ref_mae, &row.ref_max}) {
      const bool has = read_bool(r, "error row");
      const double v = r.pod<double>("error row");
      if (has) *o = v;
    }
    c.rows.push_back(row);
  }
  c.rounds_recorded = r.pod<uint32_t>("rounds recorded");
  c.samples_recorded = r.pod<uint64_t>("samples recorded");
  if (!r.done()) r.fail("end", "bytes left over after the last field");
  // Sizes that must agree with each other (agreement with the job is the caller's check).
  const uint64_t pixels = uint64_t{c.width} * c.height;
  if (c.sum.size() != pixels * 3 || c.sum_sq.size() != pixels * 3 ||
      (v1 && v1_pixel_spp != pixels)) {
    throw CheckpointError("malformed payload: the film's arrays do not match its size " +
                          std::to_string(c.width) + "x" + std::to_string(c.height));
  }
  for (uint8_t m : c.merged) {
    if (m > 1)
      throw CheckpointError("malformed payload: the merged-unit map holds a value not 0 or 1");
  }
  return c;
}

std::shared_ptr<spdlog::logger> log_jobs() { return get_logger("jobs"); }

}  // namespace

std::string encode_checkpoint(const Checkpoint& checkpoint) {
  std::string out;
  out.reserve(kHeaderSize + kDigestSize + checkpoint.sum.size() * sizeof(Fixed) * 2 +
              checkpoint.merged.size() + 4096);
  out.append(kMagic, sizeof kMagic);
  Writer w(out);
  w.pod(kCheckpointVersion);
  w.pod(uint64_t{0});  // payload size, filled in below
  encode_payload(checkpoint, w);
  const uint64_t payload = out.size() - kHeaderSize;
  std::memcpy(out.data() + 12, &payload, sizeof payload);
  const Digest digest = sha256(out);
  out.append(reinterpret_cast<const char*>(digest.data()), digest.size());
  return out;
}

Checkpoint decode_checkpoint(const std::string& bytes) {
  if (bytes.size() < kHeaderSize) {
    throw CheckpointError("truncated: " + std::to_string(bytes.size()) +
                          " bytes, shorter than the header");
  }
  if (std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0) {
    throw CheckpointError("not a rayfarm checkpoint (wrong magic bytes)");
  }
  uint32_t version = 0;
  uint64_t payload = 0;
  std::memcpy(&version, bytes.data() + 8, sizeof version);
  std::memcpy(&payload, bytes.data() + 12, sizeof payload);
  if (version != kCheckpointVersion && version != 1) {
    throw CheckpointError("format version " + std::to_string(version) +
                          ", this master reads 1 to " + std::to_string(kCheckpointVersion));
  }
  const uint64_t available = bytes.size() - kHeaderSize;
  if (payload > available || available - payload != kDigestSize) {
    const bool short_file = payload > available || available - payload < kDigestSize;
    throw CheckpointError(std::string(short_file ? "truncated" : "trailing bytes") + ": " +
                          std::to_string(bytes.size()) + " bytes, the header announces " +
                          std::to_string(payload + kHeaderSize + kDigestSize));
  }
  const Digest digest = sha256(std::string_view(bytes).substr(0, kHeaderSize + payload));
  if (std::memcmp(digest.data(), bytes.data() + kHeaderSize + payload, kDigestSize) != 0) {
    throw CheckpointError("checksum mismatch (SHA-256): the file is corrupt");
  }
  Reader r(bytes.data() + kHeaderSize, payload);
  return decode_payload(r, version);
}

fs::path checkpoint_path(const fs::path& job_dir, int slot) {
  return job_dir / ("checkpoint-" + std::to_string(slot) + ".bin");
}

Checkpoint read_checkpoint(const fs::path& path) {
  std::string bytes;
  try {
    bytes = read_whole_file(path, kNoSizeCap);
  } catch (const FileReadError& e) {
    throw CheckpointError(path.string() + ": " + e.what());
  }
  try {
    return decode_checkpoint(bytes);
  } catch (const CheckpointError& e) {
    throw CheckpointError(path.string() + ": " + e.what());
  }
}

std::optional<LoadedCheckpoint> load_newest_checkpoint(
    const fs::path& job_dir, std::vector<std::string>& problems,
    const std::function<void(const Checkpoint&)>& accept) {
  std::vector<LoadedCheckpoint> usable;
  for (int slot = 0; slot < 2; ++slot) {
    const fs::path file = checkpoint_path(job_dir, slot);
    std::error_code ec;
    if (!fs::exists(file, ec)) continue;
    try {
      Checkpoint c = read_checkpoint(file);
      if (accept) {
        try {
          accept(c);
        } catch (const CheckpointError& e) {
          throw CheckpointError(file.string() + ": " + e.what());
        }
      }
      usable.push_back({std::move(c), slot, file});
    } catch (const CheckpointError& e) {
      problems.push_back(e.what());
    }
  }
  if (usable.empty()) return std::nullopt;
  if (usable.size() == 2 && usable[0].checkpoint.sequence > usable[1].checkpoint.sequence) {
    return std::move(usable[0]);
  }
  return std::move(usable.back());
}

void remove_checkpoints(const fs::path& job_dir) {
  std::error_code ec;
  for (int slot = 0; slot < 2; ++slot) fs::remove(checkpoint_path(job_dir, slot), ec);
  // Temporaries a crash left mid-write: "checkpoint-N.bin.tmp" (older masters) and
  // "checkpoint-N.bin.tmp-PID-SEQ" (write_file_atomically).
  std::vector<fs::path> leftovers;
  for (fs::directory_iterator it(job_dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind("checkpoint-", 0) == 0 && name.find(".bin.tmp") != std::string::npos) {
      leftovers.push_back(it->path());
    }
  }
  for (const fs::path& path : leftovers) fs::remove(path, ec);
}

// --- CheckpointWriter ---

void CheckpointWriter::submit(const fs::path& job_dir, Checkpoint checkpoint) {
  const std::string id = checkpoint.job_id;
  tasks_.submit(Task{job_dir, std::move(checkpoint)}, [&](const Task& waiting) {
    return !waiting.remove && waiting.checkpoint.job_id == id;
  });
}

void CheckpointWriter::set_newest_slot(const std::string& job_id, int slot) {
  std::lock_guard lock(mutex_);
  newest_slot_[job_id] = slot;
}

void CheckpointWriter::flush() { tasks_.flush(); }

void CheckpointWriter::forget(const std::string& job_id, const fs::path& job_dir) {
  tasks_.discard([&](const Task& waiting) { return waiting.checkpoint.job_id == job_id; });
  Task task;
  task.job_dir = job_dir;
  task.checkpoint.job_id = job_id;
  task.remove = true;
  tasks_.submit(std::move(task), [](const Task&) { return false; });
}

double CheckpointWriter::seconds(const std::string& job_id) const {
  std::lock_guard lock(mutex_);
  auto it = seconds_.find(job_id);
  return it == seconds_.end() ? 0.0 : it->second;
}

std::string CheckpointWriter::failure(const std::string& job_id) const {
  std::lock_guard lock(mutex_);
  auto it = failures_.find(job_id);
  return it == failures_.end() ? std::string() : it->second;
}

void CheckpointWriter::write(Task& task) {
  const std::string& id = task.checkpoint.job_id;
  if (task.remove) {
    {
      std::lock_guard lock(mutex_);
      newest_slot_.erase(id);
      seconds_.erase(id);
    }
    remove_checkpoints(task.job_dir);  // no error: what is left is ignored for a finished job
    return;
  }
  int slot = 0;
  {
    std::lock_guard lock(mutex_);
    auto newest = newest_slot_.find(id);
    slot = newest == newest_slot_.end() ? 0 : 1 - newest->second;
  }
  const auto start = std::chrono::steady_clock::now();
  bool ok = false;
  size_t bytes = 0;
  std::string failure;
  try {
    const std::string encoded = encode_checkpoint(task.checkpoint);
    bytes = encoded.size();
    write_file_atomically(checkpoint_path(task.job_dir, slot), encoded, Sync::kFileAndFolder);
    ok = true;
  } catch (const std::exception& e) {
    failure = e.what();
    log_jobs()->error("job {}: checkpoint {} not written: {}", id, task.checkpoint.sequence,
                      e.what());
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (ok) {
    metrics().checkpoint_seconds.observe(seconds);
    log_jobs()->debug("job {}: checkpoint {} written to {} ({:.1f} MB in {:.3f} s)", id,
                      task.checkpoint.sequence, checkpoint_path(task.job_dir, slot).string(),
                      bytes / 1e6, seconds);
  }
  std::lock_guard lock(mutex_);
  seconds_[id] = seconds;
  if (ok) {
    failures_.erase(id);
  } else {
    failures_[id] = failure;
  }
  if (ok) newest_slot_[id] = slot;
}

}  // namespace rayfarm::master
