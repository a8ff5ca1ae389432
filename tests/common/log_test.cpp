// One record is one line, whatever its message holds: with --log-format json every record is one
// JSON object whose "msg" is the message; in text, control characters in the message are escaped so
// that a string from a peer cannot forge a line of its own.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <sstream>

#include "common/util/log.h"
#include "common/util/log_throttle.h"

namespace rayfarm {
namespace {

TEST(LogTest, JsonRecordsStayValidWithQuotesBackslashesAndControlCharacters) {
  configure_logging("info", LogFormat::kJson);
  const std::string message = "scene \"a.json\": C:\\path\tline\nnext \x01 end";
  ::testing::internal::CaptureStderr();
  auto logger = get_logger("logtest");
  logger->info("{}", message);
  logger->flush();
  const std::string out = ::testing::internal::GetCapturedStderr();
  configure_logging("info", LogFormat::kText);
  std::istringstream lines(out);
  std::string line;
  ASSERT_TRUE(std::getline(lines, line)) << "no record written";
  const nlohmann::json record = nlohmann::json::parse(line);  // throws on invalid JSON
  EXPECT_EQ(record.at("msg").get<std::string>(), message);
  EXPECT_EQ(record.at("logger").get<std::string>(), "logtest");
  EXPECT_EQ(record.at("level").get<std::string>(), "info");
  EXPECT_FALSE(std::getline(lines, line)) << "one record must be one line";
}

TEST(LogTest, TextRecordsEscapeControlCharactersSoAPeerCannotForgeALine) {
  configure_logging("info", LogFormat::kText);
  // A scene path as a client might send it: a newline followed by what looks like a record.
  const std::string forged = "2026-01-01 00:00:00.000 error [jobs] FAKE LINE";
  const std::string message = "x\n" + forged + "\r\tend\x01\x1b[31m\x7f.";
  ::testing::internal::CaptureStderr();
  auto logger = get_logger("logtest-text");
  logger->warn("job refused: scene '{}'", message);
  logger->flush();
  const std::string out = ::testing::internal::GetCapturedStderr();
  std::istringstream lines(out);
  std::string line;
  ASSERT_TRUE(std::getline(lines, line)) << "no record written";
  EXPECT_FALSE(std::getline(lines, line)) << "one record must be one line:\n" << out;
  const std::string record = out.substr(0, out.find('\n'));
  EXPECT_NE(record.find(" [logtest-text] job refused: scene 'x\\n" + forged +
                        "\\r\\tend\\x01\\x1b[31m\\x7f.'"),
            std::string::npos)
      << record;
  for (const char c : record) {
    const auto byte = static_cast<unsigned char>(c);
    EXPECT_FALSE(byte < 0x20 || byte == 0x7f) << "control byte " << int(byte) << " in " << record;
  }
  // Printable text, UTF-8 included, is written as it is.
  ::testing::internal::CaptureStderr();
  logger->info("scène \"a.json\": C:\\path");
  logger->flush();
  const std::string plain = ::testing::internal::GetCapturedStderr();
  EXPECT_NE(plain.find("[logtest-text] scène \"a.json\": C:\\path\n"), std::string::npos) << plain;
}

TEST(LogThrottleTest, FirstOccurrenceThenAtMostOneLinePerIntervalWithTheCount) {
  using std::chrono::seconds;
  LogThrottle throttle(seconds{10});
  const LogThrottle::Clock::time_point t0{seconds{1000}};
  const auto first = throttle.occur(t0);
  EXPECT_TRUE(first.log);
  EXPECT_EQ(first.unlogged, 0u);
  EXPECT_EQ(LogThrottle::suffix(first), "");
  for (int i = 1; i <= 9; ++i) EXPECT_FALSE(throttle.occur(t0 + seconds{i}).log) << i;
  const auto summary = throttle.occur(t0 + seconds{10});
  EXPECT_TRUE(summary.log);
  EXPECT_EQ(summary.unlogged, 9u);
  EXPECT_EQ(LogThrottle::suffix(summary), " (9 more since the last line)");
  // The interval runs from the last line logged, not from the first occurrence.
  EXPECT_FALSE(throttle.occur(t0 + seconds{19}).log);
  const auto next = throttle.occur(t0 + seconds{20});
  EXPECT_TRUE(next.log);
  EXPECT_EQ(next.unlogged, 1u);
  EXPECT_EQ(throttle.total(), 13u);
}

TEST(LogTest, UnknownLevelIsRejected) {
  EXPECT_THROW(configure_logging("loud"), std::invalid_argument);
}

}  // namespace
}  // namespace rayfarm
