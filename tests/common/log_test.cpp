// One record is one line, whatever its message holds: with --log-format json every record is one
// JSON object whose "msg" is the message; in text, control characters in the message are escaped so
// that a string from a peer cannot forge a line of its own.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <sstream>

#include "common/util/log.h"

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

TEST(LogTest, UnknownLevelIsRejected) {
  EXPECT_THROW(configure_logging("loud"), std::invalid_argument);
}

}  // namespace
}  // namespace rayfarm
