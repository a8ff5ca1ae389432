// Checkpoint files: a round trip keeps every bit (sums of 128 bits, the merged map, the planner's
// decisions, the error rows); a truncated, corrupt or foreign file is detected and named with its
// cause; two generations alternate, so the newest usable one wins and a broken newest falls back
// to the one before; files of format version 1 are still read; the writer thread writes a 512x512
// film and says how long it took.
#include <gtest/gtest.h>

#include <openssl/evp.h>

#include <chrono>
#include <cstring>
#include <fstream>
#include <random>

#include "master/checkpoint.h"
#include "master/merger.h"
#include "tests/support/temp_dir.h"

namespace rayfarm::master {
namespace {
namespace fs = std::filesystem;
using testing::TempDir;

/// A checkpoint of a `size` x `size` film with random sums that use all 128 bits.
Checkpoint random_checkpoint(uint32_t size, uint64_t sequence, uint32_t seed = 1) {
  std::mt19937_64 rng(seed);
  Checkpoint c;
  c.sequence = sequence;
  c.job_id = "j0042";
  c.width = c.height = size;
  c.tile_size = 16;
  c.spp = 64;
  c.pass_spp = 8;
  c.elapsed_seconds = 12.345678901234567;
  const size_t pixels = size_t{size} * size;
  for (size_t i = 0; i < pixels * 3; ++i) {
    c.sum.push_back(fixed_from_parts(rng(), static_cast<int64_t>(rng())));
    c.sum_sq.push_back(fixed_from_parts(rng(), static_cast<int64_t>(rng() >> 1)));
  }
  c.merged.assign(40, 0);
  c.merged[3] = c.merged[17] = 1;
  c.nonfinite = 7;
  c.rays = 123456789012345;
  c.planner.tiles = {{3, true, false, 0.25, 0.125}, {2, false, true, 1e-4, 3e-4}};
  ErrorRow row;
  row.time_s = 0.1;
  row.spp = 8;
  row.samples_per_s = 1e6;
  row.est_rel_mse = 1.0 / 3.0;
  row.est_rmse = 5e-324;
  row.ref_mae = 0.5;
  c.rows = {row, row};
  c.rows[1].ref_rel_mse = 0.0;
  c.rounds_recorded = 2;
  c.samples_recorded = 99;
  return c;
}

void expect_same_row(const ErrorRow& a, const ErrorRow& b) {
  EXPECT_EQ(a.time_s, b.time_s);
  EXPECT_EQ(a.spp, b.spp);
  EXPECT_EQ(a.samples_per_s, b.samples_per_s);
  EXPECT_EQ(a.est_rel_mse, b.est_rel_mse);
  EXPECT_EQ(a.est_rmse, b.est_rmse);
  EXPECT_EQ(a.ref_rel_mse, b.ref_rel_mse);
  EXPECT_EQ(a.ref_rmse, b.ref_rmse);
  EXPECT_EQ(a.ref_mae, b.ref_mae);
  EXPECT_EQ(a.ref_max, b.ref_max);
}

/// Every field equal, bit for bit.
void expect_same(const Checkpoint& a, const Checkpoint& b) {
  EXPECT_EQ(a.sequence, b.sequence);
  EXPECT_EQ(a.job_id, b.job_id);
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  EXPECT_EQ(a.tile_size, b.tile_size);
  EXPECT_EQ(a.spp, b.spp);
  EXPECT_EQ(a.pass_spp, b.pass_spp);
  EXPECT_EQ(a.elapsed_seconds, b.elapsed_seconds);
  EXPECT_EQ(a.merged, b.merged);
  EXPECT_TRUE(a.sum == b.sum);
  EXPECT_TRUE(a.sum_sq == b.sum_sq);
  EXPECT_EQ(a.nonfinite, b.nonfinite);
  EXPECT_EQ(a.rays, b.rays);
  EXPECT_TRUE(a.planner == b.planner);
  ASSERT_EQ(a.rows.size(), b.rows.size());
  for (size_t i = 0; i < a.rows.size(); ++i) expect_same_row(a.rows[i], b.rows[i]);
  EXPECT_EQ(a.rounds_recorded, b.rounds_recorded);
  EXPECT_EQ(a.samples_recorded, b.samples_recorded);
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void spit(const fs::path& p, const std::string& bytes) {
  std::ofstream(p, std::ios::binary | std::ios::trunc) << bytes;
}

std::string error_of(const std::string& bytes) {
  try {
    decode_checkpoint(bytes);
  } catch (const CheckpointError& e) {
    return e.what();
  }
  return "";
}

/// The bytes a master of format version 1 wrote for `c`: besides version 2's fields, the samples
/// per pixel after the sums, each planner tile's merged count, and the planner's pending units.
std::string encode_version_1(const Checkpoint& c, const std::vector<uint32_t>& pixel_spp,
                             const std::vector<uint32_t>& tile_merged) {
  std::string out("RFCKPT\r\n", 8);
  auto pod = [&](const auto& v) { out.append(reinterpret_cast<const char*>(&v), sizeof v); };
  auto array = [&](const auto& values) {
    pod(uint64_t{values.size()});
    for (const auto& v : values) pod(v);
  };
  pod(uint32_t{1});
  pod(uint64_t{0});
  pod(c.sequence);
  pod(uint64_t{c.job_id.size()});
  out += c.job_id;
  for (uint32_t v : {c.width, c.height, c.tile_size, c.spp, c.pass_spp}) pod(v);
  pod(c.elapsed_seconds);
  array(c.merged);
  array(c.sum);
  array(c.sum_sq);
  array(pixel_spp);
  pod(c.nonfinite);
  pod(c.rays);
  pod(uint64_t{c.planner.tiles.size()});
  for (size_t i = 0; i < c.planner.tiles.size(); ++i) {
    const PlannerState::Tile& t = c.planner.tiles[i];
    pod(t.released);
    pod(tile_merged[i]);
    pod(uint8_t{t.open});
    pod(uint8_t{t.converged});
    pod(t.error);
    pod(t.budget);
  }
  array(std::vector<uint64_t>{});
  pod(uint64_t{c.rows.size()});
  for (const ErrorRow& r : c.rows) {
    for (double v : {r.time_s, r.spp, r.samples_per_s, r.est_rel_mse, r.est_rmse}) pod(v);
    for (const auto* o : {&r.ref_rel_mse, &r.ref_rmse, &r.ref_mae, &r.ref_max}) {
      pod(uint8_t{o->has_value()});
      pod(o->value_or(0.0));
    }
  }
  pod(c.rounds_recorded);
  pod(c.samples_recorded);
  const uint64_t payload = out.size() - 20;
  std::memcpy(out.data() + 12, &payload, sizeof payload);
  unsigned char digest[32];
  unsigned int length = 0;
  EVP_Digest(out.data(), out.size(), digest, &length, EVP_sha256(), nullptr);
  out.append(reinterpret_cast<const char*>(digest), sizeof digest);
  return out;
}

TEST(Checkpoint, RoundTripKeepsEveryBit) {
  const Checkpoint c = random_checkpoint(20, 7);
  const Checkpoint back = decode_checkpoint(encode_checkpoint(c));
  expect_same(back, c);
  EXPECT_TRUE(back.sum[5] == c.sum[5]);  // 128-bit values compare whole
  EXPECT_FALSE(back.rows[0].ref_rel_mse.has_value());
  EXPECT_EQ(back.rows[1].ref_rel_mse, std::optional<double>(0.0));
  EXPECT_EQ(encode_checkpoint(back), encode_checkpoint(c));
}

TEST(Checkpoint, TruncatedCorruptAndForeignFilesAreDetected) {
  const std::string good = encode_checkpoint(random_checkpoint(8, 1));
  ASSERT_EQ(error_of(good), "");
  for (size_t cut : {size_t{0}, size_t{5}, size_t{19}, good.size() / 2, good.size() - 1}) {
    const std::string why = error_of(good.substr(0, cut));
    EXPECT_NE(why.find("truncated"), std::string::npos) << cut << ": " << why;
  }
  // Every single flipped bit in the payload or the digest is caught.
  std::mt19937 rng(3);
  for (int i = 0; i < 200; ++i) {
    std::string bad = good;
    const size_t at = 20 + rng() % (bad.size() - 20);
    bad[at] = static_cast<char>(bad[at] ^ (1 << (rng() % 8)));
    EXPECT_NE(error_of(bad).find("checksum mismatch"), std::string::npos) << at;
  }
  EXPECT_NE(error_of(good + "xx").find("trailing bytes"), std::string::npos);
  std::string magic = good;
  magic[0] = 'X';
  EXPECT_NE(error_of(magic).find("not a rayfarm checkpoint"), std::string::npos);
  std::string version = good;
  version[8] = 9;
  EXPECT_NE(error_of(version).find("format version 9"), std::string::npos);
}

TEST(Checkpoint, AVersion1FileIsStillRead) {
  // A master upgraded in the middle of a job resumes it from the checkpoint the old one wrote.
  const Checkpoint c = random_checkpoint(8, 5);
  const std::string old = encode_version_1(c, std::vector<uint32_t>(64, 16), {2, 2});
  ASSERT_EQ(error_of(old), "");
  expect_same(decode_checkpoint(old), c);
  EXPECT_NE(encode_checkpoint(c), old) << "written in the current version";
  // Its samples-per-pixel array is no longer kept, but still has to be the film's size.
  EXPECT_NE(error_of(encode_version_1(c, std::vector<uint32_t>(63, 16), {2, 2})), "");
}

TEST(Checkpoint, TwoGenerationsAlternateAndTheNewestUsableWins) {
  TempDir dir;
  CheckpointWriter writer;
  for (uint64_t seq = 1; seq <= 3; ++seq) {
    writer.submit(dir.path(), random_checkpoint(8, seq));
    writer.flush();
  }
  // 1 -> slot 0, 2 -> slot 1, 3 -> slot 0.
  EXPECT_EQ(read_checkpoint(checkpoint_path(dir.path(), 0)).sequence, 3u);
  EXPECT_EQ(read_checkpoint(checkpoint_path(dir.path(), 1)).sequence, 2u);
  std::vector<std::string> problems;
  auto newest = load_newest_checkpoint(dir.path(), problems);
  ASSERT_TRUE(newest);
  EXPECT_EQ(newest->checkpoint.sequence, 3u);
  EXPECT_EQ(newest->slot, 0);
  EXPECT_TRUE(problems.empty());

  // The newest truncated: named with its cause, the previous generation is used.
  const fs::path file0 = checkpoint_path(dir.path(), 0);
  const std::string bytes = slurp(file0);
  spit(file0, bytes.substr(0, bytes.size() / 3));
  newest = load_newest_checkpoint(dir.path(), problems);
  ASSERT_TRUE(newest);
  EXPECT_EQ(newest->checkpoint.sequence, 2u);
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_NE(problems[0].find(file0.string() + ": truncated"), std::string::npos) << problems[0];

  // The next write replaces the broken one and keeps the good one.
  writer.set_newest_slot("j0042", newest->slot);
  writer.submit(dir.path(), random_checkpoint(8, 4));
  writer.flush();
  EXPECT_EQ(read_checkpoint(file0).sequence, 4u);
  EXPECT_EQ(read_checkpoint(checkpoint_path(dir.path(), 1)).sequence, 2u);

  // A checkpoint the caller rejects (other settings) falls back too; none at all is nullopt.
  problems.clear();
  newest = load_newest_checkpoint(dir.path(), problems, [](const Checkpoint& c) {
    if (c.sequence == 4) throw CheckpointError("of other settings");
  });
  ASSERT_TRUE(newest);
  EXPECT_EQ(newest->checkpoint.sequence, 2u);
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_NE(problems[0].find("of other settings"), std::string::npos);

  // Temporaries a crash left mid-write go with the checkpoints; other files stay.
  for (const char* name : {"checkpoint-0.bin.tmp", "checkpoint-1.bin.tmp-4242-7", "image.exr"}) {
    spit(dir.path() / name, "left over");
  }
  writer.forget("j0042", dir.path());
  writer.flush();
  EXPECT_FALSE(fs::exists(file0));
  EXPECT_FALSE(fs::exists(dir.path() / "checkpoint-0.bin.tmp"));
  EXPECT_FALSE(fs::exists(dir.path() / "checkpoint-1.bin.tmp-4242-7"));
  EXPECT_TRUE(fs::exists(dir.path() / "image.exr"));
  problems.clear();
  EXPECT_FALSE(load_newest_checkpoint(dir.path(), problems));
  EXPECT_TRUE(problems.empty());
}

TEST(Checkpoint, AMergerRestoresExactlyAndRefusesInconsistentState) {
  const UnitGrid grid({24, 16}, 16, 12, 4);  // 2 tiles x 3 passes
  Merger merger(grid);
  for (uint64_t unit : {0u, 3u, 5u}) {
    const auto u = grid.unit(unit);
    TileResult r(u.rect, u.samples);
    for (size_t i = 0; i < r.sum.size(); ++i) {
      r.sum[i] = to_fixed(0.1 * double(i + unit));
      r.sum_sq[i] = to_fixed(0.01 * (double(i + unit) * double(i + unit) + double(i * unit)));
    }
    r.rays = 10 + unit;
    r.nonfinite = unit;
    ASSERT_EQ(merger.add(unit, r), MergeOutcome::kMerged);
  }
  const Film& f = merger.film();
  Merger restored(grid);
  restored.restore(merger.merged_units().to_bytes(), f.sum(), f.sum_sq(), f.nonfinite(), f.rays());
  EXPECT_EQ(restored.film().sum(), f.sum());
  EXPECT_EQ(restored.film().sum_sq(), f.sum_sq());
  EXPECT_EQ(restored.film().spp(), f.spp());
  EXPECT_EQ(restored.film().rays(), f.rays());
  EXPECT_EQ(restored.film().nonfinite(), f.nonfinite());
  EXPECT_EQ(restored.merged_count(), 3u);
  EXPECT_EQ(restored.samples_merged(), merger.samples_merged());
  EXPECT_EQ(restored.min_spp(), merger.min_spp());
  TileResult again(grid.unit(3).rect, grid.unit(3).samples);
  EXPECT_EQ(restored.add(3, again), MergeOutcome::kDuplicate);

  // Sums without samples (a tile with sums but no merged unit), or a map of another grid.
  std::vector<uint8_t> map = merger.merged_units().to_bytes();
  map[0] = 0;
  EXPECT_THROW(restored.restore(map, f.sum(), f.sum_sq(), 0, 0), std::invalid_argument);
  map.push_back(0);
  EXPECT_THROW(restored.restore(map, f.sum(), f.sum_sq(), 0, 0), std::invalid_argument);
  EXPECT_EQ(restored.merged_count(), 3u) << "a refused restore changes nothing";
}

TEST(Checkpoint, AWriteOf512x512TakesTheWriterThreadNotTheCaller) {
  TempDir dir;
  CheckpointWriter writer;
  Checkpoint c = random_checkpoint(512, 1);
  c.merged.assign(64 * 8, 1);
  const auto start = std::chrono::steady_clock::now();
  const Checkpoint copy = c;  // what the reactor pays: copying the sums
  writer.submit(dir.path(), std::move(c));
  const double submit_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  writer.flush();
  const double written_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() - submit_s;
  const uint64_t bytes = fs::file_size(checkpoint_path(dir.path(), 0));
  EXPECT_GT(bytes, 25'000'000u);
  const auto read_start = std::chrono::steady_clock::now();
  expect_same(read_checkpoint(checkpoint_path(dir.path(), 0)), copy);
  const double read_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - read_start).count();
  std::printf(
      "512x512 checkpoint: %.1f MB; copy + submit %.3f s (reactor), encode + SHA-256 + "
      "write + fsync + rename %.3f s (writer thread), read + verify %.3f s\n",
      bytes / 1e6, submit_s, written_s, read_s);
}

}  // namespace
}  // namespace rayfarm::master
