// `rayfarm report`: the built binary on error.csv files (table, summary slope, plots, errors naming
// file:line) and on jobs of a stand-in master that answers Hello, StatusRequest and FetchImage.
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "common/net/socket.h"
#include "common/protocol/codec.h"
#include "common/report/error_log.h"
#include "tests/e2e/process.h"
#include "tests/support/read_png.h"
#include "tests/support/temp_dir.h"

namespace rayfarm::test {
namespace {
namespace fs = std::filesystem;
namespace wire = rayfarm::wire;
using std::chrono::seconds;

struct RunResult {
  int code = -1;
  std::string out, err;
};

/// Rows of an unbiased render: relMSE = 0.05 / t, a reference from the third row on.
std::vector<ErrorRow> inverse_time_rows(int n) {
  std::vector<ErrorRow> rows;
  double t = 0.4;
  for (int i = 0; i < n; ++i, t *= 1.5) {
    ErrorRow r;
    r.time_s = t;
    r.spp = 4.0 * (i + 1);
    r.samples_per_s = 2.5e6;
    r.est_rel_mse = 0.05 / t;
    r.est_rmse = std::sqrt(r.est_rel_mse);
    if (i >= 2) r.ref_rel_mse = 1.1 * r.est_rel_mse;
    rows.push_back(r);
  }
  return rows;
}

/// The number after "slope " in `text`; NaN when there is none.
double reported_slope(const std::string& text) {
  const size_t at = text.find("slope ");
  if (at == std::string::npos) return std::nan("");
  return std::strtod(text.c_str() + at + 6, nullptr);
}

bool is_png(const fs::path& path) {
  const testing::RgbImage image = testing::read_png_rgb8(path);
  return image.error.empty() && image.width > 0 && image.height > 0;
}

class ReportTest : public ::testing::Test {
 protected:
  testing::TempDir dir_;

  /// Runs the built rayfarm with `args` in the test's folder, at most 30 s.
  RunResult cli(std::vector<std::string> args) {
    static int runs = 0;
    const std::string tag = std::to_string(runs++);
    const fs::path out = dir_.path() / ("out-" + tag), err = dir_.path() / ("err-" + tag);
    args.insert(args.begin(), (fs::path(RAYFARM_BINARY_DIR) / "cli" / "rayfarm").string());
    // The child runs in the test's folder, so that a default output lands there.
    const fs::path here = fs::current_path();
    fs::current_path(dir_.path());
    Process process(args, out, err);
    fs::current_path(here);
    const auto code = process.wait(std::chrono::seconds{30});
    return {code.value_or(-1), testing::read_file(out), testing::read_file(err)};
  }

  /// The options that let the CLI talk to a plain (non-CURVE) master on loopback, if it has any.
  std::vector<std::string> plain_master_options() {
    const RunResult help = cli({"report", "--help"});
    if (help.out.find("--insecure") != std::string::npos) return {"--insecure"};
    return {};
  }
};

TEST_F(ReportTest, PrintsTheTableTheSlopeAndThePlotBesideTheCsv) {
  const std::vector<ErrorRow> rows = inverse_time_rows(10);
  const fs::path csv = dir_.path() / "job" / "error.csv";
  fs::create_directories(csv.parent_path());
  write_error_csv(csv, rows);

  RunResult r = cli({"report", csv.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(count_of(r.out, "\n"), rows.size() + 3) << r.out;  // header, rows, summary, plot
  EXPECT_NE(r.out.find("est relMSE"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("ref relMSE"), std::string::npos) << r.out;
  EXPECT_NEAR(reported_slope(r.out), -1.0, 0.011) << r.out;
  EXPECT_NE(r.out.find("10 rows"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("none beside"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(dir_.path() / "job" / "error.png")) << "no -o: no plot drawn";

  // With the render's error.png beside it, the report points at it.
  write_error_plot(dir_.path() / "job" / "error.png", rows, "job");
  r = cli({"report", csv.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("plot: " + (dir_.path() / "job" / "error.png").string()), std::string::npos)
      << r.out;

  // -o draws the plot there.
  const fs::path plot = dir_.path() / "again.png";
  r = cli({"report", csv.string(), "-o", plot.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(is_png(plot));
  EXPECT_NE(r.out.find(plot.string()), std::string::npos) << r.out;
}

TEST_F(ReportTest, TheSlopeShowsABiasedRender) {
  // relMSE that stops falling (a bias of 1e-2) gives a slope well above -1.
  std::vector<ErrorRow> rows = inverse_time_rows(12);
  for (ErrorRow& row : rows) row.est_rel_mse += 1e-2;
  const fs::path csv = dir_.write("error.csv", format_error_csv(rows));
  const RunResult r = cli({"report", csv.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_GT(reported_slope(r.out), -0.5) << r.out;
}

TEST_F(ReportTest, FileErrorsAreClear) {
  const std::string header = format_error_csv({});
  const fs::path bad = dir_.write("bad.csv", header + "1,2,3,4,5,,,,\n1,2,x,4,5,,,,\n");
  RunResult r = cli({"report", bad.string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find(bad.string() + ":3:"), std::string::npos) << r.err;

  const fs::path missing = dir_.path() / "missing.csv";
  r = cli({"report", missing.string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find(missing.string()), std::string::npos) << r.err;

  const fs::path empty = dir_.write("empty.csv", header);
  r = cli({"report", empty.string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("no rows"), std::string::npos) << r.err;
}

TEST_F(ReportTest, AnUnreachableMasterIsExitCode3) {
  const int port = free_port();
  std::vector<std::string> args = {
      "report", "j0001", "--master", "tcp://127.0.0.1:" + std::to_string(port), "--timeout", "0.5"};
  for (const std::string& o : plain_master_options()) args.push_back(o);
  const auto start = Clock::now();
  const RunResult r = cli(args);
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_NE(r.err.find("cannot reach master"), std::string::npos) << r.err;
  EXPECT_LT(Clock::now() - start, seconds{10});
}

/// A master that knows two jobs: j0001 with an error record and j0002 with no image yet.
class StandInMaster {
 public:
  explicit StandInMaster(std::string csv) : socket_("tcp://127.0.0.1:0"), csv_(std::move(csv)) {
    thread_ = std::thread([this] { serve(); });
  }
  ~StandInMaster() {
    stop_ = true;
    thread_.join();
  }
  std::string endpoint() const { return endpoint_; }

 private:
  net::Router socket_;
  const std::string endpoint_ = socket_.endpoint();
  std::string csv_;
  std::atomic<bool> stop_{false};
  std::thread thread_;

  void serve() {
    while (!stop_) {
      auto delivery = socket_.receive(milliseconds{20});
      if (!delivery) continue;
      const protocol::Decoded msg = protocol::decode(delivery->frames);
      if (msg.as<wire::Hello>()) {
        socket_.send(delivery->peer, protocol::encode(wire::Welcome{}));
      } else if (const auto* status = msg.as<wire::StatusRequest>()) {
        socket_.send(delivery->peer, answer_status(status->job_id()));
      } else if (const auto* fetch = msg.as<wire::FetchImage>()) {
        socket_.send(delivery->peer, answer_fetch(fetch->job_id()));
      }
    }
  }
  static net::Frames error(const std::string& message) {
    wire::Error e;
    e.set_message(message);
    return protocol::encode(std::move(e));
  }
  net::Frames answer_status(const std::string& job) const {
    if (job != "j0001" && job != "j0002") return error("unknown job '" + job + "'");
    wire::JobStatus st;
    st.set_job_id(job);
    st.set_name("cornell-box/scene.json");
    st.set_state(job == "j0001" ? wire::JOB_DONE : wire::JOB_QUEUED);
    st.set_stop_reason(job == "j0001" ? "target error" : "");
    st.set_spp_mean(job == "j0001" ? 37.5 : 0.0);
    st.set_tiles_converged(job == "j0001" ? 12 : 0);
    st.set_tiles_total(16);
    st.set_est_rel_mse(job == "j0001" ? 2.5e-3 : -1.0);
    st.set_ref_rel_mse(-1.0);
    return protocol::encode(std::move(st));
  }
  net::Frames answer_fetch(const std::string& job) const {
    if (job != "j0001") return error("job " + job + " has no image yet (no unit has been merged)");
    wire::ImageData image;
    image.set_job_id(job);
    image.set_exr("not an exr: the report does not read it");
    image.set_error_csv(csv_);
    return protocol::encode(std::move(image));
  }
};

TEST_F(ReportTest, ReportsAJobOfTheMaster) {
  const std::vector<ErrorRow> rows = inverse_time_rows(8);
  StandInMaster master(format_error_csv(rows));
  std::vector<std::string> client = {"--master", master.endpoint(), "--timeout", "10"};
  for (const std::string& o : plain_master_options()) client.push_back(o);
  const auto with_client = [&](std::vector<std::string> args) {
    args.insert(args.end(), client.begin(), client.end());
    return args;
  };

  RunResult r = cli(with_client({"report", "j0001"}));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NEAR(reported_slope(r.out), -1.0, 0.011) << r.out;
  EXPECT_NE(r.out.find("target error"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("12/16"), std::string::npos) << r.out;
  // No plot from the master: drawn here, under the default name, in the current folder.
  EXPECT_TRUE(is_png(dir_.path() / "j0001-error.png"));
  EXPECT_NE(r.out.find("j0001-error.png"), std::string::npos) << r.out;

  const fs::path plot = dir_.path() / "mine.png";
  r = cli(with_client({"report", "j0001", "-o", plot.string()}));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(is_png(plot));

  r = cli(with_client({"report", "j0002"}));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("no error rows yet"), std::string::npos) << r.err;

  r = cli(with_client({"report", "j0404"}));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("unknown job 'j0404'"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace rayfarm::test
