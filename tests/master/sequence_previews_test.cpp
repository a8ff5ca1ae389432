// A sequence's previews: its contact sheet grows as frames finish, its movie is made by a real
// ffmpeg once every frame is done (and only the movie is skipped when ffmpeg is missing, fails or
// hangs), both are fetched through the job manager, and a restart makes what is missing.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <fstream>

#include "common/bundle/bundle.h"
#include "common/image/contact_sheet.h"
#include "common/image/decode_image.h"
#include "common/protocol/convert.h"
#include "common/util/read_file.h"
#include "master/job_manager.h"
#include "tests/master/job_requests.h"
#include "tests/support/temp_dir.h"

namespace rayfarm::master {
namespace {

namespace fs = std::filesystem;
using testing::TempDir;

/// Frames 1, 3, 5 of the bundled animation at 15x9 (odd sides: the movie pads them), one unit
/// a frame.
wire::SubmitJob three_frames() {
  const PackedScene packed =
      pack_scene(fs::path(RAYFARM_SOURCE_DIR) / "scenes" / "animated-box" / "scene.json");
  wire::SubmitJob request;
  protocol::bundle_to_wire(packed.bundle, request.mutable_bundle());
  request.set_scene_path(packed.scene_path);
  wire::JobOverrides* o = request.mutable_overrides();
  o->set_spp(1);
  o->set_tile_size(16);
  o->set_width(15);
  o->set_height(9);
  *request.mutable_frames() = protocol::frames_to_wire({1, 5, 2});
  return request;
}

/// Renders (with fake results of `value`) the next frame of the sequence and waits until it is
/// done.
void finish_next_frame(JobManager& jobs, double value) {
  const auto unit = jobs.next_unit("w1");
  ASSERT_TRUE(unit);
  ASSERT_EQ(jobs.on_result("w1", test_jobs::result_for(*unit, value)), MergeOutcome::kMerged);
  test_jobs::tick_while_running(jobs, unit->job_id());
  ASSERT_EQ(jobs.status(unit->job_id(), 1)->state(), wire::JOB_DONE);
}

/// A program's standard output (trimmed).
std::string output_of(const std::string& command) {
  std::string out;
  if (FILE* p = popen(command.c_str(), "r")) {
    char buf[256];
    while (fgets(buf, sizeof buf, p)) out += buf;
    pclose(p);
  }
  while (!out.empty() && (out.back() == '\n' || out.back() == ' ')) out.pop_back();
  return out;
}

/// An executable shell script standing in for ffmpeg.
fs::path fake_ffmpeg(const TempDir& dir, const std::string& body) {
  const fs::path path = dir.path() / "fake-ffmpeg";
  std::ofstream(path) << "#!/bin/sh\n" << body << "\n";
  fs::permissions(path, fs::perms::owner_all);
  return path;
}

TEST(SequencePreviews, TheContactSheetGrowsAndTheMovieComesWithTheLastFrame) {
  TempDir dir;
  JobStore store(dir.path() / "data");
  JobManager jobs(store);
  const std::string seq = jobs.submit(three_frames(), "alice");
  const fs::path sheet = store.job_dir(seq) / "contact.png";
  const fs::path movie = store.job_dir(seq) / "preview.mp4";
  EXPECT_EQ(jobs.status(seq, 1)->previews(),
            "contact sheet when a frame is done; movie when every frame is done");
  EXPECT_THROW(jobs.image(seq, false, true), JobRejected);  // no contact sheet yet

  finish_next_frame(jobs, 0.5);  // frame 1: mid grey
  jobs.wait_for_previews();
  ASSERT_TRUE(fs::exists(sheet));
  const std::string bytes = read_whole_file(sheet, 1 << 30);
  const DecodedImage png =
      decode_image({reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()}, "sheet");
  const SheetLayout layout = sheet_layout(3, 15, 9);
  ASSERT_EQ(png.width, layout.width());
  ASSERT_EQ(png.height, layout.height());
  ASSERT_EQ(png.channels, 3u);
  // Frame 1's cell holds its picture (0.5 -> sRGB 188), frames 3 and 5 are empty cells (48). The
  // cells' top right corners are clear of the labels.
  const auto at = [&](uint32_t x, uint32_t y) {
    return png.bytes[(size_t{y} * png.width + x) * 3];
  };
  const uint32_t right = kSheetGap + layout.cell_width - 1;
  EXPECT_EQ(at(right, kSheetGap), 188);
  EXPECT_EQ(at(right + layout.cell_width + kSheetGap, kSheetGap), 48);
  EXPECT_EQ(jobs.image(seq, false, /*sheet=*/true).png(), bytes);
  EXPECT_THROW(jobs.image(seq), JobRejected);  // a sequence has no image of its own
  EXPECT_EQ(jobs.status(seq, 1)->previews(), "contact sheet; movie when every frame is done");
  try {
    (void)jobs.image(seq, /*movie=*/true);
    ADD_FAILURE() << "a movie before every frame is done";
  } catch (const JobRejected& e) {
    EXPECT_NE(std::string(e.what()).find("movie when every frame is done"), std::string::npos);
  }
  EXPECT_FALSE(fs::exists(movie));

  finish_next_frame(jobs, 0.2);
  finish_next_frame(jobs, 0.8);
  jobs.wait_for_previews();
  ASSERT_TRUE(fs::exists(movie));
  EXPECT_EQ(jobs.status(seq, 1)->previews(), "contact sheet; movie");
  EXPECT_EQ(jobs.image(seq, true).mp4(), read_whole_file(movie, 1 << 30));
  // What ffprobe reads from it: 3 frames, padded to even sides, H.264, at the animation's 24 fps
  // over a step of 2.
  const std::string probe =
      "ffprobe -v error -select_streams v:0 -count_frames -of "
      "default=noprint_wrappers=1:nokey=1 -show_entries stream=";
  EXPECT_EQ(output_of(probe + "nb_read_frames '" + movie.string() + "'"), "3");
  EXPECT_EQ(output_of(probe + "width,height '" + movie.string() + "'"), "16\n10");
  EXPECT_EQ(output_of(probe + "codec_name '" + movie.string() + "'"), "h264");
  EXPECT_EQ(output_of(probe + "r_frame_rate '" + movie.string() + "'"), "12/1");
  // A still job has no movie.
  EXPECT_THROW(jobs.image(seq + ".0001", true), JobRejected);
}

TEST(SequencePreviews, ARestartMakesWhatIsMissing) {
  TempDir dir;
  std::string seq;
  {
    JobStore store(dir.path() / "data");
    JobManager jobs(store);
    seq = jobs.submit(three_frames(), "alice");
    for (int i = 0; i < 3; ++i) finish_next_frame(jobs, 0.5);
    jobs.wait_for_previews();
  }
  JobStore store(dir.path() / "data");
  const fs::path sheet = store.job_dir(seq) / "contact.png";
  const fs::path movie = store.job_dir(seq) / "preview.mp4";
  ASSERT_TRUE(fs::exists(sheet) && fs::exists(movie));
  const auto made = fs::last_write_time(movie);
  fs::remove(sheet);
  std::ofstream(store.job_dir(seq) / "preview.mp4.tmp-123-4") << "half a movie";
  {
    JobManager restarted(store);
    restarted.recover();
    restarted.wait_for_previews();
  }
  EXPECT_TRUE(fs::exists(sheet));
  EXPECT_EQ(fs::last_write_time(movie), made);                             // not made again
  EXPECT_FALSE(fs::exists(store.job_dir(seq) / "preview.mp4.tmp-123-4"));  // a stop's leftover
  // A sheet older than a finished frame (a stop before it was rewritten) is made again.
  const auto old =
      fs::last_write_time(store.job_dir(seq + ".0003") / "image.exr") - std::chrono::hours(1);
  fs::last_write_time(sheet, old);
  JobManager restarted(store);
  restarted.recover();
  restarted.wait_for_previews();
  EXPECT_GT(fs::last_write_time(sheet), old);
  // Removing the sequence removes its previews with its folder.
  restarted.remove(seq);
  EXPECT_FALSE(fs::exists(store.job_dir(seq)));
}

TEST(SequencePreviews, WithoutAWorkingFfmpegOnlyTheMovieIsSkippedWithTheCause) {
  TempDir dir;
  struct Case {
    std::string ffmpeg;
    std::string note;
  };
  const std::vector<Case> cases = {
      {"/nonexistent/ffmpeg", "no movie: ffmpeg not found (/nonexistent/ffmpeg)"},
      {fake_ffmpeg(dir, "echo 'first line' >&2; echo 'the encoder is broken' >&2; exit 3"),
       "no movie: ffmpeg exited with status 3: the encoder is broken"},
      {"", "no movie (turned off)"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.ffmpeg);
    JobStore store(dir.path() / ("data" + std::to_string(&c - cases.data())));
    JobManagerOptions options;
    options.ffmpeg = c.ffmpeg;
    JobManager jobs(store, options);
    const std::string seq = jobs.submit(three_frames(), "alice");
    for (int i = 0; i < 3; ++i) finish_next_frame(jobs, 0.5);
    jobs.wait_for_previews();
    const auto st = jobs.status(seq, 1);
    EXPECT_EQ(st->state(), wire::JOB_DONE);
    EXPECT_EQ(st->previews(), "contact sheet; " + c.note);
    EXPECT_TRUE(fs::exists(store.job_dir(seq) / "contact.png"));
    EXPECT_FALSE(fs::exists(store.job_dir(seq) / "preview.mp4"));
  }
}

TEST(SequencePreviews, AStoppingMasterDoesNotWaitForAHungFfmpeg) {
  TempDir dir;
  JobStore store(dir.path() / "data");
  JobManagerOptions options;
  options.ffmpeg = fake_ffmpeg(dir, "exec sleep 600").string();  // never reads, never ends
  auto jobs = std::make_unique<JobManager>(store, options);
  const std::string seq = jobs->submit(three_frames(), "alice");
  for (int i = 0; i < 3; ++i) finish_next_frame(*jobs, 0.5);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the movie under way
  const auto start = std::chrono::steady_clock::now();
  jobs.reset();
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));
  EXPECT_FALSE(fs::exists(store.job_dir(seq) / "preview.mp4"));
  // No temporary file is left behind either.
  for (const auto& entry : fs::directory_iterator(store.job_dir(seq))) {
    EXPECT_EQ(entry.path().filename().string().find("preview.mp4."), std::string::npos)
        << entry.path();
  }
}

}  // namespace
}  // namespace rayfarm::master
